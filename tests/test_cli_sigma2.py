"""σ² from the data on the command line: `shapelib info` reports it and `--sigma2 auto` uses it."""

import re

import numpy as np
import pandas as pd
import pytest

import shapelib as sl

from shapelib import io, pairwise_distances
from shapelib.geometry.scale import estimate_sigma2
from tests.test_cli import files, run  # noqa: F401  (the CLI tests' fixture and runner)


def test_info_reports_the_estimate_and_when_the_shapes_need_aligning(files, rng):  # noqa: F811
    out = run("info", files["tps"], check=0).stdout
    est = estimate_sigma2(files["x"])
    line = next(ln for ln in out.splitlines() if ln.startswith("sigma2"))
    assert f"{est.sigma2:.4g} ± {est.standard_error:.2g}" in line and "`--sigma2 auto` uses it" in line
    assert "position and orientation" not in out  # the ellipses differ by landmark noise only
    turned = files["x"].copy()
    for i, a in enumerate(rng.uniform(0, 2 * np.pi, size=len(turned))):
        c, s = np.cos(a), np.sin(a)
        turned[i] = turned[i] @ np.array([[c, -s], [s, c]]) + 300
    src = files["dir"] / "turned.csv"
    io.write_landmarks(src, turned, pd.DataFrame({"id": files["ids"]}))
    out = run("info", src, check=0).stdout
    assert "of the scatter as given is position and orientation" in out
    sigma2 = float(re.search(r"^sigma2\s+(\S+)", out, re.M).group(1))
    assert sigma2 == pytest.approx(est.sigma2, rel=1e-3)  # pose does not enter the estimate


def test_distances_with_sigma2_auto_uses_and_states_the_estimate(files):  # noqa: F811
    out = files["dir"] / "alpha.csv"
    proc = run("distances", files["csv"], "--metric", "alpha_bound", "--sigma2", "auto", "--jobs", 1,
               "--no-progress", "-o", out, check=0)
    m = re.search(r"sigma2 = (\S+) \(auto: the landmarks' scatter", proc.stdout)
    assert m, proc.stdout
    sigma2 = float(m.group(1))
    assert sigma2 == pytest.approx(estimate_sigma2(files["x"]).sigma2, rel=1e-5)
    got = pd.read_csv(out, index_col=0).to_numpy()
    aligned = sl.pose_align(files["x"])[0]  # the command line aligns first for a pose-dependent metric
    want = pairwise_distances(aligned, metric="alpha_bound", sigma2=sigma2, n_jobs=1, progress=False)
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_sigma2_must_be_a_number_or_auto(files):  # noqa: F811
    proc = run("distances", files["csv"], "--metric", "alpha_bound", "--sigma2", "often", "-o",
               files["dir"] / "x.csv")
    assert proc.returncode == 2 and "expected a number or 'auto'" in proc.stderr
