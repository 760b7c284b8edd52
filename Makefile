# fleetplan: the two commands a newcomer needs are `make run` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: run test lint bench install clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# Reinstall whenever the project's dependencies change.
$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/fleetplan plan planner/examples/paper-circle8.json -o plan-paper-circle8.json

test: $(STAMP)
	$(PY) -m ruff check planner gcs tests bench
	$(PY) -m pytest

lint: $(STAMP)
	$(PY) -m ruff check planner gcs tests bench

bench: $(STAMP)
	$(PY) bench/planner.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
