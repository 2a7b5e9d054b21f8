# Every target creates or refreshes the virtual environment from pyproject.toml itself,
# so on a fresh machine `make demo` and `make test` are the only commands needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
export XLA_FLAGS ?= --xla_force_host_platform_device_count=2
export PYTHONHASHSEED := 0

.PHONY: venv venv-bench venv-docs demo test test-slow lint bench docs clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	-$(BIN)/python -m pip install -q uv

# uv (from the registry, into the venv) downloads and installs in parallel: a fresh venv
# takes about 25 s instead of about 4 minutes with pip. Where uv is missing or fails, pip
# does the same install. uv compiles the bytecode as pip does (--compile-bytecode, about
# 14 s more): without it every process compiles its imports again where bytecode is not
# written (PYTHONDONTWRITEBYTECODE=1), 9.8 s of imports against 3.4 s, and a user's first
# fit pays it once.
INSTALL = sh -c '{ $(BIN)/python -c "import uv" 2>/dev/null \
	&& $(BIN)/python -m uv pip install -q --compile-bytecode --python $(BIN)/python "$$@"; } \
	|| $(BIN)/python -m pip install -q "$$@"' install

# The stamp is rebuilt whenever pyproject.toml changes.
$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	$(INSTALL) -e '.[dev]'
	touch $@

$(VENV)/.installed-bench: pyproject.toml $(VENV)/.installed-dev
	$(INSTALL) -e '.[dev,bench]'
	touch $@

$(VENV)/.installed-docs: pyproject.toml $(VENV)/.installed-dev
	$(INSTALL) -e '.[dev,docs]'
	touch $@

venv: $(VENV)/.installed-dev
venv-bench: $(VENV)/.installed-bench
venv-docs: $(VENV)/.installed-docs

demo: venv
	$(BIN)/are-stats demo --out demo-output --force

lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check are_stats tests

# Two workers, each taking whole test files (module fixtures are built once), the longest
# files first (tests/conftest.py: HEAVY_FILES); TEST_WORKERS=0 runs the suite serially.
# `make test` leaves out the tests marked slow (longer statistical tests, each with a
# cheaper check of its feature in the default run); `make test-slow` runs only those, the
# same way. CI (.ci/run) runs both, so every test runs there.
TEST_WORKERS ?= 2
PYTEST = $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=15
test: venv
	$(BIN)/ruff check .
	$(PYTEST) -m "not slow"

test-slow: venv
	$(PYTEST) -m slow

bench: venv-bench
	$(BIN)/python -m tests.benchmarks

# Figures (docs/make_figures.py) and the executed notebooks are made during the build and
# cached in docs/.cache; the site lands in docs/site.
docs: venv-docs
	$(BIN)/mkdocs build --strict -f docs/mkdocs.yml

clean:
	rm -rf $(VENV) docs/site docs/.cache .pytest_cache .ruff_cache
