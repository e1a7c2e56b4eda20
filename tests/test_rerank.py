"""Re-ranking a dissimilarity matrix (:func:`shapelib.rerank`): shape, symmetry, fixed points, gain, bad input."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.rerank import RERANK_METHODS, rerank


def noisy_classes(seed=0, n_classes=6, per_class=10, noise=0.35):
    """Dissimilarities 1 within a class and 1.5 between, blurred by symmetric Gaussian noise."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.arange(n_classes), per_class)
    e = rng.normal(scale=noise, size=(len(labels), len(labels)))
    d = np.abs(np.where(labels[:, None] == labels[None, :], 1.0, 1.5) + (e + e.T) / 2)
    np.fill_diagonal(d, 0.0)
    return d, labels


@pytest.mark.parametrize("method", RERANK_METHODS)
def test_shape_range_and_zero_diagonal(method):
    d, _ = noisy_classes()
    r = rerank(d, method=method, k=5)
    assert r.shape == d.shape
    assert np.all(np.diag(r) == 0)
    assert r.min() >= 0 and r.max() <= 1


def test_tpg_is_symmetric_even_for_an_asymmetric_input():
    d, _ = noisy_classes(seed=3)
    d = d * (1 + 0.2 * np.random.default_rng(1).random(d.shape))  # asymmetric
    r = rerank(d, method="tpg", k=6)
    assert np.array_equal(r, r.T)


@pytest.mark.parametrize("method", RERANK_METHODS)
def test_perfect_block_diagonal_stays_perfect(method):
    # every class-mate nearer than every stranger, and the graph's neighbourhoods inside the classes:
    # the diffusion never leaves a class, so the re-ranked matrix separates them completely
    labels = np.repeat(np.arange(4), 5)
    rng = np.random.default_rng(2)
    d = np.where(labels[:, None] == labels[None, :], rng.uniform(0.1, 0.3, (20, 20)), rng.uniform(2, 3, (20, 20)))
    d = (d + d.T) / 2
    np.fill_diagonal(d, 0)
    assert sl.bullseye(d, labels, top=5).value == 1.0
    r = rerank(d, method=method, k=5)
    assert sl.bullseye(r, labels, top=5).value == 1.0
    same = labels[:, None] == labels[None, :]
    off = ~np.eye(20, dtype=bool)
    # every stranger at the largest dissimilarity: no walk inside the kNN graph reaches it
    assert r[same & off].max() < r[~same].min()


@pytest.mark.parametrize("method", RERANK_METHODS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_improves_bullseye_on_noisy_clusters(method, seed):
    d, labels = noisy_classes(seed=seed)
    raw = sl.bullseye(d, labels).value
    new = sl.bullseye(rerank(d, method=method, k=6), labels).value
    assert raw < 0.95  # the noise costs the raw matrix retrievals
    assert new > raw + 0.03


@pytest.mark.parametrize("method", RERANK_METHODS)
def test_invariant_to_a_common_scale(method):
    # the kernel's width is the neighbours' mean distance: D and c·D give the same re-ranking
    d, _ = noisy_classes(seed=4)
    np.testing.assert_allclose(rerank(7.5 * d, method=method, k=5), rerank(d, method=method, k=5), atol=1e-12)


def test_tpg_agrees_with_the_truncated_series_computed_densely():
    # independent: the sum Σ_{s≤T} P^s (Pᵀ)^s with dense matrix powers, P built here from the definition
    d, _ = noisy_classes(seed=5, n_classes=3, per_class=6)
    k, mu, t = 4, 0.5, 6
    order = np.argsort(d + np.diag(np.full(len(d), -np.inf)), axis=1, kind="stable")[:, :k]
    np.testing.assert_allclose(rerank(d, method="tpg", k=k, mu=mu, n_iter=t), _dense_tpg(d, order, mu, t),
                               atol=1e-12)


def test_lcdp_rows_rank_like_the_dense_recursion():
    d, _ = noisy_classes(seed=6, n_classes=3, per_class=6)
    k, mu, t = 4, 0.5, 3
    n = len(d)
    order = np.argsort(d + np.diag(np.full(n, -np.inf)), axis=1, kind="stable")[:, :k]
    kappa = np.array([d[i, order[i, 1:]].mean() for i in range(n)])
    a = np.exp(-(d / (mu * (kappa[:, None] + kappa[None, :]) / 2)) ** 2)
    pk = np.zeros((n, n))
    for i in range(n):
        pk[i, order[i]] = a[i, order[i]] / a[i, order[i]].sum()
    w = a / a.sum(axis=1, keepdims=True)
    for _ in range(t):
        w = pk @ w @ pk.T
    expect = 1 - w / w.max()
    np.fill_diagonal(expect, 0)
    np.testing.assert_allclose(rerank(d, method="lcdp", k=k, mu=mu, n_iter=t), expect, atol=1e-12)


@pytest.mark.parametrize("bad, name", [
    (dict(D=np.ones((3, 4))), "D"),
    (dict(D=np.array([[0.0, np.nan], [1.0, 0.0]])), "D"),
    (dict(D=np.array([[0.0, -1.0], [1.0, 0.0]])), "D"),
    (dict(method="pagerank"), "method"),
    (dict(k=1), "k"),
    (dict(k=99), "k"),
    (dict(k=2.5), "k"),
    (dict(mu=0.0), "mu"),
    (dict(mu=np.inf), "mu"),
    (dict(n_iter=0), "n_iter"),
])
def test_bad_input_names_the_parameter(bad, name):
    d, _ = noisy_classes(n_classes=2, per_class=4)
    kw = {"D": d, "k": 3, **bad}
    with pytest.raises(ValueError, match=rf"^{name} "):
        rerank(kw.pop("D"), **kw)


def test_public():
    assert sl.rerank is rerank and set(RERANK_METHODS) >= {"tpg", "lcdp"}


def test_input_checks_say_where_and_accept_the_edges():
    """The offending entry is named (row, column from 0); two items, k = 2 and k = n, one iteration
    are allowed; a boolean or non-numeric mu or n_iter is refused."""
    d = np.array([[0.0, 1.0, 2.0], [1.0, 0.0, 1.5], [2.0, 1.5, 0.0]])
    bad = d.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"^D must be finite \(first non-finite entry at row 1, column 2\)$"):
        rerank(bad)
    bad = d.copy()
    bad[2, 0] = -0.5
    with pytest.raises(ValueError, match=r"^D must be a dissimilarity, ≥ 0 \(D\[2, 0\] = -0.5\)$"):
        rerank(bad)
    bad[2, 0] = 0.5  # entries in (0, 1) are fine
    assert rerank(bad, k=2).shape == (3, 3)
    with pytest.raises(ValueError, match=r"^D must compare at least 2 items; got shape \(1, 1\)$"):
        rerank(np.zeros((1, 1)))
    for method in RERANK_METHODS:
        assert rerank(d[:2, :2], method=method, k=2).shape == (2, 2)
        assert rerank(d, method=method, k=3, n_iter=1).shape == (3, 3)
    for kw in ({"k": 1}, {"k": 4}, {"mu": True}, {"mu": "0.5"}, {"n_iter": True}, {"n_iter": 1.0}, {"n_iter": 0}):
        with pytest.raises(ValueError, match=rf"^{next(iter(kw))} must be"):
            rerank(d, **{"k": 3, **kw})


def test_affinity_of_duplicated_items_has_its_closed_form():
    """Items 0 and 1 coincide, item 2 is 0.3 away: with k = 2 their neighbour distances κ are 0, 0
    and 0.3; a zero κ is raised to 1e-3 of the smallest positive one, so a = exp(−(d / (μ (κ_i +
    κ_j)/2))²): 1 between the twins, exp(−(0.3 / (0.25 · 0.3003))²) to the third. All items equal:
    every affinity is 1."""
    from shapelib.rerank import _affinity, _neighbours

    d = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.3], [0.3, 0.3, 0.0]])
    a = _affinity(d, _neighbours(d, 2), 0.5)
    far = np.exp(-(0.3 / (0.5 * 0.5 * (0.3e-3 + 0.3))) ** 2)
    np.testing.assert_allclose(a, [[1.0, 1.0, far], [1.0, 1.0, far], [far, far, 1.0]], rtol=1e-12)
    np.testing.assert_array_equal(_affinity(np.zeros((3, 3)), _neighbours(np.zeros((3, 3)), 2), 0.5), 1.0)


def _dense_tpg(d, order, mu, t):
    """TPG by dense matrix powers from each row's neighbour list ``order`` (the row itself first)."""
    n = len(d)
    kappa = np.array([d[i, order[i, 1:]].mean() for i in range(n)])
    a = np.exp(-(d / (mu * (kappa[:, None] + kappa[None, :]) / 2)) ** 2)
    p = np.zeros((n, n))
    for i in range(n):
        p[i, order[i]] = a[i, order[i]] / a[i, order[i]].sum()
    q = sum(np.linalg.matrix_power(p, s) @ np.linalg.matrix_power(p.T, s) for s in range(t + 1))
    expect = 1 - q / q.max()
    np.fill_diagonal(expect, 0)
    return expect


def test_the_defaults_are_tpg_with_ten_neighbours_mu_one_half_and_twenty_steps():
    d, _ = noisy_classes(seed=8, n_classes=3, per_class=8)
    order = np.argsort(d + np.diag(np.full(len(d), -np.inf)), axis=1, kind="stable")[:, :10]
    np.testing.assert_allclose(rerank(d), _dense_tpg(d, order, 0.5, 20), atol=1e-12)


def test_equal_dissimilarities_are_ranked_by_index():
    """A matrix of small integers has many ties; the neighbours of each row are then the k − 1 items
    of smallest (dissimilarity, index), here by np.lexsort, after the row itself."""
    rng = np.random.default_rng(0)
    n, k = 40, 8
    d = rng.integers(1, 4, size=(n, n)).astype(float)
    d = np.minimum(d, d.T)
    np.fill_diagonal(d, 0.0)
    order = np.array([[i] + [j for j in np.lexsort((np.arange(n), d[i])) if j != i][:k - 1] for i in range(n)])
    np.testing.assert_allclose(rerank(d, k=k, n_iter=5), _dense_tpg(d, order, 0.5, 5), atol=1e-12)
