# Every target creates or refreshes the virtual environment from pyproject.toml itself,
# so on a fresh machine `make demo` and `make test` are the only commands needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
export XLA_FLAGS ?= --xla_force_host_platform_device_count=2
export PYTHONHASHSEED := 0

.PHONY: venv venv-bench venv-docs demo test test-slow lint bench docs clean

# The venv's own pip installs uv (a fresh venv's bundled pip does this as well as an upgraded
# one: the self-upgrade cost 14 s wall, 3.4 s CPU, for nothing).
$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	-$(BIN)/python -m pip install -q uv

# uv (from the registry, into the venv) downloads and installs in parallel: a fresh venv
# takes about 25 s instead of about 4 minutes with pip. Where uv is missing or fails, pip
# does the same install.
INSTALL = sh -c '{ $(BIN)/python -c "import uv" 2>/dev/null \
	&& $(BIN)/python -m uv pip install -q --python $(BIN)/python "$$@"; } \
	|| $(BIN)/python -m pip install -q "$$@"' install

# Two stamps, each rebuilt whenever pyproject.toml changes. `make demo` needs only the
# package (.installed); the dev extra (pytest, hypothesis, ruff, the docs and notebook
# tools: 2,000 more files) is for `make test`, `make lint`, `make test-slow` (.installed-dev,
# which stands for .installed too). The dev install also compiles the bytecode of the whole
# environment (UV_COMPILE_BYTECODE, as pip does by default): the test run starts many
# processes, and where bytecode is not written (PYTHONDONTWRITEBYTECODE=1) each of them
# would compile its imports again (the demo's imports: 20.6 s CPU without bytecode, 7.2 s
# with). The demo is one process: compiling its 7,900 files first costs more CPU (69 s
# with compileall) than compiling what it imports once (13.5 s), so the run-only install
# leaves it to Python (issue 29, measurements in the commit).
# uv compiles only what it installs: what the run-only install left without bytecode
# (.uncompiled) is compiled when the dev extra comes (compileall: 13.6 s CPU even where
# every file is compiled, so only then). Bytecode only saves time: a file some package ships
# that does not compile (compileall's exit 1) must not stop the install.
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(INSTALL) -e .
	touch $(VENV)/.uncompiled $@

$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	UV_COMPILE_BYTECODE=1 $(INSTALL) -e '.[dev]'
	if [ -e $(VENV)/.uncompiled ]; then \
		$(BIN)/python -m compileall -q -j 0 $(VENV)/lib > /dev/null || true; \
		rm $(VENV)/.uncompiled; fi
	touch $(VENV)/.installed $@

$(VENV)/.installed-bench: pyproject.toml $(VENV)/.installed-dev
	UV_COMPILE_BYTECODE=1 $(INSTALL) -e '.[dev,bench]'
	touch $@

$(VENV)/.installed-docs: pyproject.toml $(VENV)/.installed-dev
	UV_COMPILE_BYTECODE=1 $(INSTALL) -e '.[dev,docs]'
	touch $@

venv: $(VENV)/.installed-dev
venv-bench: $(VENV)/.installed-bench
venv-docs: $(VENV)/.installed-docs

demo: $(VENV)/.installed
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
