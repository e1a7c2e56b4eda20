"""Morphological disparity and two-block PLS against independent computations: NumPy's covariance
traces, scikit-learn's PLSSVD, pose invariance, exact limits and the permutation counts redone by
brute force."""

import numpy as np
import pytest
from sklearn.cross_decomposition import PLSSVD

import shapelib as sl
from shapelib.geometry.procrustes import procrustes_distance

BASE = np.array([[0, 0], [2, 0], [2.5, 1], [1, 1.6], [0, 1.0]])


def _rot(t):
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def _groups(rng, scales, n=8):
    shapes = np.concatenate([BASE + rng.normal(scale=s, size=(n, 5, 2)) for s in scales])
    labels = np.repeat([f"g{k}" for k in range(len(scales))], n)
    return shapes, labels


# --- morphological disparity ----------------------------------------------------------------------

@pytest.mark.parametrize("about", ["group", "grand"])
def test_disparity_is_the_trace_of_numpys_covariance(about):
    rng = np.random.default_rng(0)
    y = rng.normal(size=(15, 6)) * np.repeat([1.0, 2.0, 0.5], 5)[:, None] + np.repeat([0.0, 1.0, 3.0], 5)[:, None]
    labels = np.repeat(["a", "b", "c"], 5)
    res = sl.morphological_disparity(y, labels, about=about, n_permutations=19)
    for k, g in enumerate("abc"):
        yg = y[labels == g]
        if about == "group":
            expect = np.trace(np.cov(yg.T, ddof=0))
        else:  # about the grand mean: the group's mean squared distance to it
            expect = np.mean(np.sum((yg - y.mean(axis=0)) ** 2, axis=1))
        assert res.value[k] == pytest.approx(expect, rel=1e-12)
    assert list(res.groups) == ["a", "b", "c"] and list(res.sizes) == [5, 5, 5]
    np.testing.assert_allclose(res.differences, np.abs(res.value[:, None] - res.value[None, :]))


def test_disparity_of_landmarks_is_pose_free_and_matches_procrustes_distances():
    rng = np.random.default_rng(1)
    shapes, labels = _groups(rng, [0.02, 0.06])
    res = sl.morphological_disparity(shapes, labels, n_permutations=19)
    moved = np.stack([3.0 * s @ _rot(t).T + [5, -2] for s, t in zip(shapes, rng.uniform(0, 6, len(shapes)))])
    again = sl.morphological_disparity(moved, labels, n_permutations=19)
    np.testing.assert_allclose(again.value, res.value, rtol=1e-8)
    # within a group of small variation, PV ≈ mean squared Procrustes distance to the group's mean / 2 over pairs
    for k, g in enumerate(res.groups):
        grp = shapes[labels == g]
        pair = [procrustes_distance(grp[i], grp[j]) ** 2 for i in range(len(grp)) for j in range(len(grp)) if i < j]
        # Σ_i |y_i − ȳ|² = (1/n) Σ_{i<j} |y_i − y_j|² for points in a flat space; Procrustes distances to first order
        assert res.value[k] == pytest.approx(np.sum(pair) / len(grp) ** 2, rel=0.05)


def test_disparity_p_values_redone_by_brute_force():
    rng = np.random.default_rng(2)
    y = rng.normal(size=(12, 4)) * np.repeat([1.0, 1.6, 1.0], 4)[:, None]
    labels = np.repeat([0, 1, 2], 4)
    n_perm = 59
    res = sl.morphological_disparity(y, labels, n_permutations=n_perm, seed=7)
    d = np.array([np.sum((y[i] - y[labels == labels[i]].mean(axis=0)) ** 2) for i in range(12)])
    np.testing.assert_allclose(res.residuals2, d, rtol=1e-12)
    gen = np.random.default_rng(7)
    count = np.zeros((3, 3))
    for _ in range(n_perm):
        dp = d[gen.permutation(12)]
        pv = [dp[labels == g].mean() for g in range(3)]
        for a in range(3):
            for b in range(3):
                count[a, b] += abs(pv[a] - pv[b]) >= abs(res.value[a] - res.value[b]) - 1e-12
    expect = (1 + count) / (1 + n_perm)
    np.fill_diagonal(expect, 1.0)
    np.testing.assert_allclose(res.p_values, expect)


def test_disparity_limits():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(6, 4))
    # group b: the same residuals as a (reordered): equal disparity, every permutation is as far: p = 1
    y = np.concatenate([a, a[::-1] + 5.0])
    res = sl.morphological_disparity(y, np.repeat(["a", "b"], 6), n_permutations=99)
    assert res.value[0] == pytest.approx(res.value[1], rel=1e-12) and res.p_values[0, 1] == 1.0
    # group b ten times as spread: no permutation reaches it
    y = np.concatenate([a, 10 * a])
    res = sl.morphological_disparity(y, np.repeat(["a", "b"], 6), n_permutations=99)
    assert res.value[1] == pytest.approx(100 * res.value[0]) and res.p_values[0, 1] == pytest.approx(0.01)
    assert "PV" in res.summary() and "p = 0.01" in res.summary()


@pytest.mark.parametrize("kwargs, match", [
    (dict(groups=["a"] * 6), "^groups: need at least two groups to compare$"),
    (dict(groups=["a"] * 5 + ["b"]), "group 'b' has 1"),
    (dict(groups=["a"] * 5), "one label per specimen"),
    (dict(groups=["a", "b"] * 3, about="median"), "about"),
    (dict(groups=["a", "b"] * 3, n_permutations=10), "n_permutations"),
])
def test_disparity_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        sl.morphological_disparity(np.random.default_rng(0).normal(size=(6, 4)), **kwargs)
    y = np.ones((6, 4))
    y[2, 3] = np.nan
    with pytest.raises(ValueError, match="coordinate 3 of specimen 2"):
        sl.morphological_disparity(y, ["a", "b"] * 3)


# --- two-block PLS --------------------------------------------------------------------------------

def _blocks(seed=0, n=25, noise=0.5):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 5)) * [3, 2, 1, 1, 0.5]
    y = x[:, :2] @ rng.normal(size=(2, 4)) + noise * rng.normal(size=(n, 4)) + 10
    return x, y


def test_pls_agrees_with_scikit_learn():
    x, y = _blocks()
    res = sl.two_block_pls(x, y, n_permutations=19)
    ref = PLSSVD(n_components=4, scale=False).fit(x, y)
    sx, sy = ref.transform(x, y)
    for k in range(4):
        sign = np.sign(ref.x_weights_[:, k] @ res.weights1[:, k])
        np.testing.assert_allclose(sign * res.weights1[:, k], ref.x_weights_[:, k], atol=1e-10)
        np.testing.assert_allclose(sign * res.weights2[:, k], ref.y_weights_[:, k], atol=1e-10)
        np.testing.assert_allclose(sign * res.scores1[:, k], sx[:, k], atol=1e-9)
    assert res.value == pytest.approx(np.corrcoef(sx[:, 0], sy[:, 0])[0, 1], rel=1e-12)
    assert res.summary().count(" %") == 3  # the first three pairs' shares
    # σ_k is the covariance of the k-th pair of scores, and the shares sum to one
    cov = np.array([np.cov(res.scores1[:, k], res.scores2[:, k])[0, 1] for k in range(4)])
    np.testing.assert_allclose(cov, res.singular_values, rtol=1e-10)
    assert np.all(np.diff(res.singular_values) <= 0) and res.covariance_share.sum() == pytest.approx(1.0)


def test_pls_null_redone_with_scikit_learn():
    x, y = _blocks(1, n=12, noise=3.0)
    res = sl.two_block_pls(x, y, n_permutations=25, seed=4)
    gen = np.random.default_rng(4)
    null = []
    for _ in range(25):
        yp = y[gen.permutation(12)]
        sx, sy = PLSSVD(n_components=1, scale=False).fit(x, yp).transform(x, yp)
        null.append(np.corrcoef(sx[:, 0], sy[:, 0])[0, 1])
    np.testing.assert_allclose(res.null, null, rtol=1e-9)
    assert res.p_value == pytest.approx((1 + np.sum(np.array(null) >= res.value - 1e-12)) / 26)
    assert res.z == pytest.approx((res.value - np.mean(null)) / np.std(null, ddof=1), rel=1e-9)


def test_pls_invariances_and_exact_limit():
    x, y = _blocks(2)
    res = sl.two_block_pls(x, y, n_permutations=19)
    q, _ = np.linalg.qr(np.random.default_rng(5).normal(size=(5, 5)))
    turned = sl.two_block_pls(3.0 * x @ q + 1.0, y, n_permutations=19)
    swapped = sl.two_block_pls(y, x, n_permutations=19)
    assert turned.value == pytest.approx(res.value, rel=1e-10)
    np.testing.assert_allclose(turned.singular_values, 3 * res.singular_values, rtol=1e-10)
    assert swapped.value == pytest.approx(res.value, rel=1e-10)
    np.testing.assert_allclose(swapped.singular_values, res.singular_values, rtol=1e-10)
    # the second block a rotation of the first: the first scores coincide
    exact = sl.two_block_pls(x, x @ q - 2.0, n_permutations=99)
    assert exact.value == pytest.approx(1.0) and exact.p_value == pytest.approx(0.01)
    assert "r_PLS = 1" in exact.summary()


def test_pls_of_landmark_blocks_flattens_them():
    rng = np.random.default_rng(8)
    a = rng.normal(size=(10, 3, 2))
    b = a[:, :2] * 2 + 0.1 * rng.normal(size=(10, 2, 2))
    r3 = sl.two_block_pls(a, b, n_permutations=19)
    r2 = sl.two_block_pls(a.reshape(10, 6), b.reshape(10, 4), n_permutations=19)
    assert r3.value == r2.value and r3.weights1.shape[0] == 6


@pytest.mark.parametrize("b, match", [
    (np.random.default_rng(3).normal(size=(7, 3)), "block2: 7 specimens"),
    (np.ones((8, 3)), "constant"),
    (np.random.default_rng(0).normal(size=(2, 3)), "N >= 3"),
])
def test_pls_bad_input(b, match):
    with pytest.raises(ValueError, match=match):
        sl.two_block_pls(np.random.default_rng(1).normal(size=(8, 2)), b)
    x = np.random.default_rng(1).normal(size=(8, 2))
    x[4, 1] = np.inf
    with pytest.raises(ValueError, match="variable 1 of specimen 4"):
        sl.two_block_pls(x, np.random.default_rng(2).normal(size=(8, 2)))
    with pytest.raises(ValueError, match="n_permutations"):
        sl.two_block_pls(np.random.default_rng(1).normal(size=(8, 2)), np.random.default_rng(2).normal(size=(8, 2)),
                         n_permutations=5)


def test_disparity_summary_defaults_and_options():
    rng = np.random.default_rng(9)
    shapes, labels = _groups(rng, [0.02, 0.05], n=6)
    res = sl.morphological_disparity(shapes, labels)
    assert res.n_permutations == 999 and res.about == "group"
    # the default seed is 0: a p-value far from 0 differs from seed to seed
    mixed = labels[np.random.default_rng(3).permutation(len(labels))]
    p0 = sl.morphological_disparity(shapes, mixed).p_values[0, 1]
    assert p0 == sl.morphological_disparity(shapes, mixed, seed=0).p_values[0, 1]
    assert p0 != sl.morphological_disparity(shapes, mixed, seed=1).p_values[0, 1]
    text = res.summary()
    assert text.count(" vs ") == 1 and all(line.startswith("  ") for line in text.splitlines()[1:])
    assert "about its group's mean, 999 permutations" in text
    for g, v in zip(res.groups, res.value):
        assert f"{g:>12}  n = 6    PV = {v:.4g}" in text
    assert f"g0 vs g1: |ΔPV| = {res.differences[0, 1]:.4g}, p = {res.p_values[0, 1]:.4g}" in text
    grand = sl.morphological_disparity(shapes, labels, about="grand", n_permutations=19)
    assert grand.about == "grand" and "about the grand mean" in grand.summary()
    # aligned shapes are flattened as they are; unaligned ones are aligned first (pose-free)
    y = sl.procrustes_coordinates(shapes).reshape(shapes.shape)
    flat = sl.morphological_disparity(y.reshape(len(y), -1), labels, n_permutations=19)
    as_given = sl.morphological_disparity(y, labels, aligned=True, n_permutations=19)
    np.testing.assert_allclose(as_given.value, flat.value, rtol=1e-14)
    np.testing.assert_allclose(as_given.value, res.value, rtol=1e-10)
    raw = sl.morphological_disparity(shapes, labels, aligned=True, n_permutations=19)
    assert not np.allclose(raw.value, res.value, rtol=1e-3)  # the raw coordinates carry pose and size
    # two specimens per group are enough
    two = sl.morphological_disparity(rng.normal(size=(4, 3)), ["a", "a", "b", "b"], n_permutations=19)
    assert list(two.sizes) == [2, 2]


def test_disparity_errors_name_the_parameter():
    with pytest.raises(ValueError, match=r"^shapes must contain at least 2"):
        sl.morphological_disparity(np.ones((1, 3, 2)), ["a"])
    with pytest.raises(ValueError, match="n_permutations must be a positive integer"):
        sl.morphological_disparity(np.random.default_rng(0).normal(size=(4, 3)), ["a", "a", "b", "b"],
                                   n_permutations=2.5)


def test_pls_with_one_variable_is_its_regression_direction():
    rng = np.random.default_rng(10)
    x = rng.normal(size=(20, 4))
    size = x @ [1.0, -0.5, 0, 0] + 0.5 * rng.normal(size=20)
    res = sl.two_block_pls(x, size, n_permutations=19)
    xc, yc = x - x.mean(axis=0), size - size.mean()
    t1 = xc @ (xc.T @ yc)  # S₁₂ is one column: u₁ ∝ X₁ᵀ y
    assert res.value == pytest.approx(abs(np.corrcoef(t1, yc)[0, 1]), rel=1e-12)
    assert res.weights2.shape == (1, 1) and res.singular_values[0] == pytest.approx(
        np.linalg.norm(xc.T @ yc) / 19, rel=1e-12)
    text = res.summary()
    assert text.startswith("two-block PLS (20 specimens, blocks of 4 and 1 variables): r_PLS = ")
    assert "19 permutations" in text and f"z = {res.z:.3g}" in text and "100.0 %" in text


def test_pls_of_two_orthonormal_bases_of_the_specimens_is_always_one():
    # each block an orthonormal basis of the N − 1 centred dimensions: whatever the pairing of the rows,
    # the covariance is largest for equal scores, so r_PLS is 1 for every permutation and the test
    # cannot reject (p = 1, no effect: z = 0)
    rng = np.random.default_rng(11)
    c = rng.normal(size=(4, 3))
    q1, _ = np.linalg.qr(c - c.mean(axis=0))
    turn, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    res = sl.two_block_pls(q1, q1 @ turn + 1.0)
    assert res.value == pytest.approx(1.0) and res.n_permutations == 999
    np.testing.assert_allclose(res.null, 1.0)
    assert res.p_value == 1.0 and res.z == 0.0
    np.testing.assert_allclose(res.singular_values, 1 / 3)  # XᵀX₂ = turn, all singular values 1, over N − 1
    shares = res.covariance_share
    assert f"{100 * shares[0]:.1f} %, {100 * shares[1]:.1f} %, {100 * shares[2]:.1f} %" in res.summary()


def test_pls_smallest_inputs_and_the_constant_check():
    rng = np.random.default_rng(12)
    three = sl.two_block_pls(rng.normal(size=(3, 1)), rng.normal(size=(3, 1)), n_permutations=19)
    assert three.scores1.shape == (3, 1)
    with pytest.raises(ValueError, match=r"got shape \(2, 3\)"):
        sl.two_block_pls(rng.normal(size=(2, 3)), rng.normal(size=(2, 3)))
    # variation relative to the values, not absolute: 1e6 ± 1e-8 is constant, 0.5 ± 1.5e-12 is not
    with pytest.raises(ValueError, match="block1: every variable is constant"):
        sl.two_block_pls(1e6 + 1e-8 * rng.normal(size=(5, 2)), rng.normal(size=(5, 2)))
    tiny = 0.5 + np.array([[3e-12], [0.0], [3e-12], [0.0], [3e-12], [0.0]])
    sl.two_block_pls(tiny, rng.normal(size=(6, 2)), n_permutations=19)


def test_pls_rank_defaults_and_names():
    rng = np.random.default_rng(13)
    x = rng.normal(size=(10, 3))
    # a second block of one direction twice: S₁₂ has rank 1, and only that pair is reported
    col = x @ [1.0, 2.0, 0.0] + rng.normal(size=10)
    res = sl.two_block_pls(x, np.column_stack([col, col]), n_permutations=19)
    assert res.singular_values.shape == (1,) and res.covariance_share[0] == 1.0 and res.weights2.shape == (2, 1)
    np.testing.assert_allclose(np.abs(res.weights2[:, 0]), np.sqrt(0.5))
    assert "blocks of 3 and 2 variables" in res.summary()
    # exactly uncorrelated blocks: S₁₂ = 0, r_PLS = 0
    zero = sl.two_block_pls([[1.0, 1.0], [-1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]],
                            [[1.0, 2.0], [-1.0, -2.0], [-1.0, -2.0], [1.0, 2.0]], n_permutations=19)
    assert zero.value == 0.0 and zero.singular_values.shape == (1,) and zero.covariance_share[0] == 0.0
    # the default seed is 0
    y = rng.normal(size=(10, 2))
    np.testing.assert_array_equal(sl.two_block_pls(x, y).null, sl.two_block_pls(x, y, seed=0).null)
    bad = y.copy()
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match="^block2: variable 0 of specimen 3"):
        sl.two_block_pls(x, bad)
    with pytest.raises(ValueError, match="n_permutations must be a positive integer"):
        sl.two_block_pls(x, y, n_permutations=2.5)
