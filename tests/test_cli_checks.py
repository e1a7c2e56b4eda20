"""What the command line checks for the user (docs/guide/checks.md), run as users run it: pose
(aligned by default for pose-dependent metrics), scale, convergence words, round trips of the
files it writes, plots. Library-level cases: tests/test_checks.py."""

import numpy as np
import pandas as pd
import pytest

import shapelib as sl
from shapelib import io
from tests.test_cli import _matrix, one_line_error, run


def _rotated_population(rng, n=5, k=9):
    """Ellipses in pixel coordinates (positive, as tpsDig writes them), each turned by its own
    angle about its own centre: raw specimens in different poses."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    out = []
    for i in range(n):
        base = np.column_stack([120 * np.cos(t), 60 * np.sin(t)]) + rng.normal(scale=6, size=(k, 2))
        a = np.deg2rad(25 * i)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        out.append(base @ rot.T + [300 + 10 * i, 250 - 5 * i])
    return np.round(np.stack(out), 4)


@pytest.fixture
def raw(tmp_path, rng):
    x = _rotated_population(rng)
    ids = [f"sp{i}" for i in range(len(x))]
    path = io.write_tps(tmp_path / "raw.tps", x, ids)
    return {"x": x, "ids": ids, "tps": path, "dir": tmp_path}


SIGMA2 = 3600.0  # sigma of about one landmark spacing (~80 px): no scale warning


def test_distances_align_by_default_for_a_pose_dependent_metric(raw):
    out = raw["dir"] / "d.csv"
    proc = run("distances", raw["tps"], "--metric", "alpha_bound", "--sigma2", SIGMA2, "--jobs", 1, "--no-progress",
               "-o", out, check=0)
    notes = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(notes) == 1 and notes[0].startswith("shapelib: note: alpha_bound depends on the pose"), proc.stderr
    assert "--no-align" in notes[0]
    aligned = sl.pose_align(raw["x"])[0]
    want = sl.pairwise_distances(aligned, metric="alpha_bound", sigma2=SIGMA2, n_jobs=1, progress=False)
    np.testing.assert_allclose(_matrix(out).to_numpy(), want, rtol=1e-12, atol=1e-15)
    # --no-align: the file's pose, and one warning saying what that means and what to do
    proc = run("distances", raw["tps"], "--metric", "alpha_bound", "--sigma2", SIGMA2, "--jobs", 1, "--no-progress",
               "--no-align", "-o", out, check=0)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("shapelib: warning: alpha_bound depends on the pose"), proc.stderr
    assert "Drop --no-align" in lines[0] and "pose_align" not in lines[0]
    with pytest.warns(sl.PoseWarning):
        want = sl.pairwise_distances(raw["x"], metric="alpha_bound", sigma2=SIGMA2, n_jobs=1, progress=False)
    np.testing.assert_allclose(_matrix(out).to_numpy(), want, rtol=1e-12, atol=1e-15)
    # a pose-invariant metric is computed on the file's shapes, with nothing to say
    proc = run("distances", raw["tps"], "--metric", "procrustes", "--jobs", 1, "--no-progress", "-o", out, check=0)
    assert proc.stderr == ""


def test_geodesic_aligns_the_whole_file_as_distances_does(raw):
    out = raw["dir"] / "path.csv"
    proc = run("geodesic", raw["tps"], "--from", "sp0", "--to", "sp3", "--metric", "alpha", "--sigma2", SIGMA2,
               "--n-steps", 4, "-o", out, check=0)
    assert "shapelib: note: alpha depends on the pose" in proc.stderr and "warning" not in proc.stderr
    aligned = sl.pose_align(raw["x"])[0]
    path = pd.read_csv(out)
    np.testing.assert_allclose(path[path.step == 0][["x", "y"]].to_numpy(), aligned[0], rtol=1e-12)
    np.testing.assert_allclose(path[path.step == 4][["x", "y"]].to_numpy(), aligned[3], rtol=1e-12)
    proc = run("geodesic", raw["tps"], "--from", "sp0", "--to", "sp3", "--metric", "alpha", "--sigma2", SIGMA2,
               "--n-steps", 4, "--no-align", "-o", out, check=0)
    assert "shapelib: warning: alpha depends on the pose" in proc.stderr
    path = pd.read_csv(out)
    np.testing.assert_allclose(path[path.step == 0][["x", "y"]].to_numpy(), raw["x"][0], rtol=1e-12)


def test_help_examples_run_no_pose_dependent_metric_on_raw_coordinates():
    for command in ("distances", "geodesic"):
        text = run(command, "--help", check=0).stdout.replace("\\\n", " ")
        commands = [ln for ln in text.splitlines() if ln.strip().startswith(f"shapelib {command} ")]
        assert commands, text
        for line in commands:
            if any(m in line for m in ("alpha", "fisher_rao", "hausdorff", "diffeomorphism")):
                assert "aligned." in line, line
            assert "--negative-coordinates" not in line, line  # shapelib reads back what it writes


@pytest.mark.parametrize("command", ["distances", "geodesic"])
def test_fisher_rao_on_raw_pixels_is_a_one_line_error_not_an_internal_error(raw, command):
    out = raw["dir"] / "out.csv"
    where = ["--from", "sp0", "--to", "sp1"] if command == "geodesic" else ["--jobs", 1, "--no-progress"]
    proc = run(command, raw["tps"], *where, "--metric", "fisher_rao", "--sigma2", 0.5, "--param", "n_steps=2", "-o", out)
    one_line_error(proc, "sigma2 = 0.5 is too small", "Use sigma2 >=")
    assert "internal error" not in proc.stderr and not out.exists()


def test_distances_say_bracket_wider_than_rtol_apart_from_solver_failed(raw):
    out, pairs = raw["dir"] / "d.csv", raw["dir"] / "pairs.csv"
    common = ["--metric", "alpha", "--sigma2", SIGMA2, "--jobs", 1, "--no-progress", "-o", out, "--pairs", pairs]
    proc = run("distances", raw["tps"], *common, "--rtol", 1e-9, "--param", "max_n_steps=8", check=0)
    line = [ln for ln in proc.stderr.splitlines() if "warning" in ln]
    assert len(line) == 1 and "10 of 10 pairs: the certified bracket is wider than --rtol 1e-09 (relative gap median" \
        in line[0] and "solver did not fail" in line[0], proc.stderr
    table = pd.read_csv(pairs)
    assert set(table["status"]) == {"bracket wider than rtol"} and (table["rel_gap"] > 1e-9).all()
    proc = run("distances", raw["tps"], *common, "--param", "max_iter=1", "--param", "n_steps=8")
    assert proc.returncode == 4, (proc.returncode, proc.stderr)
    assert "10 of 10 pairs: solver failed" in proc.stderr and "exit status 4" in proc.stderr
    assert set(pd.read_csv(pairs)["status"]) == {"solver failed"} and out.exists()


def test_an_unconverged_geodesic_is_written_flagged_and_exits_4(raw):
    out = raw["dir"] / "path.csv"
    proc = run("geodesic", raw["tps"], "--from", "sp0", "--to", "sp2", "--metric", "alpha", "--sigma2", SIGMA2,
               "--n-steps", 8, "--param", "max_iter=1", "-o", out)
    assert proc.returncode == 4, (proc.returncode, proc.stderr)
    assert "converged False" in proc.stdout and out.exists()
    warning = [ln for ln in proc.stderr.splitlines() if ln.startswith("shapelib: warning:")]
    assert len(warning) == 1 and "did not converge (stopped by max_iter after 1 iterations)" in warning[0]
    assert "upper bound only" in warning[0] and "raise --param max_iter" in warning[0]
    # raw pixels at sigma2 = 0.5: the landmarks' Gaussians do not interact, the solver stops at the
    # straight path (a geodesic: solved again from a perturbed path it comes back to the same length);
    # the scale warning says what to do in the command's options
    proc = run("geodesic", raw["tps"], "--from", "sp0", "--to", "sp2", "--metric", "alpha", "--sigma2", 0.5,
               "--n-steps", 4, "-o", out)
    assert proc.returncode == 0 and "converged back to the same length" in proc.stderr, proc.stderr
    assert "Use a larger --sigma2" in proc.stderr and "max_iter" not in proc.stderr
    proc = run("geodesic", raw["tps"], "--from", "sp0", "--to", "sp2", "--metric", "alpha", "--sigma2", SIGMA2,
               "--n-steps", 4, "-o", out, check=0)
    assert "warning" not in proc.stderr


# ---------------------------------------------------------------------------------------------
# Round trips: every landmark file shapelib writes reads back with the same command line
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", ["tps", "csv", "npz"])
def test_an_aligned_file_reads_back_with_no_options(raw, ext):
    src = raw["dir"] / f"raw.{ext}"
    if ext != "tps":
        io.write_landmarks(src, raw["x"], raw["ids"])
    out = raw["dir"] / f"aligned.{ext}"
    run("align", src, "-o", out, "--size", 20, check=0)
    info = run("info", out, check=0)
    assert "missing     none" in info.stdout and "warning" not in info.stderr, (info.stdout, info.stderr)
    d = raw["dir"] / "d.csv"
    proc = run("distances", out, "--metric", "alpha_bound", "--sigma2", 25.0, "--jobs", 1, "--no-progress", "-o", d,
               check=0)
    assert proc.stderr == ""  # read back as written, already aligned: nothing to say
    back, _ = io.read_landmarks(out)
    assert (back < 0).any()  # centred coordinates, read as coordinates
    np.testing.assert_allclose([sl.centroid_size(s) for s in back], 20.0, rtol=1e-12)
    want = sl.pairwise_distances(back, metric="alpha_bound", sigma2=25.0, n_jobs=1, progress=False)
    np.testing.assert_allclose(_matrix(d).to_numpy(), want, rtol=1e-12, atol=1e-15)
    # written again (aligning an aligned file) and read again: the same shapes, up to one rotation
    # of the whole set (GPA's orientation is arbitrary), which changes no distance
    again = raw["dir"] / f"again.{ext}"
    run("align", out, "-o", again, "--size", 20, check=0)
    np.testing.assert_allclose(sl.pairwise_distances(io.read_landmarks(again)[0], metric="alpha_bound", sigma2=25.0,
                                                     n_jobs=1, progress=False), want, rtol=1e-9, atol=1e-12)


def test_distances_say_the_estimated_time_before_the_run(raw):
    """The real CLI (its main, in a fresh process) with every run counted as long: the estimate is a
    note on stderr before the progress bar starts."""
    import subprocess
    import sys

    from tests.conftest import ROOT

    out = raw["dir"] / "d.csv"
    code = ("import sys, shapelib.pairwise._driver as p; p.LONG_RUN_SECONDS = 0.0; from shapelib.cli import main; "
            f"sys.exit(main(['distances', {str(raw['tps'])!r}, '--metric', 'alpha_bound', '--sigma2', '3600', "
            f"'--jobs', '1', '-o', {str(out)!r}]))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    notes = [ln for ln in proc.stderr.splitlines() if "s per pair (timed)" in ln]
    assert len(notes) == 1 and notes[0].startswith("shapelib: note: alpha_bound: 10 pairs × "), proc.stderr
    assert "÷ 1 worker ≈ " in notes[0]
    assert proc.stderr.index(notes[0]) < proc.stderr.index("alpha_bound pairs")  # before the progress bar


# ---------------------------------------------------------------------------------------------
# Ctrl-C: one line, no warning noise (tracebacks, atexit errors, leaked semaphores)
# ---------------------------------------------------------------------------------------------

_CTRL_C = '''
import os, signal, sys
import distributed
from shapelib import pairwise
from shapelib.cli import main

def hooks(second):
    """Ctrl-C (a real SIGINT) once the second block is on disk, and with `second` again as the
    engine starts closing its LocalCluster (an impatient user): no timing involved."""
    written, fired = [], []
    write = pairwise._Store.write_block
    def write_block(self, a, b, out):
        write(self, a, b, out)
        written.append((a, b))
        if len(written) == 2:
            os.kill(os.getpid(), signal.SIGINT)
    pairwise._Store.write_block = write_block
    close = distributed.LocalCluster.close
    def close_once(self, *a, **k):
        if second and not fired:
            fired.append(1)
            os.kill(os.getpid(), signal.SIGINT)
        return close(self, *a, **k)
    distributed.LocalCluster.close = close_once

if __name__ == "__main__":
    hooks(sys.argv[1] == "twice")
    sys.exit(main(sys.argv[2:]))
'''


@pytest.mark.processes
@pytest.mark.parametrize("presses", ["once", "twice"])
def test_ctrl_c_leaves_one_line_and_no_warning_noise(raw, presses):
    import subprocess
    import sys

    from shapelib.pairwise import open_store
    from tests.conftest import ROOT

    script = raw["dir"] / "ctrl_c.py"
    script.write_text(_CTRL_C)
    store, out = raw["dir"] / "s.zarr", raw["dir"] / "d.csv"
    proc = subprocess.run([sys.executable, str(script), presses, "distances", str(raw["tps"]), "--metric", "alpha",
                           "--sigma2", str(SIGMA2), "--param", "n_steps=8", "--jobs", "2", "--block-size", "1",
                           "--no-progress", "--store", str(store), "-o", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip() and not ln.startswith("shapelib: note:")]
    assert proc.returncode == 130 and lines == ["shapelib: interrupted"], (proc.returncode, proc.stderr)
    assert not out.exists()
    partial = open_store(store)  # what was written before the Ctrl-C is kept for the rerun
    pairs = int(partial.computed[~np.eye(5, dtype=bool)].sum()) // 2  # two blocks: (0, 0) has no pair, (0, 1) one
    assert 1 <= pairs < 10 and not partial.complete


# ---------------------------------------------------------------------------------------------
# Plots: links as given (points only by default), a legend, axes fitted to the shapes
# ---------------------------------------------------------------------------------------------


def test_parse_links():
    from shapelib.plotting import parse_links

    assert parse_links("1-2, 2-3,3-1", 3) == [(0, 1), (1, 2), (2, 0)]
    assert parse_links("contour", 4) == [(0, 1), (1, 2), (2, 3), (3, 0)]
    with pytest.raises(ValueError, match=r"'2-9' names landmark 9, but the shapes have landmarks 1 to 4"):
        parse_links("1-2,2-9", 4)
    with pytest.raises(ValueError, match=r"'1:2' is not a pair of landmark numbers"):
        parse_links("1:2", 4)


def test_plot_geodesic_draws_only_the_links_given_with_a_legend_in_a_fitted_figure():
    import matplotlib

    matplotlib.use("Agg")
    from shapelib.plotting import plot_geodesic

    # a thin strip (a wing): 10 x 1 units
    t = np.linspace(0, 1, 8)
    u = np.c_[10 * t, 0.5 * np.sin(np.pi * t)]
    v = sl.procrustes_align(u, u + np.c_[0 * t, 0.3 * np.sin(2 * np.pi * t)], scaling=False)  # bent, aligned
    result = sl.geodesic(u, v, metric="alpha", sigma2=1.0, n_steps=4)
    points_only = plot_geodesic(result)
    w, h = points_only.get_size_inches()
    assert w / h > 2  # wide like the shapes, not a square
    ax = points_only.axes[0]
    assert ax.get_aspect() == 1.0
    lo, hi = ax.get_xlim()
    assert lo < u[:, 0].min() and hi > u[:, 0].max() and hi - lo < 1.2 * 10  # fitted, with a small margin
    n_lines = len(ax.lines)
    [legend] = points_only.legends
    assert [t.get_text() for t in legend.get_texts()][:2] == ["landmark trajectory", "straight line (initial path)"]
    with_links = plot_geodesic(result, links=[(0, 1), (1, 2)])
    assert len(with_links.axes[0].lines) == n_lines + 4  # two links on the start shape, two on the end shape
    assert "start shape (links)" in [t.get_text() for t in with_links.legends[0].get_texts()]


def test_geodesic_plot_takes_links_from_the_command_line(raw, rng):
    from PIL import Image

    t = np.linspace(0, 2 * np.pi, 9, endpoint=False)
    strips = np.stack([np.c_[300 + 200 * np.cos(t), 250 + 20 * np.sin(t)] + rng.normal(scale=2, size=(9, 2))
                       for _ in range(3)])  # thin, wide outlines, in one pose
    src = io.write_tps(raw["dir"] / "strips.tps", strips, ["sp0", "sp1", "sp2"])
    out, png = raw["dir"] / "path.csv", raw["dir"] / "path.png"
    base = ["geodesic", src, "--from", "sp0", "--to", "sp1", "--metric", "alpha", "--sigma2", 400.0,
            "--n-steps", 4, "-o", out, "--plot", png]
    run(*base, "--links", "contour", check=0)
    with Image.open(png) as im:
        assert im.size[0] > 1.5 * im.size[1]  # the outlines are wide: so is the figure (legend included)
    run(*base, "--links", "1-2,2-3", check=0)
    one_line_error(run(*base, "--links", "1-12"), "--links: '1-12' names landmark 12", "landmarks 1 to 9")
    one_line_error(run(*base[:-2], "--links", "contour"), "--links applies to --plot and --animate")


@pytest.mark.parametrize("command", [
    ("distances", "--metric", "procrustes", "--jobs", 0, "-o", "d.csv"),
    ("mean", "--metric", "alpha", "--sigma2", SIGMA2, "--jobs", -2, "-o", "m.tps"),
    ("test", "--covariates", "c.csv", "--by", "g", "--metric", "procrustes", "--jobs", 0),
    ("align", "--size", -1, "-o", "a.tps"),
    ("pca", "--metric", "alpha", "--sigma2", SIGMA2, "--size", 0, "-o", "s.csv"),
])
def test_jobs_and_size_are_checked_alike_by_every_command(raw, command):
    """--jobs: a positive number of workers or -1; --size: a positive centroid size; the same words everywhere."""
    name, *options = command
    flag = "--jobs" if "--jobs" in options else "--size"
    value = options[options.index(flag) + 1]
    proc = run(name, raw["tps"], *options, cwd=raw["dir"])
    line = one_line_error(proc, f"{flag} must be a positive number", f"got {value}")
    assert not any((raw["dir"] / f).exists() for f in ("d.csv", "m.tps", "a.tps", "s.csv")), line
