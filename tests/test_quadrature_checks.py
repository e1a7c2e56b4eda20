"""Checks of shapelib.geometry.quadrature against independent values: the trapezoid rule's integrals of
Gaussians and their polynomial moments (closed forms), the lattice built by brute force (itertools.product
of the per-axis nodes, every node an integer multiple of h, the smallest lattice box that covers the points
plus the margin), and the size limit counted by hand."""

import itertools
import math

import numpy as np
import pytest

import shapelib.geometry.quadrature as quadrature
from shapelib.geometry.quadrature import Grid, make_grid


def _gauss(nodes, mean, s2):
    d = nodes.shape[1]
    return np.exp(-0.5 * ((nodes - mean) ** 2).sum(axis=1) / s2) / (2 * np.pi * s2) ** (d / 2)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_gaussian_and_its_moments_integrate_to_their_closed_forms(d):
    s2 = 0.7
    mean = np.linspace(-0.3, 0.4, d)
    grid = make_grid(mean[None, :], sigma2=s2)
    p = _gauss(grid.nodes, mean, s2)
    assert grid.integrate(p) == pytest.approx(1.0, abs=1e-7)
    # first and second moments: E x = mean, E (x − mean)² = σ² per axis
    np.testing.assert_allclose(grid.integrate(p[:, None] * grid.nodes), mean, atol=1e-7)
    np.testing.assert_allclose(grid.integrate(p[:, None] * (grid.nodes - mean) ** 2), s2, rtol=1e-6)


def test_integrate_sums_along_the_given_axis():
    grid = make_grid([[0.0, 0.0]], sigma2=1.0)
    p = _gauss(grid.nodes, np.zeros(2), 1.0)
    stacked = np.stack([p, 2 * p, 3 * p])  # (3, M): integrate along axis 1
    np.testing.assert_allclose(grid.integrate(stacked, axis=1), [1, 2, 3], atol=1e-7)
    np.testing.assert_allclose(grid.integrate(stacked.T), [1, 2, 3], atol=1e-7)


@pytest.mark.parametrize("spacing, margin, s2", [(0.35, 6.0, 0.5), (0.5, 4.0, 1.3), (0.25, 3.0, 0.2)])
def test_the_lattice_is_the_smallest_box_of_multiples_of_h_covering_points_and_margin(spacing, margin, s2):
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(2, 4, 2)) * [1.5, 0.7] + [0.3, -2.0]  # (N, K, d): all shapes along a path
    grid = make_grid(pts, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    sigma = math.sqrt(s2)
    h = spacing * sigma
    flat = pts.reshape(-1, 2)
    assert grid.weight == pytest.approx(h ** 2, rel=1e-14)
    for i, ax in enumerate(grid.axes):
        k = ax / h
        np.testing.assert_allclose(k, np.round(k), atol=1e-9)          # integer multiples of h
        np.testing.assert_allclose(np.diff(ax), h, rtol=1e-12)          # step h
        lo, hi = flat[:, i].min() - margin * sigma, flat[:, i].max() + margin * sigma
        assert ax[0] <= lo + 1e-12 and ax[-1] >= hi - 1e-12             # covers
        assert ax[0] > lo - h and ax[-1] < hi + h                       # and no more than needed
    assert grid.shape == tuple(len(a) for a in grid.axes)
    assert all(type(n) is int for n in grid.shape)
    brute = np.array(list(itertools.product(*grid.axes)))              # C order: the last axis fastest
    np.testing.assert_array_equal(grid.nodes, brute)


def test_a_single_point_and_a_flat_point_array_give_the_same_grid():
    a = make_grid([0.2, -0.1, 0.4], sigma2=0.5, grid_spacing=0.6, grid_margin=3.0)
    b = make_grid([[0.2, -0.1, 0.4]], sigma2=0.5, grid_spacing=0.6, grid_margin=3.0)
    assert a.shape == b.shape and a.nodes.shape == (np.prod(a.shape), 3)
    np.testing.assert_array_equal(a.nodes, b.nodes)
    assert a.weight == pytest.approx((0.6 * math.sqrt(0.5)) ** 3)


def _size(points, s2, spacing=0.35, margin=6.0):
    """Nodes and landmarks of the grid, counted by hand."""
    pts = np.asarray(points, dtype=float)
    h, sigma = spacing * math.sqrt(s2), math.sqrt(s2)
    flat = pts.reshape(-1, pts.shape[-1])
    counts = [math.ceil((flat[:, i].max() + margin * sigma) / h) - math.floor((flat[:, i].min() - margin * sigma) / h)
              + 1 for i in range(flat.shape[1])]
    return counts, pts.shape[-2]


def test_max_entries_counts_nodes_times_landmarks_and_refuses_above_it():
    pts = np.random.default_rng(2).normal(size=(3, 5, 2))  # 3 shapes of K = 5 landmarks
    counts, k = _size(pts, 0.5)
    assert k == 5
    entries = math.prod(counts) * k
    grid = make_grid(pts, sigma2=0.5, max_entries=entries)          # exactly at the limit: built
    assert list(grid.shape) == counts
    with pytest.raises(ValueError, match="quadrature grid") as err:
        make_grid(pts, sigma2=0.5, max_entries=entries - 1)
    msg = str(err.value)
    total = math.prod(counts)
    assert f"{total:,} nodes" in msg
    assert " x ".join(f"{c:,}" for c in counts) in msg
    assert f"about {total * k * 8 / 2**30:.3g} GiB" in msg and f"(nodes x {k} landmarks)" in msg
    assert f"limit of {entries - 1:,} nodes x landmarks" in msg
    extent = float(np.max(pts.reshape(-1, 2).max(axis=0) - pts.reshape(-1, 2).min(axis=0)))
    assert f"span {extent:.4g} units" in msg and f"sigma = {math.sqrt(0.5):.3g}" in msg
    assert "grid step is 0.35 sigma" in msg


def test_the_default_limit_is_read_at_call_time(monkeypatch):
    pts = [[0.0, 0.0], [1.0, 0.0]]
    counts, k = _size(pts, 0.5)
    entries = math.prod(counts) * k
    monkeypatch.setattr(quadrature, "MAX_ENTRIES", entries)
    make_grid(pts, sigma2=0.5)
    monkeypatch.setattr(quadrature, "MAX_ENTRIES", entries - 1)
    with pytest.raises(ValueError, match="above the limit"):
        make_grid(pts, sigma2=0.5)


def test_the_defaults_are_documented_values():
    assert quadrature.DEFAULT_SPACING == 0.35 and quadrature.DEFAULT_MARGIN == 6.0
    assert quadrature.MAX_ENTRIES == 20_000_000
    pts = [[0.0, 0.0], [1.0, 0.0]]
    g = make_grid(pts, sigma2=0.5)
    assert list(g.shape) == _size(pts, 0.5)[0]


@pytest.mark.parametrize("name, kw", [("sigma2", dict(sigma2=0.0)), ("sigma2", dict(sigma2=-1.0)),
                                      ("grid_spacing", dict(sigma2=1.0, grid_spacing=0.0)),
                                      ("grid_margin", dict(sigma2=1.0, grid_margin=-1.0))])
def test_non_positive_settings_are_value_errors_naming_them(name, kw):
    with pytest.raises(ValueError, match=f"^{name} must be a positive finite number"):
        make_grid([[0.0, 0.0]], **kw)


@pytest.mark.parametrize("points", [[], np.zeros((0, 2)), 3.0])
def test_empty_or_scalar_points_are_value_errors(points):
    with pytest.raises(ValueError, match="^points must be a non-empty array with last axis d; got shape"):
        make_grid(points, sigma2=1.0)


@pytest.mark.parametrize("points", [[[0.0, np.nan]], [[np.inf, 0.0]]])
def test_non_finite_points_are_value_errors(points):
    with pytest.raises(ValueError, match="^points contain non-finite values: cannot place a quadrature grid$"):
        make_grid(points, sigma2=1.0)


def test_a_single_point_counts_as_one_landmark_against_the_limit():
    nodes = math.prod(_size([[0.3, -0.2]], 0.5)[0])
    make_grid([0.3, -0.2], sigma2=0.5, max_entries=nodes)  # one landmark: exactly at the limit
    with pytest.raises(ValueError, match="above the limit"):
        make_grid([0.3, -0.2], sigma2=0.5, max_entries=nodes - 1)


def test_a_grid_record_integrates_with_its_weight():
    g = Grid(nodes=np.zeros((3, 1)), weight=0.5, shape=(3,))
    assert g.axes == () and g.integrate(np.array([1.0, 2.0, 3.0])) == pytest.approx(3.0)
