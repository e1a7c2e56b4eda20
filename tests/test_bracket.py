"""Certified distance brackets (shapelib.solver.bracket): lower ≤ d ≤ upper, at the requested width."""

import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import shapelib
from shapelib.solver import bracket as bracket_module
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
    ({"device": "gpu"}, 'device="gpu" needs backend="jax"'),
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


def test_extrapolation_needs_the_last_three_finite_strictly_shrinking_gaps():
    """Aitken's limit of g(n) = 0.01 + n⁻² (n = 1, 2, 4) is 0.01 with order 2, from exactly three gaps
    or the last three of more; an infinite earlier gap is not among them, an infinite one among them
    gives nothing, and so does a last difference of 0 (no geometric convergence to fit)."""
    for gaps in ([1.01, 0.26, 0.0725], [np.inf, 1.01, 0.26, 0.0725]):
        limit, order = extrapolate_doublings(gaps)
        assert limit == pytest.approx(0.01, rel=1e-12, abs=0) and order == pytest.approx(2.0, rel=1e-12)
    assert extrapolate_doublings([np.inf, 0.26, 0.0725]) == (None, None)
    assert extrapolate_doublings([0.26, 0.0725]) == (None, None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert extrapolate_doublings([1.0, 0.5, 0.5]) == (None, None)


def test_refine_path_of_two_points_and_integer_input():
    """The straight segment from 0 to 2 in one step: its midpoint is added (1, not a rounded 0 or 2)."""
    fine = refine_path(np.array([[[0, 0]], [[2, 0]]]))
    np.testing.assert_array_equal(fine[:, 0, 0], [0.0, 1.0, 2.0])
    fine = refine_path(np.array([[[0, 0]], [[1, 0]]]))
    np.testing.assert_array_equal(fine[:, 0, 0], [0.0, 0.5, 1.0])
    with pytest.raises(ValueError, match=r"^path must have shape \(n \+ 1, K, d\) with n >= 1"):
        refine_path(np.zeros((1, 3, 2)))


def test_level_options_defaults_and_names():
    """level_tol defaults to rtol / 10 and is used as given otherwise; min_shrink 0 is allowed; the
    coarse Fisher-Rao grid from rtol = BRACKET_SPACING_RTOL on; each bad option is named."""
    from shapelib.geometry.quadrature import DEFAULT_SPACING
    from shapelib.solver.bracket import BRACKET_SPACING, BRACKET_SPACING_RTOL, _check_levels

    ok = dict(rtol=1e-3, n_steps=8, max_n_steps=64, level_iter=5, level_tol=None, min_shrink=0.0, grid_spacing=None)
    assert _check_levels(**ok) == (1e-3, 8, 64, 5, pytest.approx(1e-4), 0.0, BRACKET_SPACING)
    assert _check_levels(**{**ok, "level_tol": 0.5})[4] == 0.5
    assert _check_levels(**{**ok, "rtol": BRACKET_SPACING_RTOL})[6] == BRACKET_SPACING
    assert _check_levels(**{**ok, "rtol": BRACKET_SPACING_RTOL / 2})[6] == DEFAULT_SPACING
    for bad in ("rtol", "n_steps", "max_n_steps", "level_iter", "level_tol"):
        with pytest.raises(ValueError, match=rf"^{bad}\b"):
            _check_levels(**{**ok, bad: -1})


def test_level_stop_reasons():
    """After a level: within rtol; stalled when the gap shrank by less than min_shrink; stalled when
    the gaps extrapolate above rtol; max_n_steps when doubling would pass it; else go on."""
    from shapelib.solver.bracket import _level_stop

    def levels(*pairs):
        return [{"rel_gap": g, "n_steps": n} for g, n in pairs]

    kw = dict(rtol=1e-3, min_shrink=0.1, max_n=32)
    assert _level_stop(levels((0.1, 8), (0.095, 16)), 0.1, **kw) == "stalled"  # 0.095 ≥ 0.9 · 0.1
    assert _level_stop(levels((0.1, 8), (0.05, 16)), 0.1, **kw) is None  # halved, 2 · 16 = 32 allowed
    assert _level_stop(levels((0.1, 16), (0.05, 32)), 0.1, **kw) == "max_n_steps"
    assert _level_stop(levels((1.01, 2), (0.26, 4), (0.0725, 8)), 0.26, **kw) == "stalled"  # limit 0.01
    assert _level_stop(levels((1.01, 2), (0.26, 4), (0.0725, 8)), 0.26, **{**kw, "rtol": 0.02}) is None
    assert _level_stop(levels((1e-3, 8)), None, **kw) == "rtol"


def test_lower_bound_passes_its_grid_on(rng):
    """The Fisher-Rao bound on a coarse grid is fisher_rao_lower_bound on that grid, not the default."""
    u = rng.normal(size=(6, 2))
    v = u + 0.3 * rng.normal(size=u.shape)
    coarse = lower_bound(u, v, metric="fisher_rao", sigma2=0.5, grid_spacing=0.9, grid_margin=3.0)
    want = shapelib.fisher_rao_lower_bound(u, v, sigma2=0.5, grid_spacing=0.9, grid_margin=3.0)
    assert coarse == want
    assert coarse != lower_bound(u, v, metric="fisher_rao", sigma2=0.5)
    assert coarse != lower_bound(u, v, metric="fisher_rao", sigma2=0.5, grid_spacing=0.9)


# --- what a bracket reports, and how its levels are solved (each a property another computation checks)

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions
#: go through a trampoline, more stack frames between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(bracket_module))


def _one_warning(record, category):
    caught = [w for w in record if issubclass(w.category, category)]
    assert len(caught) == 1 and "shapelib" not in Path(caught[0].filename).parts  # not inside the library
    if not UNDER_MUTMUT:  # the caller's line (mutmut's trampoline adds frames of its own)
        assert caught[0].filename == __file__
    return str(caught[0].message)


def test_the_warning_says_why_it_stopped_and_where_the_distance_lies(pair, far_pair):
    """max_n_steps: the level, the iterations and the interval, and the remedy; stalled: why the gap
    stays open; σ far below the landmark spacing: that, and the remedy for it."""
    u, v = pair
    with pytest.warns(GeodesicWarning) as record:
        b = distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=1e-9, n_steps=4, max_n_steps=4)
    text = _one_warning(record, GeodesicWarning)
    assert b.n_iter > 0 and text.startswith(f"alpha distance bracket stopped (max_n_steps) at relative gap "
                                            f"{b.rel_gap:.2e} > rtol 1.0e-09 (n_steps 4, {b.n_iter} iterations)")
    assert f"[{b.lower:.6g}, {b.upper:.6g}]; raise max_n_steps to refine further" in text
    u, v = far_pair
    with pytest.warns(GeodesicWarning) as record:
        b = distance_bracket(u, v, metric="fisher_rao", sigma2=0.5)
    text = _one_warning(record, GeodesicWarning)
    assert text.startswith("fisher_rao distance bracket stopped (stalled)") and text.endswith(
        "; the gap no longer shrinks with n_steps, so the geodesic is itself longer than the closed-form bound "
        "(typical at small sigma2)")
    u, v = pair
    with pytest.warns(GeodesicWarning) as record:  # σ = 0.04 landmark spacings (and ScaleWarning)
        b = distance_bracket(20 * u, 20 * shapelib.procrustes_align(u, v, scaling=False), metric="alpha", sigma2=0.5)
    text = _one_warning(record, GeodesicWarning)
    assert _one_warning(record, shapelib.ScaleWarning).startswith("sigma = 0.707 (sigma2 = 0.5) is ")
    assert b.stopped_by == "stalled" and "the gap no longer shrinks" not in text
    assert f"sigma is {b.log['sigma_ratio']:.3g} landmark spacings" in text and "(shapelib.to_centroid_size)" in text
    assert b.log["sigma_ratio"] == pytest.approx(shapelib.sigma_ratio(np.stack([b.path[0], b.path[-1]]), sigma2=0.5))


def test_identical_shapes_give_a_standing_path_with_the_options(pair):
    u, _ = pair
    t0 = time.perf_counter()
    b = distance_bracket(u, u.copy(), metric="alpha", sigma2=0.3, n_steps=5, rtol=1e-2)
    wall = time.perf_counter() - t0
    assert b.path.shape == (6,) + u.shape and np.array_equal(b.path, np.broadcast_to(u, b.path.shape))
    assert (b.metric, b.sigma2, b.n_steps) == ("alpha", 0.3, 5)
    assert b.log["levels"] == [] and b.log["rtol"] == 1e-2 and b.log["n_steps"] == 5
    assert 0.0 <= b.seconds <= wall


def test_the_log_holds_the_options_and_every_level(pair):
    """The options as given (level_tol too); the levels double n_steps from n_steps, each with at most
    level_iter iterations, the last one's upper end and n_steps the bracket's; the levels' times add
    up to at most the bracket's, which is at most the wall-clock time around the call."""
    u, v = pair
    v = shapelib.procrustes_align(u, v, scaling=False)
    t0 = time.perf_counter()
    b = distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=1e-9, n_steps=2, max_n_steps=8, level_iter=2,
                         level_tol=1e-12, min_shrink=0.01, warn=False)
    wall = time.perf_counter() - t0
    assert (b.metric, b.sigma2) == ("alpha", 0.5)
    log = b.log
    assert (log["rtol"], log["n_steps"], log["max_n_steps"], log["level_iter"], log["level_tol"], log["min_shrink"],
            log["hessian"]) == (1e-9, 2, 8, 2, 1e-12, 0.01, "exact")
    assert log["sigma_ratio"] == pytest.approx(shapelib.sigma_ratio(np.stack([u, v]), sigma2=0.5), rel=1e-12)
    levels = log["levels"]
    assert [lv["n_steps"] for lv in levels] == [2, 4, 8][:len(levels)] and levels[-1]["n_steps"] == b.n_steps
    assert levels[-1]["upper"] == b.upper and levels[-1]["rel_gap"] == b.rel_gap
    assert all(lv["n_iter"] <= 2 for lv in levels) and b.n_iter == sum(lv["n_iter"] for lv in levels)
    assert 0.0 <= sum(lv["seconds"] for lv in levels) <= b.seconds <= wall


def test_a_level_stops_as_soon_as_the_energy_certifies_rtol(pair):
    """√E ≤ lower · (1 + rtol) ends the level (length ≤ √E): the last level stopped on that target."""
    u, v = pair
    for metric in METRICS:
        b = distance_bracket(u, v, metric=metric, sigma2=0.5, rtol=1e-3)
        assert b.log["levels"][-1]["stopped_by"] == "target_energy"
        assert b.lower <= b.upper <= np.sqrt(b.energy) <= b.lower * (1 + 1e-3) * (1 + 1e-12)


def test_each_level_is_the_geodesic_solver_warm_started_from_the_last(far_pair):
    """Level 1 is geodesic() at n_steps with level_iter iterations, level_tol, a 2-iteration window and
    the Hessian asked for; level 2 is geodesic() at 2·n_steps started from level 1's path refined."""
    u, v = far_pair
    v = shapelib.procrustes_align(u, v, scaling=False)
    kw = dict(metric="fisher_rao", sigma2=0.5, rtol=1e-9, level_iter=6, level_tol=1e-3, hessian="model",
              min_shrink=0.0, warn=False)
    one = distance_bracket(u, v, n_steps=4, max_n_steps=4, **kw)
    two = distance_bracket(u, v, n_steps=4, max_n_steps=8, **kw)
    solver = dict(metric="fisher_rao", sigma2=0.5, max_iter=6, tol=1e-3, window=2, hessian="model",
                  grid_spacing=one.log["grid_spacing"], warn=False)
    first = geodesic(u, v, n_steps=4, **solver)
    np.testing.assert_allclose(one.path, first.path, rtol=0, atol=1e-12)
    assert one.upper == pytest.approx(first.length, rel=1e-12) and one.n_iter == first.n_iter
    assert one.log["levels"][0]["stopped_by"] == "energy_window" and one.n_iter < 6  # the window ended it
    second = geodesic(u, v, n_steps=8, init=refine_path(one.path), **solver)
    assert [lv["n_steps"] for lv in two.log["levels"]] == [4, 8]
    np.testing.assert_allclose(two.path, second.path, rtol=0, atol=1e-12)
    assert two.upper == pytest.approx(second.length, rel=1e-12)


def test_default_refinement_options(pair, far_pair):
    """max_n_steps 64 by default (n_steps 65 must raise it); at most 3 iterations a level by default,
    and a pair that needs them uses 3."""
    u, v = pair
    with pytest.raises(ValueError, match="max_n_steps must be >= n_steps"):
        distance_bracket(u, v, metric="alpha", sigma2=0.5, n_steps=65)
    assert distance_bracket(u, v, metric="alpha", sigma2=0.5, n_steps=64, rtol=10.0).n_steps == 64
    u, v = far_pair
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GeodesicWarning)
        b = distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=1e-9, n_steps=2, max_n_steps=8, min_shrink=0.0)
    assert max(lv["n_iter"] for lv in b.log["levels"]) == 3


def test_the_fisher_rao_grid_margin_reaches_the_bound(pair):
    from shapelib.solver.bracket import BRACKET_SPACING

    u, v = pair
    v = shapelib.procrustes_align(u, v, scaling=False)
    b = distance_bracket(u, v, metric="fisher_rao", sigma2=0.5, rtol=10.0, grid_margin=2.5)
    assert b.lower == shapelib.fisher_rao_lower_bound(u, v, sigma2=0.5, grid_spacing=BRACKET_SPACING, grid_margin=2.5)
    assert b.lower != shapelib.fisher_rao_lower_bound(u, v, sigma2=0.5, grid_spacing=BRACKET_SPACING)


def test_cpu_batch_is_the_single_bracket_of_each_pair_with_the_same_options(pair, far_pair):
    """distance_brackets(backend="cpu") passes every option on to distance_bracket, pair by pair, in order."""
    (u, v), (_, w) = pair, far_pair
    v, w = (shapelib.procrustes_align(u, x, scaling=False) for x in (v, w))
    kw = dict(metric="fisher_rao", sigma2=0.4, rtol=1e-2, n_steps=4, max_n_steps=8, level_iter=2, level_tol=1e-4,
              min_shrink=0.1, grid_spacing=0.45, grid_margin=4.0, hessian="exact")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GeodesicWarning)
        got = shapelib.distance_brackets(np.stack([u, w, u]), np.stack([v, u, u]), backend="cpu", **kw)
        want = [distance_bracket(a, c, **kw) for a, c in ((u, v), (w, u), (u, u))]
    assert len(got) == 3 and got[2].stopped_by == "trivial"
    for g, x in zip(got, want):
        assert (g.lower, g.upper, g.n_steps, g.n_iter, g.stopped_by) == (x.lower, x.upper, x.n_steps, x.n_iter,
                                                                         x.stopped_by)
        np.testing.assert_array_equal(g.path, x.path)
        assert {k: g.log[k] for k in g.log if k != "levels"} == {k: x.log[k] for k in x.log if k != "levels"}
    # the defaults are distance_bracket's
    b, one = shapelib.distance_brackets(u[None], v[None], metric="alpha", sigma2=0.5, backend="cpu")[0], \
        distance_bracket(u, v, metric="alpha", sigma2=0.5)
    assert {k: b.log[k] for k in b.log if k != "levels"} == {k: one.log[k] for k in one.log if k != "levels"}
    assert (b.log["rtol"], b.log["n_steps"], b.log["max_n_steps"], b.log["level_iter"]) == (1e-3, 8, 64, 3)
    with pytest.warns(GeodesicWarning, match="max_n_steps"):  # warn=True by default, for each pair
        shapelib.distance_brackets(u[None], v[None], metric="alpha", sigma2=0.5, rtol=1e-9, n_steps=2,
                                   max_n_steps=2, backend="cpu")


def test_a_cpu_batch_with_warn_false_is_silent(pair):
    u, v = pair
    v = shapelib.procrustes_align(u, v, scaling=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GeodesicWarning)
        b = shapelib.distance_brackets(u[None], v[None], metric="alpha", sigma2=0.5, rtol=1e-9, n_steps=2,
                                       max_n_steps=2, backend="cpu", warn=False)[0]
    assert b.stopped_by == "max_n_steps" and not b.converged
