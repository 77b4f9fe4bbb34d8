# Two commands (README "Quick start"):  make run   and   make test
# Both build .venv on first use and are idempotent: the install is redone only when
# pyproject.toml changes.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
CORES  ?= 2

.PHONY: run test test-fast lint bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml $(VENV)/.installed
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@

# A run killed with kill -9 leaves Snakemake's lock behind: clear it, but only when no
# Snakemake of this .venv is running, then resume (finished time blocks are kept).
run: $(VENV)/.installed
	@if ! pgrep -f "$(abspath $(BIN))/snakemake" >/dev/null; then \
		PATH="$(abspath $(BIN)):$$PATH" $(BIN)/snakemake --unlock -q >/dev/null 2>&1 || true; fi
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/snakemake --cores $(CORES) --rerun-incomplete

# the whole suite, slow tests included (this is what CI runs)
test: $(VENV)/.installed-test
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pytest -q

# quick loop for development: skips tests marked slow
test-fast: $(VENV)/.installed-test
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pytest -q -m "not slow"

lint: $(VENV)/.installed
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/snakemake --lint

bench: $(VENV)/.installed-test
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python bench/ephemeris.py
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python bench/image.py

clean:
	rm -rf results .snakemake
