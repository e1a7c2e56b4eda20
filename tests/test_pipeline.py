"""run_all.py: atomic results, skipping unchanged inputs, failures that name the cell, kills."""
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

import run_all
from tests.conftest import ROOT, requires_data

GOOD = textwrap.dedent('''\
    # %% tags=["parameters"]
    output_dir = "x"
    value = 1.0
    sleep = 0.0

    # %%
    import time
    from shapelib.study import record_values
    time.sleep(sleep)
    record_values(output_dir, {"toy/value": value})
''')
BROKEN = GOOD.replace("record_values(output_dir", "raise RuntimeError('boom')\nrecord_values(output_dir")


@pytest.fixture
def toy(tmp_path, monkeypatch):
    nbdir = tmp_path / "notebooks"
    nbdir.mkdir()
    (nbdir / "toy.py").write_text(GOOD)
    monkeypatch.setattr(run_all, "NOTEBOOK_DIR", nbdir)
    monkeypatch.setitem(run_all.NOTEBOOKS, "toy", {"params": {"value": 2.0}, "quick": {"value": 3.0}, "data": [], "expects": {}})
    return nbdir, tmp_path / "results"


def values(results, name="toy"):
    return json.loads((results / name / "values.json").read_text())["values"]


def test_runs_skips_unchanged_and_reruns_on_change(toy):
    nbdir, results = toy
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results)[1] == "ok"
    assert values(results) == {"toy/value": 2.0}
    assert (results / "toy" / "toy.ipynb").exists()
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results)[1] == "skipped"
    assert run_all.run_one("toy", quick=False, force=True, results_dir=results)[1] == "ok"
    # other parameters -> other inputs -> re-run
    assert run_all.run_one("toy", quick=True, force=False, results_dir=results)[1] == "ok"
    assert values(results) == {"toy/value": 3.0}
    # a changed notebook source -> re-run
    (nbdir / "toy.py").write_text(GOOD.replace("value = 1.0", "value = 1.5"))
    assert run_all.run_one("toy", quick=True, force=False, results_dir=results)[1] == "ok"


def test_failure_names_the_cell_and_keeps_previous_results(toy):
    nbdir, results = toy
    run_all.run_one("toy", quick=False, force=False, results_dir=results)
    before = sorted(p.name for p in (results / "toy").iterdir())
    (nbdir / "toy.py").write_text(BROKEN)
    name, status, _, msg = run_all.run_one("toy", quick=False, force=False, results_dir=results)
    assert status == "FAILED" and "cell" in msg and "RuntimeError" in msg and "boom" in msg
    assert sorted(p.name for p in (results / "toy").iterdir()) == before
    assert values(results) == {"toy/value": 2.0}
    assert not list(results.glob(".tmp-*"))


def test_unknown_parameter_is_an_error(toy, tmp_path):
    with pytest.raises(ValueError, match=r"unknown parameter.*'bogus'"):
        run_all.execute_notebook("toy", {"bogus": 1}, tmp_path / "out")


def test_run_all_exit_code_and_report(toy, monkeypatch):
    nbdir, results = toy
    assert run_all.run_all(["toy"], quick=False, force=False, jobs=1, results_dir=results) == 0
    assert (results / "REPORT.md").exists()
    (nbdir / "toy.py").write_text(BROKEN)
    assert run_all.run_all(["toy"], quick=False, force=True, jobs=1, results_dir=results) == 1


def test_killed_run_leaves_previous_results_intact(toy):
    nbdir, results = toy
    run_all.run_one("toy", quick=False, force=False, results_dir=results)
    before = {p.name: p.read_bytes() for p in (results / "toy").iterdir()}
    script = textwrap.dedent(f'''
        import sys; sys.path.insert(0, {str(ROOT)!r})
        from pathlib import Path
        import run_all
        run_all.NOTEBOOK_DIR = Path({str(nbdir)!r})
        run_all.NOTEBOOKS["toy"] = {{"params": {{"value": 9.0, "sleep": 60.0}}, "quick": {{}}, "data": [], "expects": {{}}}}
        run_all.run_one("toy", quick=False, force=True, results_dir=Path({str(results)!r}))
    ''')
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    deadline = time.time() + 60
    while time.time() < deadline and not list(results.glob(".tmp-toy-*/toy.ipynb")):
        time.sleep(0.2)  # wait until papermill is executing
    time.sleep(1.0)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    after = {p.name: p.read_bytes() for p in (results / "toy").iterdir()}
    assert after == before
    # the next run clears the leftovers of the killed one
    assert run_all.run_all(["toy"], quick=False, force=False, jobs=1, results_dir=results) == 0
    assert not list(results.glob(".tmp-*"))
