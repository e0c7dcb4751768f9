# Two commands for a fresh machine with only python3:
#   make demo   simulate the paper's Table 2 experiment once; print LS, BCLS, AsML next to the truth
#   make test   run the test suite (the default run excludes tests marked slow)
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow lint format-check bench reproduce clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m jitterid.demo

test: $(STAMP)
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy

# Not part of lint yet: the code has not been through `ruff format` (82 files would change).
format-check: $(STAMP)
	$(BIN)/ruff format --check src tests benchmarks

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

reproduce: $(STAMP)
	$(BIN)/jitterid reproduce all --out docs/reproduction

clean:
	rm -rf $(VENV) build dist .pytest_cache .mypy_cache .ruff_cache
