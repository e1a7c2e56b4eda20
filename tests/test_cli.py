"""The ``shapelib`` command line on real .tps and .csv files, broken ones included: results checked
against the library, errors are one line on stderr naming the file/specimen/landmark/parameter,
never a traceback.

Commands run through :func:`shapelib.cli.main`, the function the console script and ``python -m
shapelib`` call, with its exit status, stdout and stderr captured as a process's would be; where
the process itself is under test (the console entry, exit statuses through ``sys.exit``, Ctrl-C,
child processes) they run in a subprocess (``run(..., process=True)``)."""

import os
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from shapelib import io
from shapelib.geometry.procrustes import centroid_size, procrustes_distance
from tests.conftest import ROOT


def run(*args, cwd=None, check=None, process=False):
    """``shapelib ARGS``: its exit status, stdout and stderr (a ``CompletedProcess``).

    In this process through :func:`shapelib.cli.main` (no interpreter start and no kernel loading per
    call), or in a subprocess, ``python -m shapelib``, with ``process=True``."""
    argv = [str(a) for a in args]
    if process:
        env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
        env.pop("SHAPELIB_DEBUG", None)
        proc = subprocess.run([sys.executable, "-m", "shapelib", *argv], capture_output=True, text=True,
                              env=env, cwd=cwd, timeout=300)
    else:
        proc = _run_in_process(argv, cwd)
    if check is not None:
        assert proc.returncode == check, (proc.returncode, proc.stdout, proc.stderr)
    return proc


def _run_in_process(argv, cwd=None):
    import contextlib
    import io as _io

    import matplotlib.pyplot as plt

    from shapelib.cli import main

    out, err = _io.StringIO(), _io.StringIO()
    debug = os.environ.pop("SHAPELIB_DEBUG", None)
    try:
        with contextlib.chdir(cwd or os.getcwd()), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse: --help (0) and usage errors (2)
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
                if not isinstance(exc.code, (int, type(None))):
                    print(exc.code, file=sys.stderr)
    finally:
        if debug is not None:
            os.environ["SHAPELIB_DEBUG"] = debug
        plt.close("all")
    return subprocess.CompletedProcess(["shapelib", *argv], int(code or 0), out.getvalue(), err.getvalue())


def one_line_error(proc, *fragments):
    assert proc.returncode == 1, (proc.returncode, proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("shapelib: error:")]
    assert len(lines) == 1, proc.stderr
    for frag in fragments:
        assert frag in lines[0], (frag, lines[0])
    return lines[0]


def _shapes(rng, n=4, k=9):
    """Perturbed ellipses in pixel coordinates (positive, as tpsDig writes them)."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    base = np.column_stack([200 + 120 * np.cos(t), 150 + 60 * np.sin(t)])
    return np.round(base + rng.normal(scale=8, size=(n, k, 2)), 2)


@pytest.fixture
def files(tmp_path, rng):
    x = _shapes(rng)
    ids = ["sp_a", "sp_b", "sp_c", "sp_d"]
    # tpsDig layout, written by hand: LM=, rows, IMAGE=, ID=, SCALE=, CRLF line endings
    blocks = []
    for i, s in zip(ids, x):
        rows = "\n".join(f"{a:.5f} {b:.5f}" for a, b in s)
        blocks.append(f"LM={len(s)}\n{rows}\nIMAGE={i}.jpg\nID={i}\nSCALE=0.01\n")
    tps = tmp_path / "fish.tps"
    tps.write_bytes("\n".join(blocks).replace("\n", "\r\n").encode())
    # wide CSV as a spreadsheet would have it
    header = "id,group," + ",".join(f"x{k + 1},y{k + 1}" for k in range(x.shape[1]))
    lines = [header] + [f"{i},{'AB'[n % 2]}," + ",".join(f"{v:g}" for v in s.ravel()) for n, (i, s) in enumerate(zip(ids, x))]
    csv = tmp_path / "fish.csv"
    csv.write_text("\n".join(lines) + "\n")
    return {"x": x, "ids": ids, "tps": tps, "csv": csv, "dir": tmp_path}


def test_help_shows_an_example_for_every_subcommand():
    from shapelib.cli import build_parser

    top = run("--help", check=0).stdout
    assert "examples:" in top
    assert "example" in run("distances", "--help", check=0).stdout.split("options:")[-1]
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    assert set(commands) == {"info", "align", "distances", "geodesic", "mean", "pca", "test", "regress", "register",
                             "study"}
    for cmd, sub in commands.items():
        assert cmd in top
        if cmd == "study":  # `shapelib study --help` is run_all.py's help (test_study_...)
            continue
        out = sub.format_help()
        assert "example" in out and f"shapelib {cmd}" in out.split("example", 1)[1], cmd


def test_usage_errors_exit_2():
    proc = run("align", "x.tps")
    assert proc.returncode == 2 and "-o/--output" in proc.stderr and "Traceback" not in proc.stderr
    assert run().returncode == 2


def test_info(files):
    out = run("info", files["tps"], check=0).stdout
    assert "specimens   4" in out and "landmarks   9" in out and "dimension   2" in out
    assert "missing     none" in out and "SCALE=      4 of 4 specimens, not applied" in out and "sp_a, sp_b" in out
    out = run("info", files["csv"], check=0).stdout
    assert "specimens   4" in out and "(csv, wide layout)" in out
    broken = files["dir"] / "miss.tps"
    broken.write_text(files["tps"].read_text().replace(f"{files['x'][2, 4, 0]:.5f} {files['x'][2, 4, 1]:.5f}", "-1 -1"))
    out = run("info", broken, check=0).stdout
    assert "missing     1 landmark(s) in 1 specimen(s): sp_c (landmark 5)" in out


def test_align_tps_and_csv(files):
    out = files["dir"] / "aligned.tps"
    proc = run("align", files["tps"], "-o", out, "--size", 20, check=0)
    assert "shapelib reads back as coordinates" in proc.stderr
    aligned, spec = io.read_tps(out)
    assert spec["id"].tolist() == files["ids"]
    x = files["x"]
    for i in range(len(x)):
        assert centroid_size(aligned[i]) == pytest.approx(20.0, rel=1e-12)
        np.testing.assert_allclose(aligned[i].mean(axis=0), 0.0, atol=1e-12)
        for j in range(i):  # alignment changes no shape: Procrustes distances are invariant
            assert procrustes_distance(aligned[i], aligned[j]) == pytest.approx(procrustes_distance(x[i], x[j]), abs=1e-9)
    # SCALE= no longer applies to aligned coordinates and is not written again
    assert "SCALE=" not in out.read_text()
    # CSV in, CSV out, metadata kept
    out_csv = files["dir"] / "aligned.csv"
    run("align", files["csv"], "-o", out_csv, check=0)
    a2, spec2 = io.read_landmarks(out_csv)
    assert spec2["group"].tolist() == ["A", "B", "A", "B"]
    np.testing.assert_allclose(a2, aligned / 20.0, atol=1e-9)
    one_line_error(run("align", files["tps"], "-o", files["dir"] / "aligned.csv"), "-o", "input's format (tps)")


def test_geodesic_path_figure_and_animation(files):
    al = files["dir"] / "al.tps"
    run("align", files["tps"], "-o", al, "--size", 20, check=0)
    path_csv, png, gif = (files["dir"] / n for n in ("path.csv", "path.png", "path.gif"))
    proc = run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "sp_c", "--metric", "alpha",
               "--sigma2", 0.5, "--n-steps", 4, "-o", path_csv, "--plot", png, "--animate", gif, check=0)
    assert "sp_a -> sp_c: alpha: length" in proc.stdout
    path = pd.read_csv(path_csv)
    assert list(path.columns) == ["step", "t", "landmark", "x", "y"] and len(path) == 5 * 9
    aligned, _ = io.read_tps(al, negative="coordinates")
    ends = path.set_index(["step", "landmark"])[["x", "y"]]
    np.testing.assert_array_equal(ends.loc[0].to_numpy(), aligned[0])
    np.testing.assert_array_equal(ends.loc[4].to_numpy(), aligned[2])
    from PIL import Image

    assert Image.open(png).size[0] > 100
    with Image.open(gif) as im:
        assert im.n_frames == 2 * 5 - 2  # forth and back
    one_line_error(run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "nope", "--metric", "alpha",
                       "--sigma2", 0.5, "-o", path_csv), "--to nope", "no specimen with that id", "sp_a, sp_b")
    one_line_error(run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "sp_b", "--metric",
                       "procrustes", "-o", path_csv), "--metric procrustes", "path metrics")
    one_line_error(run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "sp_b", "--metric", "alpha",
                       "-o", path_csv), "--metric alpha", "sigma2")
    one_line_error(run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "sp_b", "--metric", "alpha",
                       "--sigma2", -1, "-o", path_csv), "sigma2")
    # n_steps through --param is honoured; given both ways it is an error
    run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "sp_c", "--metric", "alpha",
        "--sigma2", 0.5, "--param", "n_steps=3", "-o", path_csv, check=0)
    assert pd.read_csv(path_csv).step.max() == 3
    one_line_error(run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "sp_c", "--metric", "alpha",
                       "--sigma2", 0.5, "--param", "n_steps=3", "--n-steps", 5, "-o", path_csv), "n_steps given twice")
    # a failing command writes nothing: checked before any work
    fresh = files["dir"] / "fresh.csv"
    for extra, fragment in ((["--animate", gif, "--fps", 0], "--fps must be >= 1"),
                            (["--animate", gif, "--fps", -3], "--fps must be >= 1")):
        one_line_error(run("geodesic", al, "--negative-coordinates", "--from", "sp_a", "--to", "sp_c", "--metric",
                           "alpha", "--sigma2", 0.5, "-o", fresh, *extra), fragment)
    three = files["dir"] / "three.csv"
    io.write_landmarks(three, np.dstack([files["x"], files["x"][:, :, :1]]), pd.DataFrame({"id": files["ids"]}))
    one_line_error(run("geodesic", three, "--from", "sp_a", "--to", "sp_c", "--metric", "alpha", "--sigma2", 500,
                       "-o", fresh, "--animate", gif), "--animate draws 2-D landmarks")
    assert not fresh.exists()
    # 3-D landmarks: --plot draws them on 3-D axes
    png3 = files["dir"] / "three.png"
    run("geodesic", three, "--from", "sp_a", "--to", "sp_c", "--metric", "alpha", "--sigma2", 500, "-o", fresh,
        "--plot", png3, check=0)
    assert png3.stat().st_size > 0


@pytest.mark.parametrize("kind, mutate, fragments", [
    ("tps", lambda t: t.replace("LM=9", "LM=10", 1), ["fish.tps: line 11", "specimen #1", "LM=10"]),
    ("tps", lambda t: re.sub(r"^(\d+)\.", r"\1x", t.split("\n", 1)[1], count=1).join([t.split("\n", 1)[0] + "\n", ""]),
     ["fish.tps: line 2", "specimen #1", "point 1", "non-numeric"]),
    ("tps", lambda t: "", ["fish.tps: no landmarks"]),
    ("tps", lambda t: t.replace("\nSCALE=0.01", "\nSCALE=0.01\nLM=2\n1 1\n2 2\nID=extra", 1),
     ["fish.tps: specimen #2 (ID=extra)", "has 2 landmarks but specimen #1 has 9"]),
    ("csv", lambda t: t.replace("sp_c,A,", "sp_c,A,1,"), ["fish.csv: not a valid CSV file", "line 4"]),
    ("csv", lambda t: t.rstrip("\n").rsplit(",", 1)[0] + "\n", ["fish.csv: line 5, specimen 'sp_d' (#4): landmark 9 is missing"]),
    ("csv", lambda t: re.sub(r"^sp_b,B,[^,]+,", "sp_b,B,seven,", t, flags=re.M),
     ["fish.csv: line 3, specimen 'sp_b', landmark 1", "non-numeric value 'seven'"]),
    ("csv", lambda t: "", ["fish.csv: empty file"]),
])
def test_broken_files_give_one_line_errors(files, kind, mutate, fragments):
    path = files[kind]
    path.write_text(mutate(path.read_text().replace("\r\n", "\n")))
    out = files["dir"] / f"out.{kind}"
    one_line_error(run("align", path, "-o", out), *fragments)
    assert not out.exists()  # nothing half-written


def test_every_reading_command_fails_the_same_way(files):
    broken = files["dir"] / "broken.tps"
    broken.write_text(files["tps"].read_text().replace("LM=9", "LM=10", 1))
    fragments = ["broken.tps: line 11", "specimen #1", "LM=10"]
    one_line_error(run("info", broken), *fragments)
    one_line_error(run("geodesic", broken, "--from", "sp_a", "--to", "sp_b", "--metric", "alpha", "--sigma2", 0.5,
                       "-o", files["dir"] / "p.csv"), *fragments)
    assert not (files["dir"] / "p.csv").exists()
    # info reports missing landmarks where the other commands refuse them
    missing = files["dir"] / "missing.csv"
    missing.write_text(re.sub(r"^(sp_b,B,[^,]+),[^,]+,", r"\1,NA,", files["csv"].read_text(), flags=re.M))
    assert "missing     1 landmark(s) in 1 specimen(s): sp_b (landmark 1)" in run("info", missing, check=0).stdout
    one_line_error(run("geodesic", missing, "--from", "sp_a", "--to", "sp_b", "--metric", "alpha", "--sigma2", 0.5,
                       "-o", files["dir"] / "p.csv"), "missing.csv: line 3, specimen 'sp_b' (#2): landmark 1 is missing")


def test_missing_file_and_unknown_extension(files):
    one_line_error(run("info", files["dir"] / "nothere.tps"), "nothere.tps: no such file")
    one_line_error(run("info", files["dir"] / "data.xlsx"), "unknown landmark file extension '.xlsx'")
    one_line_error(run("info", files["csv"], "--scale"), "--scale applies to .tps files only")


def test_parse_assignment():
    """The one NAME=VALUE parser of --param and run_all.py -p: Python literals, else text."""
    from shapelib.cli import parse_assignment

    assert parse_assignment("value=5") == ("value", 5)
    assert parse_assignment(" names = ['a', 'b'] ") == ("names", ["a", "b"])
    assert parse_assignment("fish_name=fish-2") == ("fish_name", "fish-2")  # not a literal: text
    assert parse_assignment("flag=True", flag="-p") == ("flag", True)
    for bad in ("value", "=3", "2x=1", "a b=1"):
        with pytest.raises(ValueError, match=rf"^-p {re.escape(repr(bad))}: expected NAME=VALUE, e\.g\. -p x=1$"):
            parse_assignment(bad, flag="-p", example="x=1")


def test_study_lists_notebooks_in_a_checkout_and_refuses_outside_one(tmp_path):
    # in subprocesses: `shapelib study` replaces its process with run_all.py (os.execv)
    out = run("study", "--list", check=0, process=True).stdout.split()
    assert "table1_pairwise" in out and "fig01_gmm_representation" in out
    # every option goes through to run_all.py, which parses it: its help, its -p, its errors
    helptext = run("study", "--help", check=0, process=True).stdout
    assert "--results-dir" in helptext and "-p NAME=VALUE" in helptext and "shapelib study" in helptext
    proc = run("study", "--only", "fig01_gmm_representation", "-p", "bogus", check=None, process=True)
    assert proc.returncode == 2 and "-p 'bogus': expected NAME=VALUE" in proc.stderr
    # an installed copy of the package without the repository around it
    import shutil

    shutil.copytree(ROOT / "shapelib", tmp_path / "site" / "shapelib", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "site")}
    proc = subprocess.run([sys.executable, "-m", "shapelib", "study", "--quick"], capture_output=True, text=True,
                          env=env, cwd=tmp_path, timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("shapelib: error: `shapelib study` runs run_all.py from a source checkout")


# ------------------------------------------------------------------------------------ distances


def _matrix(path):
    frame = pd.read_csv(path, index_col=0)
    assert frame.index.name == "id" and list(frame.columns) == list(frame.index)
    return frame


def test_distances_labelled_matrix_equals_the_library(files):
    from shapelib.comparison.splines import wendland_bending_energy

    out = files["dir"] / "d.csv"
    proc = run("distances", files["tps"], "--metric", "procrustes", "--jobs", 1, "--no-progress", "-o", out, check=0)
    assert proc.stderr == ""  # no progress bar asked for
    frame = _matrix(out)
    assert frame.index.tolist() == files["ids"]
    x = files["x"]
    want = np.array([[procrustes_distance(a, b) if i != j else 0.0 for j, b in enumerate(x)] for i, a in enumerate(x)])
    np.testing.assert_allclose(frame.to_numpy(), want, rtol=1e-13, atol=1e-15)
    # asymmetric metric: [i, j] is the map from i onto j; extra options through --param
    run("distances", files["csv"], "--metric", "wendland", "--param", "support=3.0", "--jobs", 1, "-o", out, check=0)
    w = _matrix(out).to_numpy()
    assert w[0, 1] == pytest.approx(wendland_bending_energy(x[0], x[1], support=3.0), rel=1e-12)
    assert w[1, 0] == pytest.approx(wendland_bending_energy(x[1], x[0], support=3.0), rel=1e-12)
    one_line_error(run("distances", files["tps"], "--metric", "alpah", "-o", out), "--metric alpah", "unknown metric")
    one_line_error(run("distances", files["tps"], "--metric", "procrustes", "--param", "nope=1", "-o", out),
                   "--metric procrustes", "nope")
    one_line_error(run("distances", files["tps"], "--metric", "alpha", "--param", "n_steps", "-o", out),
                   "--param 'n_steps': expected NAME=VALUE, e.g. --param n_steps=16")
    one_line_error(run("distances", files["tps"], "--metric", "procrustes", "-o", files["dir"] / "d.txt"),
                   "-o", "d.txt", ".csv")
    one_line_error(run("distances", files["tps"], "--metric", "fisher_rao_bound", "-o", out),
                   "--metric fisher_rao_bound needs --sigma2")
    one_line_error(run("distances", files["tps"], "--metric", "procrustes", "-o", out, "--pairs", out),
                   "--pairs", "the same file as -o")


def test_reader_advice_names_the_command_line_options(files):
    al = files["dir"] / "al.tps"
    run("align", files["tps"], "-o", al, "--size", 20, check=0)
    # aligned by another program: negative coordinates without shapelib's COMMENT= line
    al.write_text(al.read_text().replace(f"COMMENT={io.NEGATIVE_COORDINATES_COMMENT}\n", ""))
    out = files["dir"] / "d.csv"
    line = one_line_error(run("distances", al, "--metric", "procrustes", "-o", out),
                          "is missing", "estimate or drop the missing landmarks first", "add --negative-coordinates")
    assert "missing='nan'" not in line
    plain = files["dir"] / "plain.tps"
    plain.write_text(files["tps"].read_text().replace("SCALE=0.01\n", ""))
    one_line_error(run("info", "--scale", plain), "--scale but specimen #1")
    pkn = files["dir"] / "pkn.npy"
    np.save(pkn, np.transpose(files["x"], (1, 2, 0)))  # geomorph's p x k x n
    line = one_line_error(run("info", pkn), "read it with --pkn")
    assert "from_pkn" not in line


def test_a_scale_problem_is_one_warning_for_the_whole_file(files):
    # raw pixel coordinates with sigma2 = 0.5: sigma is far below the landmark spacing
    out = files["dir"] / "raw.csv"
    proc = run("distances", files["tps"], "--metric", "alpha", "--sigma2", 0.5, "--param", "n_steps=2", "--param",
               "max_iter=2", "--jobs", 1, "--no-progress", "-o", out, check=0)
    # the Gaussians do not interact: straight paths are the geodesics, found again from a perturbed start
    assert "converged back to the same length" in proc.stderr, proc.stderr
    lines = proc.stderr.splitlines()
    assert sum("shapelib: warning: --sigma2 0.5 puts sigma at" in ln for ln in lines) == 1, proc.stderr
    assert not any("nonconverged_pairs()" in ln for ln in lines), proc.stderr  # the library's hint, not the CLI's
    assert all(ln.startswith(("shapelib: warning:", "shapelib: note:")) for ln in lines), proc.stderr


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_degenerate_specimen_is_named(files, jobs):
    # sp_c's landmarks 5 and 6 coincide: the spline metrics cannot use it as the source (u)
    x = files["x"].copy()
    x[2, 5] = x[2, 4]
    src = files["dir"] / "coincident.tps"
    io.write_landmarks(src, x, pd.DataFrame({"id": files["ids"]}))
    out = files["dir"] / "tps.csv"
    line = one_line_error(run("distances", src, "--metric", "tps", "--jobs", jobs, "--block-size", 1, "--no-progress",
                              "-o", out), "coincident.tps: specimens 'sp_c' (#3) and", "as u and v",
                          "coincident landmarks 4 and 5", "counts landmarks from 0")
    assert not out.exists(), line


#: the CLI as a user who registered a metric of their own runs it: their module imported first
GATED_CLI = "import sys, tests.gated_metric; from shapelib.cli import main; sys.exit(main(sys.argv[1:]))"


def _aligned_file(files, n):
    """``n`` aligned specimens (centroid size 20) in a CSV file, ids s0, s1, ..."""
    from shapelib.geometry.procrustes import generalized_procrustes

    x, _ = generalized_procrustes(_shapes(np.random.default_rng(7), n=n))
    path = files["dir"] / f"aligned{n}.csv"
    io.write_landmarks(path, 20 * x, pd.DataFrame({"id": [f"s{i}" for i in range(n)]}))
    return path, 20 * x


@pytest.mark.processes
@pytest.mark.parametrize("jobs", [1, 2])
def test_distances_resume_after_interrupt_through_the_store(files, jobs):
    """Fault injection with the real CLI: Ctrl-C mid-run, rerun with the same store, same matrix.
    With --jobs 2 the SIGINT goes to the whole process group, workers included, as a terminal
    sends it: still one line, no worker traceback, no process left behind. The metric is
    tests/gated_metric.py's "gated_alpha" ("alpha" whose calls after the first two wait for the
    test's gate): the signal lands after two pairs, with every worker inside a pair."""
    import signal

    import psutil

    from shapelib.pairwise import _Store, compute_pairwise, open_store
    from tests.gated_metric import Gate
    from tests.conftest import command_line, wait_for

    src, x = _aligned_file(files, 5)
    off = ~np.eye(len(x), dtype=bool)
    out, store = files["dir"] / "alpha.csv", files["dir"] / "alpha.zarr"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("SHAPELIB_DEBUG", None)
    with Gate(files["dir"] / "gate") as gate:
        def args(jobs=jobs, sigma2=16.0):
            return ["distances", src, "--metric", "gated_alpha", "--sigma2", sigma2, "--param", "n_steps=6",
                    "--param", f"gate={gate.path}", "--param", "free=2", "--jobs", jobs, "--block-size", 1,
                    "--store", store, "-o", out]

        def pairs_done():
            try:
                return sum(a != b for a, b in _Store.open(store).task_done())
            except Exception:  # not there yet
                return 0

        proc = subprocess.Popen([sys.executable, "-c", GATED_CLI, *map(str, args())], env=env, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
        try:
            # two pairs in the store, then one call per worker process waiting at the gate
            wait_for(lambda: gate.tickets() >= 2 + jobs and pairs_done() >= 2, "two pairs done, the rest waiting")
            kids = psutil.Process(proc.pid).children(recursive=True)  # the run's worker processes
            if jobs == 1:
                proc.send_signal(signal.SIGINT)
            else:
                os.killpg(proc.pid, signal.SIGINT)  # its own session: the group is the run's
            _, err = proc.communicate(timeout=120)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            gate.release()
        assert proc.returncode == 130 and "shapelib: interrupted" in err and "Traceback" not in err, (
            proc.returncode, err)
        assert "KeyboardInterrupt" not in err and "CancelledError" not in err, err  # nothing from the workers
        assert not out.exists()  # no half-written matrix
        workers = [k for k in kids if "resource_tracker" not in command_line(k)]  # (not the cluster's)
        assert jobs == 1 or len(workers) >= 2, kids
        _, alive = psutil.wait_procs(kids, timeout=30)
        assert not alive, f"worker processes left behind: {alive}"
        partial = open_store(store)
        assert not partial.complete and partial.computed[off].sum() == 2 * 2  # both halves of each pair
        proc = subprocess.run([sys.executable, "-c", GATED_CLI, *map(str, args(jobs=1))], env=env, text=True,
                              capture_output=True, timeout=300)
        assert proc.returncode == 0 and "resumed:" in proc.stdout, (proc.stdout, proc.stderr)
        # the same store with other parameters is refused, naming the store and what differs
        one_line_error(subprocess.run([sys.executable, "-c", GATED_CLI, *map(str, args(sigma2=9.0))], env=env,
                                      text=True, capture_output=True, timeout=300), store.name, "sigma2")
    # an independent, uninterrupted computation: "alpha" itself, without a store
    fresh = compute_pairwise(x, metric="alpha", sigma2=16.0, n_steps=6, n_jobs=1, progress=False).matrix
    np.testing.assert_allclose(_matrix(out).to_numpy(), fresh, rtol=1e-10, atol=0)


def test_max_blocks_stops_with_status_75_and_the_rerun_finishes(files):
    """On a LocalCluster: the blocks still running when the 4th is written are cancelled."""
    from shapelib.pairwise import open_store

    src, x = _aligned_file(files, 5)
    out, store = files["dir"] / "d.csv", files["dir"] / "d.zarr"
    args = ["distances", src, "--metric", "procrustes", "--jobs", 2, "--block-size", 1, "--no-progress",
            "--store", store, "-o", out]
    proc = run(*args, "--max-blocks", 4, check=75)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("shapelib: stopped after 4 block(s)"), proc.stderr
    assert "4 of 15 in store" in lines[0] and "rerun" in lines[0] and not out.exists()
    assert open_store(store).log["blocks_done"] == 4  # exactly: blocks still running were cancelled
    proc = run(*args[:4], "--jobs", 1, *args[6:], check=0)
    assert "resumed: 4 of 15 blocks" in proc.stdout
    want = np.array([[procrustes_distance(a, b) if i != j else 0.0 for j, b in enumerate(x)] for i, a in enumerate(x)])
    np.testing.assert_allclose(_matrix(out).to_numpy(), want, rtol=1e-12, atol=1e-15)
    one_line_error(run(*args[:-4], "-o", out, "--max-blocks", 2), "--max-blocks needs --store")
    one_line_error(run(*args, "--max-blocks", 0), "--max-blocks must be >= 1")


def test_a_stray_option_is_reported_with_its_command_usage(files):
    proc = run("geodesic", files["tps"], "--from", "sp_a", "--to", "sp_b", "--metric", "alpha", "-o",
               files["dir"] / "p.csv", "--rtol", "1e-3")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "usage: shapelib geodesic" in proc.stderr
    assert "shapelib geodesic: error: unrecognized arguments: --rtol 1e-3" in proc.stderr
