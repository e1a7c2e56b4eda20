"""The distance-based statistics against independent computations: PERMANOVA's permuted F against
least-squares refits over more draws than one vectorised chunk holds, its table's bookkeeping
against closed forms, leave-one-out k-NN against a brute-force vote and scikit-learn's
cross_val_predict, classical MDS against NumPy's eigendecomposition of Gower's matrix, the Mantel
correlation against SciPy, and the validation of distance matrices at its tolerances."""

import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.distance import cdist

from shapelib.statistics.distance_based import (
    TIE_RTOL,
    as_distance_matrix,
    classical_mds,
    gower_centered,
    knn_loo_accuracy,
    mantel_test,
    permanova,
)


def _rss(m, y):
    beta, *_ = np.linalg.lstsq(m, y, rcond=None)
    return float(np.sum((y - m @ beta) ** 2))


# ---- as_distance_matrix --------------------------------------------------------------------


def test_three_objects_are_the_fewest():
    d3 = cdist(*[np.array([[0.0], [1.0], [3.0]])] * 2)
    np.testing.assert_array_equal(as_distance_matrix(d3), d3)
    with pytest.raises(ValueError, match=r"D must hold at least 3 objects; got 2"):
        as_distance_matrix(d3[:2, :2], name="D")
    with pytest.raises(ValueError, match=r"D must be a square \(N, N\) matrix; got shape \(3,\)"):
        as_distance_matrix(np.zeros(3), name="D")


def test_tolerances_are_relative_to_the_largest_entry():
    base = cdist(*[np.arange(5.0)[:, None]] * 2)
    for scale in (1e-6, 1.0, 1e6):
        d = base * scale
        ok = d.copy()
        ok[1, 3] += 0.5e-9 * d.max()  # within atol · max: symmetrised
        out = as_distance_matrix(ok)
        assert out[1, 3] == out[3, 1] == pytest.approx(0.5 * (ok[1, 3] + ok[3, 1]), rel=1e-15)
        bad = d.copy()
        bad[1, 3] += 2e-9 * d.max()
        with pytest.raises(ValueError, match=r"distances is not symmetric: \[1, 3\]"):
            as_distance_matrix(bad)
        diag = d.copy()
        diag[2, 2] = 0.5e-9 * d.max()
        assert as_distance_matrix(diag)[2, 2] == 0.0  # exactly zero after the check
        diag[2, 2] = 2e-9 * d.max()
        with pytest.raises(ValueError, match=r"distances\[2, 2\] = .*: the diagonal must be zero"):
            as_distance_matrix(diag)
    # atol = 0: exact symmetry and an exactly zero diagonal pass, the least asymmetry does not
    np.testing.assert_array_equal(as_distance_matrix(base, atol=0.0), base)
    bad = base.copy()
    bad[0, 4] = np.nextafter(4.0, 5.0)
    with pytest.raises(ValueError, match="not symmetric"):
        as_distance_matrix(bad, atol=0.0)
    # a looser atol accepts what the default refuses
    bad = base.copy()
    bad[0, 4] += 1e-6
    assert as_distance_matrix(bad, atol=1e-6)[0, 4] == pytest.approx(4.0 + 0.5e-6, rel=1e-15)


def test_any_real_array_like_is_read_as_floats():
    """Exact fractions (an object array to NumPy) are read as the floats they round to."""
    from fractions import Fraction

    exact = [[Fraction(0), Fraction(1, 3), Fraction(2, 3)], [Fraction(1, 3), Fraction(0), Fraction(1, 3)],
             [Fraction(2, 3), Fraction(1, 3), Fraction(0)]]
    out = as_distance_matrix(exact)
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [[0, 1 / 3, 2 / 3], [1 / 3, 0, 1 / 3], [2 / 3, 1 / 3, 0]])


def test_validation_messages_name_the_entry():
    d = cdist(*[np.arange(5.0)[:, None]] * 2)
    bad = d.copy()
    bad[3, 1] = np.inf
    with pytest.raises(ValueError, match=r"^M\[3, 1\] is inf: distances must be finite$"):
        as_distance_matrix(bad, name="M")
    bad = d.copy()
    bad[2, 4] = bad[4, 2] = -1.5
    with pytest.raises(ValueError, match=r"^M\[2, 4\] = -1.5 is negative$"):
        as_distance_matrix(bad, name="M")
    bad = d.copy()
    bad[4, 0] = 9.0
    with pytest.raises(ValueError, match=r"^M is not symmetric: \[0, 4\] = 4.0 but \[4, 0\] = 9.0 "
                                         r"\(symmetrise an asymmetric measure first\)$"):
        as_distance_matrix(bad, name="M")
    bad = d.copy()
    bad[3, 3] = 0.25
    with pytest.raises(ValueError, match=r"^M\[3, 3\] = 0.25: the diagonal must be zero$"):
        as_distance_matrix(bad, name="M")


def test_gower_trace_is_the_total_sum_of_squares():
    """tr G = Σ_{i<j} d_ij² / N, also for non-Euclidean distances, and G's rows sum to zero."""
    rng = np.random.default_rng(0)
    d = cdist(rng.normal(size=(9, 2)), rng.normal(size=(9, 2)) * 0 + rng.normal(size=(9, 2)), "cityblock")
    d = 0.5 * (d + d.T)
    np.fill_diagonal(d, 0.0)
    g = gower_centered(d)
    iu = np.triu_indices(9, 1)
    assert np.trace(g) == pytest.approx(np.sum(d[iu] ** 2) / 9, rel=1e-12)
    np.testing.assert_allclose(g.sum(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(g.sum(axis=1), 0.0, atol=1e-12)
    j = np.eye(9) - 1 / 9
    np.testing.assert_allclose(g, j @ (-0.5 * d * d) @ j, atol=1e-12)


# ---- PERMANOVA -----------------------------------------------------------------------------


def _design(n, seed):
    rng = np.random.default_rng(seed)
    age = rng.uniform(7, 21, n)
    grp = np.array(["b", "a", "c"] * (n // 3))
    y = rng.normal(size=(n, 3)) + 0.2 * age[:, None] + 0.4 * (grp == "c")[:, None]
    return y, grp, age


@pytest.mark.parametrize("permute", ["residuals", "rows"])
def test_the_null_over_several_chunks_equals_least_squares_refits(permute):
    """150 draws (the vectorised null works in chunks of 64): every permuted F against a refit,
    Freedman–Lane (residuals of the model with age permuted) or whole rows permuted."""
    n = 18
    y, grp, age = _design(n, 1)
    res = permanova(cdist(y, y), {"group": grp, "age": age}, permute=permute, n_permutations=150, seed=3)
    r = np.random.default_rng(3)
    perms = np.stack([r.permutation(n) for _ in range(150)])
    one = np.ones((n, 1))
    dummies = np.column_stack([grp == "b", grp == "c"]).astype(float)
    z = np.column_stack([one, age])
    x = np.column_stack([z, dummies])

    def f(yy, zz, xx):
        return ((_rss(zz, yy) - _rss(xx, yy)) / 2) / (_rss(xx, yy) / (n - 4))

    fitted = z @ np.linalg.lstsq(z, y, rcond=None)[0]
    if permute == "residuals":
        want = [f(fitted + (y - fitted)[np.argsort(p)], z, x) for p in perms]
    else:  # row i gets design row π(i)
        want = [f(y, np.column_stack([one, age[p]]), np.column_stack([one, age[p], dummies[p]])) for p in perms]
    np.testing.assert_allclose(res.null["group"], want, rtol=1e-9)
    f_obs = f(y, z, x)
    assert res.table.loc["group", "pseudo_F"] == pytest.approx(f_obs, rel=1e-10)
    count = np.count_nonzero(np.asarray(want) >= f_obs * (1 - 1e-9))
    assert res.table.loc["group", "p_value"] == pytest.approx((1 + count) / 151, abs=1e-15)
    assert res.n_permutations == 150 and res.seed == 3 and res.permute == permute and res.by == "margin"


def test_the_table_adds_up():
    """df, sums of squares and R² of each row: marginal sums of squares from refits, the residual
    from the full model, R² = SS / SS_T, and Residual/Total without F or p."""
    n = 21
    y, grp, age = _design(n, 2)
    res = permanova(cdist(y, y), {"group": grp, "age": age}, n_permutations=9, seed=0)
    t = res.table
    one = np.ones((n, 1))
    dummies = np.column_stack([grp == "b", grp == "c"]).astype(float)
    full = np.column_stack([one, dummies, age])
    ss_total = float(np.sum((y - y.mean(axis=0)) ** 2))
    assert list(t.index) == ["group", "age", "Residual", "Total"]
    assert list(t.columns) == ["df", "sum_of_squares", "r2", "pseudo_F", "p_value", "ss_type", "p_tests"]
    assert t.loc["group", "df"] == 2 and t.loc["age", "df"] == 1
    assert t.loc["Residual", "df"] == n - 4 and t.loc["Total", "df"] == n - 1
    assert t.loc["group", "sum_of_squares"] == pytest.approx(
        _rss(np.column_stack([one, age]), y) - _rss(full, y), rel=1e-10)
    assert t.loc["age", "sum_of_squares"] == pytest.approx(
        _rss(np.column_stack([one, dummies]), y) - _rss(full, y), rel=1e-10)
    assert t.loc["Residual", "sum_of_squares"] == pytest.approx(_rss(full, y), rel=1e-10)
    assert t.loc["Total", "sum_of_squares"] == pytest.approx(ss_total, rel=1e-12)
    np.testing.assert_allclose(t["r2"], t["sum_of_squares"] / ss_total, rtol=1e-12)
    assert t.loc["Total", "r2"] == 1.0
    for row in ("Residual", "Total"):
        assert np.isnan(t.loc[row, "pseudo_F"]) and np.isnan(t.loc[row, "p_value"])
        assert pd.isna(t.loc[row, "ss_type"]) and pd.isna(t.loc[row, "p_tests"])
    assert (t.loc[["group", "age"], "ss_type"] == "III (marginal)").all()
    assert t.loc["group", "p_tests"] == "no effect of group given age (residuals of the model without group permuted)"
    assert set(res.null) == {"group", "age"} and res.null["age"].shape == (9,)
    text = res.summary().splitlines()
    assert text[0] == ("PERMANOVA, 9 permutations (Freedman-Lane: residuals of the model without the term "
                       "permuted); sums of squares marginal (type III)")
    row = next(line for line in text if line.startswith("group "))  # four significant digits
    assert f" {t.loc['group', 'pseudo_F']:.4g} " in row and f"{t.loc['group', 'pseudo_F']:.6g}" not in row
    assert text[-2:] == [f"p of group: {t.loc['group', 'p_tests']}", f"p of age: {t.loc['age', 'p_tests']}"]


def test_a_sequential_table_says_what_it_tests_and_notes_a_shared_effect():
    """by="terms": type I sums of squares; x carries z's effect and none of its own, so its
    sequential SS is mostly shared with z (a note says so, with the share computed here from the
    marginal SS); z, the last term, gets no note."""
    rng = np.random.default_rng(1)
    z = rng.normal(size=30)
    x = z + 0.05 * rng.normal(size=30)
    y = np.c_[2 * z, rng.normal(size=30)] + rng.normal(size=(30, 2))
    d = cdist(y, y)
    seq = permanova(d, {"x": x, "z": z}, by="terms", n_permutations=19)
    t = seq.table
    one = np.ones((30, 1))
    full = np.column_stack([one, x, z])
    ss_seq = _rss(one, y) - _rss(np.column_stack([one, x]), y)
    ss_own = _rss(np.column_stack([one, z]), y) - _rss(full, y)
    assert t.loc["x", "sum_of_squares"] == pytest.approx(ss_seq, rel=1e-10)
    assert (t.loc[["x", "z"], "ss_type"] == "I (sequential)").all()
    assert t.loc["x", "p_tests"] == "no effect of x given z (residuals of the model without x permuted)"
    assert len(seq.notes) == 1 and seq.notes[0].startswith(f"x: F = {t.loc['x', 'pseudo_F']:.4g} is x given")
    assert f"; {1 - ss_own / ss_seq:.0%} of its sequential sum of squares is shared with z, " in seq.notes[0]
    # the note does not depend on the units of the distances
    assert permanova(1e-3 * d, {"x": x, "z": z}, by="terms", n_permutations=19).notes == seq.notes
    text = seq.summary()
    assert text.splitlines()[0] == ("PERMANOVA, 19 permutations (Freedman-Lane: residuals of the model without the "
                                    "term permuted); sums of squares sequential (type I)")
    assert "p of x: no effect of x given z" in text and text.endswith("note: " + seq.notes[0])
    # the same model in the other order: the sequential SS of z is mostly shared with x as well,
    # but z keeps most of its own (its marginal SS above half its sequential one): no note
    other = permanova(d, {"z": z, "x": x}, by="terms", n_permutations=19)
    ss_z_seq = _rss(one, y) - _rss(np.column_stack([one, z]), y)
    ss_z_own = _rss(np.column_stack([one, x]), y) - _rss(full, y)
    assert (ss_z_own >= 0.5 * ss_z_seq) == (other.notes == [])
    rows = permanova(d, {"x": x, "z": z}, by="terms", permute="rows", n_permutations=19)
    assert rows.notes == [] and rows.table.loc["x", "p_tests"] == "no effect of any term (whole rows permuted)"
    assert rows.summary().splitlines()[0].endswith("(rows permuted); sums of squares sequential (type I)")
    single = permanova(d, {"z": z}, n_permutations=19)
    assert single.table.loc["z", "p_tests"].startswith("no effect of z (no other terms)")


def test_a_note_needs_the_own_share_below_half():
    """The note's threshold: own (marginal) SS below half the sequential SS. Two covariates with a
    chosen correlation, the share computed from refits, and a note exactly where it is below half."""
    rng = np.random.default_rng(5)
    n = 40
    z = rng.normal(size=n)
    e = rng.normal(size=n)
    seen = set()
    for w in (0.2, 0.6, 1.0, 1.5, 3.0):
        x = z + w * e
        y = np.c_[x + z, rng.normal(size=n)] + 0.3 * rng.normal(size=(n, 2))
        one = np.ones((n, 1))
        full = np.column_stack([one, x, z])
        own = _rss(np.column_stack([one, z]), y) - _rss(full, y)
        share = own / (_rss(one, y) - _rss(np.column_stack([one, x]), y))
        res = permanova(cdist(y, y), {"x": x, "z": z}, by="terms", n_permutations=9)
        assert (len(res.notes) == 1) == (share < 0.5), (w, share)
        if res.notes:
            assert f"; {1 - share:.0%} of its sequential sum of squares" in res.notes[0]
        seen.add(share < 0.5)
    assert seen == {True, False}


def test_term_coding_and_its_errors():
    """A categorical column's unused categories are not levels; booleans and strings are factors;
    a numeric column is one centred column whatever its units."""
    n = 12
    rng = np.random.default_rng(7)
    y = rng.normal(size=(n, 2))
    d = cdist(y, y)
    lab = np.array(["p", "q", "r"] * 4)
    plain = permanova(d, {"g": lab}, n_permutations=9).table
    cat = permanova(d, {"g": pd.Categorical(lab, categories=["r", "zz", "q", "p"])}, n_permutations=9).table
    assert cat.loc["g", "df"] == 2
    pd.testing.assert_frame_equal(plain, cat, rtol=1e-10)
    with pytest.raises(ValueError, match=r"covariate 'g' has a single level \['p'\]: nothing to test"):
        permanova(d, {"g": pd.Categorical(["p"] * n, categories=["p", "q"])})
    flag = np.arange(n) % 2 == 0
    as_bool = permanova(d, {"f": flag}, n_permutations=9).table
    as_str = permanova(d, {"f": np.where(flag, "yes", "no")}, n_permutations=9).table
    pd.testing.assert_frame_equal(as_bool, as_str, rtol=1e-10)
    assert as_bool.loc["f", "sum_of_squares"] == pytest.approx(
        _rss(np.ones((n, 1)), y) - _rss(np.column_stack([np.ones(n), flag]), y), rel=1e-10)
    age = rng.normal(size=n)
    with pytest.raises(ValueError, match=r"covariate 'age' is inf at row 4"):
        permanova(d, {"age": np.r_[age[:4], np.inf, age[5:]]})
    with pytest.raises(ValueError, match=r"covariate 'age' is constant: nothing to test"):
        permanova(d, {"age": np.full(n, 3.0)})
    with pytest.raises(ValueError, match=r"covariate 'g' is missing at row 5"):
        permanova(d, {"g": pd.Series(list(lab[:5]) + [None] + list(lab[6:]))})


def test_permanova_refuses_settings_naming_them():
    rng = np.random.default_rng(8)
    y = rng.normal(size=(6, 2))
    d = cdist(y, y)
    g = np.array(["a", "b"] * 3)
    with pytest.raises(ValueError, match="no terms to test"):
        permanova(d, {"g": g}, terms=[])
    with pytest.raises(ValueError, match=r"terms repeated: \['g', 'g'\]"):
        permanova(d, {"g": g}, terms=["g", "g"])
    with pytest.raises(ValueError, match=r"covariates have 5 rows but distances are 6 x 6"):
        permanova(d, pd.DataFrame({"g": g[:5]}))
    with pytest.raises(ValueError, match=r"no residual degrees of freedom: 3 objects, 3 model columns"):
        permanova(d[:3, :3], {"g": ["a", "b", "b"], "age": [1.0, 2.0, 4.0]})
    one_left = permanova(d[:3, :3], {"g": ["a", "b", "b"]}, n_permutations=5)
    assert one_left.table.loc["Residual", "df"] == 1
    # the default terms are the columns, in order; terms= picks and orders them
    age = np.arange(6.0) ** 1.5
    picked = permanova(d, {"g": g, "age": age}, terms=["age"], n_permutations=5).table
    assert list(picked.index) == ["age", "Residual", "Total"]
    # covariates with their own index are taken row by row
    indexed = pd.DataFrame({"g": g}, index=[10, 3, 7, 1, 0, 2])
    pd.testing.assert_frame_equal(permanova(d, indexed, n_permutations=9).table,
                                  permanova(d, {"g": g}, n_permutations=9).table)


def test_ties_count_within_the_relative_tolerance():
    """A permuted F within TIE_RTOL·F below the observed one counts as at least as large: with a
    group design invariant under swapping two members of a group, every such draw ties exactly."""
    assert TIE_RTOL == 1e-9
    rng = np.random.default_rng(2)
    y = rng.normal(size=(8, 2))
    d = cdist(y, y)
    g = np.array(["a"] * 4 + ["b"] * 4)
    res = permanova(d, {"g": g}, n_permutations=99, seed=1)
    f, null = res.table.loc["g", "pseudo_F"], res.null["g"]
    count = np.count_nonzero(null >= f * (1 - 1e-9))
    assert count > np.count_nonzero(null > f * (1 + 1e-12))  # ties present (a relabelling within groups)
    assert res.table.loc["g", "p_value"] == pytest.approx((1 + count) / 100, abs=1e-15)


# ---- k-NN ----------------------------------------------------------------------------------


def _brute_force_knn(d, codes, k):
    """Leave-one-out vote of the k nearest others, a tie going to the smallest code."""
    n = len(d)
    pred = np.empty(n, dtype=int)
    for i in range(n):
        others = [j for j in np.argsort(d[i], kind="stable") if j != i][:k]
        counts = np.bincount(codes[others], minlength=codes.max() + 1)
        pred[i] = int(np.argmax(counts))
    return pred


def test_knn_null_over_several_chunks_is_a_brute_force_vote():
    """300 label permutations (more than one chunk of 256) drawn as permutation_test_score draws
    them, each scored by a brute-force leave-one-out vote; three unbalanced classes."""
    rng = np.random.default_rng(4)
    y = rng.normal(size=(14, 2))
    d = cdist(y, y)
    labels = np.array(list("aaaaaabbbbbccc"))
    res = knn_loo_accuracy(d, labels, n_neighbors=3, n_permutations=300, seed=6)
    codes = np.unique(labels, return_inverse=True)[1]
    pred = _brute_force_knn(d, codes, 3)
    assert res.accuracy == pytest.approx(np.mean(pred == codes), abs=1e-15)
    np.testing.assert_array_equal(res.predictions, np.array(list("abc"))[pred])
    rs = np.random.RandomState(6)
    want = []
    for _ in range(300):
        c = codes[rs.permutation(14)]
        want.append(np.mean(_brute_force_knn(d, c, 3) == c))
    np.testing.assert_allclose(res.null, want, atol=1e-15)
    assert res.p_value == pytest.approx((1 + np.count_nonzero(np.asarray(want) >= res.accuracy)) / 301, abs=1e-15)
    assert res.majority_rate == pytest.approx(6 / 14, abs=1e-15)
    assert res.n_neighbors == 3 and res.n_permutations == 300


def test_tied_votes_go_to_the_first_class_as_scikit_learn_predicts():
    """An even k with several classes ties votes; the prediction is scikit-learn's own
    leave-one-out prediction (cross_val_predict)."""
    from sklearn.model_selection import LeaveOneOut, cross_val_predict
    from sklearn.neighbors import KNeighborsClassifier

    rng = np.random.default_rng(9)
    y = rng.normal(size=(15, 2))
    d = cdist(y, y)
    labels = np.array(list("xyzzyxxyzzyxzyx"))
    for k in (2, 4):
        res = knn_loo_accuracy(d, labels, n_neighbors=k, n_permutations=3)
        want = cross_val_predict(KNeighborsClassifier(n_neighbors=k, metric="precomputed"), d, labels,
                                 cv=LeaveOneOut())
        np.testing.assert_array_equal(res.predictions, want)
        assert res.accuracy == pytest.approx(np.mean(want == labels), abs=1e-15)


def test_knn_settings_are_checked_at_their_bounds():
    rng = np.random.default_rng(3)
    y = rng.normal(size=(8, 2))
    d = cdist(y, y)
    g = np.array(["a", "b"] * 4)
    assert knn_loo_accuracy(d, g, n_neighbors=6, n_permutations=2).n_neighbors == 6  # N − 2
    assert knn_loo_accuracy(d, g, n_neighbors=1, n_permutations=2).n_neighbors == 1
    assert knn_loo_accuracy(d, g, n_neighbors=3.0, n_permutations=2).n_neighbors == 3
    for bad in (0, 7, 2.5):
        with pytest.raises(ValueError, match=rf"n_neighbors must be an integer in \[1, 6\]; got {bad!r}"):
            knn_loo_accuracy(d, g, n_neighbors=bad)
    with pytest.raises(ValueError, match=r"labels must have shape \(8,\) to match distances; got \(4,\)"):
        knn_loo_accuracy(d, g[:4])
    with pytest.raises(ValueError, match=r"labels are missing at row 2"):
        knn_loo_accuracy(d, np.array(["a", "b", None, "b", "a", "b", "a", "b"], dtype=object))
    with pytest.raises(ValueError, match="n_permutations must be a positive integer"):
        knn_loo_accuracy(d, g, n_permutations=0)
    with pytest.raises(ValueError, match=r"labels have a single class \['a'\]: nothing to classify"):
        knn_loo_accuracy(d, ["a"] * 8)


# ---- classical MDS and Mantel --------------------------------------------------------------


def test_mds_shares_are_gowers_eigenvalues_over_its_trace():
    """Non-Euclidean distances: the shares are the leading eigenvalues of G over tr G (NumPy),
    the coordinates' Gram matrix is the rank-k part of G."""
    rng = np.random.default_rng(11)
    d = cdist(rng.normal(size=(10, 3)), rng.normal(size=(10, 3)) * 0 + rng.normal(size=(10, 3)), "cityblock") ** 0.8
    d = 0.5 * (d + d.T)
    np.fill_diagonal(d, 0.0)
    g = gower_centered(d)
    lam, vec = np.linalg.eigh(g)
    lam, vec = lam[::-1], vec[:, ::-1]
    coords, explained = classical_mds(d, n_components=3)
    np.testing.assert_allclose(explained, lam[:3] / np.trace(g), rtol=1e-9)
    np.testing.assert_allclose(coords @ coords.T, (vec[:, :3] * lam[:3]) @ vec[:, :3].T, atol=1e-9)


def test_mds_gives_two_axes_by_default_and_refuses_without_numpy_warnings():
    rng = np.random.default_rng(2)
    y = rng.normal(size=(7, 3))
    coords, explained = classical_mds(cdist(y, y))
    assert coords.shape == (7, 2) and explained.shape == (2,)
    # three objects breaking the triangle inequality: one positive eigenvalue, one negative
    bad = np.array([[0.0, 1.0, 1.0], [1.0, 0.0, 3.0], [1.0, 3.0, 0.0]])
    assert (np.linalg.eigvalsh(gower_centered(bad)) < -1e-9).sum() == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the square root of the negative one is not warned about
        with pytest.raises(ValueError, match="only 1 positive eigenvalues"):
            classical_mds(bad, n_components=2)
    # a star whose arms are far shorter than the distances between their tips: Gower's matrix has two
    # positive eigenvalues, a third axis takes the square root of a (rounding-)negative one
    star = np.full((4, 4), 3.0)
    star[0, :] = star[:, 0] = 1.0
    np.fill_diagonal(star, 0.0)
    with np.errstate(invalid="warn"), warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="only 2 positive eigenvalues"):
            classical_mds(star, n_components=3)
    with pytest.raises(ValueError, match=r"^distances are all zero: there is nothing to ordinate$"):
        classical_mds(np.zeros((4, 4)), n_components=1)


def test_mds_counts_positive_eigenvalues_relative_to_the_largest():
    """A second dimension 1e-13 of the first (in eigenvalue) is not an axis at any scale; one 1e-10
    of the first is. Checked on the same shape in kilometres and millimetres."""
    t = np.linspace(0.0, 1.0, 7)
    wiggle = np.arange(7) % 2 - 0.5
    lam1 = np.linalg.eigvalsh(gower_centered(cdist(t[:, None], t[:, None])))[-1]
    for scale in (1e-6, 1e6):
        for ratio, axes in ((1e-13, 1), (1e-10, 2)):
            pts = scale * np.column_stack([t, np.sqrt(ratio * lam1 / np.sum(wiggle ** 2)) * wiggle])
            d = cdist(pts, pts)
            lam = np.linalg.eigvalsh(gower_centered(d))[::-1]
            assert lam[1] / lam[0] == pytest.approx(ratio, rel=0.05)
            if axes == 2:
                assert classical_mds(d, n_components=2)[0].shape == (7, 2)
            else:
                with pytest.raises(ValueError, match="only 1 positive eigenvalues"):
                    classical_mds(d, n_components=2)


def test_mds_takes_up_to_n_minus_one_axes():
    """Four points of a regular simplex in three dimensions: three equal positive eigenvalues."""
    simplex = np.eye(4)
    d = cdist(simplex, simplex)
    coords, explained = classical_mds(d, n_components=3)
    np.testing.assert_allclose(cdist(coords, coords), d, atol=1e-9)
    np.testing.assert_allclose(explained, [1 / 3] * 3, rtol=1e-9)
    with pytest.raises(ValueError, match=r"n_components must be an integer in \[1, 3\]; got 4"):
        classical_mds(d, n_components=4)


def test_mds_refuses_axes_beyond_the_positive_eigenvalues():
    """Points on a line: one positive eigenvalue; a second axis is refused however it rounds, and a
    tiny but genuine second dimension (1e-5 of the first) is kept."""
    t = np.linspace(0.0, 1.0, 7)
    flat = np.column_stack([t, 1e-5 * (np.arange(7) % 2 - 0.5)])
    coords, explained = classical_mds(cdist(flat, flat), n_components=2)
    assert explained[1] > 0 and explained[1] / explained[0] < 1e-8
    with pytest.raises(ValueError, match=r"n_components = 2 but Gower's matrix has only 1 positive eigenvalues"):
        classical_mds(cdist(t[:, None], t[:, None]), n_components=2)


def test_mantel_is_the_correlation_of_the_upper_triangles():
    from scipy.stats import pearsonr, spearmanr

    rng = np.random.default_rng(14)
    a = cdist(*[rng.normal(size=(9, 2))] * 2)
    z = rng.normal(size=(9, 2))
    b = cdist(z, z) + 0.5 * a
    iu = np.triu_indices(9, 1)
    r_s, p_s = mantel_test(a, b, n_permutations=199, seed=3)
    assert r_s == pytest.approx(spearmanr(a[iu], b[iu])[0], rel=1e-12)
    r_p, p_p = mantel_test(a, b, method="pearson", n_permutations=199, seed=3)
    assert r_p == pytest.approx(pearsonr(a[iu], b[iu])[0], rel=1e-12)
    # two-sided: the p of −r (distances reversed in rank) is that of r
    r_neg, p_neg = mantel_test(a, b.max() + 1.0 - b + np.diag(np.full(9, -b.max() - 1.0)), method="pearson",
                               n_permutations=199, seed=3)
    assert r_neg == pytest.approx(-r_p, rel=1e-12) and p_neg == pytest.approx(p_p, abs=1e-15)
    assert 1 / 200 <= p_p <= 1 and (p_p * 200) == pytest.approx(round(p_p * 200), abs=1e-9)
    # the seed fixes the draws
    assert mantel_test(a, b, n_permutations=199, seed=3) == (r_s, p_s)
    flat = np.ones((9, 9)) - np.eye(9)
    with pytest.raises(ValueError, match=r"^x has all off-diagonal distances equal \(1.0\): its correlation with "
                                         r"anything is undefined$"):
        mantel_test(flat, b)
    # every pair counts: three objects whose two longer distances are equal are not constant
    three = np.array([[0.0, 1.0, 2.0], [1.0, 0.0, 2.0], [2.0, 2.0, 0.0]])
    other = np.array([[0.0, 1.0, 3.0], [1.0, 0.0, 2.0], [3.0, 2.0, 0.0]])
    assert mantel_test(three, other, method="pearson", n_permutations=5)[0] == pytest.approx(
        pearsonr([1.0, 2.0, 2.0], [1.0, 3.0, 2.0])[0], rel=1e-12)
    with pytest.raises(ValueError, match=r"x\[0, 1\] = -\S+ is negative"):
        mantel_test(-a, b)
    with pytest.raises(ValueError, match=r"y\[0, 1\] = -\S+ is negative"):
        mantel_test(a, -b)


def test_mantel_defaults_are_999_permutations_and_seed_0():
    rng = np.random.default_rng(15)
    y = rng.normal(size=(8, 2))
    a = cdist(y, y)
    b = a ** 2 + 0.01 * cdist(*[rng.normal(size=(8, 2))] * 2)
    r, p = mantel_test(a, b)
    assert p == pytest.approx(1 / 1000, abs=1e-15)  # the strongest evidence 999 permutations give
    rng = np.random.default_rng(15)
    a = cdist(*[rng.normal(size=(8, 2))] * 2)
    weak = cdist(*[rng.normal(size=(8, 2))] * 2) + 0.3 * a
    r, p = mantel_test(a, weak, n_permutations=99)
    assert (r, p) == mantel_test(a, weak, n_permutations=99, seed=0)
    assert p != mantel_test(a, weak, n_permutations=99, seed=1)[1]  # (0.13 against 0.10)


def test_mantel_without_scikit_bio_says_how_to_install_it(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "skbio.stats.distance", None)  # an import of it fails
    a = cdist(*[np.arange(5.0)[:, None]] * 2)
    with pytest.raises(ImportError, match=r"^mantel_test runs scikit-bio's Mantel test: pip install scikit-bio "
                                          r"\(it comes with the study extra, pip install 'shapelib\[study\]'\)$"):
        mantel_test(a, a ** 2)


def test_knn_defaults_are_five_neighbours_999_permutations_and_seed_0():
    rng = np.random.default_rng(16)
    y = rng.normal(size=(16, 2))
    d = cdist(y, y)
    g = np.array(list("ab") * 8)
    res = knn_loo_accuracy(d, g)
    same = knn_loo_accuracy(d, g, n_neighbors=5, n_permutations=999, seed=0)
    assert res.n_neighbors == 5 and res.n_permutations == 999 and res.null.shape == (999,)
    np.testing.assert_array_equal(res.null, same.null)
    np.testing.assert_array_equal(res.predictions, np.array(list("ab"))[_brute_force_knn(d, (g == "b").astype(int), 5)])
    assert not np.array_equal(res.null, knn_loo_accuracy(d, g, seed=1).null)


def test_factor_levels_of_any_type_and_a_numeric_covariate_far_from_zero():
    """Labels of mixed types (sorted as text) are a factor; an all-True boolean is a factor with a
    single level; a numeric covariate is centred before anything else, so an offset a hundred billion
    times its spread changes nothing (uncentred, it would look collinear with the intercept)."""
    rng = np.random.default_rng(17)
    y = rng.normal(size=(12, 2))
    d = cdist(y, y)
    mixed = np.array([1, "a"] * 6, dtype=object)
    as_text = np.array(["1", "a"] * 6)
    pd.testing.assert_frame_equal(permanova(d, {"m": mixed}, n_permutations=9).table,
                                  permanova(d, {"m": as_text}, n_permutations=9).table)
    with pytest.raises(ValueError, match=r"covariate 'f' has a single level \[.*True_?\]: nothing to test"):
        permanova(d, {"f": np.ones(12, dtype=bool)})
    age = np.arange(12.0)
    base = permanova(d, {"age": age}, n_permutations=19).table
    far = permanova(d, {"age": 1e12 + age}, n_permutations=19).table
    pd.testing.assert_frame_equal(base, far, rtol=1e-6)


def test_a_covariate_is_collinear_below_1e_minus_10_of_its_own_part():
    """b = a + ε w with w orthogonal to the intercept and a: after centring and scaling to unit
    length, the part of b outside (1, a) has length ε; it is a term of its own for ε = 1.5e-10
    and collinear for ε = 0.5e-10."""
    rng = np.random.default_rng(18)
    n = 10
    y = rng.normal(size=(n, 2))
    d = cdist(y, y)
    basis, _ = np.linalg.qr(np.column_stack([np.ones(n), rng.normal(size=(n, 2))]))
    a, w = basis[:, 1], basis[:, 2]  # centred, unit, orthogonal
    res = permanova(d, {"a": a, "b": a + 1.5e-10 * w}, n_permutations=5).table
    assert res.loc["b", "df"] == 1 and res.loc["Residual", "df"] == n - 3
    with pytest.raises(ValueError, match=r"^term 'b' is collinear with the terms before it"):
        permanova(d, {"a": a, "b": a + 0.5e-10 * w}, n_permutations=5)


def test_permanova_defaults_are_999_permutations_and_seed_0():
    rng = np.random.default_rng(19)
    y = rng.normal(size=(9, 2))
    d = cdist(y, y)
    g = np.array(list("aab") * 3)
    res = permanova(d, {"g": g})
    assert res.n_permutations == 999 and res.seed == 0 and res.null["g"].shape == (999,)
    np.testing.assert_array_equal(res.null["g"], permanova(d, {"g": g}, n_permutations=999, seed=0).null["g"])
    assert not np.array_equal(res.null["g"], permanova(d, {"g": g}, seed=1).null["g"])
    with pytest.raises(ValueError, match=r"^no terms to test$"):
        permanova(d, {"g": g}, terms=())
    with pytest.raises(ValueError, match=r"^distances are all zero: there is no variation to test$"):
        permanova(np.zeros((9, 9)), {"g": g})


def test_three_terms_name_all_the_others():
    """x = z + w + noise: x's sequential sum of squares is shared with both later terms, and its
    p tests x given z + w."""
    rng = np.random.default_rng(20)
    n = 30
    z, w = rng.normal(size=n), rng.normal(size=n)
    x = z + w + 0.05 * rng.normal(size=n)
    y = np.c_[z, w] + 0.5 * rng.normal(size=(n, 2))
    res = permanova(cdist(y, y), {"x": x, "z": z, "w": w}, by="terms", n_permutations=9)
    t = res.table
    assert t.loc["x", "p_tests"] == "no effect of x given z + w (residuals of the model without x permuted)"
    assert t.loc["z", "p_tests"] == "no effect of z given x + w (residuals of the model without z permuted)"
    one = np.ones((n, 1))
    full = np.column_stack([one, x, z, w])
    share = 1 - (_rss(np.column_stack([one, z, w]), y) - _rss(full, y)) / (
        _rss(one, y) - _rss(np.column_stack([one, x]), y))
    assert share > 0.5 and res.notes[0].startswith("x: ")
    assert f"; {share:.0%} of its sequential sum of squares is shared with z + w, which" in res.notes[0]
    assert not any(note.startswith("w: ") for note in res.notes)  # the last term has nothing after it


def test_ties_of_a_huge_f_count_within_a_relative_tolerance():
    """Two tight, far-apart clusters: F ~ 5e6, and exactly the draws that keep or swap the two groups
    reach it (counted here from the labels, no arithmetic); their permuted F differ from the
    observed one by rounding only, which the tolerance relative to F absorbs."""
    rng = np.random.default_rng(1)
    pts = np.r_[rng.normal(size=(4, 2)) * 1e-3, 1.0 + rng.normal(size=(4, 2)) * 1e-3]
    g = np.array(["a"] * 4 + ["b"] * 4)
    res = permanova(cdist(pts, pts), {"g": g}, permute="rows", n_permutations=999, seed=1)
    assert res.table.loc["g", "pseudo_F"] > 1e6
    r = np.random.default_rng(1)
    draws = [r.permutation(8) for _ in range(999)]
    same = sum(np.array_equal(g[p], g) or np.array_equal(g[p], g[::-1]) for p in draws)
    assert same > 0
    assert res.table.loc["g", "p_value"] == pytest.approx((1 + same) / 1000, abs=1e-15)
