"""shapelib.register and its pieces against independent values: the kernels and the Fisher–Rao weight
metric against brute-force quadrature of the Gaussians' integrals; EM's σ² and outlier weight against the
maximum of the mixture's likelihood found by SciPy; the objective against quadrature of the two mixtures;
σ², the objective and the points under a change of units of both sets; the pose, the path and the warp
against doing it by hand; correspondences and counts on a set with known removed points and added
outliers; the non-rigid fit of an exact similarity against that similarity; the farthest-point sample
against brute force; and one ValueError naming the parameter for each bad input."""

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize, minimize_scalar
from scipy.spatial.distance import cdist
from scipy.spatial.transform import Rotation
from scipy.stats import multivariate_normal

from scipy.special import logsumexp

import shapelib as sl
from shapelib.pointsets import registration as reg

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions go
#: through a trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(reg))


def fish(n=30):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])


def rot2(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def quietly(x, y, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.RegistrationWarning)
        return sl.register(x, y, **kw)


def grid(points, sigma, step=0.3, margin=8.0):
    """Nodes (k, 2) of a square grid around ``points`` and the area of one cell: the sum of a smooth
    integrand of Gaussians of width σ over the nodes, times the cell, is exact to round-off at a step of
    0.3 σ (the error of the rule falls as exp(−2π²σ²/step²))."""
    lo, hi = points.min(0) - margin * sigma, points.max(0) + margin * sigma
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0], step * sigma), np.arange(lo[1], hi[1], step * sigma))
    return np.column_stack([gx.ravel(), gy.ravel()]), (step * sigma) ** 2


def normals(z, means, s2):
    """N(z; mean_a, s2 I) (k, n): the isotropic normal density of each mean (SciPy's squared distances)."""
    d = z.shape[1]
    return np.exp(-cdist(z, means, "sqeuclidean") / (2 * s2)) / (2 * np.pi * s2) ** (d / 2)


def test_normals_is_scipys_density():
    z, means = np.array([[0.1, 0.2], [1.0, -0.5]]), np.array([[0.0, 0.0], [0.3, 0.4], [1.0, 1.0]])
    expected = np.column_stack([multivariate_normal(mean=m, cov=0.3 * np.eye(2)).pdf(z) for m in means])
    assert np.allclose(normals(z, means, 0.3), expected, rtol=1e-12)


# ---------------------------------------------------------------------------------------------------------
# the kernels: integrals of the components
# ---------------------------------------------------------------------------------------------------------

def test_the_overlap_and_alpha_kernels_are_the_l2_integrals_of_the_components_and_their_derivatives():
    s2 = 0.3
    a = np.array([[0.0, 0.0], [0.5, 0.2], [-0.3, 0.6]])
    b = np.array([[0.2, -0.4], [0.0, 0.0], [0.9, 0.1], [-0.6, -0.2]])
    z, da = grid(np.vstack([a, b]), np.sqrt(s2))
    na, nb = normals(z, a, s2), normals(z, b, s2)
    self_overlap = da * np.sum(na[:, 0] ** 2)
    overlap = da * (na.T @ nb) / self_overlap
    assert np.allclose(reg.overlap_kernel(a, b, s2), overlap, atol=1e-6)
    # ∂N(z; u)/∂u = N (z − u)/σ²: the α-order metric's block of a and b, over the same block of one point
    ga = na[:, :, None] * (z[:, None, :] - a[None]) / s2  # (k, n, 2)
    gb = nb[:, :, None] * (z[:, None, :] - b[None]) / s2
    blocks = da * np.einsum("kip,kjq->ipjq", ga, gb)
    diag = da * np.einsum("kp,kq->pq", ga[:, 0], ga[:, 0])
    assert np.allclose(diag, diag[0, 0] * np.eye(2), atol=1e-9)
    kernel = reg.alpha_kernel(a, b, s2)
    assert kernel.shape == (6, 8)
    assert np.allclose(kernel, blocks.reshape(6, 8) / diag[0, 0], atol=1e-6)
    # for a = b the kernel on the means is the α-order metric over its diagonal, as the docstring says
    g = reg._kernel(a, s2, "alpha", "means")
    assert np.allclose(g, reg.alpha_kernel(a, a, s2), atol=1e-12)
    assert np.allclose(reg._kernel(a, s2, "alpha", "weights"), reg.overlap_kernel(a, a, s2))


def test_the_fisher_rao_weight_metric_is_the_integral_of_na_nb_over_the_mixture():
    s2 = 0.2
    u = np.array([[0.0, 0.0], [0.6, 0.1], [0.1, 0.7], [-0.5, 0.3]])
    z, da = grid(u, np.sqrt(s2))
    n = normals(z, u, s2)
    p = n.mean(axis=1)  # the mixture of eq. (5): equal weights
    g = da * (n.T @ (n / p[:, None]))
    got = reg._fr_weight_metric(u, s2)
    assert np.allclose(got, g, rtol=2e-3, atol=0)
    kernel = reg._kernel(u, s2, "fisher_rao", "weights")
    assert np.allclose(kernel, g / np.mean(np.diag(g)), rtol=2e-3)
    assert np.mean(np.diag(kernel)) == pytest.approx(1.0, rel=1e-12)


# ---------------------------------------------------------------------------------------------------------
# EM with the means held at the pose: the maximum likelihood
# ---------------------------------------------------------------------------------------------------------

def noisy_case():
    """A fish turned and moved, with noise, and 6 clutter points inside its bounding box."""
    rng = np.random.default_rng(4)
    x = fish(30)
    y = x @ rot2(0.9).T + [1.0, -2.0] + 0.03 * rng.normal(size=x.shape)
    lo, hi = y.min(0), y.max(0)
    return x, np.vstack([y, lo + (hi - lo) * rng.random((6, 2))])


def log_likelihood(theta, y, s2, w):
    """Σ_j log p(y_j) of CPD's mixture: w uniform over the target's bounding box, (1 − w) the Gaussians."""
    volume = np.prod(np.ptp(y, axis=0))
    p = w / volume + (1 - w) * normals(y, theta, s2).mean(axis=1)
    return float(np.sum(np.log(p)))


def test_em_sigma2_and_w_are_the_maximum_of_the_likelihood_at_the_pose():
    x, y = noisy_case()
    res = sl.register(x, y, transform="rigid", w="auto", tol=1e-12, max_iter=5000)
    assert res.converged and res.stop_reason == "tolerance" and res.n_iter > 1
    assert np.allclose(res.points, res.pose(x), atol=1e-12)  # the means are held at the pose
    best = minimize(lambda v: -log_likelihood(res.points, y, np.exp(v[0]), 1 / (1 + np.exp(-v[1]))),
                    [np.log(res.sigma2) + 0.3, 0.0], method="Nelder-Mead",
                    options=dict(xatol=1e-9, fatol=1e-12, maxiter=4000))
    assert res.sigma2 == pytest.approx(np.exp(best.x[0]), rel=1e-4)
    assert res.w == pytest.approx(1 / (1 + np.exp(-best.x[1])), abs=1e-4)


def test_em_sigma2_at_a_fixed_w_and_w_at_a_fixed_sigma2_are_the_one_dimensional_maxima():
    x, y = noisy_case()
    res = sl.register(x, y, transform="rigid", w=0.2, tol=1e-12, max_iter=5000)
    assert res.w == 0.2
    best = minimize_scalar(lambda v: -log_likelihood(res.points, y, np.exp(v), 0.2), bounds=(-12, 2),
                           method="bounded", options=dict(xatol=1e-10))
    assert res.sigma2 == pytest.approx(np.exp(best.x), rel=1e-4)
    s2 = 0.004
    res = sl.register(x, y, transform="rigid", sigma2=s2, w="auto", tol=1e-12, max_iter=5000)
    assert res.sigma2 == s2 and res.sigma2_objective == pytest.approx(s2, rel=1e-12)
    best = minimize_scalar(lambda w: -log_likelihood(res.points, y, s2, w), bounds=(1e-6, 0.9), method="bounded",
                           options=dict(xatol=1e-10))
    assert res.w == pytest.approx(best.x, abs=1e-5)
    # both given: nothing to estimate
    res = sl.register(x, y, transform="rigid", sigma2=s2, w=0.3)
    assert (res.sigma2, res.w, res.n_iter, res.converged, res.stop_reason) == (s2, 0.3, 0, True, "tolerance")


def test_w_stops_at_its_largest_on_a_target_mostly_clutter_and_sigma2_at_its_floor_on_an_exact_fit():
    x = fish(12)
    rng = np.random.default_rng(0)
    y = np.vstack([x @ rot2(0.3).T, rng.uniform(-1.3, 1.3, size=(150, 2))])
    res = quietly(x, y, transform="rigid", sigma2=0.002, w="auto", max_iter=500)
    assert res.w == reg.W_MAX  # the likelihood's maximum is near 150/162, above the cap
    # an exact fit: the likelihood grows without bound as σ² → 0; EM stops at its floor, a documented
    # fraction of the target's leave-one-out σ² (the objective's σ²)
    x = fish(30)
    res = quietly(x, x @ rot2(2.0).T + 1.0, transform="rigid", w=0.0, max_iter=500)
    assert res.sigma2 == pytest.approx(reg.SIGMA2_FLOOR * res.sigma2_objective, rel=1e-9)


def test_an_em_stopped_early_warns_at_the_caller_unless_told_not_to():
    x, y = noisy_case()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sl.register(x, y, transform="similarity", max_iter=2)
    assert [w.category for w in caught] == [sl.RegistrationWarning]
    assert "EM stopped after 2 iterations" in str(caught[0].message)
    assert f"sigma2 = {res.sigma2:.3g}" in str(caught[0].message)
    if not UNDER_MUTMUT:  # mutmut's trampoline adds a frame of its own
        assert caught[0].filename == __file__
    assert (res.converged, res.stop_reason, res.n_iter) == (False, "max_iter", 2)
    assert re.search(r"^EM: .*, 2 iterations, NOT converged \(max_iter\)$", res.summary(), flags=re.M)
    # the non-rigid search says the same
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sl.register(x[:20], y[:20], max_iter=2)
    messages = [str(w.message) for w in caught if issubclass(w.category, sl.RegistrationWarning)]
    assert (f"register: EM stopped after 2 iterations without converging (sigma2 = {res.sigma2:.3g}); raise "
            "max_iter or loosen tol") in messages
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sl.register(x, y, transform="similarity", max_iter=2, warn=False).n_iter == 2


# ---------------------------------------------------------------------------------------------------------
# the objective, units, the pose by hand
# ---------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_the_objective_is_the_distance_of_the_two_mixtures_by_quadrature(metric):
    x, y = noisy_case()
    res = sl.register(x, y, transform="similarity", metric=metric)
    s2 = res.sigma2_objective
    z, da = grid(np.vstack([res.points, y]), np.sqrt(s2))
    p, q = normals(z, res.points, s2).mean(axis=1), normals(z, y, s2).mean(axis=1)
    if metric == "alpha":
        expected = np.sqrt(da * np.sum((p - q) ** 2))
    else:
        expected = 2 * np.arccos(min(da * np.sum(np.sqrt(p * q)), 1.0))
    assert res.objective == pytest.approx(expected, rel=2e-3)
    # Pose.value: the bound at the pose's σ² after the move, in the input units (the points are the pose's)
    assert res.pose.value == pytest.approx(expected, rel=2e-3)
    # the σ² of the objective is the target's leave-one-out σ² (the pose search's), in the target's units
    assert s2 == pytest.approx(sl.fit_mixture(y, warn=False).sigma2, rel=1e-6)
    assert res.pose.sigma2 == pytest.approx(s2, rel=1e-12)


@pytest.mark.parametrize("transform", ["rigid", "similarity", "affine"])
def test_a_change_of_units_of_both_sets_scales_sigma2_the_objective_and_the_points(transform):
    x, y = noisy_case()
    s, cx, cy = 7.0, np.array([3.0, -1.0]), np.array([-20.0, 5.0])
    a = sl.register(x, y, transform=transform, w=0.1)
    b = sl.register(s * x + cx, s * y + cy, transform=transform, w=0.1)
    assert b.sigma2 == pytest.approx(s ** 2 * a.sigma2, rel=1e-5)
    assert b.sigma2_objective == pytest.approx(s ** 2 * a.sigma2_objective, rel=1e-6)
    assert b.pose.sigma2 == pytest.approx(s ** 2 * a.pose.sigma2, rel=1e-6)
    assert b.objective == pytest.approx(a.objective / s, rel=1e-4)  # ‖p − q‖ of 2-D densities: per unit length
    assert b.pose.value == pytest.approx(a.pose.value / s, rel=1e-4)
    assert a.pose.value == pytest.approx(a.objective, rel=1e-6)  # the same bound: the points are the pose's
    assert np.allclose(b.points, s * a.points + cy, atol=1e-5 * s)
    assert np.allclose(b.pose.matrix, a.pose.matrix, atol=1e-6)
    assert np.array_equal(b.correspondence, a.correspondence)
    # a σ² given in the target's units
    a = sl.register(x, y, transform=transform, sigma2=0.01)
    b = sl.register(s * x + cx, s * y + cy, transform=transform, sigma2=0.01 * s ** 2)
    assert b.sigma2 == pytest.approx(s ** 2 * a.sigma2, rel=1e-9) and a.sigma2 == 0.01
    assert b.sigma2_objective == pytest.approx(0.01 * s ** 2, rel=1e-9)
    assert np.allclose(b.points, s * a.points + cy, atol=1e-5 * s)


def test_three_dimensional_objective_and_pose_value_scale_as_a_density_distance_in_three_dimensions():
    rng = np.random.default_rng(6)
    x = rng.normal(size=(20, 3)) * [2.0, 1.0, 0.5]
    y = x @ Rotation.random(random_state=5).as_matrix().T + 0.05 * rng.normal(size=(20, 3))
    s = 4.0
    a = sl.register(x, y, transform="rigid")
    b = sl.register(s * x, s * y, transform="rigid")
    assert b.objective == pytest.approx(a.objective / s ** 1.5, rel=1e-4)  # ‖p − q‖ of 3-D densities
    assert b.pose.value == pytest.approx(a.pose.value / s ** 1.5, rel=1e-4)
    assert a.pose.value == pytest.approx(a.objective, rel=1e-6)


def test_the_similarity_part_is_the_least_squares_similarity_onto_the_fitted_points():
    rng = np.random.default_rng(8)
    x = 0.1 * rng.normal(size=(12, 2)) + [2.0, -1.0]  # off the origin, and small: sum |x - mean|² < 1
    a_true, t_true = 0.7 * rot2(2.2), np.array([-3.0, 0.5])
    a, t = reg._similarity_part(x, x @ a_true.T + t_true, False)
    assert np.allclose(a, a_true, atol=1e-12) and np.allclose(t, t_true, atol=1e-12)
    mirror = a_true @ np.diag([1.0, -1.0])
    a, t = reg._similarity_part(x, x @ mirror.T + t_true, True)
    assert np.allclose(a, mirror, atol=1e-12) and np.allclose(t, t_true, atol=1e-12)


def test_the_pose_the_path_and_the_warp_of_a_rigid_registration_are_its_matrix_and_translation_by_hand():
    x, y = noisy_case()
    res = sl.register(x, y, transform="affine", n_steps=3)
    a, t = res.pose.matrix, res.pose.translation
    new = np.random.default_rng(1).normal(size=(5, 2))
    by_hand = np.array([a @ p + t for p in new])
    assert np.allclose(res.pose(new), by_hand, atol=1e-12) and np.allclose(res.warp(new), by_hand, atol=1e-12)
    assert np.allclose(res.rigid_points, [a @ p + t for p in x], atol=1e-12)
    assert np.allclose(res.pose.points, res.rigid_points, atol=1e-12)
    assert np.allclose(res.points, res.rigid_points, atol=1e-12)
    path = res.path
    assert path.shape == (4, 30, 2) and res.geodesic is None
    for k in range(4):
        assert np.allclose(path[k], x + k / 3 * (res.points - x), atol=1e-12)
    assert res.pose.transform == "affine" and res.pose.metric == "alpha" and res.transform == "affine"
    # the pose reports its search
    assert res.pose.converged is True and res.pose.stop_reason in ("gradient", "objective_change", "no_decrease")
    assert isinstance(res.pose.n_iter, int) and res.pose.n_iter > 0 and np.isfinite(res.pose.objective)
    assert isinstance(res.pose.n_starts, int) and res.pose.n_starts >= 1
    # one start angle: one start refined
    assert sl.register(x, y, transform="rigid", n_angles=1).pose.n_starts == 1


def test_the_probabilities_are_bayes_posteriors_of_the_mixture():
    x, y = noisy_case()
    res = sl.register(x, y, transform="rigid", w="auto")
    volume = np.prod(np.ptp(y, axis=0))
    joint = (1 - res.w) / len(x) * normals(y, res.points, res.sigma2).T  # (n, m)
    expected = joint / (joint.sum(axis=0) + res.w / volume)
    assert np.allclose(res.probabilities, expected, rtol=1e-6, atol=1e-12)


def test_correspondences_and_counts_on_a_set_with_removed_points_and_added_outliers():
    x = fish(30)
    rng = np.random.default_rng(3)
    keep = np.r_[0:5, 8:30]  # source points 5, 6, 7 have no image
    clutter = np.array([[0.3, 0.05], [2.1, 0.0], [0.3, 1.2]])  # half a fish's length or more from its outline
    y = np.vstack([(x @ rot2(2.5).T)[keep], clutter])
    perm = rng.permutation(len(y))
    # a σ² of about a tenth of the point spacing: the pose search's density distance then matches points, not
    # blurred outlines, and the gap and the clutter cannot bias the pose (at the leave-one-out σ² they turn it)
    res = quietly(x, y[perm], transform="rigid", w="auto", sigma2=0.002)
    inv = np.argsort(perm)  # y[i] is y[perm][inv[i]]
    expected = np.full(30, -1)
    expected[keep] = inv[:27]
    assert np.array_equal(res.correspondence, expected)
    expected_t = np.full(30, -1)
    expected_t[inv[:27]] = keep
    assert np.array_equal(res.target_correspondence, expected_t)
    assert "27 of 30 source points matched, 27 of 30 target points" in res.summary()
    assert "rigid registration (alpha) of 30 points onto 30" in res.summary()
    assert res.summary().splitlines()[-1] == "reliable: nothing says the registration failed"
    assert f"outlier weight w = {res.w:.3g}" in res.summary()
    assert re.search(r"^EM: .*iterations, converged \(tolerance\)$", res.summary(), flags=re.M)


def test_an_unreliable_result_says_why_in_its_summary_and_its_warning():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    ellipse = np.column_stack([1.6 * np.cos(t), np.sin(t)])  # the same shape after a half turn
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sl.register(ellipse, ellipse @ rot2(0.4).T)
    assert not res.reliable and res.reasons
    assert res.summary().splitlines()[-1] == "NOT RELIABLE (the registration probably failed): " + "; ".join(res.reasons)
    assert [str(w.message) for w in caught] == ["register: the registration is probably wrong: " + "; ".join(res.reasons)]


# ---------------------------------------------------------------------------------------------------------
# non-rigid
# ---------------------------------------------------------------------------------------------------------

def test_a_nonrigid_fit_of_an_exact_similarity_reports_it_as_the_pose_and_warps_new_points_by_it():
    x = fish(30) + [3.0, 1.0]  # off the origin: the frames' centres matter
    s, r, t = 1.8, rot2(1.2), np.array([2.0, -3.0])
    y = s * x @ r.T + t
    res = quietly(x, y[::-1])
    assert np.abs(res.points - y).max() < 1e-3 * s
    assert np.allclose(res.pose.matrix, s * r, atol=1e-3) and np.allclose(res.pose.translation, t, atol=1e-3)
    assert res.pose.transform == "similarity" and res.pose.n_starts > 1
    assert np.allclose(res.pose.points, s * x @ r.T + t, atol=2e-3 * s)
    # the pose reports the fit kept: its EM, its σ² (in the target's units), its objective
    assert res.pose.converged is True and res.pose.stop_reason == res.stop_reason == "tolerance"
    assert res.pose.n_iter == res.n_iter > 0 and res.pose.metric == "alpha"
    assert res.pose.sigma2 == pytest.approx(res.sigma2, rel=1e-12)
    assert np.isfinite(res.pose.objective) and res.diagnostics["objective"] == res.pose.objective
    assert res.diagnostics["candidates"][0][0] == res.pose.objective and len(res.diagnostics["candidates"]) > 1
    new = np.array([[3.3, 1.1], [2.5, 1.2], [3.0, 1.0]])
    assert np.allclose(res.warp(new), s * new @ r.T + t, atol=2e-3 * s)
    assert np.allclose(res.rigid_points, s * x @ r.T + t, atol=2e-3 * s)
    # σ_g² in units of the target's squared RMS radius
    radius2 = np.mean(np.sum((y - y.mean(0)) ** 2, axis=1))
    assert res.sigma2_metric == pytest.approx(2.0 * radius2, rel=1e-12)
    # σ over the target's point spacing (the median distance to the nearest neighbour), as diagnosed
    dist = cdist(y, y)
    np.fill_diagonal(dist, np.inf)
    spacing = np.median(dist.min(axis=1))
    assert res.diagnostics["sigma_over_spacing"] == pytest.approx(np.sqrt(res.sigma2) / spacing, rel=1e-9)
    # the path is the geodesic from the posed source to the fit
    assert res.geodesic is not None


@pytest.mark.parametrize("kernel", ["weights", "means"])
def test_a_nonrigid_fit_at_a_given_sigma2_is_in_the_target_units(kernel):
    x = fish(24)
    y = x + np.column_stack([0.05 * np.sin(2 * x[:, 1]), 0.2 * x[:, 0] ** 2])
    s, c = 5.0, np.array([1.0, 2.0])
    a = quietly(x, y, sigma2=0.002, kernel=kernel, w=0.1)  # a weight that "auto" does not try
    b = quietly(s * x - c, s * y + c, sigma2=0.002 * s ** 2, kernel=kernel, w=0.1)
    assert a.sigma2 == 0.002 and a.sigma2_objective == pytest.approx(0.002, rel=1e-12)
    assert b.sigma2 == pytest.approx(0.002 * s ** 2, rel=1e-12) and b.w == 0.1
    assert np.allclose(b.points, s * a.points + c, atol=1e-5 * s)
    assert b.objective == pytest.approx(a.objective / s, rel=1e-4)
    new = np.array([[0.2, 0.1], [-0.4, 0.3]])
    assert np.allclose(b.warp(s * new - c), s * a.warp(new) + c, atol=1e-5 * s)
    assert np.allclose(a.warp(x), a.points, atol=1e-8)


def test_a_nonrigid_fit_of_a_mirror_image_is_found_when_asked():
    x = fish(24)[:18]  # an open piece of outline: no symmetry
    y = x @ np.diag([1.0, -1.0]) @ rot2(0.7).T
    res = quietly(x, y, reflection=True)
    assert res.pose.reflection and np.abs(res.points - y).max() < 1e-3
    assert np.allclose(res.pose.matrix, rot2(0.7) @ np.diag([1.0, -1.0]), atol=1e-3)


def test_a_nonrigid_fisher_rao_fit_refits_from_the_search_and_reports_its_kernel_units():
    x = fish(20)
    y = 3.0 * (x + np.column_stack([np.zeros(20), 0.15 * x[:, 0] ** 2])) @ rot2(0.5).T
    res = quietly(x, y, metric="fisher_rao", sigma2_metric=1.5)
    radius2 = np.mean(np.sum((y - y.mean(0)) ** 2, axis=1))
    assert res.sigma2_metric == pytest.approx(1.5 * radius2, rel=1e-12)
    assert res.metric == "fisher_rao" and res.diagnostics["objective"] is None
    assert np.abs(res.points - y).max() < 0.02 * np.sqrt(radius2)
    message = "method='kernel' needs the closed-form alpha kernel; register with metric='alpha'"
    with pytest.raises(ValueError, match="^" + re.escape(message) + "$"):
        res.warp(x)


# ---------------------------------------------------------------------------------------------------------
# large sets, farthest points
# ---------------------------------------------------------------------------------------------------------

def test_farthest_points_start_nearest_the_centroid_then_take_the_farthest_point():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(40, 2)) * [3.0, 1.0]
    first = int(np.argmin(np.linalg.norm(a - a.mean(0), axis=1)))
    assert reg.farthest_points(a, 1).tolist() == [first]
    second = int(np.argmax(np.linalg.norm(a - a[first], axis=1)))
    assert reg.farthest_points(a, 2).tolist() == sorted([first, second])
    third = int(np.argmax(np.minimum(np.linalg.norm(a - a[first], axis=1), np.linalg.norm(a - a[second], axis=1))))
    assert reg.farthest_points(a, 3).tolist() == sorted([first, second, third])
    assert reg.farthest_points(a, 40).tolist() == list(range(40))


def test_a_large_rigid_registration_finds_the_known_correspondences_and_leaves_far_clutter_unmatched(monkeypatch):
    monkeypatch.setattr(reg, "MAX_POINTS", 40)
    x = fish(90)
    rng = np.random.default_rng(5)
    perm = rng.permutation(90)
    gap = np.r_[5:12]  # source points whose images the target lacks
    kept = np.setdiff1d(np.arange(90), gap)
    images = (x @ rot2(0.8).T + [1.0, 1.0])[kept]
    perm = rng.permutation(len(kept))
    y = np.vstack([images[perm], [[1.3, 1.05], [3.2, 1.0]]])
    res = quietly(x, y, transform="rigid", sigma2=1e-4)
    assert res.diagnostics["subsets"] == (40, 40)
    inv = np.argsort(perm)
    # the middle of the gap is farther than 3σ and a point spacing (0.03 + 0.055) from any target point (0.16 to 0.35)
    assert np.array_equal(res.correspondence[kept], inv) and np.all(res.correspondence[6:11] == -1)
    assert np.array_equal(res.target_correspondence[:len(kept)], kept[perm])
    assert res.target_correspondence[len(kept):].tolist() == [-1, -1]
    assert np.allclose(res.points, res.pose(x), atol=1e-12) and np.allclose(res.rigid_points, res.points)
    matched = int(np.sum(res.correspondence >= 0))
    assert f"rigid registration (alpha) of 90 points onto {len(y)}" in res.summary()
    assert f"{matched} of 90 source points matched, {len(kept)} of {len(y)} target points" in res.summary()


def test_a_large_nonrigid_registration_keeps_the_diagnostics_of_its_subsets(monkeypatch):
    monkeypatch.setattr(reg, "MAX_POINTS", 30)
    x = fish(60)
    res = quietly(x, x @ rot2(0.5).T)
    assert res.diagnostics["subsets"] == (30, 30)
    assert {"sigma_over_spacing", "unmatched_source_share", "candidates"} <= set(res.diagnostics)
    assert np.allclose(res.points, x @ rot2(0.5).T, atol=1e-2) and np.allclose(res.rigid_points, res.pose(x))


def test_a_large_nonrigid_registration_with_another_kernel_is_refused(monkeypatch):
    monkeypatch.setattr(reg, "MAX_POINTS", 20)
    with pytest.raises(ValueError, match="kernel='weights'.*got metric='alpha', kernel='means'"):
        sl.register(fish(30), fish(25), kernel="means")
    with pytest.raises(ValueError, match="sets of over 20 points"):
        sl.register(fish(10), fish(25), metric="fisher_rao")
    sl.register(fish(30), fish(25), transform="rigid", metric="fisher_rao", warn=False)  # rigid: any metric


# ---------------------------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, words", [
    (dict(n_steps=0), "n_steps must be"),
    (dict(max_iter=0), "max_iter must be"),
    (dict(n_angles=-1), "n_angles must be"),
    (dict(tol=0.0), "tol must be"),
    (dict(sigma2_metric=-2.0), "sigma2_metric must be"),
    (dict(lam=float("nan")), "lam must be"),
    (dict(w=-0.1), "w must be in [0, 1) or 'auto'; got -0.1"),
    (dict(w="AUTO"), "w must be a number in [0, 1) or 'auto'; got 'AUTO'"),
    (dict(sigma2="Auto"), "sigma2 must be a positive number or 'auto'; got 'Auto'"),
    (dict(transform="Rigid"), "transform must be one of ('rigid', 'similarity', 'affine', 'nonrigid'); got 'Rigid'"),
    (dict(metric="l2"), "metric must be one of"),
    (dict(kernel="Weights"), "kernel must be one of ('weights', 'means'); got 'Weights'"),
    (dict(progress="bar"), "progress must be a callable progress(done, total) or None; got 'bar'"),
    (dict(n_threads=0), "n_threads must be"),
    (dict(n_threads=1.5), "n_threads must be"),
])
def test_each_bad_option_gets_a_value_error_naming_it(kwargs, words):
    with pytest.raises(ValueError) as info:
        sl.register(fish(10), fish(12), **kwargs)
    assert str(info.value).startswith(words)  # the message starts with the parameter's name


def test_the_threads_of_the_search_change_nothing_and_default_to_the_cores_outside_a_dask_worker(monkeypatch):
    x, y = noisy_case()
    one = sl.register(x, y, n_threads=1, warn=False)
    two = sl.register(x, y, n_threads=2, warn=False)
    np.testing.assert_array_equal(one.points, two.points)
    np.testing.assert_array_equal(one.correspondence, two.correspondence)
    assert (one.sigma2, one.w, one.objective, one.reliable) == (two.sigma2, two.w, two.objective, two.reliable)
    seen = []
    from shapelib.pointsets import _nonrigid

    fit_all = _nonrigid.fit_all

    def spy(*args, **kwargs):
        seen.append(kwargs["n_threads"])
        return fit_all(*args, **kwargs)

    monkeypatch.setattr(_nonrigid, "fit_all", spy)
    monkeypatch.setattr(reg, "n_cores", lambda: 3)
    sl.register(x, y, warn=False)
    monkeypatch.setattr(reg, "in_dask_worker", lambda: True)
    sl.register(x, y, warn=False)
    sl.register(x, y, warn=False, n_threads=2)
    assert seen == [3, 1, 2]


def test_sigma2_none_means_auto_and_w_zero_is_allowed():
    x, y = noisy_case()
    a = sl.register(x, y, transform="rigid", sigma2=None, w=0.0)
    b = sl.register(x, y, transform="rigid", sigma2="auto", w=0.0)
    assert a.sigma2 == b.sigma2 and a.w == 0.0


def test_warp_checks_its_points_and_method():
    x = fish(20)
    res = quietly(x, x @ rot2(0.4).T)
    with pytest.raises(ValueError, match="x must have d = 2 coordinates per point; got 3"):
        res.warp(np.random.default_rng(0).normal(size=(4, 3)))
    with pytest.raises(ValueError, match="method must be 'extrinsic' or 'kernel'; got 'tps'"):
        res.warp(x, method="tps")
    with pytest.raises(sl.InputError, match="^x: point 1 has a non-finite coordinate"):
        res.warp([[0.0, 0.0], [np.nan, 1.0]])
    rng = np.random.default_rng(1)
    x3 = rng.normal(size=(20, 3)) * [2.0, 1.0, 0.5]
    res3 = quietly(x3, x3 @ Rotation.random(random_state=2).as_matrix().T)
    message = "the extrinsic warp (§III-E) is implemented in 2-D; use method='kernel' in 3-D"
    with pytest.raises(ValueError, match="^" + re.escape(message) + "$"):
        res3.warp(x3, method="extrinsic")
    assert Path(reg.__file__).name == "registration.py"


def test_the_deformation_energy_is_the_objective_less_the_datas_negative_log_likelihood():
    """``deformation_energy`` = F − (−Σ_j log Σ_i N(y_j; θ_i, σ²)/n) at w = 0 and no price on the turn: the
    objective's other term, computed here from the moved points and σ² in the search's units (the target
    centred at unit RMS radius), at two stiffnesses; 0 for a pose alone."""
    x, y = 2.0 * fish(24) + 1.0, 0.7 * (fish(20) + [0.0, 0.3] * fish(20)[:, :1] ** 2) @ rot2(0.4).T - 3.0
    scale = np.sqrt(np.mean(np.sum((y - y.mean(axis=0)) ** 2, axis=1)))
    yn = (y - y.mean(axis=0)) / scale
    energies = []
    for lam in (2.0, 6.0):
        r = sl.register(x, y, w=0.0, pose_prior=0.0, lam=lam)
        theta = (r.points - y.mean(axis=0)) / scale
        s2 = r.sigma2 / scale ** 2
        n, d = theta.shape
        d2 = np.sum((theta[:, None, :] - yn[None]) ** 2, axis=-1)
        nll = -np.sum(logsumexp(-d2 / (2 * s2), axis=0) - np.log(n) - 0.5 * d * np.log(2 * np.pi * s2))
        assert r.deformation_energy == pytest.approx(r.diagnostics["objective"] - nll, rel=1e-6, abs=1e-9), lam
        assert type(r.deformation_energy) is float and r.deformation_energy > 0
        energies.append(r.deformation_energy)
    assert energies[0] != pytest.approx(energies[1], rel=1e-2)
    assert sl.register(x, y, transform="similarity").deformation_energy == 0.0
