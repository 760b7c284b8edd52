# fleetplan: the two commands a newcomer needs are `make run` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

# Python caches compiled modules here even where the environment says not to
# (PYTHONDONTWRITEBYTECODE, common in container images): without the cache every process the
# suite starts (services, planner and Dask workers, CLI runs) compiles numpy, scipy, FastAPI
# and the rest again, about 2.5 s of CPU each. The caches stay in the venv and __pycache__/.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test test-fast lint bench install clean test-tools docs

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet uv

# Reinstall whenever the project's dependencies change. uv installs the same packages from
# the same index as pip, in seconds rather than a minute and a half, and compiles them at once
# (on every core) rather than in each process that first imports them; pip is the fallback.
$(STAMP): pyproject.toml | $(PY)
	$(VENV)/bin/uv pip install --quiet --compile-bytecode --python $(PY) -e '.[test]' || \
	  $(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# The service with mock vehicles (4, and as many as a plan needs up to 256): open the printed
# URL (Ctrl-C stops it). Host, port and the rest come from the settings (defaults
# 127.0.0.1:8000; FLEETPLAN_HOST, FLEETPLAN_PORT, ./fleetplan.toml), so nothing is forced here.
run: $(STAMP)
	$(VENV)/bin/fleetplan serve

# Test processes (pytest-xdist): one per core, plus one when the machine is idle at the start
# (tests/jobs.py), at most 3; `make test JOBS=N` to choose.
JOBS ?= $(shell $(PYTHON) tests/jobs.py 2>/dev/null || echo 2)

# Every check: ruff, then every test with mypy beside them (its report follows the tests').
# Test files run in parallel processes (JOBS), one file per process at a time; the 15 slowest
# tests are listed at the end.
test: $(STAMP) test-tools
	$(PY) -m ruff check planner gcs tests bench
	@$(PY) -m mypy > $(VENV)/mypy.log 2>&1 & types=$$!; \
	$(PY) -m pytest -n $(JOBS) --dist loadfile --durations=15; tests=$$?; \
	wait $$types; typed=$$?; echo "mypy:"; cat $(VENV)/mypy.log; \
	test $$tests -eq 0 && test $$typed -eq 0

# The inner loop: no browser and no full mock flights (markers `browser`, `flight`).
test-fast: $(STAMP)
	$(PY) -m pytest -n $(JOBS) --dist loadfile --durations=15 \
	  -m "not browser and not flight"

# The browser tests drive Debian's Chromium; docker-compose validates docker-compose.yml;
# a throwaway PostgreSQL server checks the service on it. Installed here when missing and
# possible (root with apt-get), never interactively.
test-tools:
	@missing=""; \
	command -v chromium >/dev/null 2>&1 || missing="$$missing chromium"; \
	command -v docker-compose >/dev/null 2>&1 || missing="$$missing docker-compose"; \
	ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || missing="$$missing postgresql"; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing$$missing (Debian packages) for the browser, deployment, database tests"; \
	    DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null && \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq$$missing >/dev/null || \
	    echo "could not install$$missing: those tests will skip"; \
	  else \
	    echo "not installed:$$missing (sudo apt-get install$$missing); those tests will skip"; \
	  fi; \
	fi

lint: $(STAMP)
	$(PY) -m ruff check planner gcs tests bench
	$(PY) -m mypy

bench: $(STAMP)
	$(PY) bench/planner.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache .mypy_cache site

# The documentation site (MkDocs, Material theme) from docs/ into site/; --strict turns broken
# links, anchors and pages missing from the nav into errors. Nothing is fetched: it builds offline.
docs: $(STAMP)
	$(PY) -m mkdocs build --strict --site-dir site
