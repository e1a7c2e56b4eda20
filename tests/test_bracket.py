"""Certified distance brackets (shapelib.solver.bracket): lower ≤ d ≤ upper, at the requested width."""

import warnings

import numpy as np
import pytest

import shapelib
from shapelib.solver.bracket import DistanceBracket, distance_bracket, extrapolate_doublings, lower_bound, refine_path
from shapelib.solver.geodesic import GeodesicWarning, geodesic
from shapelib.geometry.procrustes import PoseWarning

METRICS = ["alpha", "fisher_rao"]


def rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


U = np.array([[0.0, 0.0], [1.0, 0.2], [2.0, 0.0], [1.0, -0.8], [0.5, 0.6]])


@pytest.fixture
def pair(rng):
    """A small deformation: the geodesic is within ~5e-4 of the bound, so 1e-3 is reachable."""
    return U, U + 0.06 * rng.normal(size=U.shape)


@pytest.fixture
def far_pair(rng):
    """A large deformation at σ² = 0.5: the geodesic is ~1 % longer than the chord."""
    return U, U @ rot(0.5).T + [0.3, 0.1] + 0.15 * rng.normal(size=U.shape)


@pytest.mark.parametrize("s2", [0.3, 1.0])
def test_lower_bounds_match_single_gaussian_closed_forms(s2):
    """K = 1: ‖N_a − N_b‖² = 2 (G(0) − G(Δ)) with G(Δ) = e^{−|Δ|²/4σ²} / (4πσ²), and the
    Bhattacharyya coefficient of two Gaussians with equal covariance is e^{−|Δ|²/8σ²}."""
    a, b = np.array([[0.0, 0.0]]), np.array([[1.2, -0.5]])
    dd = np.sum((a - b) ** 2)
    g = lambda q: np.exp(-q / (4 * s2)) / (4 * np.pi * s2)
    assert lower_bound(a, b, metric="alpha", sigma2=s2) == pytest.approx(np.sqrt(2 * (g(0) - g(dd))), rel=1e-12)
    assert lower_bound(a, b, metric="fisher_rao", sigma2=s2) == pytest.approx(
        2 * np.arccos(np.exp(-dd / (8 * s2))), rel=1e-6)


@pytest.mark.parametrize("metric, hessian", [("alpha", None), ("fisher_rao", None), ("alpha", "model"),
                                             ("fisher_rao", "exact")])
def test_bracket_is_certified_and_contains_a_converged_fine_geodesic(pair, metric, hessian):
    u, v = pair
    b = distance_bracket(u, v, metric=metric, sigma2=0.5, rtol=1e-3, hessian=hessian)
    assert b.log["hessian"] == (hessian or {"alpha": "exact", "fisher_rao": "model"}[metric])
    assert isinstance(b, DistanceBracket)
    assert b.converged and b.stopped_by == "rtol"
    assert 0 < b.lower <= b.upper and b.rel_gap == pytest.approx(b.upper / b.lower - 1, rel=1e-12)
    assert b.rel_gap <= 1e-3
    assert b.upper ** 2 <= b.energy * (1 + 1e-9)  # Cauchy–Schwarz: the length of the path ≤ √E
    assert b.path.shape == (b.n_steps + 1,) + u.shape
    assert np.array_equal(b.path[0], u) and np.array_equal(b.path[-1], v)
    # the length of that very path, recomputed independently
    grid = {"grid_spacing": b.log["grid_spacing"]} if metric == "fisher_rao" else {}
    assert shapelib.path_length(b.path, metric=metric, sigma2=0.5, **grid) == pytest.approx(b.upper, rel=1e-12)
    fine = geodesic(u, v, metric=metric, sigma2=0.5, n_steps=32, tol=1e-10)
    assert fine.converged
    assert b.lower <= fine.length <= b.upper * (1 + 1e-9)


def test_lower_never_exceeds_upper_even_when_the_gap_cannot_close(far_pair):
    u, v = far_pair
    for s2 in (0.1, 0.3, 2.0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", GeodesicWarning)
            b = distance_bracket(u, v, metric="alpha", sigma2=s2, rtol=1e-9, max_n_steps=32)
        assert b.lower <= b.upper
        assert not b.converged and b.stopped_by in ("stalled", "max_n_steps") and b.rel_gap > 1e-9
        gaps = [lv["rel_gap"] for lv in b.log["levels"]]
        assert all(g2 <= g1 * (1 + 1e-9) for g1, g2 in zip(gaps, gaps[1:]))  # refining never widens it
        assert b.n_iter == sum(lv["n_iter"] for lv in b.log["levels"])


def test_a_geodesic_longer_than_the_bound_stops_stalled_near_its_true_gap(far_pair):
    u, v = far_pair
    with pytest.warns(GeodesicWarning, match="stalled"):
        b = distance_bracket(u, v, metric="alpha", sigma2=0.5)
    fine = geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=32, tol=1e-10)
    assert b.stopped_by == "stalled" and not b.converged
    assert b.lower <= fine.length <= b.upper  # still a certified bracket
    assert b.rel_gap <= 1.5 * (fine.length / b.lower - 1)  # and close to the best one


def test_stalled_gap_is_reported_and_warned():
    """Relabelled landmarks: the densities coincide (lower bound 0) but the landmarks must move,
    so no refinement can close the gap; it is reported, not hidden."""
    u = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, 1.5]])
    v = u[[1, 0, 2]]
    with pytest.warns(GeodesicWarning, match="stopped \\(stalled\\).*certified only to lie in"):
        b = distance_bracket(u, v, metric="alpha", sigma2=0.5)
    assert b.lower == pytest.approx(0.0, abs=1e-12) and b.upper > 0.1
    assert b.rel_gap == np.inf and not b.converged and b.stopped_by == "stalled"
    with warnings.catch_warnings():
        warnings.simplefilter("error", GeodesicWarning)  # (a relabelling is not a pose: PoseWarning aside)
        warnings.simplefilter("ignore", PoseWarning)
        distance_bracket(u, v, metric="alpha", sigma2=0.5, warn=False)


def test_max_n_steps_stops_refinement(pair):
    u, v = pair
    with pytest.warns(GeodesicWarning, match="max_n_steps"):
        b = distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=1e-9, n_steps=4, max_n_steps=4)
    assert b.stopped_by == "max_n_steps" and b.n_steps == 4 and not b.converged


@pytest.mark.parametrize("metric", METRICS)
def test_symmetry_and_rigid_invariance(pair, metric):
    u, v = pair
    b = distance_bracket(u, v, metric=metric, sigma2=0.5)
    back = distance_bracket(v, u, metric=metric, sigma2=0.5)
    r = rot(2.1)
    moved = distance_bracket(u @ r.T + [4.0, -2.5], v @ r.T + [4.0, -2.5], metric=metric, sigma2=0.5)
    # the bound is exactly symmetric and invariant (α: closed form; FR: quadrature, ~1e-7)
    tol = 1e-12 if metric == "alpha" else 1e-6
    assert back.lower == pytest.approx(b.lower, rel=tol) and moved.lower == pytest.approx(b.lower, rel=tol)
    for other in (back, moved):  # certified intervals of the same number must overlap
        assert other.converged
        assert other.lower <= b.upper * (1 + tol) and b.lower <= other.upper * (1 + tol)


def test_identical_shapes_are_trivial(pair):
    u, _ = pair
    b = distance_bracket(u, u.copy(), metric="fisher_rao", sigma2=0.5)
    assert (b.lower, b.upper, b.rel_gap, b.energy, b.n_iter) == (0.0, 0.0, 0.0, 0.0, 0)
    assert b.converged and b.stopped_by == "trivial"
    assert "trivial" in b.summary()


def test_straight_line_good_enough_costs_no_iteration(pair):
    u, v = pair
    b = distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=10.0)
    assert b.converged and b.n_iter == 0 and b.log["levels"][0]["stopped_by"] == "target_energy"


@pytest.mark.parametrize("kwargs, match", [
    ({"metric": "euclid"}, "metric must be"),
    ({"rtol": 0.0}, "rtol"),
    ({"n_steps": 0}, "n_steps"),
    ({"n_steps": 16, "max_n_steps": 8}, "max_n_steps must be >= n_steps"),
    ({"level_iter": 1.5}, "level_iter"),
    ({"min_shrink": 1.0}, "min_shrink"),
    ({"hessian": "newton"}, "hessian must be"),
    ({"sigma2": -1.0}, "sigma2"),
])
def test_errors(pair, kwargs, match):
    u, v = pair
    args = {"metric": "alpha", "sigma2": 0.5} | kwargs
    with pytest.raises(ValueError, match=match):
        distance_bracket(u, v, **args)
    if set(kwargs) <= {"metric", "sigma2"}:
        with pytest.raises(ValueError, match=match):
            lower_bound(u, v, **args)


def test_refine_path_keeps_the_curve_and_its_length(far_pair):
    u, v = far_pair
    path = geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=4).path
    fine = refine_path(path)
    assert fine.shape == (9,) + u.shape and np.array_equal(fine[::2], path)
    assert shapelib.path_length(fine, metric="alpha", sigma2=0.5) == pytest.approx(
        shapelib.path_length(path, metric="alpha", sigma2=0.5), rel=1e-9)
    with pytest.raises(ValueError, match="path must have shape"):
        refine_path(path[0])


def test_exported():
    assert shapelib.distance_bracket is distance_bracket


def test_fisher_rao_bracket_grid_follows_rtol_and_stays_accurate(pair):
    from shapelib.solver.bracket import BRACKET_SPACING
    from shapelib.geometry.quadrature import DEFAULT_SPACING

    u, v = pair
    coarse = distance_bracket(u, v, metric="fisher_rao", sigma2=0.5, rtol=1e-3)
    assert coarse.log["grid_spacing"] == BRACKET_SPACING
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GeodesicWarning)
        tight = distance_bracket(u, v, metric="fisher_rao", sigma2=0.5, rtol=1e-6, max_n_steps=8)
    assert tight.log["grid_spacing"] == DEFAULT_SPACING
    given = distance_bracket(u, v, metric="fisher_rao", sigma2=0.5, rtol=1e-3, grid_spacing=0.25)
    assert given.log["grid_spacing"] == 0.25
    # the coarse grid's quadrature error is far inside rtol: bound and length as on a 0.25σ grid
    assert coarse.lower == pytest.approx(given.lower, rel=1e-6)
    assert shapelib.path_length(coarse.path, metric="fisher_rao", sigma2=0.5, grid_spacing=0.25) == pytest.approx(
        coarse.upper, rel=1e-6)


@pytest.mark.parametrize("p", [0.7, 1.1, 2.0])
def test_extrapolate_doublings_is_exact_for_power_laws(p):
    """g(n) = g∞ + C n^−p at n, 2n, 4n: the fitted-order Richardson (= Aitken Δ²) limit is g∞."""
    n = np.array([4.0, 8.0, 16.0, 32.0])
    gaps = 2e-3 + 0.05 * n**-p
    limit, order = extrapolate_doublings(list(gaps))
    assert limit == pytest.approx(2e-3, rel=1e-10) and order == pytest.approx(p, rel=1e-10)
    for bad in ([1e-3, 5e-4], [3e-3, 2e-3, 1.5e-3 + 1e-3], [3e-3, 2e-3, 1e-3], [1e-3, np.nan, 5e-4, 2e-4],
                [3e-3, 3e-3, 3e-3]):
        assert extrapolate_doublings(bad) == (None, None)  # too few, rising, not shrinking geometrically, NaN, flat
