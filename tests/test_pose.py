"""The pose search of ``shapelib.pointsets.align``, number by number: what it returns is checked
against the public density functions (the bound and the normalised objective at the pose, the
coarse σ² the candidates were refined at), finite differences (each returned pose is a stationary
point of its objective), a brute-force grid, exact recoveries, the documented start sets, and the
argument checks. The exact-copy tests of tests/test_pointsets.py cannot see the σ² schedule (an
exact copy is the optimum at every σ²); the targets here are noisy or partial."""

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize, rosen, rosen_der
from scipy.spatial.transform import Rotation

import shapelib as sl
from shapelib.pointsets import PoseSearchWarning, align, density_distance, density_inner, hellinger_sq
from shapelib.pointsets import pose as pose_module
from shapelib.pointsets.pose import COARSE_SIGMA2, _choose, _starts, _stop

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions
#: go through a trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(pose_module))


def pear(n=40):
    """An outline with no rotational symmetry (a mirror symmetry about the x-axis only)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([2 * np.cos(t) + 0.5 * np.cos(2 * t), np.sin(t)])


def rot2(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def noisy_target():
    """Every second point of the pear, rotated, scaled by 1.3, moved and jittered: no pose matches it
    exactly, so the optimum moves with σ² and the source and target centroids do not correspond."""
    rng = np.random.default_rng(0)
    return (pear() @ rot2(0.5).T * 1.3 + [2.0, 1.0])[::2] + 0.03 * rng.normal(size=(20, 2))


def rms_radius(y):
    return np.sqrt(np.mean(np.sum((y - y.mean(axis=0)) ** 2, axis=1)))


def sigma2_levels(y, sigma2):
    """The σ² schedule as documented: σ² multiplied by 4 until it reaches COARSE_SIGMA2 times the
    target's squared RMS radius; the first is the coarsest."""
    levels = [sigma2]
    while levels[0] < COARSE_SIGMA2 * rms_radius(y) ** 2:
        levels.insert(0, 4 * levels[0])
    return levels


def objective(z, y, s2):
    """The α objective ‖p_z − p_y‖² / ‖p_y‖², from the public density functions."""
    return density_distance(z, y, sigma2=s2) ** 2 / density_inner(y, y, sigma2=s2)


def moved(z, p):
    """z rotated by p[0] (and, with 4 parameters, scaled by e^{p[3]}) about its centroid, then shifted by p[1:3]."""
    c = z.mean(axis=0)
    s = np.exp(p[3]) if len(p) > 3 else 1.0
    return s * (z - c) @ rot2(p[0]).T + c + p[1:3]


def fd_gradient(f, n, h=1e-5):
    """Central differences of f at 0 in n parameters."""
    g = []
    for k in range(n):
        e = np.zeros(n)
        e[k] = h
        g.append((f(e) - f(-e)) / (2 * h))
    return np.array(g)


# ---------------------------------------------------------------------------------------------
# argument checks
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("bad, message", [
    (dict(source=np.zeros(3)), r"^source must be a 2-D array"),
    (dict(target=np.zeros(3)), r"^target must be a 2-D array"),
    (dict(metric="l2"), r"^metric must be one of \('alpha', 'fisher_rao'\); got 'l2'$"),
    (dict(n_angles=0), r"^n_angles must be a positive integer; got 0$"),
    (dict(n_starts=0), r"^n_starts must be a positive integer; got 0$"),
    (dict(n_starts=1.5), r"^n_starts must be a positive integer; got 1.5$"),
    (dict(max_iter=0), r"^max_iter must be a positive integer; got 0$"),
])
def test_align_names_the_argument_at_fault(bad, message):
    args = dict(source=pear(), target=pear(), sigma2=0.1) | bad
    with pytest.raises(ValueError, match=message):
        align(**args)


# ---------------------------------------------------------------------------------------------
# what align returns, against the public density functions
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("transform", ["rigid", "similarity", "affine"])
def test_value_objective_and_candidates_are_the_density_quantities_at_their_poses(transform):
    """value = ‖p_{Ax+t} − p_y‖ and objective = value² / ‖p_y‖² at the requested σ²; each candidate
    (objective, A, t) is that objective at the coarsest σ² of the documented schedule, best first;
    the pose moves points by x ↦ A x + t and says what was asked."""
    x, y, s2 = pear() + [5.0, -3.0], noisy_target(), 0.002  # a source away from the origin
    levels = sigma2_levels(y, s2)
    assert len(levels) == 5  # the schedule is exercised: 0.002·4⁴ ≥ 0.1·r² > 0.002·4³
    pose = align(x, y, sigma2=s2, transform=transform)
    assert np.allclose(pose.points, x @ pose.matrix.T + pose.translation, rtol=0, atol=1e-12)
    assert np.allclose(pose([list(p) for p in x]), pose.points, rtol=0, atol=1e-12)
    assert pose.value == pytest.approx(density_distance(pose.points, y, sigma2=s2), rel=1e-10)
    assert pose.objective == pytest.approx(objective(pose.points, y, s2), rel=1e-10)
    assert (pose.transform, pose.metric, pose.sigma2) == (transform, "alpha", s2)
    assert pose.converged and pose.stop_reason in ("gradient", "objective_change", "no_decrease")
    assert 1 <= pose.n_starts == len(pose.candidates) <= 6 and pose.n_iter >= pose.n_starts
    fvals = [c[0] for c in pose.candidates]
    assert fvals == sorted(fvals)
    for fval, a, t in pose.candidates:
        assert fval == pytest.approx(objective(x @ a.T + t, y, levels[0]), rel=1e-10)


def test_value_in_three_dimensions_scales_with_the_size_of_the_points():
    """‖p‖² of a mixture scales as size^{−d}: the bound of a 3-D pose at σ² is the density distance
    computed directly, for a target far from unit size."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(30, 3)) * [3.0, 2.0, 1.0]
    r = Rotation.random(random_state=2).as_matrix()
    y = 7.0 * ((x @ r.T)[::2] + 0.1 * rng.normal(size=(15, 3)))
    s2 = 0.5
    pose = align(x, y, sigma2=s2, transform="similarity")
    assert pose.value == pytest.approx(density_distance(pose.points, y, sigma2=s2), rel=1e-9)
    assert pose.objective == pytest.approx(objective(pose.points, y, s2), rel=1e-9)
    assert pose.angle is None and pose.scale == pytest.approx(7.0, rel=0.02)


def test_a_pose_is_a_stationary_point_of_its_objective_and_the_best_on_a_grid_around_it():
    """Central differences of the α objective (public density functions) over rotation, shift and
    scale vanish at the returned pose (at the requested σ²) and at each candidate (at the coarsest
    σ²); no pose on a grid around the returned one does better."""
    x, y, s2 = pear(), noisy_target(), 0.002
    coarse = sigma2_levels(y, s2)[0]
    for transform, n in (("rigid", 3), ("similarity", 4)):
        pose = align(x, y, sigma2=s2, transform=transform)
        g = fd_gradient(lambda p: objective(moved(pose.points, p), y, s2), n)
        assert np.abs(g).max() < 1e-6, (transform, g)
        for _, a, t in pose.candidates:
            z = x @ a.T + t
            g = fd_gradient(lambda p: objective(moved(z, p), y, coarse), n)
            assert np.abs(g).max() < 1e-7, (transform, g)
    steps = np.linspace(-0.004, 0.004, 5)
    grid = [objective(moved(pose.points, np.array([a, u, v, s])), y, s2)
            for a in steps for u in steps for v in steps for s in steps]
    assert min(grid) >= pose.objective - 1e-12


def test_a_requested_sigma2_at_or_above_the_coarsest_is_searched_at_that_sigma2_alone():
    """σ² ≥ 0.1 r²: one level, so the winner is the best candidate and its objective is at σ²."""
    x, y = pear(), noisy_target()
    s2 = 0.2 * rms_radius(y) ** 2
    pose = align(x, y, sigma2=s2)
    fval, a, t = pose.candidates[0]
    assert pose.objective == pytest.approx(fval, rel=1e-12) and np.allclose(pose.matrix, a, atol=1e-12)
    assert fval == pytest.approx(objective(x @ a.T + t, y, s2), rel=1e-10)


def test_one_iteration_per_level_counts_one_iteration_per_level():
    """max_iter = 1 and one start: one L-BFGS iteration at each σ² of the documented schedule, no
    convergence (stop reason max_iter), and nothing else refined."""
    x, y, s2 = pear(), noisy_target(), 0.002
    for transform in ("rigid", "similarity", "affine"):
        pose = align(x, y, sigma2=s2, transform=transform, n_starts=1, max_iter=1, warn=False)
        assert pose.n_iter == len(sigma2_levels(y, s2)) == 5
        assert (pose.n_starts, len(pose.candidates), pose.converged, pose.stop_reason) == (1, 1, False, "max_iter")


def test_one_iteration_per_refinement_with_two_starts():
    """Two starts refined with one iteration each at the coarsest σ², then one or both followed with
    one iteration at each of the four finer levels."""
    x, y, s2 = pear(), noisy_target(), 0.002
    pose = align(x, y, sigma2=s2, n_starts=2, max_iter=1, warn=False)
    assert pose.n_starts == 2 and pose.n_iter in (2 + 4, 2 + 2 * 4)


def test_the_schedule_stops_at_the_coarsest_sigma2_itself():
    """A target of RMS radius exactly 1 and σ² = 0.1 / 16: the levels are 0.1, 0.025 and σ² exactly
    (4 × σ² twice is 0.1 in floating point too), three L-BFGS iterations with max_iter = 1, and the
    candidates are refined at σ² = 0.1."""
    y = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [0.0, 0.0]]) * np.sqrt(5 / 4)
    y = y - y.mean(axis=0)
    assert rms_radius(y) == 1.0
    s2 = 0.1 / 16
    assert 16 * s2 == 0.1 and sigma2_levels(y, s2) == [0.1, 0.025, s2]
    x = np.array([[1.0, 0.1], [0.0, 1.2], [-1.1, 0.0], [0.2, -1.0], [0.1, 0.1]])
    pose = align(x, y, sigma2=s2, n_starts=1, max_iter=1, warn=False)
    assert pose.n_iter == 3
    fval, a, t = pose.candidates[0]
    assert fval == pytest.approx(objective(x @ a.T + t, y, 0.1), rel=1e-10)


def test_at_most_max_iter_iterations_per_refinement():
    x, y, s2 = pear(), noisy_target(), 0.002
    pose = align(x, y, sigma2=s2, max_iter=2, warn=False)
    assert pose.n_iter <= 2 * pose.n_starts * len(sigma2_levels(y, s2))


def test_fisher_rao_value_and_objective_use_the_grid_given():
    """4 arcsin(H/2) and H² of hellinger_sq on the grid asked for (not the default grid): agreement up
    to where the grid nodes fall (they are multiples of the step, which the search takes in its own
    units), much closer than to the same quantities on a grid with the default step or margin."""
    x, y, s2 = pear()[::3], noisy_target(), 0.05
    grid = dict(grid_spacing=0.9, grid_margin=2.5)
    pose = align(x, y, sigma2=s2, metric="fisher_rao", **grid)
    assert pose.metric == "fisher_rao"
    h2 = hellinger_sq(pose.points, y, sigma2=s2, **grid)
    assert pose.value == pytest.approx(4 * np.arcsin(np.sqrt(h2) / 2), abs=6e-5)
    assert pose.objective == pytest.approx(h2, abs=6e-5)
    for other in (dict(grid_spacing=0.9), dict(grid_margin=2.5)):
        assert abs(density_distance(pose.points, y, sigma2=s2, metric="fisher_rao", **other) - pose.value) > 1.2e-4


# ---------------------------------------------------------------------------------------------
# recovery of known poses
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("transform", ["similarity", "affine"])
@pytest.mark.parametrize("scale", [30.0, 1 / 30])
def test_a_scale_far_from_one_is_recovered_from_a_source_far_from_the_origin(transform, scale):
    x = pear() + [50.0, -20.0]
    y = scale * x @ rot2(2.0).T + [1.0, 2.0]
    pose = align(x, y[::-1], sigma2=0.01 * scale ** 2, transform=transform)
    assert np.abs(pose.points - y).max() < 1e-6 * scale
    assert pose.scale == pytest.approx(scale, rel=1e-7)
    assert np.allclose(pose.translation, y.mean(axis=0) - pose.matrix @ x.mean(axis=0), atol=1e-6 * scale)


@pytest.mark.parametrize("transform", ["similarity", "affine"])
def test_a_source_much_smaller_than_one_is_scaled_up_from_the_start(transform):
    """A source of RMS radius 0.015 and a target 50 times larger: the search starts every start at
    the ratio of the two radii, and recovers the pose exactly."""
    x = 0.01 * pear() + [0.5, 0.2]
    y = 50.0 * x @ rot2(2.0).T + [1.0, 2.0]
    pose = align(x, y[::-1], sigma2=0.01 * 50 ** 2 * 1e-4, transform=transform)
    assert np.abs(pose.points - y).max() < 1e-6 and pose.scale == pytest.approx(50.0, rel=1e-7)


def test_the_pose_of_a_permuted_source_or_target_is_the_same():
    x, y = pear(), noisy_target()
    rng = np.random.default_rng(1)
    pose = align(x, y, sigma2=0.002)
    for xs, ys in ((x[rng.permutation(40)], y), (x, y[rng.permutation(20)])):
        other = align(xs, ys, sigma2=0.002)
        assert np.allclose(other.matrix, pose.matrix, atol=1e-6) and np.allclose(other.translation, pose.translation,
                                                                                  atol=1e-6)
        assert other.value == pytest.approx(pose.value, rel=1e-9)


def test_the_defaults_are_the_documented_ones():
    """Every 10° (36 angles), six starts refined, 200 iterations, a warning when not converged: the
    defaults give exactly what the explicit values give."""
    x, y = pear(), noisy_target()
    default = align(x, y, sigma2=0.002)
    explicit = align(x, y, sigma2=0.002, n_angles=36, n_starts=6, max_iter=200, warn=True)
    assert default.n_iter == explicit.n_iter and default.objective == explicit.objective
    assert [c[0] for c in default.candidates] == [c[0] for c in explicit.candidates]


def test_six_starts_are_refined_by_default_when_there_are_more_local_minima():
    """A star with nine arms has nine equally good orientations 40° apart: nine local minima of the
    start scores over the 36 angles, of which six are refined (n_starts), all reaching the same bound."""
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    x = np.column_stack([np.cos(t), np.sin(t)]) * (1 + 0.4 * np.cos(9 * t))[:, None]
    y = x @ rot2(0.1).T
    pose = align(x, y, sigma2=0.01)
    assert pose.n_starts == 6 and len(pose.candidates) == 6
    assert align(x, y, sigma2=0.01, n_starts=9).n_starts == 9
    assert align(x, y, sigma2=0.01, n_starts=20).n_starts == 9
    # any of the nine orientations fits (the points then land on others of the target's)
    assert pose.value < 1e-6 * density_distance(x, y, sigma2=0.01)


# ---------------------------------------------------------------------------------------------
# which refined starts are followed down to σ², and which wins
# ---------------------------------------------------------------------------------------------


def test_a_start_much_worse_at_the_coarsest_sigma2_is_dropped_even_if_it_would_win_at_sigma2():
    """Module docstring, step 4: only starts within SELECT_RTOL (5 %) of the best at the coarsest σ²
    are followed. The target is a jittered egg plus six of its points turned by 180°: the turned
    pose matches those six exactly, so at the small σ² it beats the right one (checked here with the
    public density functions), but at the coarsest σ² it is more than 5 % (and less than 0.05) worse,
    so the right pose is returned."""
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    x = np.column_stack([2 * np.cos(t) + 0.1 * np.cos(2 * t), np.sin(t)])
    rng = np.random.default_rng(0)
    y = np.vstack([x + 0.08 * rng.normal(size=x.shape), x[:6] @ rot2(np.pi).T])
    s2 = 1e-4
    pose = align(x, y, sigma2=s2)
    (best, *_), (second, a2, _) = pose.candidates
    assert abs(abs(np.degrees(np.arctan2(a2[1, 0], a2[0, 0]))) - 180.0) < 10.0  # the turned pose
    assert 1.05 * best < second < best + 0.05
    assert objective(x @ rot2(np.pi).T, y, s2) < pose.objective  # it would win at σ²
    assert abs(pose.angle) < 5.0


def test_starts_tied_at_the_coarsest_sigma2_are_all_followed_and_the_best_at_sigma2_wins():
    """A six-armed star whose points have the star's symmetry but for two tiny radial shifts: point
    0 by δ in the source; in the target point 0 by δ and point 8 (two arms on) by 2δ. At the coarsest
    σ² the six orientations are tied within 1e-12 (all followed) and the one two arms on is the best
    (the 2δ shift weighs more than the δ one); at σ = δ/3 only the true orientation puts the source's
    points on the target's."""
    t = 2 * np.pi * np.arange(24) / 24
    radial = np.column_stack([np.cos(t), np.sin(t)])
    star = radial * (1 + 0.4 * np.cos(6 * t))[:, None]
    delta = 3e-6
    x = star.copy()
    x[0] += delta * radial[0]
    y = x.copy()
    y[8] += 2 * delta * radial[8]
    y = y @ rot2(0.3).T
    pose = align(x, y, sigma2=(delta / 3) ** 2, n_starts=6)
    fvals = [c[0] for c in pose.candidates]
    assert len(fvals) == 6 and max(fvals) < 1e-12
    first = pose.candidates[0][1]
    assert np.degrees(np.arctan2(first[1, 0], first[0, 0])) == pytest.approx(np.degrees(0.3) + 120.0, abs=0.1)
    assert np.abs(pose.points - y).max() < 3 * delta and pose.angle == pytest.approx(np.degrees(0.3), abs=1e-4)


# ---------------------------------------------------------------------------------------------
# convergence reports and the warning
# ---------------------------------------------------------------------------------------------


def test_stop_reasons_follow_scipy_l_bfgs_b():
    """The reason of each of L-BFGS-B's stops, from real runs: gradient tolerance, relative objective
    change, iteration limit, and a line search that finds no decrease (a wrong-sign gradient: SciPy
    before 1.17 says status 2, from 1.17 status 0 and "relative reduction" at the unmoved start)."""
    x0, r0 = np.array([1.0, 2.0]), np.array([-1.2, 1.0])
    quad = minimize(lambda p: (p @ p, 2 * p), x0, jac=True, method="L-BFGS-B")
    slow = minimize(lambda p: (rosen(p), rosen_der(p)), r0, jac=True, method="L-BFGS-B", options={"ftol": 1e-3})
    short = minimize(lambda p: (rosen(p), rosen_der(p)), r0, jac=True, method="L-BFGS-B", options={"maxiter": 2})
    wrong = minimize(lambda p: (p @ p, -2 * p), x0, jac=True, method="L-BFGS-B")
    assert [r.status for r in (quad, slow, short)] == [0, 0, 1] and wrong.status in (0, 2)
    assert np.array_equal(wrong.x, x0) and wrong.fun == 5.0  # no step was taken
    assert [_stop(r, s) for r, s in ((quad, x0), (slow, r0), (short, r0), (wrong, x0))] == [
        (True, "gradient"), (True, "objective_change"), (False, "max_iter"), (True, "no_decrease")]


def test_an_unconverged_search_warns_at_the_caller_and_a_converged_one_is_silent():
    x, y = pear(), pear() @ rot2(0.7).T * 1.5 + [3.0, 1.0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pose = align(x, y, sigma2=0.01, max_iter=1)
    assert [w.category for w in caught] == [PoseSearchWarning]
    assert str(caught[0].message) == ("align: the refinement of the best start stopped after 1 iterations without "
                                      "converging (max_iter); raise max_iter")
    assert "shapelib" not in Path(caught[0].filename).parts  # not inside the library
    if not UNDER_MUTMUT:  # mutmut's trampoline adds a frame of its own
        assert caught[0].filename == __file__
    assert not pose.converged and pose.stop_reason == "max_iter"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert align(x, y, sigma2=0.01, max_iter=1, warn=False).stop_reason == "max_iter"
        assert align(x, y, sigma2=0.01, transform="similarity").converged


def test_summary_reports_the_pose():
    x = pear()
    y = 1.5 * x @ rot2(np.radians(40.0)).T + [0.123456, 2.0]
    pose = align(x, y, sigma2=0.01, transform="similarity")
    text = pose.summary()
    assert text.startswith("similarity pose (alpha, sigma2 = 0.01): scale 1.5, angle 40.00 deg, translation [")
    assert "0.1235" in text and "0.12346" not in text and "mirrored" not in text
    assert text.endswith(f"converged ({pose.stop_reason})") and "NOT" not in text
    assert f"{pose.n_starts} starts refined, {pose.n_iter} iterations" in text
    half = x[np.argsort(x[:, 0])][:30]  # half a pear has no symmetry at all
    m = align(half, half @ np.diag([-1.0, 1.0]) @ rot2(1.1).T, sigma2=0.01, reflection=True)
    assert m.reflection and ", mirrored, translation" in m.summary()
    short = align(x, 1.5 * x @ rot2(0.7).T, sigma2=0.01, max_iter=1, warn=False)
    assert short.summary().endswith("NOT converged (max_iter)")
    rng = np.random.default_rng(4)
    x3 = rng.normal(size=(20, 3)) * [3.0, 2.0, 1.0]
    s3 = align(x3, x3 + 1.0, sigma2=0.1).summary()
    assert s3.startswith("rigid pose (alpha, sigma2 = 0.1): scale 1, translation [1. 1. 1.]")


# ---------------------------------------------------------------------------------------------
# the starts and their choice
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n_angles", [5, 36])
def test_two_dimensional_starts_are_rotations_evenly_spaced_over_the_circle_then_their_mirrors(n_angles):
    starts = _starts(None, None, 2, n_angles, True)
    assert [k for k, _ in starts] == [0] * n_angles + [1] * n_angles
    roots = np.exp(2j * np.pi * np.arange(n_angles) / n_angles)
    for k, mirror in ((0, np.eye(2)), (1, np.diag([-1.0, 1.0]))):
        b = np.array([s for g, s in starts if g == k]) @ mirror  # the rotations
        assert np.allclose(b[:, 0, 0] + 1j * b[:, 1, 0], roots, atol=1e-15)
        assert np.allclose(b[:, 1, 1] + 1j * b[:, 0, 1], np.conj(roots), atol=1e-15)


@pytest.mark.parametrize("seeds", [(3, 4), (1, 101)])
def test_three_dimensional_starts_take_principal_axes_to_principal_axes_then_cover_every_rotation(seeds):
    """The first four starts map the source's principal axes to ±the target's, all four proper sign
    patterns (the mirrored group: the four improper ones); then the icosahedral group (60 distinct
    rotations closed under products), no rotation farther than 44.5° from one of them (the covering
    radius of the group, 44.48°: random rotations come within a degree of it)."""
    q = Rotation.random(random_state=seeds[0]).as_matrix()
    r = Rotation.random(random_state=seeds[1]).as_matrix()
    z = np.vstack([np.diag([3.0, 2.0, 1.0]), -np.diag([3.0, 2.0, 1.0])])  # principal axes e1, e2, e3
    x = z @ q.T
    y = x @ r.T
    starts = _starts(x, y, 3, 36, True)
    assert [k for k, _ in starts] == [0] * 64 + [1] * 64
    signs = []
    for k in (0, 1):
        b = np.array([s for g, s in starts if g == k])
        assert np.allclose(np.einsum("nij,nkj->nik", b, b), np.eye(3), atol=1e-12)
        assert np.allclose(np.linalg.det(b), 1.0 if k == 0 else -1.0, atol=1e-12)
        for bb in b[:4]:
            dd = (r @ q).T @ bb @ q  # diagonal ±1 when bb takes axis i of x to ± axis i of y
            assert np.allclose(dd, np.diag(np.round(np.diag(dd))), atol=1e-9)
            signs.append(tuple(np.round(np.diag(dd)).astype(int)))
        group = b[4:] @ (np.eye(3) if k == 0 else np.diag([-1.0, 1.0, 1.0]))
        keys = {tuple(np.round(g, 6).ravel()) for g in group}
        assert len(keys) == 60
        if k == 0:
            for g in group[::7]:
                for h in group[::5]:
                    assert tuple(np.round(g @ h, 6).ravel()) in keys
    assert sorted(signs) == sorted({(a, b, c) for a in (1, -1) for b in (1, -1) for c in (1, -1)})
    assert all(np.prod(s) == 1 for s in signs[:4]) and all(np.prod(s) == -1 for s in signs[4:])
    group = Rotation.from_matrix(np.array([s for g, s in starts if g == 0][4:]))
    probes = Rotation.random(2000, random_state=6)
    worst = max(np.min((group.inv() * p).magnitude()) for p in probes)
    assert 43.0 < np.degrees(worst) < 44.5


def _local_minima_on_circles(scores, groups):
    """Brute force: i with a score ≤ both circular neighbours of its own group, by score."""
    keep = []
    for k in sorted(set(groups)):
        idx = [i for i in range(len(scores)) if groups[i] == k]
        n = len(idx)
        for j, i in enumerate(idx):
            if scores[i] <= scores[idx[(j - 1) % n]] and scores[i] <= scores[idx[(j + 1) % n]]:
                keep.append(i)
    return sorted(keep, key=lambda i: scores[i])


@pytest.mark.parametrize("seed", range(6))
def test_two_dimensional_choice_is_the_local_minima_of_each_circle_best_first(seed):
    rng = np.random.default_rng(seed)
    scores = rng.random(24)
    starts = [(0, None)] * 10 + [(1, None)] * 14
    want = _local_minima_on_circles(scores, [k for k, _ in starts])
    assert [int(i) for i in _choose(scores, starts, 2, 50)] == want
    assert [int(i) for i in _choose(scores, starts, 2, 2)] == want[:2]


def test_a_flat_run_of_scores_counts_each_start_of_it_and_the_circle_wraps_around():
    scores = np.array([0.1, 0.5, 0.3, 0.3, 0.6, 0.2, 0.4, 0.25, 0.25, 0.9])
    starts = [(0, None)] * 5 + [(1, None)] * 5
    # circle 0: 0.1 (wraps to 0.6), 0.3 and 0.3; circle 1: 0.2 (wraps to 0.9), 0.25 and 0.25
    assert [int(i) for i in _choose(scores, starts, 2, 10)] == [0, 5, 7, 8, 2, 3]


def test_three_dimensional_choice_is_the_best_scores():
    scores = np.array([0.5, 0.1, 0.4, 0.3, 0.2, 0.05, 0.6, 0.7])
    starts = [(0, None)] * 4 + [(1, None)] * 4
    assert [int(i) for i in _choose(scores, starts, 3, 3)] == [5, 1, 4]
