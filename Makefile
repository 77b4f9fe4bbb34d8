# Two commands (README "Quick start"):  make run   and   make test
# Both build .venv on first use and are idempotent: the install is redone only when
# pyproject.toml changes.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
CORES  ?= 2

.PHONY: run test test-fast lint docs bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml $(VENV)/.installed
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@

# A Snakemake process: its command line starts with the program, `[python] [-m] [dir/]snakemake`
# (what pgrep -f matches: the arguments joined by spaces).  Anchored at the program, the pattern
# cannot match this recipe's own shell (`/bin/sh -c ...`), whose command line contains it.
SNAKEMAKE_PROCESS := ^([^ ]*/)?(python[0-9.]* (-m )?([^ ]*/)?)?snakemake( |$$)

# Snakemake's lock (.snakemake/locks) names no owner: a run killed with kill -9 leaves it behind
# and the next run stops with a LockException.  Clear it only when no Snakemake that takes the
# lock runs in this checkout: none of this user's Snakemake processes working in this folder,
# dry runs and unlocks aside (they take no lock); without /proc (not Linux): none of the
# user's Snakemake processes anywhere.  Then resume: finished time blocks are kept, the killed
# run's jobs and workers have died with it.
run: $(VENV)/.installed
	@running=; for p in $$(pgrep -u "$$(id -u)" -f '$(SNAKEMAKE_PROCESS)'); do \
		if [ -d /proc/self ]; then \
			[ "$$(readlink /proc/$$p/cwd 2>/dev/null)" = "$(CURDIR)" ] || continue; \
			tr '\0' '\n' </proc/$$p/cmdline 2>/dev/null | grep -qxE -- '-n|--dry-?run|--unlock' && continue; \
		fi; running="$$running $$p"; done; \
	if [ -z "$$running" ]; then PATH="$(abspath $(BIN)):$$PATH" $(BIN)/snakemake --unlock -q >/dev/null 2>&1 || true; \
	else echo "make run: Snakemake is running here (pid$$running): its lock is kept"; fi
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/snakemake --cores $(CORES) --rerun-incomplete

# the whole suite, slow tests included (this is what CI runs), in TEST_WORKERS processes (a test
# module's tests stay together in one, the modules handed out in tests/conftest.py's order, not
# pytest-xdist's by number of tests; the slowest 25 tests are listed at the end)
TEST_WORKERS ?= 2
test: $(VENV)/.installed-test
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile \
		--no-loadscope-reorder --durations=25

# quick loop for development: skips tests marked slow
test-fast: $(VENV)/.installed-test
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pytest -q -m "not slow"

# ruff: the code's layout (ruff format), then pyflakes, import order, line length and numpy
# docstrings (pyproject.toml [tool.ruff]); Snakemake's own lint of the workflow
lint: $(VENV)/.installed-test
	$(BIN)/ruff format --check .
	$(BIN)/ruff check .
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/snakemake --lint

# the API reference from the docstrings (docs/api/), warnings as errors, into docs/api/_build/html;
# tests/test_api_reference.py runs the same build in `make test`
docs: $(VENV)/.installed-test
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs/api docs/api/_build/html

bench: $(VENV)/.installed-test
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python bench/ephemeris.py
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python bench/image.py

clean:
	rm -rf results .snakemake
