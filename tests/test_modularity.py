"""The covariance ratio and modularity test against independent computations: a value worked out by
hand, loops over the covariances, the closed form of a module and its copy, exact zeros, pose and
labelling invariances, the permutation counts redone by brute force, and the test's behaviour on
modular and integrated data."""

import itertools
import warnings

import numpy as np
import pytest

import shapelib as sl


def _rot(t):
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def _with_covariance(s, n, rng):
    """n specimens whose sample covariance (divisor n − 1) is exactly ``s``."""
    z = rng.normal(size=(n, len(s)))
    z -= z.mean(axis=0)
    q, _ = np.linalg.qr(z)  # orthonormal, centred columns
    return np.sqrt(n - 1) * q @ np.linalg.cholesky(s).T


def _cr_loops(x, labels):
    """CR from its definition, by loops: the sample covariances one by one, then the sums of squares
    between two modules and within each (variances left out); the mean over the pairs, and the pairs."""
    n, p = x.shape
    mean = [sum(x[i, a] for i in range(n)) / n for a in range(p)]
    cov = [[sum((x[i, a] - mean[a]) * (x[i, b] - mean[b]) for i in range(n)) / (n - 1) for b in range(p)]
           for a in range(p)]
    modules = sorted(set(labels))
    members = {m: [a for a in range(p) if labels[a] == m] for m in modules}

    def within(m):
        return sum(cov[a][b] ** 2 for a in members[m] for b in members[m] if a != b)

    pairs = {}
    for m1, m2 in itertools.combinations(modules, 2):
        between = sum(cov[a][b] ** 2 for a in members[m1] for b in members[m2])
        pairs[m1, m2] = np.sqrt(between / np.sqrt(within(m1) * within(m2)))
    return sum(pairs.values()) / len(pairs), pairs


def _shapes(rng, n=30, k=12, modular=True, noise=0.02):
    """Landmarks about an ellipse moved by one factor per half (modular: the halves independent) or by
    one factor for all (integrated), with isotropic noise."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    base = np.c_[2 * np.cos(t), np.sin(t)]
    m = 2 if modular else 1
    load = rng.normal(size=(m, k, 2))
    if modular:
        load *= np.repeat(np.eye(2), k // 2, axis=1)[:, :, None]
    f = rng.normal(size=(n, m))
    return base + 0.05 * np.einsum("nm,mkd->nkd", f, load) + noise * rng.normal(size=(n, k, 2))


HALVES = np.repeat(["a", "b"], 6)


# --- the statistic --------------------------------------------------------------------------------

def test_cr_worked_out_by_hand():
    # within each module the two variables covary by 1, across modules two pairs by 0.5:
    # CR = sqrt((0.5² + 0.5²) / sqrt((1² + 1²)(1² + 1²))) = sqrt(0.5 / 2) = 0.5
    s = np.array([[2, 1, .5, 0], [1, 2, 0, .5], [.5, 0, 2, 1], [0, .5, 1, 2.0]])
    x = _with_covariance(s, 9, np.random.default_rng(0))
    np.testing.assert_allclose(np.cov(x, rowvar=False), s, atol=1e-12)
    res = sl.modularity_test(x, [0, 0, 1, 1], n_permutations=19)
    assert res.value == pytest.approx(0.5, rel=1e-12)
    assert res.pairwise[0, 1] == res.pairwise[1, 0] == pytest.approx(0.5, rel=1e-12)
    assert np.isnan(res.pairwise[0, 0]) and np.isnan(res.pairwise[1, 1])
    # the variances do not enter: inflating them leaves CR as it is
    big = s + np.diag([3.0, 0.0, 7.0, 1.0])
    x2 = _with_covariance(big, 9, np.random.default_rng(1))
    assert sl.modularity_test(x2, [0, 0, 1, 1], n_permutations=19).value == pytest.approx(0.5, rel=1e-12)


@pytest.mark.parametrize("labels", [[0, 0, 1, 1, 1], [2, 0, 0, 1, 2, 1, 1], ["u", "v", "u", "w", "v", "w"]])
def test_cr_of_variables_redone_by_loops(labels):
    rng = np.random.default_rng(len(labels))
    x = rng.normal(size=(8, len(labels))) @ rng.normal(size=(len(labels), len(labels)))
    res = sl.modularity_test(x, labels, n_permutations=19)
    value, pairs = _cr_loops(x, labels)
    assert res.value == pytest.approx(value, rel=1e-10)
    names = list(res.modules)
    assert names == sorted(set(labels))
    for (m1, m2), cr in pairs.items():
        assert res.pairwise[names.index(m1), names.index(m2)] == pytest.approx(cr, rel=1e-10)
        assert res.pairwise[names.index(m2), names.index(m1)] == pytest.approx(cr, rel=1e-10)
    np.testing.assert_array_equal(res.sizes, [labels.count(m) for m in names])
    assert not res.landmarks


def test_cr_of_landmarks_redone_by_loops_on_their_coordinates():
    """A landmark's module is that of each of its coordinates; the covariance of its own x and y
    stays in the within-module sums (only the variances go)."""
    rng = np.random.default_rng(3)
    shapes = rng.normal(size=(7, 4, 2)) + rng.normal(size=(7, 1, 1)) * rng.normal(size=(4, 2))
    part = ["p", "q", "p", "q"]
    res = sl.modularity_test(shapes, part, n_permutations=19, principal_axes=False)
    value, _ = _cr_loops(shapes.reshape(7, 8), np.repeat(part, 2).tolist())
    assert res.value == pytest.approx(value, rel=1e-10)
    assert res.landmarks
    np.testing.assert_array_equal(res.sizes, [2, 2])
    # with principal axes: the same loops on the coordinates turned onto the mean's axes
    mean = shapes.mean(axis=0) - shapes.mean(axis=(0, 1))
    w, v = np.linalg.eigh(mean.T @ mean)
    turned = shapes @ v
    value_axes, _ = _cr_loops(turned.reshape(7, 8), np.repeat(part, 2).tolist())
    assert sl.modularity_test(shapes, part, n_permutations=19).value == pytest.approx(value_axes, rel=1e-10)


def test_cr_of_a_module_and_its_copy():
    """Two modules that are copies of each other: S₁₂ = S₁₁ with its variances, so
    CR² = 1 + Σ variances² / Σ_{i≠j} covariances²."""
    rng = np.random.default_rng(4)
    a = rng.normal(size=(20, 3)) @ rng.normal(size=(3, 3))
    x = np.hstack([a, a])
    s = np.cov(a, rowvar=False)
    expect = np.sqrt(1 + np.sum(np.diag(s) ** 2) / (np.sum(s**2) - np.sum(np.diag(s) ** 2)))
    assert sl.modularity_test(x, [0, 0, 0, 1, 1, 1], n_permutations=19).value == pytest.approx(expect, rel=1e-12)


def test_cr_is_zero_for_modules_that_do_not_covary():
    rng = np.random.default_rng(5)
    n = 30
    a = rng.normal(size=(n, 4)) @ rng.normal(size=(4, 4))
    a -= a.mean(axis=0)
    b = rng.normal(size=(n, 3)) @ rng.normal(size=(3, 3))
    b -= b.mean(axis=0)
    basis = np.linalg.qr(np.c_[np.ones(n), a])[0]
    b -= basis @ (basis.T @ b)  # b orthogonal to a's columns: the sample cross-covariance is 0
    np.testing.assert_allclose(a.T @ b, 0, atol=1e-10)
    res = sl.modularity_test(np.hstack([b, a]), [1, 1, 1, 0, 0, 0, 0], n_permutations=99)
    assert res.value == pytest.approx(0, abs=1e-7)
    # no other split of these sizes (one of 35) separates them: only the permutations that draw this
    # split again give CR* = 0, every other is well above
    again = np.abs(res.null) < 1e-7
    assert 0 < np.sum(again) < 10 and np.all(res.null[~again] > 1e-2)
    assert res.p_value == pytest.approx((1 + np.sum(again)) / 100)


def test_three_modules_are_the_mean_of_the_two_module_tests():
    rng = np.random.default_rng(6)
    x = rng.normal(size=(15, 9)) @ rng.normal(size=(9, 9))
    labels = np.array(["c", "a", "b", "a", "c", "b", "b", "a", "c"])
    res = sl.modularity_test(x, labels, n_permutations=19)
    assert res.pairwise.shape == (3, 3)
    for i, j in itertools.combinations(range(3), 2):
        keep = np.isin(labels, [res.modules[i], res.modules[j]])
        two = sl.modularity_test(x[:, keep], labels[keep], n_permutations=19)
        assert res.pairwise[i, j] == pytest.approx(two.value, rel=1e-12)
    upper = res.pairwise[np.triu_indices(3, 1)]
    assert res.value == pytest.approx(upper.mean(), rel=1e-12)
    np.testing.assert_array_equal(res.pairwise, res.pairwise.T)


# --- invariances -----------------------------------------------------------------------------------

def test_cr_is_free_of_the_pose_and_size_of_each_specimen():
    rng = np.random.default_rng(7)
    raw = _shapes(rng)
    moved = np.stack([s2 * (0.5 + rng.random()) @ _rot(rng.uniform(0, 2 * np.pi)) + rng.normal(size=2)
                      for s2 in raw])
    y = sl.procrustes_coordinates(raw)
    y_moved = sl.procrustes_coordinates(moved)
    res = sl.modularity_test(y, HALVES, n_permutations=49)
    again = sl.modularity_test(y_moved, HALVES, n_permutations=49)
    assert again.value == pytest.approx(res.value, rel=1e-8)
    np.testing.assert_allclose(again.null, res.null, rtol=1e-8)
    assert again.p_value == res.p_value
    # rows of coordinates (N, K·d) and landmarks (N, K, d) are the same data
    flat = sl.modularity_test(y.reshape(len(y), -1), HALVES, n_permutations=49)
    assert flat.landmarks and flat.value == pytest.approx(res.value, rel=1e-12)
    # a common rotation of the aligned coordinates changes the variances CR leaves out, so CR on the
    # coordinates as given depends on it; on the principal axes it does not
    turned = y.reshape(len(y), -1, 2) @ _rot(0.6)
    assert sl.modularity_test(turned, HALVES, n_permutations=49).value == pytest.approx(res.value, rel=1e-8)
    given = sl.modularity_test(y, HALVES, n_permutations=49, principal_axes=False).value
    given_turned = sl.modularity_test(turned, HALVES, n_permutations=49, principal_axes=False).value
    assert abs(given_turned - given) > 1e-3


def test_cr_is_free_of_the_scale_and_centre_of_the_variables():
    rng = np.random.default_rng(8)
    x = rng.normal(size=(12, 6)) @ rng.normal(size=(6, 6))
    labels = [0, 1, 0, 1, 1, 0]
    res = sl.modularity_test(x, labels, n_permutations=29, seed=3)
    other = sl.modularity_test(7.5 * x + rng.normal(size=6), labels, n_permutations=29, seed=3)
    assert other.value == pytest.approx(res.value, rel=1e-10)
    np.testing.assert_allclose(other.null, res.null, rtol=1e-10)


def test_cr_is_symmetric_in_the_modules_and_free_of_the_landmark_order():
    rng = np.random.default_rng(9)
    shapes = _shapes(rng, k=12)
    labels = np.repeat(["a", "b", "c"], 4)
    res = sl.modularity_test(shapes, labels, n_permutations=19)
    # the modules renamed (a -> c, b -> a, c -> b): the same CR, the pairwise matrix relabelled
    renamed = np.array([{"a": "c", "b": "a", "c": "b"}[m] for m in labels])
    other = sl.modularity_test(shapes, renamed, n_permutations=19)
    assert other.value == pytest.approx(res.value, rel=1e-12)
    where = [list(other.modules).index({"a": "c", "b": "a", "c": "b"}[m]) for m in res.modules]
    np.testing.assert_allclose(other.pairwise[np.ix_(where, where)], res.pairwise, rtol=1e-12)
    # the landmarks listed in another order, each keeping its module
    order = rng.permutation(12)
    shuffled = sl.modularity_test(shapes[:, order], labels[order], n_permutations=19)
    assert shuffled.value == pytest.approx(res.value, rel=1e-10)
    np.testing.assert_allclose(shuffled.pairwise, res.pairwise, rtol=1e-10)


# --- the test --------------------------------------------------------------------------------------

def test_the_null_and_p_value_redone_by_brute_force():
    rng = np.random.default_rng(10)
    x = rng.normal(size=(10, 7)) @ rng.normal(size=(7, 7))
    labels = np.array([0, 1, 1, 0, 2, 2, 1])
    n_perm = 31
    res = sl.modularity_test(x, labels, n_permutations=n_perm, seed=5)
    gen = np.random.default_rng(5)
    null = [_cr_loops(x, labels[gen.permutation(7)].tolist())[0] for _ in range(n_perm)]
    np.testing.assert_allclose(res.null, null, rtol=1e-10)
    assert res.p_value == pytest.approx((1 + np.sum(np.array(null) <= res.value + 1e-12)) / (1 + n_perm))
    assert res.z == pytest.approx((res.value - np.mean(null)) / np.std(null, ddof=1), rel=1e-9)
    assert res.n_permutations == n_perm and res.n_specimens == 10


def test_landmarks_move_with_all_their_coordinates_in_the_permutations():
    """Every CR* is the CR of some assignment of whole landmarks (all 35 of them enumerated)."""
    rng = np.random.default_rng(11)
    shapes = _shapes(rng, k=7, modular=False, noise=0.05)
    part = np.array([0, 0, 0, 1, 1, 1, 1])
    res = sl.modularity_test(shapes, part, n_permutations=60)
    every = []
    for first in itertools.combinations(range(7), 3):
        labels = np.ones(7, dtype=int)
        labels[list(first)] = 0
        every.append(sl.modularity_test(shapes, labels, n_permutations=19).value)
    every = np.array(every)
    assert all(np.min(np.abs(every - v)) < 1e-10 * v for v in res.null)
    # and the permutation p-value estimates the share of assignments with a CR as small
    exact = np.mean(every <= res.value * (1 + 1e-12))
    assert abs(res.p_value - exact) < 0.15


def test_modular_data_give_small_p_and_integrated_data_do_not():
    rng = np.random.default_rng(12)
    modular = [sl.modularity_test(_shapes(rng), HALVES, n_permutations=99) for _ in range(8)]
    integrated = [sl.modularity_test(_shapes(rng, modular=False), HALVES, n_permutations=99) for _ in range(8)]
    assert all(r.p_value == pytest.approx(0.01) and r.z < -2 for r in modular)
    p = np.array([r.p_value for r in integrated])
    assert np.sum(p <= 0.05) <= 1 and np.median(p) > 0.2
    assert np.median([abs(r.z) for r in integrated]) < 1.5
    # a hypothesis that cuts across the real modules (alternate landmarks) gets no support either
    across = [sl.modularity_test(_shapes(rng), np.tile(["a", "b"], 6), n_permutations=99) for _ in range(4)]
    assert all(r.p_value > 0.05 for r in across)


def test_seed_and_defaults():
    rng = np.random.default_rng(13)
    shapes = _shapes(rng)
    res = sl.modularity_test(shapes, HALVES, n_permutations=29)
    assert np.array_equal(res.null, sl.modularity_test(shapes, HALVES, n_permutations=29, seed=0).null)
    assert not np.array_equal(res.null, sl.modularity_test(shapes, HALVES, n_permutations=29, seed=1).null)
    default = sl.modularity_test(shapes, HALVES)
    assert default.n_permutations == 999 and len(default.null) == 999
    assert default.value == pytest.approx(res.value)


def test_no_spread_in_the_null_means_no_effect():
    """Two modules of two variables each, with the same covariance c for every pair of variables: CR is
    sqrt(4 c² / sqrt(2 c² · 2 c²)) = sqrt(2) for every assignment, so z is 0 and p is 1."""
    s = np.full((4, 4), 0.5) + 0.5 * np.eye(4)
    x = _with_covariance(s, 12, np.random.default_rng(14))
    res = sl.modularity_test(x, [0, 0, 1, 1], n_permutations=19)
    assert res.value == pytest.approx(np.sqrt(2), rel=1e-12)
    np.testing.assert_allclose(res.null, np.sqrt(2), rtol=1e-12)
    assert res.z == 0.0 and res.p_value == 1.0


def test_an_assignment_without_covariance_within_a_module_is_never_modular():
    """Columns of a Hadamard matrix are exactly orthogonal (h·h = 8): with v0 = h1, v1 = h1 + h2 + h3,
    v2 = h2, v3 = h1 + 2 h2 + h4, the products are v0·v1 = 8, v0·v2 = 0, v0·v3 = 8, v1·v2 = 8,
    v1·v3 = 24, v2·v3 = 16. By hand, the three splits into two pairs:
    {v0, v1} | {v2, v3}: sqrt((0 + 8² + 8² + 24²) / sqrt(2 · 8² · 2 · 16²)) = sqrt(11/4);
    {v0, v3} | {v1, v2}: sqrt((8² + 0 + 24² + 16²) / sqrt(2 · 8² · 2 · 8²)) = sqrt(7);
    {v0, v2} | {v1, v3}: no covariance within the first, CR* = ∞ (and no warning)."""
    h = np.array([[1.0]])
    for _ in range(3):
        h = np.block([[h, h], [h, -h]])
    h1, h2, h3, h4 = h[:, 1:5].T
    x = np.c_[h1, h1 + h2 + h3, h2, h1 + 2 * h2 + h4]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = sl.modularity_test(x, [0, 0, 1, 1], n_permutations=60)
    assert res.value == pytest.approx(np.sqrt(11 / 4), rel=1e-12)
    infinite = np.isinf(res.null)
    low = np.isclose(res.null, np.sqrt(11 / 4), rtol=1e-12)
    assert 5 < np.sum(infinite) < 40 and 5 < np.sum(low) < 40
    np.testing.assert_allclose(res.null[~infinite & ~low], np.sqrt(7), rtol=1e-12)
    assert res.p_value == pytest.approx((1 + np.sum(low)) / 61)
    finite = res.null[~infinite]
    assert res.z == pytest.approx((res.value - finite.mean()) / finite.std(ddof=1), rel=1e-9)
    assert res.z < 0


def test_summary():
    rng = np.random.default_rng(15)
    two = sl.modularity_test(_shapes(rng), HALVES, n_permutations=19)
    text = two.summary()
    assert f"CR = {two.value:.4g}" in text and f"p = {two.p_value:.4g}" in text and f"z = {two.z:.3g}" in text
    assert "30 specimens" in text and "2 modules of landmarks, a: 6, b: 6" in text and "19 random" in text
    assert "pairwise" not in text
    three = sl.modularity_test(rng.normal(size=(10, 6)), [0, 0, 1, 1, 2, 2], n_permutations=19)
    text3 = three.summary()
    assert "3 modules of variables" in text3
    assert f"pairwise CR: 0–1 {three.pairwise[0, 1]:.4g}, 0–2 {three.pairwise[0, 2]:.4g}, " \
           f"1–2 {three.pairwise[1, 2]:.4g}" in text3


@pytest.mark.parametrize("shapes, partition, kwargs, match", [
    (np.zeros((10, 4, 2)) + np.arange(8).reshape(4, 2), [0, 0, 1], {}, "partition: 3 labels for 4 landmarks"),
    (np.ones((10, 5)), [0, 0, 1, 1], {}, r"partition: 4 labels do not fit shapes of shape \(10, 5\): give "
     r"\(N, K, d\) landmarks with K labels, or \(N, p\) variables with p labels \(or p / d for rows of "
     r"landmark coordinates\)"),
    (np.ones((10, 5)), [], {}, "partition: 0 labels do not fit"),
    (np.ones((10, 4)), [[0, 0], [1, 1]], {}, "partition: expected one label"),
    (np.ones((10, 4)), [0, 0, 0, 0], {}, "at least 2 modules"),
    (np.ones((10, 4)), [0, 1, 1, 1], {}, "module 0 has one variable"),
    (np.ones((10, 5)), ["a", "a", "b", "a", "c"], {}, r"partition: module 'b' has one variable; each module needs at "
     r"least 2 \(CR compares covariances within the modules\)"),
    (np.ones((2, 4)), [0, 0, 1, 1], {}, "shapes: at least 3 specimens"),
    (np.r_[np.ones((3, 4)), [[1, np.nan, 1, 1]]], [0, 0, 1, 1], {}, "variable 1 of specimen 3 is not finite"),
    (np.ones((10, 4)), [0, 0, 1, 1], {}, "partition: the variables of module 0 do not covary among themselves; "
     "CR is not defined"),
    (np.ones((10, 4)), [0, 0, 1, 1], {"n_permutations": 18}, "n_permutations must be at least 19"),
    (np.ones((10, 4)), [0, 0, 1, 1], {"n_permutations": 2.5}, "n_permutations must be a positive integer"),
])
def test_bad_input_names_the_parameter(shapes, partition, kwargs, match):
    with pytest.raises(ValueError, match=match):
        sl.modularity_test(shapes, partition, **kwargs)


def test_smallest_modules_accepted():
    """A module of one landmark (its x and y covary) or of two variables is enough, and 3 specimens."""
    rng = np.random.default_rng(16)
    shapes = rng.normal(size=(12, 3, 2)) + rng.normal(size=(12, 1, 1)) * np.array([1.0, 1.0])
    res = sl.modularity_test(shapes, [0, 1, 1], n_permutations=19)
    assert np.isfinite(res.value) and list(res.sizes) == [1, 2]
    x = rng.normal(size=(12, 4)) @ rng.normal(size=(4, 4))
    assert np.isfinite(sl.modularity_test(x, [0, 0, 1, 1], n_permutations=19).value)
    assert np.isfinite(sl.modularity_test(x[:3], [0, 0, 1, 1], n_permutations=19).value)
    # 3-D landmarks read from rows of coordinates
    y = rng.normal(size=(12, 4, 3)) + rng.normal(size=(12, 1, 1))
    three = sl.modularity_test(y.reshape(12, 12), [0, 0, 1, 1], n_permutations=19)
    assert three.landmarks and three.value == pytest.approx(
        sl.modularity_test(y, [0, 0, 1, 1], n_permutations=19).value, rel=1e-12)
