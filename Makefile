# Quick start:  make results   (set up .venv, regenerate every result into results/)
#               make test      (run the test suite)
#               make docs      (build the documentation into docs/_build/html)
#               make lab       (open the notebooks in JupyterLab)
# run_all.py options go through ARGS, e.g.  make results ARGS="--only fig04_line_bending -p sigma2=0.02"
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
JOBS   ?=
ARGS   ?=

.PHONY: setup results quick test test-processes test-all docs lab bench mutate clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[study,dev,models]'
	$(PY) -m shapelib._warmup  # the numba kernels compiled once, into numba's cache beside the sources
	touch $@

$(VENV)/.docs-installed: $(VENV)/.installed pyproject.toml
	$(PY) -m pip install --quiet -e '.[docs]'
	touch $@

setup: $(VENV)/.installed

results: setup
	$(PY) run_all.py $(if $(JOBS),-j $(JOBS),) $(ARGS)

quick: setup
	$(PY) run_all.py --quick $(ARGS)

# the suite on every core (pytest-xdist; idle workers take queued tests from busy ones); `$(PY) -m pytest tests/test_x.py` runs part of it in one process.
# Python may write its bytecode (and pytest its rewritten test modules) even where the environment says
# not to (PYTHONDONTWRITEBYTECODE): otherwise every worker, CLI child and notebook kernel compiles them again
PYTEST := PYTHONDONTWRITEBYTECODE= $(PY) -m pytest -n logical --dist worksteal
test: setup
	$(PYTEST)

# the tests that start real processes (Dask clusters, the command line in a child, notebook kernels), most
# of them to stop, kill or signal them mid-run (pytest marker `processes`; about three minutes on two
# cores; CI runs them before `make test`)
test-processes: setup
	$(PYTEST) -m processes

# every test, the slow ones too (the JAX backend's batched and engine paths, the GPU benchmark's CPU check,
# the study notebooks' quick runs) and the processes ones
test-all: setup
	$(PYTEST) -m ""

# nitpicky, warnings are errors; the examples of docs/examples are executed (sphinx-gallery; unchanged
# ones are not re-run), and the study notebooks (run_all.py: the paper's figures with their full
# parameters, the others with their quick ones; unchanged ones are not re-run), and both rendered with
# their figures; SHAPELIB_DOCS_NOTEBOOKS=results renders a full run's notebooks from results/ instead
docs: $(VENV)/.docs-installed
	$(VENV)/bin/sphinx-build -W --keep-going -b html docs docs/_build/html
	@echo "documentation: docs/_build/html/index.html"

# the notebooks are jupytext .py files: right-click one, Open With > Jupytext Notebook
lab: setup
	$(VENV)/bin/jupyter lab --notebook-dir=.

# measurements for the documentation's performance page (docs/_data/benchmarks/*.json; minutes);
# benchmarks/bench_solvers.py --record (about 13 min) is run by hand
bench: setup
	$(PY) -m pip install --quiet -e '.[bench]'
	$(PY) benchmarks/bench_geodesic.py --record
	$(PY) benchmarks/bench_bracket.py --record
	$(PY) benchmarks/bench_pairwise.py --record
	$(PY) benchmarks/bench_registration.py --samples 10 --record
	$(PY) benchmarks/bench_registration_landmarks.py --samples 10 --record
	$(PY) benchmarks/bench_registration_3d.py --record
	$(PY) benchmarks/bench_registration_batch.py --record
	$(PY) benchmarks/bench_registration_large.py --record

# mutation testing of one module of the numerical core, or of those changed since a commit, against the tests
# that cover it (benchmarks/mutation_targets.toml; minutes per module; not part of `make test`):
#   make mutate MODULE=shapelib/geometry/gmm.py     make mutate SINCE=main     (RECORD=1: into the docs' record)
#   make mutate MODULE=shapelib/pointsets/_batch.py ONLY="_search _register_jax"   (those functions' mutants only)
MODULE ?=
ONLY   ?=
SINCE  ?=
RECORD ?=
mutate: setup
	nice -n 10 $(PY) benchmarks/mutation.py $(MODULE) $(if $(SINCE),--since $(SINCE),) $(if $(ONLY),--only $(ONLY),) $(if $(RECORD),--record,)

clean:
	rm -rf $(VENV) results/*/ results/REPORT.md docs/_build docs/api/generated docs/api/reference docs/api/backreferences docs/auto_examples \
	       docs/sg_execution_times.rst docs/notebooks/*.ipynb
