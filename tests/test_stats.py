"""Population statistics (shapelib.statistics.distance_based) against scikit-bio, scikit-learn and closed forms."""

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.distance import cdist

from shapelib.statistics.distance_based import (
    as_distance_matrix,
    classical_mds,
    gower_centered,
    knn_loo_accuracy,
    mantel_test,
    permanova,
)


def _points(n=40, p=3, shift=0.0, seed=0):
    rng = np.random.default_rng(seed)
    y = rng.normal(size=(n, p))
    g = np.array(["a", "b"] * (n // 2))
    y[g == "b", 0] += shift
    return y, g


def _trace_f(y, z, x):
    """Classical multivariate trace-F of adding the columns of x to z (least squares fits)."""
    def rss(m):
        beta, *_ = np.linalg.lstsq(m, y, rcond=None)
        return float(np.sum((y - m @ beta) ** 2))
    rz, rx = rss(z), rss(x)
    df_t = np.linalg.matrix_rank(x) - np.linalg.matrix_rank(z)
    return ((rz - rx) / df_t) / (rx / (len(y) - np.linalg.matrix_rank(x)))


# ---- PERMANOVA ------------------------------------------------------------------------------


@pytest.mark.parametrize("shift", [0.0, 1.0])
def test_one_factor_equals_scikit_bio_draw_for_draw(shift):
    from skbio.stats.distance import DistanceMatrix
    from skbio.stats.distance import permanova as sk_permanova

    y, g = _points(n=30, shift=shift, seed=1)
    d = cdist(y, y)
    ours = permanova(d, {"group": g}, n_permutations=199, seed=7)
    for permute in ("residuals", "rows"):
        other = permanova(d, {"group": g}, n_permutations=199, seed=7, permute=permute)
        assert other.table.loc["group", "pseudo_F"] == pytest.approx(ours.table.loc["group", "pseudo_F"], rel=1e-12)
        np.testing.assert_allclose(other.null["group"], ours.null["group"], rtol=1e-10)
    sk = sk_permanova(DistanceMatrix(d), g, permutations=199, seed=7)
    assert ours.table.loc["group", "pseudo_F"] == pytest.approx(sk["test statistic"], rel=1e-12)
    assert ours.table.loc["group", "p_value"] == sk["p-value"]


def test_three_groups_match_scikit_bio_non_euclidean():
    from skbio.stats.distance import DistanceMatrix
    from skbio.stats.distance import permanova as sk_permanova

    rng = np.random.default_rng(3)
    y = rng.normal(size=(33, 2))
    d = cdist(y, y, "cityblock") ** 0.5  # not Euclidean-embeddable in general
    g = np.repeat(["x", "y", "z"], 11)
    ours = permanova(d, pd.DataFrame({"g": pd.Categorical(g)}), n_permutations=99, seed=0)
    sk = sk_permanova(DistanceMatrix(d), g, permutations=99, seed=0)
    assert ours.table.loc["g", "df"] == 2
    assert ours.table.loc["g", "pseudo_F"] == pytest.approx(sk["test statistic"], rel=1e-12)
    assert ours.table.loc["g", "p_value"] == sk["p-value"]


def test_f_with_covariates_equals_least_squares_trace_f():
    rng = np.random.default_rng(2)
    n = 36
    age = rng.uniform(7, 21, n)
    sex = rng.integers(0, 2, n)
    grp = np.array([0, 1] * (n // 2))
    y = rng.normal(size=(n, 4)) + 0.3 * age[:, None] + 0.5 * grp[:, None]
    d = cdist(y, y)
    res = permanova(d, {"group": grp, "sex": sex, "age": age}, n_permutations=19, seed=0)
    one = np.ones((n, 1))
    for term, others in [("group", [sex, age]), ("sex", [grp, age]), ("age", [grp, sex])]:
        z = np.column_stack([one] + others)
        x = np.column_stack([z, {"group": grp, "sex": sex, "age": age}[term]])
        assert res.table.loc[term, "pseudo_F"] == pytest.approx(_trace_f(y, z, x), rel=1e-9)
    yc = y - y.mean(axis=0)
    assert res.table.loc["Total", "sum_of_squares"] == pytest.approx(np.sum(yc**2), rel=1e-12)
    assert res.table.loc["Residual", "df"] == n - 4
    # sequential sums of squares add up to the model's
    seq = permanova(d, {"group": grp, "sex": sex, "age": age}, by="terms", n_permutations=9, seed=0).table
    assert seq.loc[["group", "sex", "age", "Residual"], "sum_of_squares"].sum() == pytest.approx(
        seq.loc["Total", "sum_of_squares"], rel=1e-12)
    assert seq.loc["age", "pseudo_F"] == pytest.approx(res.table.loc["age", "pseudo_F"], rel=1e-9)  # last term


def test_freedman_lane_permuted_f_equals_refit_on_permuted_residuals():
    rng = np.random.default_rng(4)
    n = 24
    age = rng.uniform(7, 21, n)
    grp = np.array([0, 1] * (n // 2))
    y = rng.normal(size=(n, 3)) + 0.2 * age[:, None]
    d = cdist(y, y)
    res = permanova(d, {"group": grp, "age": age}, n_permutations=5, seed=11)
    r = np.random.default_rng(11)
    perms = np.stack([r.permutation(n) for _ in range(5)])
    z = np.column_stack([np.ones(n), age])
    x = np.column_stack([z, grp])
    beta, *_ = np.linalg.lstsq(z, y, rcond=None)
    fitted, resid = z @ beta, y - z @ beta
    # draw p moves the residual of object j to row p[j]: row i gets the residual of p⁻¹(i)
    expected = [_trace_f(fitted + resid[np.argsort(p)], z, x) for p in perms]
    np.testing.assert_allclose(res.null["group"], expected, rtol=1e-9)


def test_sequential_permuted_f_equals_refit_on_residuals_of_the_other_terms():
    # by="terms": the statistic of `group` is its sum of squares after the intercept only, over the
    # full model's residual; the permutations are of the residuals of the model with all the other
    # terms (here `age`, which comes *after* group) — checked against least-squares refits.
    rng = np.random.default_rng(21)
    n = 26
    age = rng.uniform(7, 21, n)
    grp = (rng.uniform(size=n) < 0.5 + 0.02 * (age - 14)).astype(int)  # correlated with age
    y = rng.normal(size=(n, 3)) + 0.3 * age[:, None]
    d = cdist(y, y)
    res = permanova(d, {"group": grp, "age": age}, by="terms", n_permutations=6, seed=5)
    r = np.random.default_rng(5)
    perms = np.stack([r.permutation(n) for _ in range(6)])
    one = np.ones((n, 1))
    full = np.column_stack([one, grp, age])

    def sequential_f(yy):
        def rss(m):
            beta, *_ = np.linalg.lstsq(m, yy, rcond=None)
            return float(np.sum((yy - m @ beta) ** 2))
        return (rss(one) - rss(np.column_stack([one, grp]))) / (rss(full) / (n - 3))

    assert res.table.loc["group", "pseudo_F"] == pytest.approx(sequential_f(y), rel=1e-10)
    z = np.column_stack([one, age])
    beta, *_ = np.linalg.lstsq(z, y, rcond=None)
    fitted, resid = z @ beta, y - z @ beta
    expected = [sequential_f(fitted + resid[np.argsort(p)]) for p in perms]
    np.testing.assert_allclose(res.null["group"], expected, rtol=1e-9)


@pytest.mark.parametrize("by", ["terms", "margin"])
def test_a_term_without_effect_keeps_its_size_when_a_later_term_has_one(by):
    # group first, without effect and independent of age; age second, with a strong effect. A
    # sequential test that permuted only the residuals of the terms *before* group rejected it in
    # about half of such data sets; the rate at 5 % must be binomially consistent with 5 %
    # (200 data sets; 99 % interval 2 %–9.5 %).
    rejections = 0
    for rep in range(200):
        rng = np.random.default_rng(300 + rep)
        n = 24
        grp = rng.permutation(np.array([0, 1] * (n // 2)))
        age = rng.normal(size=n)
        y = rng.normal(size=(n, 2)) + 3.0 * age[:, None]
        res = permanova(cdist(y, y), {"group": grp, "age": age}, by=by, n_permutations=99, seed=rep)
        rejections += res.table.loc["group", "p_value"] <= 0.05
    assert 4 <= rejections <= 19


def test_exact_ties_in_the_null_count_towards_p():
    # Integer distances: many permutations give exactly the observed F. Count them independently
    # in exact rational arithmetic (one factor: F* ≥ F ⟺ SS_W* ≤ SS_W) with the same draws.
    from fractions import Fraction

    rng = np.random.default_rng(8)
    n = 12
    pts = rng.integers(0, 3, size=(n, 2))
    d = np.abs(pts[:, None, :] - pts[None, :, :]).sum(axis=2)  # city-block: integers
    g = np.array(["a", "b", "c"] * 4)

    def ss_within(labels):
        out = Fraction(0)
        for c in np.unique(labels):
            idx = np.flatnonzero(labels == c)
            out += Fraction(int(sum(d[i, j] ** 2 for i in idx for j in idx if i < j)), len(idx))
        return out

    observed = ss_within(g)
    r = np.random.default_rng(0)
    draws = [r.permutation(n) for _ in range(199)]
    exact = sum(ss_within(g[p]) <= observed for p in draws)
    ties = sum(ss_within(g[p]) == observed for p in draws)
    assert ties > 0  # the case under test
    for permute in ("residuals", "rows"):
        res = permanova(d.astype(float), {"g": g}, permute=permute, n_permutations=199, seed=0)
        assert res.table.loc["g", "p_value"] == pytest.approx((1 + exact) / 200, abs=1e-15)


def test_numeric_covariates_in_any_units():
    y, g = _points(n=20, seed=3)
    age = np.random.default_rng(3).uniform(7, 21, 20)
    d = cdist(y, y)
    base = permanova(d, {"g": g, "age": age}, n_permutations=19, seed=0).table
    tiny = permanova(d, {"g": g, "age": age * 1e-12}, n_permutations=19, seed=0).table
    pd.testing.assert_frame_equal(base, tiny, rtol=1e-9)


def test_f_invariant_to_relabelling_scaling_and_reordering():
    y, g = _points(n=30, shift=0.8, seed=5)
    d = cdist(y, y)
    age = np.linspace(0, 1, 30)
    base = permanova(d, {"g": g, "age": age}, n_permutations=99, seed=3).table
    swapped = permanova(d, {"g": np.where(g == "a", "b", "a"), "age": age}, n_permutations=99, seed=3).table
    scaled = permanova(7.5 * d, {"g": g, "age": age}, n_permutations=99, seed=3).table
    pd.testing.assert_frame_equal(base, swapped, rtol=1e-10)
    pd.testing.assert_frame_equal(base[["df", "r2", "pseudo_F", "p_value"]],
                                  scaled[["df", "r2", "pseudo_F", "p_value"]], rtol=1e-10)
    order = np.random.default_rng(0).permutation(30)
    moved = permanova(d[np.ix_(order, order)], {"g": g[order], "age": age[order]}, n_permutations=9, seed=3).table
    assert moved.loc["g", "pseudo_F"] == pytest.approx(base.loc["g", "pseudo_F"], rel=1e-10)


def test_identical_groups_give_zero_f_and_p_one():
    y, _ = _points(n=20, seed=6)
    y2 = np.vstack([y, y])  # every point once in each group: the group centroids coincide
    g = np.repeat(["a", "b"], 20)
    res = permanova(cdist(y2, y2), {"g": g}, n_permutations=99, seed=0)
    assert res.table.loc["g", "pseudo_F"] == pytest.approx(0.0, abs=1e-12)
    assert res.table.loc["g", "p_value"] == 1.0


def test_p_values_are_calibrated_under_the_null_with_a_covariate():
    # groups without effect, a strong covariate correlated with the groups: the rejection rate at
    # 5 % must be binomially consistent with 5 % (200 data sets; 99 % interval 2 %–9.5 %)
    rejections = 0
    for rep in range(200):
        rng = np.random.default_rng(100 + rep)
        n = 20
        grp = np.array([0, 1] * (n // 2))
        age = rng.normal(size=n) + grp  # confounded with the grouping
        y = rng.normal(size=(n, 2)) + 2.0 * age[:, None]
        res = permanova(cdist(y, y), {"group": grp, "age": age}, n_permutations=99, seed=rep)
        rejections += res.table.loc["group", "p_value"] <= 0.05
    assert 4 <= rejections <= 19


def test_a_real_difference_is_detected():
    y, g = _points(n=40, shift=1.5, seed=8)
    res = permanova(cdist(y, y), {"g": g}, n_permutations=199, seed=0)
    assert res.table.loc["g", "p_value"] == pytest.approx(1 / 200)


def test_permanova_errors_name_the_problem():
    y, g = _points(n=10)
    d = cdist(y, y)
    with pytest.raises(ValueError, match="covariate 'age' is missing at row 2"):
        permanova(d, {"g": g, "age": [1.0, 2, np.nan] + [0.0] * 7})
    with pytest.raises(ValueError, match="'g' has a single level"):
        permanova(d, {"g": ["a"] * 10})
    with pytest.raises(ValueError, match="'g2' is collinear"):
        permanova(d, {"g": g, "g2": g})
    with pytest.raises(ValueError, match="3 rows"):
        permanova(d, {"g": g[:3]})
    with pytest.raises(ValueError, match="by must be"):
        permanova(d, {"g": g}, by="type2")
    with pytest.raises(ValueError, match="permute must be"):
        permanova(d, {"g": g}, permute="labels")
    for bad in (0, None, True, 2.5, "99"):
        with pytest.raises(ValueError, match="permutations must be a positive integer"):
            permanova(d, {"g": g}, n_permutations=bad)
    with pytest.raises(ValueError, match="all zero"):
        permanova(np.zeros((10, 10)), {"g": g})
    with pytest.raises(ValueError, match=r"\['h'\] are not columns"):
        permanova(d, {"g": g}, terms=["h"])


def test_distance_matrix_validation():
    d = cdist(*[np.arange(8.0)[:, None]] * 2)
    assert np.array_equal(as_distance_matrix(d), d)
    bad = d.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"distances\[1, 2\] is nan"):
        as_distance_matrix(bad)
    bad = d.copy()
    bad[3, 5] += 1
    with pytest.raises(ValueError, match=r"not symmetric: \[3, 5\]"):
        as_distance_matrix(bad)
    bad = d.copy()
    bad[4, 4] = 1
    with pytest.raises(ValueError, match=r"\[4, 4\] = 1.0: the diagonal"):
        as_distance_matrix(bad)
    with pytest.raises(ValueError, match="negative"):
        as_distance_matrix(-d)
    with pytest.raises(ValueError, match="square"):
        as_distance_matrix(d[:3])


def test_gower_matrix_is_the_centred_gram_for_euclidean_distances():
    y, _ = _points(n=12)
    yc = y - y.mean(axis=0)
    np.testing.assert_allclose(gower_centered(cdist(y, y)), yc @ yc.T, atol=1e-12)


# ---- k-NN -----------------------------------------------------------------------------------


def test_knn_equals_scikit_learn_permutation_test_score_draw_for_draw():
    from sklearn.model_selection import LeaveOneOut, permutation_test_score
    from sklearn.neighbors import KNeighborsClassifier

    y, g = _points(n=30, shift=1.0, seed=9)
    d = cdist(y, y)
    ours = knn_loo_accuracy(d, g, n_neighbors=3, n_permutations=15, seed=4)
    score, null, p = permutation_test_score(
        KNeighborsClassifier(n_neighbors=3, metric="precomputed"), d, g, cv=LeaveOneOut(), n_permutations=15,
        random_state=4)
    assert ours.accuracy == pytest.approx(score, abs=1e-15)
    np.testing.assert_allclose(ours.null, null, atol=1e-15)
    assert ours.p_value == pytest.approx(p, abs=1e-15)
    assert ours.majority_rate == 0.5


def test_knn_separable_groups_and_errors():
    y, g = _points(n=40, shift=8.0, seed=10)
    res = knn_loo_accuracy(cdist(y, y), g, n_neighbors=5, n_permutations=99, seed=0)
    assert res.accuracy == 1.0 and res.p_value == pytest.approx(0.01)
    assert (res.predictions == g).all()
    assert abs(res.null.mean() - 0.5) < 0.1  # chance level under permutation
    with pytest.raises(ValueError, match="single class"):
        knn_loo_accuracy(cdist(y, y), ["a"] * 40)
    with pytest.raises(ValueError, match="n_neighbors"):
        knn_loo_accuracy(cdist(y, y), g, n_neighbors=40)
    with pytest.raises(ValueError, match="shape"):
        knn_loo_accuracy(cdist(y, y), g[:5])


# ---- MDS and Mantel -------------------------------------------------------------------------


def test_classical_mds_recovers_euclidean_configuration():
    rng = np.random.default_rng(12)
    y = rng.normal(size=(25, 2)) * [3.0, 1.0]
    d = cdist(y, y)
    coords, explained = classical_mds(d, n_components=2)
    np.testing.assert_allclose(cdist(coords, coords), d, atol=1e-9)
    assert explained.sum() == pytest.approx(1.0)
    assert explained[0] > explained[1]


def test_classical_mds_errors_name_the_problem():
    line = cdist(*[np.arange(6.0)[:, None]] * 2)  # Euclidean in one dimension: one positive eigenvalue
    coords, explained = classical_mds(line, n_components=1)
    np.testing.assert_allclose(cdist(coords, coords), line, atol=1e-9)
    with pytest.raises(ValueError, match="only 1 positive eigenvalues"):
        classical_mds(line, n_components=2)
    with pytest.raises(ValueError, match="all zero"):
        classical_mds(np.zeros((5, 5)))
    for bad in (0, 2.5, None, 6):
        with pytest.raises(ValueError, match="n_components must be"):
            classical_mds(line, n_components=bad)


def test_mantel_errors_name_the_problem():
    d = cdist(*[np.arange(6.0)[:, None]] * 2)
    for bad in (0, -1, 2.5, None, "99", True):
        with pytest.raises(ValueError, match="permutations must be a positive integer"):
            mantel_test(d, d, n_permutations=bad)
    flat = np.ones((6, 6)) - np.eye(6)
    with pytest.raises(ValueError, match="y has all off-diagonal distances equal"):
        mantel_test(d, flat)
    with pytest.raises(ValueError, match=r"x is \(6, 6\) but y is \(5, 5\)"):
        mantel_test(d, d[:5, :5])


def test_mantel_identical_monotone_and_independent():
    rng = np.random.default_rng(13)
    y = rng.normal(size=(30, 2))
    d = cdist(y, y)
    r, p = mantel_test(d, d**2, n_permutations=99)
    assert r == pytest.approx(1.0) and p == pytest.approx(0.01)  # Spearman: squaring is monotone
    r_p, _ = mantel_test(d, d**2, method="pearson", n_permutations=9)
    assert r_p < 1.0
    z = rng.normal(size=(30, 2))
    r0, p0 = mantel_test(d, cdist(z, z), n_permutations=99)
    assert abs(r0) < 0.2 and p0 > 0.01
    with pytest.raises(ValueError, match="method"):
        mantel_test(d, d, method="kendall")
