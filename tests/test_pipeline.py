"""run_all.py: atomic results, skipping unchanged inputs, failures that name the cell, parameters,
progress, signals that stop every child process."""
import json
import os
import signal
import subprocess
import sys
import textwrap

import psutil
import pytest

import run_all
from tests.conftest import ROOT, wait_for

GOOD = textwrap.dedent('''\
    # %% tags=["parameters"]
    output_dir = "x"
    value = 1.0
    label = "toy"

    # %%
    from shapelib.study import record_values
    record_values(output_dir, {f"{label}/value": value})
''')
#: a notebook with worker processes, as the study's notebooks have (process pools, Dask); with
#: ``block`` it and its workers wait until they are stopped (for a signal / an event nobody sends)
WORKERS = textwrap.dedent('''\
    # %% tags=["parameters"]
    output_dir = "x"
    value = 1.0
    workers = 0
    block = False

    # %%
    import concurrent.futures as cf
    import signal
    import threading
    from shapelib.study import record_values
    pool = cf.ProcessPoolExecutor(max_workers=workers) if workers else None
    busy = [pool.submit(signal.pause) for _ in range(workers)] if block else []
    if block:
        threading.Event().wait()
    record_values(output_dir, {"toy/value": value})
''')
#: a notebook that writes ``started`` and then waits until it is killed (for a lock nobody releases)
BLOCKED = textwrap.dedent('''\
    # %% tags=["parameters"]
    output_dir = "x"
    value = 1.0
    started = "started"

    # %%
    import threading
    from pathlib import Path
    from shapelib.study import record_values
    Path(started).touch()
    threading.Event().wait()  # never set: the run can only end by a kill
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


@pytest.mark.processes
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


@pytest.mark.processes
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


@pytest.mark.processes
def test_a_run_without_the_values_or_figures_it_must_record_fails_and_keeps_previous_results(toy, monkeypatch):
    nbdir, results = toy
    assert run_all.run_one("toy", quick=True, force=False, results_dir=results)[1] == "ok"
    before = _snapshot(results / "toy")
    monkeypatch.setitem(run_all.NOTEBOOKS["toy"], "expects", {"toy/": 2})  # GOOD records one value
    name, status, _, msg = run_all.run_one("toy", quick=True, force=True, results_dir=results)
    assert status == "FAILED" and msg == "toy: 1 value(s) under 'toy/', expected 2", msg
    # with a parameter changed (-p), or in a full run, the counts are lower bounds
    msg = run_all.run_one("toy", quick=True, force=True, results_dir=results, overrides={"value": 4.0})[3]
    assert msg == "toy: 1 value(s) under 'toy/', expected at least 2", msg
    assert _snapshot(results / "toy") == before and not list(results.glob(".tmp-*"))


def _finished_run(folder, name, keys, pngs, shown):
    """A results folder as a finished run leaves it: values.json, the executed notebook, PNG files."""
    folder.mkdir()
    (folder / "values.json").write_text(json.dumps({"values": {k: 1.0 for k in keys}}))
    outputs = [{"output_type": "display_data", "data": {"image/png": "iVBOR"}}] * shown
    cells = [{"cell_type": "code", "outputs": outputs}, {"cell_type": "markdown", "source": "text"}]
    (folder / f"{name}.ipynb").write_text(json.dumps({"cells": cells}))
    for i in range(pngs):
        (folder / f"figure{i}.png").write_bytes(b"\x89PNG")
    return folder


def test_the_output_check_counts_values_exactly_in_quick_runs_and_at_least_in_others(tmp_path, monkeypatch):
    check = run_all.check_outputs
    monkeypatch.setitem(run_all.NOTEBOOKS, "toy", {"params": {}, "quick": {}, "data": [], "figures": 2,
                                                   "expects": {"toy/a/": 2, "toy/b": 1}})
    keys = ["toy/a/1", "toy/a/2", "toy/b", "other/x"]
    ok = _finished_run(tmp_path / "ok", "toy", keys, pngs=2, shown=2)
    check("toy", ok, exact=True)
    check("toy", ok, exact=False)
    more = _finished_run(tmp_path / "more", "toy", [*keys, "toy/a/3"], pngs=3, shown=3)
    check("toy", more, exact=False)  # a full run may record more (a longer sweep)
    with pytest.raises(run_all.NotebookError, match=r"^toy: 3 value\(s\) under 'toy/a/', expected 2$"):
        check("toy", more, exact=True)
    fewer = _finished_run(tmp_path / "fewer", "toy", keys[1:], pngs=2, shown=2)
    for exact, want in ((True, "expected 2"), (False, "expected at least 2")):
        with pytest.raises(run_all.NotebookError, match=rf"^toy: 1 value\(s\) under 'toy/a/', {want}$"):
            check("toy", fewer, exact=exact)
    unshown = _finished_run(tmp_path / "unshown", "toy", keys, pngs=2, shown=1)
    with pytest.raises(run_all.NotebookError, match=r"2 figure file\(s\) but 1 figure\(s\) shown in the notebook"):
        check("toy", unshown, exact=True)
    missing = _finished_run(tmp_path / "missing", "toy", keys, pngs=1, shown=1)
    with pytest.raises(run_all.NotebookError, match=r"1 figure file\(s\), expected at least 2"):
        check("toy", missing, exact=False)
    # Table I keys: those of the paper's table (data/reference/table1.csv), no others
    monkeypatch.setitem(run_all.NOTEBOOKS["toy"], "expects", {"table1/procrustes/": 2})
    table = _finished_run(tmp_path / "table", "toy", ["table1/procrustes/1-2", "table1/procrustes/1-3"], 2, 2)
    check("toy", table, exact=True)
    odd = _finished_run(tmp_path / "odd", "toy", ["table1/procrustes/1-2", "table1/procrustes/1-99"], 2, 2)
    with pytest.raises(run_all.NotebookError, match=r"^toy: 1 Table I key\(s\) not in the paper's table, "
                                                    r"e\.g\. 'table1/procrustes/1-99'$"):
        check("toy", odd, exact=True)


#: a notebook that keeps partial work in a store (as the population study keeps its zarr stores)
STORED = textwrap.dedent('''\
    # %% tags=["parameters"]
    output_dir = "x"
    store_dir = None
    fail_if = ""

    # %%
    from pathlib import Path
    from shapelib.study import record_values
    part = Path(store_dir) / "part"
    resumed = part.exists()
    part.parent.mkdir(parents=True, exist_ok=True)
    part.write_text("computed")
    if fail_if and Path(fail_if).exists():
        raise RuntimeError("stopped part-way")
    record_values(output_dir, {"toy/resumed": float(resumed)})
''')


@pytest.mark.processes
def test_store_outlives_a_failed_run_is_resumed_and_removed_once_done(toy, monkeypatch):
    nbdir, results = toy
    (nbdir / "toy.py").write_text(STORED)
    flag = results.parent / "fail"
    flag.write_text("")
    monkeypatch.setitem(run_all.NOTEBOOKS, "toy", {"params": {"fail_if": str(flag)}, "quick": {}, "data": [],
                                                   "expects": {}, "store": True})
    stale = results / ".stores" / "toy-0000000000000000"  # a store of other inputs
    stale.mkdir(parents=True)
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results)[1] == "FAILED"
    assert not stale.exists()
    (kept,) = (results / ".stores").glob("toy-*")
    assert (kept / "part").read_text() == "computed"
    flag.unlink()  # the cause of the failure is gone, the inputs are the same: the run resumes
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results)[1] == "ok"
    assert values(results) == {"toy/resumed": 1.0}
    assert not list((results / ".stores").glob("toy-*"))
    # the store path is not an input: it is not in the fingerprint, so an unchanged run is skipped
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results)[1] == "skipped"
    assert run_all.run_one("toy", quick=False, force=True, results_dir=results)[1] == "ok"
    assert values(results) == {"toy/resumed": 0.0}


#: a notebook that says when it runs: a start and an end marker in ``marks``, and which other
#: notebooks were running when it started and which started while it ran; ``meet`` names a
#: notebook it waits for (until that one has started) before it ends
MARKED = textwrap.dedent('''\
    # %% tags=["parameters"]
    output_dir = "x"
    name = "toy"
    marks = "."
    meet = ""

    # %%
    import time
    from pathlib import Path
    from shapelib.study import record_values
    marks = Path(marks)
    def running():
        return {p.stem for p in marks.glob("*.start") if not (marks / f"{p.stem}.end").exists()} - {name}
    at_start = running()
    (marks / f"{name}.start").touch()
    deadline = time.monotonic() + 120  # only to fail instead of hanging: the other must start
    while meet and not (marks / f"{meet}.start").exists():
        if time.monotonic() > deadline:
            raise RuntimeError(f"{meet} did not start while {name} ran")
        time.sleep(0.02)
    started = {p.stem for p in marks.glob("*.start")}
    (marks / f"{name}.end").touch()
    record_values(output_dir, {f"{name}/{k}": float(v) for k, v in (("others_at_start", len(at_start)),
                                                                    ("others_at_end", len(running())),
                                                                    ("seen_started", len(started)))})
''')


@pytest.mark.processes
def test_whole_machine_notebooks_run_alone_the_others_side_by_side(toy, monkeypatch):
    """No clock: the two small notebooks each wait until the other has started (run one after
    the other, the first would wait forever), and the whole-machine ones record that nothing else
    ran when they started or ended."""
    nbdir, results = toy
    marks = results.parent / "marks"
    marks.mkdir()
    meet = {"small1": "small2", "small2": "small1"}
    for name, cores in (("whole1", "all"), ("small1", None), ("small2", None), ("whole2", "all")):
        (nbdir / f"{name}.py").write_text(MARKED)
        monkeypatch.setitem(run_all.NOTEBOOKS, name, {
            "params": {"name": name, "marks": str(marks), "meet": meet.get(name, "")}, "quick": {}, "data": [],
            "expects": {}, **({"cores": cores} if cores else {})})
    names = ["small1", "small2", "whole1", "whole2"]
    assert run_all.run_all(names, quick=False, force=True, jobs=2, results_dir=results) == 0
    for whole in ("whole1", "whole2"):
        v = values(results, whole)
        assert v[f"{whole}/others_at_start"] == v[f"{whole}/others_at_end"] == 0, v
    # the second whole notebook starts after the first has ended (and after both small ones)
    order = sorted(names, key=lambda n: values(results, n)[f"{n}/seen_started"])
    assert order[2:] in (["whole1", "whole2"], ["whole2", "whole1"]), order


def test_unknown_parameter_is_an_error(toy, tmp_path):
    with pytest.raises(ValueError, match=r"unknown parameter.*'bogus'"):
        run_all.execute_notebook("toy", {"bogus": 1}, tmp_path / "out")


@pytest.mark.processes
def test_run_all_exit_code_and_report(toy, monkeypatch):
    nbdir, results = toy
    assert run_all.run_all(["toy"], quick=False, force=False, jobs=1, results_dir=results) == 0
    assert (results / "REPORT.md").exists()
    (nbdir / "toy.py").write_text(BROKEN)
    assert run_all.run_all(["toy"], quick=False, force=True, jobs=1, results_dir=results) == 1
    report = (results / "REPORT.md").read_text()
    assert "## Failed notebooks" in report
    row = next(line for line in report.splitlines() if line.startswith("| toy |"))
    assert "cell 2" in row and "RuntimeError: boom" in row  # cell 1 is papermill's injected parameters


@pytest.mark.processes
def test_a_kernel_that_dies_before_its_first_cell_is_started_once_more(toy, monkeypatch):
    """The port race of a kernel start (another process binds a port between jupyter_client's pick and
    the kernel's bind): the fault lands on the first start, the second start runs the notebook; a
    kernel that dies on both starts is a failure that says so, and a cell's error is never retried."""
    import papermill as pm

    nbdir, results = toy
    real, starts = pm.execute_notebook, []

    def dies_first(*args, **kwargs):
        starts.append(1)
        if len(starts) == 1:
            raise RuntimeError(run_all.KERNEL_START_FAILURE)
        return real(*args, **kwargs)

    monkeypatch.setattr(pm, "execute_notebook", dies_first)
    assert run_all.run_one("toy", quick=False, force=True, results_dir=results)[1] == "ok"
    assert len(starts) == 2 and values(results) == {"toy/value": 2.0}

    def always_dies(*args, **kwargs):
        starts.append(1)
        raise RuntimeError(run_all.KERNEL_START_FAILURE)

    starts.clear()
    monkeypatch.setattr(pm, "execute_notebook", always_dies)
    _, status, _, msg = run_all.run_one("toy", quick=False, force=True, results_dir=results)
    assert (status, len(starts)) == ("FAILED", 2) and run_all.KERNEL_START_FAILURE in msg
    assert values(results) == {"toy/value": 2.0}  # the previous results stay
    starts.clear()
    monkeypatch.setattr(pm, "execute_notebook", dies_first)
    (nbdir / "toy.py").write_text(BROKEN)
    starts.append(1)  # past the first start: the notebook's own error comes back, once
    _, status, _, msg = run_all.run_one("toy", quick=False, force=True, results_dir=results)
    assert (status, len(starts)) == ("FAILED", 2) and "RuntimeError: boom" in msg


def _ppid(process):
    """The parent's pid of a process listed a moment ago, or None if it has exited since."""
    try:
        return process.ppid()
    except psutil.NoSuchProcess:
        return None


def _kill_tree(proc):
    """SIGKILL ``proc``'s process group and every descendant: the kernel runs in a session of its
    own, outside the group, and an orphaned kernel is not always reaped (a failed assertion here
    once left a kernel running for the rest of the CI job)."""
    try:
        tree = psutil.Process(proc.pid).children(recursive=True)
    except psutil.NoSuchProcess:
        tree = []
    os.killpg(proc.pid, signal.SIGKILL)
    for p in tree:
        try:
            p.kill()
        except psutil.NoSuchProcess:
            pass
    proc.wait()
    psutil.wait_procs(tree, timeout=10)


@pytest.mark.processes
def test_killed_run_leaves_previous_results_intact(toy):
    nbdir, results = toy
    run_all.run_one("toy", quick=False, force=False, results_dir=results)
    before = {p.name: p.read_bytes() for p in (results / "toy").iterdir()}
    started = results.parent / "started"
    (nbdir / "toy.py").write_text(BLOCKED)  # the same notebook, now one that is killed while it runs
    script = textwrap.dedent(f'''
        import sys; sys.path.insert(0, {str(ROOT)!r})
        from pathlib import Path
        import run_all
        run_all.NOTEBOOK_DIR = Path({str(nbdir)!r})
        run_all.NOTEBOOKS["toy"] = {{"params": {{"value": 9.0, "started": {str(started)!r}}}, "quick": {{}},
                                    "data": [], "expects": {{}}}}
        run_all.run_one("toy", quick=False, force=True, results_dir=Path({str(results)!r}))
    ''')
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    try:
        wait_for(lambda: started.exists() or proc.poll() is not None, "the notebook's first cell")
        assert proc.poll() is None and list(results.glob(".tmp-toy-*/toy.ipynb"))  # papermill is executing
    finally:
        _kill_tree(proc)
    after = {p.name: p.read_bytes() for p in (results / "toy").iterdir()}
    assert after == before
    # the next run clears the leftovers of the killed one
    (nbdir / "toy.py").write_text(GOOD)
    assert run_all.run_all(["toy"], quick=False, force=False, jobs=1, results_dir=results) == 0
    assert not list(results.glob(".tmp-*"))


def _snapshot(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def _running(proc):
    try:
        return proc.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


@pytest.mark.processes
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_stops_kernel_and_workers_removes_tmp_and_keeps_results(toy, sig):
    """A real run_all.py process, a notebook busy in two worker processes, a real signal: Ctrl-C as a
    terminal sends it (SIGINT to the foreground process group) or ``kill`` (SIGTERM to the pid)."""
    nbdir, results = toy
    (nbdir / "toy.py").write_text(WORKERS)
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results)[1] == "ok"
    before = _snapshot(results / "toy")
    script = textwrap.dedent(f'''
        import sys; sys.path.insert(0, {str(ROOT)!r})
        from pathlib import Path
        import run_all
        run_all.NOTEBOOK_DIR = Path({str(nbdir)!r})
        run_all.NOTEBOOKS.clear()
        run_all.NOTEBOOKS["toy"] = {{"params": {{"value": 9.0, "workers": 2, "block": True}}, "quick": {{}},
                                    "data": [], "expects": {{}}}}
        sys.exit(run_all.main(["--force", "-j", "1", "--no-progress", "--results-dir", {str(results)!r}]))
    ''')
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        parent = psutil.Process(proc.pid)
        children = []

        def kernel_and_two_workers_up():
            children[:] = parent.children(recursive=True)  # one snapshot for the test and the assertion
            ppid = {c: _ppid(c) for c in children}  # a short-lived child may be gone by now
            kernels = [c for c in children if ppid[c] == proc.pid]
            return bool(kernels) and sum(ppid[c] == kernels[0].pid for c in children) >= 2

        wait_for(kernel_and_two_workers_up, "the kernel and its two workers")
        assert list(results.glob(".tmp-toy-*"))
        if sig == signal.SIGINT:
            os.killpg(proc.pid, sig)
        else:
            os.kill(proc.pid, sig)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            _kill_tree(proc)
    assert proc.returncode == 128 + sig, out.decode()
    assert not [c for c in children if _running(c)], out.decode()
    assert not list(results.glob(".tmp-*"))
    assert _snapshot(results / "toy") == before
    assert values(results) == {"toy/value": 2.0}


@pytest.mark.processes
def test_parameters_are_typed_validated_recorded_and_key_the_cache(toy):
    nbdir, results = toy
    declared = run_all.declared_parameters("toy")
    assert declared == {"output_dir": "x", "value": 1.0, "label": "toy"}
    with pytest.raises(ValueError, match=r"'value' must be a float like its default 1\.0; got 'abc'"):
        run_all.check_parameters("toy", {"value": "abc"}, declared)
    with pytest.raises(ValueError, match="must be a float"):
        run_all.check_parameters("toy", {"value": True}, declared)

    assert run_all.run_one("toy", quick=False, force=False, results_dir=results, overrides={"value": 5})[1] == "ok"
    assert values(results) == {"toy/value": 5}
    used = {"value": 5, "label": "toy"}
    assert json.loads((results / "toy" / "values.json").read_text())["meta"]["parameters"] == used
    inputs = json.loads((results / "toy" / ".inputs.json").read_text())
    assert inputs["params"] == used and inputs["overrides"] == {"value": 5}
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results, overrides={"value": 5})[1] == "skipped"
    assert run_all.run_one("toy", quick=False, force=False, results_dir=results, overrides={"value": 6})[1] == "ok"
    # an override for a parameter this notebook does not declare is not passed to it
    assert run_all.notebook_parameters("toy", quick=False, overrides={"n_steps": 3}) == {"value": 2.0}


@pytest.mark.parametrize("args, message", [
    (["-p", "value=abc"], "'value' must be a float"),
    (["-p", "bogus=1"], "no selected notebook declares 'bogus'"),
    (["-p", "output_dir=elsewhere"], "run_all.py chooses it"),
    (["-p", "value"], "-p 'value': expected NAME=VALUE"),
])
def test_bad_parameters_are_refused_before_anything_runs(toy, capsys, args, message):
    nbdir, results = toy
    with pytest.raises(SystemExit) as exc:
        run_all.main(["--only", "toy", "--results-dir", str(results), *args])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
    assert not results.exists()


def test_progress_in_a_log_has_lines_not_carriage_returns(toy, capfd):
    nbdir, results = toy
    assert run_all.run_all(["toy"], quick=False, force=True, jobs=1, results_dir=results, progress=True) == 0
    out, err = capfd.readouterr()
    assert "started toy" in err and "[1/1] toy" in out
    assert "\r" not in out + err


def test_executed_notebook_shows_its_figure_and_saves_it(toy, monkeypatch):
    """The kernel draws inline even when the caller exported another backend (CI exports Agg)."""
    nbdir, results = toy
    monkeypatch.setenv("MPLBACKEND", "Agg")
    (nbdir / "toy.py").write_text(GOOD + textwrap.dedent('''
        # %%
        import matplotlib.pyplot as plt
        from shapelib.study import save_figure
        fig, ax = plt.subplots()
        ax.plot([0, 1], [value, 0])
        save_figure(fig, output_dir, "toy")
    '''))
    assert run_all.run_one("toy", quick=False, force=True, results_dir=results)[1] == "ok"
    nb = json.loads((results / "toy" / "toy.ipynb").read_text())
    assert any("image/png" in o.get("data", {}) for c in nb["cells"] for o in c.get("outputs", []))
    assert (results / "toy" / "toy.png").read_bytes().startswith(b"\x89PNG")


def test_default_output_dir_is_the_top_level_results_wherever_the_notebook_runs(tmp_path, monkeypatch):
    from shapelib.study import default_output_dir

    monkeypatch.chdir(ROOT / "notebooks")
    assert default_output_dir("fig02_intrinsic_extrinsic") == ROOT / "results" / "fig02_intrinsic_extrinsic"
    monkeypatch.chdir(tmp_path)  # outside a checkout
    assert default_output_dir("x") == tmp_path / "results" / "x"
    assert default_output_dir("x", start=ROOT / "shapelib") == ROOT / "results" / "x"
    with pytest.raises(ValueError, match="without folders"):
        default_output_dir("../x")
    for name in run_all.NOTEBOOKS:  # every study notebook uses it
        assert run_all.declared_parameters(name)["output_dir"] == f'default_output_dir("{name}")', (
            f"notebooks/{name}.py: its parameters cell should set "
            f"`output_dir = default_output_dir(\"{name}\")` (from shapelib.study), so that run by hand from "
            "notebooks/ it writes to the top-level results/")


def test_recorded_timings_come_from_the_run_records_and_render_as_the_docs_table(tmp_path, monkeypatch, capsys):
    import importlib.util

    results = tmp_path / "results"
    names = list(run_all.NOTEBOOKS)
    for i, name in enumerate(names):
        (results / name).mkdir(parents=True)
        (results / name / ".inputs.json").write_text(json.dumps(
            {"mode": "full", "seconds": 60.0 * (i + 1), "jobs": 2, "finished": f"2026-11-23T12:{i:02d}:00+00:00",
             "params": {"n": i}, "machine": {"cpus": 2, "machine": "x86_64", "python": "3.11.7",
                                             "loadavg_1min": 1.0 + i}}))
    out = tmp_path / "data" / "run_times.json"
    monkeypatch.setattr(run_all, "TIMINGS_RECORD", out)
    assert run_all.main(["--results-dir", str(results), "--record-timings"]) == 0
    assert f"updated {out}" in capsys.readouterr().out
    record = json.loads(out.read_text())
    assert record["machine"]["date"] == f"2026-11-23T12:{len(names) - 1:02d}:00+00:00"  # the last to finish
    assert record["machine"]["loadavg"].startswith(f"1.0–{len(names):.1f}")
    assert {n: r["seconds"] for n, r in record["results"]["notebooks"].items()} == {
        n: 60.0 * (i + 1) for i, n in enumerate(names)}
    # the documentation's renderer turns it into the run-time table, slowest first
    spec = importlib.util.spec_from_file_location("shapelib_docs", ROOT / "docs" / "_ext" / "shapelib_docs.py")
    docs = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "shapelib_docs", docs)  # dataclasses look their module up
    spec.loader.exec_module(docs)
    (table,) = docs.benchmark_tables("run_times", data_dir=out.parent).tables
    assert table.rows[0] == [f"``{names[-1]}``", f"{len(names):.1f}"]
    assert f"{sum(range(1, len(names) + 1)):.1f} min of notebook time in all" in table.note
    # a quick run is no full run
    (results / names[0] / ".inputs.json").write_text(json.dumps({"mode": "quick", "seconds": 1.0}))
    with pytest.raises(ValueError, match=f"{names[0]}: no full run"):
        run_all.record_timings(results, out)


@pytest.mark.parametrize("name", list(run_all.NOTEBOOKS))
def test_papermill_reads_every_declared_parameter(name):
    """papermill's own parser (used for `papermill --help-notebook` and parameter injection) skips
    a line it cannot parse with a warning; every study notebook's parameters must parse."""
    import jupytext
    from papermill.translators import PythonTranslator

    nb = jupytext.read(run_all.NOTEBOOK_DIR / f"{name}.py")
    (cell,) = [c for c in nb.cells if "parameters" in c.metadata.get("tags", [])]
    assert [p.name for p in PythonTranslator.inspect(cell)] == list(run_all.declared_parameters(name))


def test_list_shows_what_a_full_and_a_quick_run_pass(toy, capsys, monkeypatch):
    # the toy notebook declares value = 1.0; the registry passes 2.0, and 3.0 with --quick
    monkeypatch.setattr(run_all, "NOTEBOOKS", {"toy": run_all.NOTEBOOKS["toy"]})
    assert run_all.main(["--list"]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("toy "))
    assert "value=2.0 [3.0]" in line and "label=toy" in line and "label=toy [" not in line
