# Quick start:  make results   (set up .venv, regenerate every result into results/)
#               make test      (run the test suite)
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
JOBS   ?=

.PHONY: setup results quick test bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[study,dev]'
	touch $@

setup: $(VENV)/.installed

results: setup
	$(PY) run_all.py $(if $(JOBS),-j $(JOBS),)

quick: setup
	$(PY) run_all.py --quick

test: setup
	$(PY) -m pytest

bench: setup
	$(PY) benchmarks/bench_geodesic.py

clean:
	rm -rf $(VENV) results/*/ results/REPORT.md
