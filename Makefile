# Every target creates or refreshes the virtual environment from pyproject.toml itself,
# so on a fresh machine `make demo` and `make test` are the only commands needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
export XLA_FLAGS ?= --xla_force_host_platform_device_count=2
export PYTHONHASHSEED := 0

.PHONY: venv venv-bench demo test lint bench docs clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

# The stamp is rebuilt whenever pyproject.toml changes.
$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $@

$(VENV)/.installed-bench: pyproject.toml $(VENV)/.installed-dev
	$(BIN)/python -m pip install -q -e '.[dev,bench]'
	touch $@

venv: $(VENV)/.installed-dev
venv-bench: $(VENV)/.installed-bench

demo: venv
	$(BIN)/are-stats demo --out demo-output --force

lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check are_stats tests

test: venv
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q

bench: venv-bench
	$(BIN)/python -m tests.benchmarks

docs: venv
	$(BIN)/mkdocs build --strict -f docs/mkdocs.yml

clean:
	rm -rf $(VENV) docs/site .pytest_cache .ruff_cache
