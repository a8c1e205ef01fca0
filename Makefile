# Two commands do all the set-up on a fresh clone:
#   make demo     - virtual environment, install, then the main job on a small default
#   make test     - the same set-up, then the test suite but the tests marked slow, on 2 processes
#   make test-all - every test `make test` ran before issue 40, slow ones included (what CI runs)
#   make lint     - ruff, as configured in pyproject.toml (CI runs it first)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
# The CPU build of torch; an unpinned torch pulls a CUDA build of several GB.
TORCH  ?= torch==2.13.0

# Test processes (pytest-xdist): the project's machine has 2 cores.
TEST_WORKERS ?= 2

.PHONY: demo test test-all lint install bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install "$(TORCH)"
	$(BIN)/python -m pip install -e ".[dev,parquet,cluster,diagnostics]"
	touch $@

install: $(VENV)/.installed

# The main job on a small default: generate a small dataset, train every model
# family, benchmark them on the same test split and write reports/quick/.
demo: install
	$(BIN)/hybrid-dyn bench --profile quick --out reports/quick

test: install
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) -m "not slow"

test-all: install
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS)

# The linter (ruff, configured in pyproject.toml); .ci/run runs it before the tests.
lint: install
	$(BIN)/ruff check src tests benchmarks checks examples

bench: install
	$(BIN)/python benchmarks/analytic_speed.py

clean:
	rm -rf $(VENV)
