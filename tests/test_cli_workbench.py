"""What a morphometrician meets first, run as users run it: the README's own commands on a shared
dataset, σ² = auto on shapes whose landmarks vary less than they are apart, convergence words,
the PERMANOVA table's words, figures and bad input."""

import re
import shlex
import warnings

import numpy as np
import pandas as pd
import pytest

import shapelib as sl
from shapelib import io
from tests.conftest import ROOT, ellipse_population, requires_data
from tests.test_cli import one_line_error, run


@pytest.fixture(scope="module")
def adhd_sparse(tmp_path_factory):
    """Six ADHD-200 corpus callosum outlines with every second landmark (25), aligned at unit size:
    σ from their own scatter is about 0.15 landmark spacings (the Gaussians barely overlap)."""
    from shapelib.datasets import load_adhd200

    x, labels = load_adhd200()
    d = tmp_path_factory.mktemp("adhd")
    ids = labels["patient.id"].astype(str).tolist()[:6]
    raw = io.write_landmarks(d / "raw.tps", x[:6, ::2], pd.DataFrame({"id": ids}))
    run("align", raw, "-o", d / "aligned.tps", check=0)
    return d / "aligned.tps"


# ---------------------------------------------------------------------------------------------
# the README's commands, as written
# ---------------------------------------------------------------------------------------------


def _readme_commands(name):
    text = (ROOT / "README.md").read_text()
    lines = [ln.strip() for ln in text.splitlines() if re.match(rf"shapelib\s+{name}\s", ln.strip())]
    assert lines, f"README.md has no `shapelib {name}` line"
    return lines


@requires_data
def test_the_readme_mean_and_pca_commands_run_as_written(tmp_path):
    """``--sigma2 auto`` on ``mean`` and ``pca``: the README's lines, verbatim, on corpus callosum
    outlines of the shared data (5 specimens, every third landmark, to keep it short)."""
    from shapelib.datasets import load_corpus_callosum

    x, _ = load_corpus_callosum()
    raw = io.write_landmarks(tmp_path / "cc.tps", x[:5, ::3], pd.DataFrame({"id": [f"cc{i}" for i in range(5)]}))
    run("align", raw, "-o", tmp_path / "aligned.tps", check=0)
    for name in ("mean", "pca"):
        for line in _readme_commands(name):
            proc = run(*shlex.split(line)[1:], cwd=tmp_path)
            assert proc.returncode == 0, (line, proc.stderr)
            assert "sigma2 = " in proc.stdout and "(auto:" in proc.stdout
            assert "warning" not in proc.stderr, proc.stderr
    mean, _ = io.read_landmarks(tmp_path / "mean.tps")
    assert mean.shape == (1, 21, 2)
    scores = pd.read_csv(tmp_path / "scores.csv", index_col=0)
    assert len(scores) == 5 and np.allclose(scores.mean(axis=0), 0.0, atol=1e-6 * scores.abs().max().max())
    assert (tmp_path / "mean.png").stat().st_size > 0 and (tmp_path / "modes.png").stat().st_size > 0


# ---------------------------------------------------------------------------------------------
# σ well below the landmark spacing: the honest words
# ---------------------------------------------------------------------------------------------


@requires_data
def test_auto_sigma2_says_once_what_a_small_sigma_means_and_gives_no_rescaling_advice(adhd_sparse, tmp_path):
    proc = run("distances", adhd_sparse, "--metric", "alpha_bound", "--sigma2", "auto", "--jobs", 1, "--no-progress",
               "-o", tmp_path / "d.csv", check=0)
    assert "to_centroid_size" not in proc.stderr and "Bring the shapes" not in proc.stderr, proc.stderr
    assert "warning" not in proc.stderr, proc.stderr
    notes = [ln for ln in proc.stderr.splitlines() if "barely overlap" in ln]
    assert len(notes) == 1 and "--sigma2" in notes[0]
    # the library: the shapes' own estimate draws no rescaling advice, a quarter of it does
    x, _ = io.read_landmarks(adhd_sparse)
    est = sl.estimate_sigma2(x)
    assert est.sigma_over_spacing < 0.2
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.ScaleWarning)
        sl.geometry.scale.check_scale(x, est.sigma2)
    with pytest.warns(sl.ScaleWarning, match="spacing") as rec:
        sl.geometry.scale.check_scale(x, est.sigma2 / 4)
    assert rec[0].message.facts["kind"] == "small" and rec[0].message.facts["estimate"] == pytest.approx(est.sigma2)


@requires_data
def test_an_explicit_small_sigma2_is_advised_in_command_line_options(adhd_sparse, tmp_path):
    proc = run("distances", adhd_sparse, "--metric", "alpha_bound", "--sigma2", 1e-6, "--jobs", 1, "--no-progress",
               "-o", tmp_path / "d.csv", check=0)
    warning = [ln for ln in proc.stderr.splitlines() if ln.startswith("shapelib: warning:")]
    assert len(warning) == 1 and "--sigma2 auto" in warning[0] and "larger --sigma2" in warning[0]
    assert "shapelib." not in warning[0] and "(shapes)" not in warning[0]


@requires_data
def test_pairs_stopped_at_the_straight_path_are_solved_again_not_called_failures(adhd_sparse, tmp_path):
    """At σ of 0.07 landmark spacings the solver stops some pairs at their straight start and marks
    them unconverged; solved again from a perturbed path they come back to the same length (a local
    minimum of the energy reached from elsewhere), so they are geodesics, with wide brackets because
    the L2 lower bound saturates. Exit 0, their own status word."""
    pairs, out = tmp_path / "pairs.csv", tmp_path / "d.csv"
    proc = run("distances", adhd_sparse, "--metric", "alpha", "--sigma2", 1.4e-5, "--jobs", 1, "--no-progress",
               "--pairs", pairs, "-o", out)
    assert proc.returncode == 0, proc.stderr
    assert "solver failed" not in proc.stderr
    table = pd.read_csv(pairs)
    again = table[table["status"].str.startswith("converged (found again")]
    assert len(again) >= 1 and table["converged"].all(), table["status"].value_counts()
    assert (again["rel_gap"] > 0.5).all()  # the certificate is wide where the pairs stopped early
    # independently: each such pair's length is a local minimum reached from a far perturbed start
    x, _ = io.read_landmarks(adhd_sparse)
    i, j, value = int(again["i"].iloc[0]), int(again["j"].iloc[0]), float(again["value"].iloc[0])
    straight = np.linspace(x[i], x[j], 17)
    init = straight + np.r_[0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0][:, None, None] * \
        np.random.default_rng(5).normal(scale=np.sqrt(1.4e-5), size=straight.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = sl.geodesic(x[i], x[j], metric="alpha", sigma2=1.4e-5, init=init, max_iter=2000)
    assert r.converged and r.length == pytest.approx(value, rel=1e-4) and r.lower_bound < value / 1.5


# ---------------------------------------------------------------------------------------------
# words in the library's summaries
# ---------------------------------------------------------------------------------------------


def test_a_group_test_summary_says_when_a_group_mean_did_not_converge(rng):
    x = ellipse_population(rng, 8, k=8, noise=0.05)
    groups = np.repeat(["a", "b"], 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sl.mean_difference_test(x, groups, metric="alpha", sigma2=0.5, n_permutations=19, max_iter=1,
                                      tol=1e-12)
    assert not all(m.converged for m in res.means)
    assert "not converged" in res.summary() and not res.converged
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok = sl.mean_difference_test(x, groups, metric="alpha", sigma2=0.5, n_permutations=19)
    assert ok.converged and "not converged" not in ok.summary()


def test_a_thirty_against_one_group_test_warns(rng):
    x = ellipse_population(rng, 31, k=6, noise=0.05)
    with pytest.warns(UserWarning, match=r"group 'b' has 1 shape.*31 distinct relabellings"):
        sl.mean_difference_test(x, np.r_[["a"] * 30, ["b"]], metric="alpha", sigma2=0.5, n_permutations=19,
                                group_means=False)


def test_a_sequential_permanova_table_says_what_each_p_tests_and_why_f_and_p_disagree():
    from scipy.spatial.distance import cdist

    from shapelib.statistics.distance_based import permanova

    rng = np.random.default_rng(1)
    z = rng.normal(size=60)
    x = z + 0.05 * rng.normal(size=60)  # x carries z's effect, none of its own
    y = np.c_[2 * z, rng.normal(size=60)] + rng.normal(size=(60, 2))
    d = cdist(y, y)
    seq = permanova(d, {"x": x, "z": z}, by="terms", n_permutations=199)
    t = seq.table
    assert t.loc["x", "pseudo_F"] > 20 and t.loc["x", "p_value"] > 0.05  # the contradiction the table showed
    assert t.loc["x", "ss_type"] == "I (sequential)" and "given z" in t.loc["x", "p_tests"]
    assert len(seq.notes) == 1 and seq.notes[0].startswith("x:") and "shared with z" in seq.notes[0]
    assert "note: x:" in seq.summary() and "p of x: no effect of x given z" in seq.summary()
    marg = permanova(d, {"x": x, "z": z}, by="margin", n_permutations=199)
    assert marg.notes == [] and marg.table.loc["x", "ss_type"] == "III (marginal)"
    rows = permanova(d, {"x": x, "z": z}, by="terms", permute="rows", n_permutations=199)
    assert rows.table.loc["x", "p_value"] <= 0.01 and "no effect of any term" in rows.table.loc["x", "p_tests"]


# ---------------------------------------------------------------------------------------------
# pose advice in the command's own options; figures
# ---------------------------------------------------------------------------------------------


def _turned(rng, n=5, k=7):
    x = ellipse_population(rng, n, k=k, noise=0.05)
    out = []
    for i, s in enumerate(x):
        a = np.deg2rad(20 * i)
        out.append(s @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T + 5.0)
    return np.stack(out)


def test_mean_on_unaligned_shapes_advises_its_own_options(rng, tmp_path):
    src = io.write_tps(tmp_path / "raw.tps", _turned(rng), [f"s{i}" for i in range(5)])
    proc = run("mean", src, "--metric", "alpha", "--sigma2", 0.5, "--jobs", 1, "--n-steps", 2,
               "-o", tmp_path / "m.tps")
    warning = [ln for ln in proc.stderr.splitlines() if "pose" in ln]
    assert warning and "--no-align" not in proc.stderr and "--size" in warning[0], proc.stderr


def test_mean_figure_draws_points_by_default_links_when_asked_and_3d(rng, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from shapelib.plotting import plot_geodesic, plot_mean, plot_modes

    x = ellipse_population(rng, 5, k=6, noise=0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sl.frechet_mean(x, metric="alpha", sigma2=0.5, n_steps=2)
    fig = plot_mean(x, res, closed=None)
    ax = fig.axes[0]
    assert all(ln.get_linestyle() == "None" for ln in ax.lines)  # points only: no polygon in file order
    assert {t.get_text() for t in ax.get_legend().get_texts()} == {"specimens (5)", "Procrustes mean (start)",
                                                                    "Fréchet mean"}
    fig = plot_mean(x, res, links=[(0, 1), (1, 2)])
    segments = [ln for ln in fig.axes[0].lines if ln.get_linestyle() != "None"]
    assert len(segments) == 2 * (len(x) + 2) and all(len(s.get_xdata()) == 2 for s in segments)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pca = sl.tangent_pca(x, metric="alpha", sigma2=0.5, n_steps=2, mean=res, modes=(0,))
    fig = plot_modes(pca, components=(0,), closed=None)
    assert fig.legends and "Fréchet mean (reference)" in [t.get_text() for t in fig.legends[0].get_texts()]
    x3 = ellipse_population(rng, 2, k=5, d=3, noise=0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        geo = sl.geodesic(x3[0], x3[1], metric="alpha", sigma2=0.5, n_steps=4)
    fig = plot_geodesic(geo, links=[(0, 1)])
    assert fig.axes[0].name == "3d" and len(fig.axes[0].get_xticks()) > 0


# ---------------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------------


def test_a_csv_without_header_or_with_semicolons_says_so(tmp_path):
    no_header = tmp_path / "nohead.csv"
    no_header.write_text("80.0,12.5,81.0,13.0,82.5,15.0\n79.0,12.0,80.5,13.5,83.0,14.0\n")
    one_line_error(run("info", no_header), "nohead.csv", "header row")
    semi = tmp_path / "semi.csv"
    semi.write_text("id;x1;y1;x2;y2;x3;y3\na;1,0;2,0;3,0;4,0;5,0;7,0\n")
    one_line_error(run("info", semi), "semi.csv", "separated by ';'")


def test_huge_coordinates_are_not_called_zero_size():
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]) * 1e200
    assert sl.geometry.procrustes.centroid_size(x) == pytest.approx(np.sqrt(4 / 3) * 1e200, rel=1e-12)
    np.testing.assert_allclose(sl.geometry.procrustes.preshape(x), sl.geometry.procrustes.preshape(x / 1e200),
                               rtol=1e-12)


def test_two_landmarks_and_coincident_landmarks_are_flagged(rng, tmp_path):
    two = io.write_tps(tmp_path / "two.tps", rng.uniform(1, 2, size=(4, 2, 2)), [f"s{i}" for i in range(4)])
    one_line_error(run("pca", two, "--metric", "alpha", "--sigma2", 0.5, "-o", tmp_path / "s.csv"),
                   "2 landmark", "at least 3 landmarks")
    x = rng.uniform(10, 20, size=(3, 5, 2))
    x[1, 3] = x[1, 1]
    dup = io.write_tps(tmp_path / "dup.tps", x, ["a", "b", "c"])
    proc = run("info", dup, check=0)
    assert "specimen 'b' has landmarks 2 and 4 at the same point" in proc.stderr, proc.stderr


# ---------------------------------------------------------------------------------------------
# shapelib test and shapelib regress
# ---------------------------------------------------------------------------------------------


def test_holm_adjust_matches_its_closed_form():
    p = np.array([0.04, 0.001, 0.03, 0.2])
    # sorted 0.001, 0.03, 0.04, 0.2 -> 4*0.001, max(.., 3*0.03), max(.., 2*0.04), max(.., 1*0.2)
    np.testing.assert_allclose(sl.holm_adjust(p), [0.09, 0.004, 0.09, 0.2])
    assert sl.holm_adjust([0.5, 0.6]).tolist() == [1.0, 1.0]
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        sl.holm_adjust([0.1, 1.5])


@pytest.fixture(scope="module")
def adhd_groups(tmp_path_factory):
    """30 ADHD-200 outlines (aligned) and a covariate table keyed by patient id, rows shuffled."""
    from shapelib.datasets import load_adhd200

    x, labels = load_adhd200()
    d = tmp_path_factory.mktemp("groups")
    lab = labels.iloc[:30].assign(id=labels["patient.id"].astype(str)[:30])
    lab["site"] = np.array(["a", "b", "c"])[np.arange(30) % 3]
    raw = io.write_landmarks(d / "raw.tps", x[:30, ::2], pd.DataFrame({"id": lab["id"]}))
    run("align", raw, "-o", d / "aligned.tps", check=0)
    lab.sample(frac=1.0, random_state=0)[["id", "site", "age", "gender"]].to_csv(d / "cov.csv", index=False)
    return d


@requires_data
def test_shapelib_test_is_permanova_of_the_metric_with_holm_adjusted_pairs(adhd_groups):
    from shapelib.statistics.distance_based import permanova

    d = adhd_groups
    proc = run("test", d / "aligned.tps", "--covariates", d / "cov.csv", "--by", "site", "--metric", "procrustes",
               "--permutations", 99, "-o", d / "t.csv", check=0)
    table = pd.read_csv(d / "t.csv")
    assert list(table["comparison"]) == ["all groups", "a vs b", "a vs c", "b vs c"]
    x, spec = io.read_landmarks(d / "aligned.tps")
    cov = pd.read_csv(d / "cov.csv", dtype={"id": str}).set_index("id").loc[spec["id"].astype(str)]
    dist = sl.pairwise_distances(x, metric="procrustes", n_jobs=1, progress=False)
    want = permanova(dist, {"site": cov["site"].to_numpy()}, n_permutations=99, seed=0).table.loc["site"]
    assert table.loc[0, "pseudo_F"] == pytest.approx(want["pseudo_F"], rel=1e-12)
    assert table.loc[0, "p_value"] == want["p_value"]
    np.testing.assert_allclose(table["p_holm"][1:], sl.holm_adjust(table["p_value"][1:]))
    assert "pairwise (Holm-adjusted over 3 comparisons)" in proc.stdout
    # ids absent from the covariates are named
    pd.read_csv(d / "cov.csv").iloc[1:].to_csv(d / "short.csv", index=False)
    one_line_error(run("test", d / "aligned.tps", "--covariates", d / "short.csv", "--by", "site", "--metric",
                       "procrustes"), "short.csv", "no row for specimen")


@requires_data
def test_shapelib_regress_is_distance_based_regression_with_a_permutation_p(adhd_groups):
    from shapelib.statistics.distance_based import permanova

    d = adhd_groups
    proc = run("regress", d / "aligned.tps", "--covariates", d / "cov.csv", "--by", "age", "--log", "--metric",
               "procrustes", "--permutations", 99, "-o", d / "r.csv", check=0)
    x, spec = io.read_landmarks(d / "aligned.tps")
    age = pd.read_csv(d / "cov.csv", dtype={"id": str}).set_index("id").loc[spec["id"].astype(str), "age"]
    dist = sl.pairwise_distances(x, metric="procrustes", n_jobs=1, progress=False)
    want = permanova(dist, {"age": np.log(age.to_numpy())}, n_permutations=99, seed=0).table.loc["age"]
    got = pd.read_csv(d / "r.csv").set_index("term").loc["age"]
    assert got["r2"] == pytest.approx(want["r2"], rel=1e-12) and got["p_value"] == want["p_value"]
    # R² of one centred numeric term: the squared-distance share of a linear fit of the coordinates
    y = x.reshape(len(x), -1) - x.reshape(len(x), -1).mean(axis=0)
    c = np.log(age.to_numpy()) - np.log(age.to_numpy()).mean()
    beta = c @ y / (c @ c)
    assert want["r2"] == pytest.approx(np.sum(np.outer(c, beta) ** 2) / np.sum(y ** 2), rel=0.05)
    assert "R² = " in proc.stdout and "log age" in proc.stdout
    one_line_error(run("regress", d / "aligned.tps", "--covariates", d / "cov.csv", "--by", "site", "--metric",
                       "procrustes"), "--by site", "not a number")


def test_align_keeps_the_centroid_sizes_for_an_allometry_regression(rng, tmp_path):
    from shapelib.geometry.procrustes import centroid_size

    x = rng.uniform(10, 50, size=(6, 5, 2)) * rng.uniform(1, 3, size=(6, 1, 1))
    src = io.write_tps(tmp_path / "raw.tps", x, [f"s{i}" for i in range(6)])
    proc = run("align", src, "-o", tmp_path / "a.tps", "--sizes", tmp_path / "sizes.csv", check=0)
    sizes = pd.read_csv(tmp_path / "sizes.csv")
    assert list(sizes["id"]) == [f"s{i}" for i in range(6)] and "--by centroid_size --log" in proc.stdout
    np.testing.assert_allclose(sizes["centroid_size"], [centroid_size(s) for s in x], rtol=1e-12)
    proc = run("regress", tmp_path / "a.tps", "--covariates", tmp_path / "sizes.csv", "--by", "centroid_size",
               "--log", "--metric", "procrustes", "--permutations", 19, "--jobs", 1, check=0)
    assert "shape on log centroid_size" in proc.stdout


def test_align_estimates_missing_landmarks_when_asked(rng, tmp_path):
    t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    x = np.stack([np.c_[100 + 30 * np.cos(t), 100 + (20 + 3 * rng.normal()) * np.sin(t)] for _ in range(8)])
    gone = x.copy()
    gone[0, 2] = np.nan
    src = tmp_path / "gone.csv"
    frame = pd.DataFrame(gone.reshape(8, -1), columns=[f"{a}{j + 1}" for j in range(8) for a in "xy"])
    frame.insert(0, "id", [f"s{i}" for i in range(8)])
    frame.to_csv(src, index=False, na_rep="NA")
    one_line_error(run("align", src, "-o", tmp_path / "a.csv"), "missing")
    proc = run("align", src, "-o", tmp_path / "a.csv", "--estimate-missing", "tps", check=0)
    assert "1 missing landmark(s) in 1 specimen(s) estimated" in proc.stderr and "s0: landmark(s) 3" in proc.stderr
    aligned, _ = io.read_landmarks(tmp_path / "a.csv")
    assert np.isfinite(aligned).all()


def test_pc_score_scatter_with_groups_and_hulls(rng, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from scipy.spatial import ConvexHull

    from shapelib.plotting import plot_scores

    scores = rng.normal(size=(30, 3))
    groups = np.repeat(["a", "b", "c"], 10)
    fig = plot_scores(scores, groups, explained=[0.5, 0.3, 0.2])
    ax = fig.axes[0]
    assert ax.get_xlabel() == "PC1 (50.0 %)"
    assert sorted(t.get_text() for t in ax.get_legend().get_texts()) == ["a (n = 10)", "b (n = 10)", "c (n = 10)"]
    rings = [ln for ln in ax.lines if ln.get_linestyle() == "-" and len(ln.get_xdata()) > 2]
    want = sorted(len(ConvexHull(scores[groups == g][:, :2]).vertices) + 1 for g in "abc")
    assert sorted(len(r.get_xdata()) for r in rings) == want  # one closed hull per group
    # on the command line, from the pca command with groups from a CSV file
    x = _turned(rng, n=6, k=6)
    src = io.write_tps(tmp_path / "s.tps", x, [f"s{i}" for i in range(6)])
    pd.DataFrame({"id": [f"s{i}" for i in range(6)], "g": list("aaabbb")}).to_csv(tmp_path / "g.csv", index=False)
    proc = run("pca", src, "--size", 1, "--metric", "alpha", "--sigma2", "auto", "--n-steps", 2, "--jobs", 1,
               "-o", tmp_path / "scores.csv", "--scores-plot", tmp_path / "sc.png", "--covariates", tmp_path / "g.csv",
               "--by", "g")
    assert proc.returncode == 0 and (tmp_path / "sc.png").stat().st_size > 0, proc.stderr


def test_an_n_d_k_array_is_not_silently_read_as_p_k_n(rng, tmp_path):
    x = rng.normal(size=(13, 28, 2))
    path = tmp_path / "ndk.npy"
    np.save(path, np.swapaxes(x, 1, 2))  # (N, d, K): looks like geomorph's (K, d, N)
    line = one_line_error(run("info", path), "--pkn", "numpy.swapaxes(array, 1, 2)")
    assert "(N, d, K)" in line
    proc = run("info", path, "--pkn", check=0)
    note = [ln for ln in proc.stderr.splitlines() if "p x k x n" in ln]
    assert len(note) == 1 and "28 specimens of 13 landmarks" in note[0] and "13 specimens of 28 landmarks" in note[0]
