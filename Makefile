# Quick start:  make results   (set up .venv, regenerate every result into results/)
#               make test      (run the test suite)
#               make lab       (open the notebooks in JupyterLab)
# run_all.py options go through ARGS, e.g.  make results ARGS="--only fig04_line_bending -p sigma2=0.02"
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
JOBS   ?=
ARGS   ?=

.PHONY: setup results quick test lab bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[study,dev]'
	touch $@

setup: $(VENV)/.installed

results: setup
	$(PY) run_all.py $(if $(JOBS),-j $(JOBS),) $(ARGS)

quick: setup
	$(PY) run_all.py --quick $(ARGS)

test: setup
	$(PY) -m pytest

# the notebooks are jupytext .py files: right-click one, Open With > Jupytext Notebook
lab: setup
	$(VENV)/bin/jupyter lab --notebook-dir=.

bench: setup
	$(PY) benchmarks/bench_geodesic.py

clean:
	rm -rf $(VENV) results/*/ results/REPORT.md
