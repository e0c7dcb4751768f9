# Two commands for a fresh machine with only python3:
#   make demo   simulate the paper's Table 2 experiment once; print LS, BCLS, AsML next to the truth
#   make test   run the test suite (the default run excludes tests marked slow)
# make docs builds the Sphinx site into docs/_build/html (warnings are errors).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow test-wheel lint format-check bench reproduce docs clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m jitterid.demo

test: $(STAMP)
	$(BIN)/python -m pytest -q

# Build the sdist and wheel, install the wheel into a fresh virtual environment and run the
# README's example there (tests/docs/test_wheel.py; downloads the dependencies).
test-wheel: $(STAMP)
	$(BIN)/python -m pytest -q -m slow tests/docs/test_wheel.py

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples docs/conf.py
	$(BIN)/ruff format --check src tests benchmarks examples docs/conf.py
	$(BIN)/mypy

format-check: $(STAMP)
	$(BIN)/ruff format --check src tests benchmarks examples docs/conf.py

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

reproduce: $(STAMP)
	$(BIN)/jitterid reproduce all --out docs/reproduction

# The docs extra is installed on first use (the dev venv does not carry Sphinx).
docs: $(STAMP)
	$(BIN)/python -c "import sphinx, numpydoc, sphinx_gallery, pydata_sphinx_theme, myst_parser" 2>/dev/null \
		|| $(BIN)/python -m pip install --quiet -e ".[docs]"
	$(BIN)/python -m sphinx -W --keep-going -b html docs docs/_build/html

clean:
	rm -rf $(VENV) build dist .pytest_cache .mypy_cache .ruff_cache
