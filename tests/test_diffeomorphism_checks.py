"""Checks of shapelib.comparison.diffeomorphism against independent values: the quadratic form against
per-coordinate linear algebra on a kernel matrix from SciPy's cdist, its gradient against central finite
differences, the metric tensor against the form it must reproduce, the far-apart limit K = I (a straight
geodesic of length √(λ/(1+λ))‖v − u‖), the lower bound against the smallest eigenvalue of the tensor over
configurations, and the warp against SciPy's solve_ivp on the same flow (second order in the substeps),
its inverse (the reversed path carries the points back) and a positive Jacobian determinant."""

import dataclasses
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.distance import cdist

import shapelib as sl
from shapelib.comparison import diffeomorphism as diffeomorphism_module
from shapelib.comparison.diffeomorphism import (DiffeomorphismPathMetric, _path_metric, diffeomorphism_quadratic_form,
                                                diffeomorphism_warp, landmark_diffeomorphism)

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions go through a
#: trampoline, more stack frames between the caller and the code: the warning's line is checked outside it
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(diffeomorphism_module))

U = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
V_RAW = np.array([[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]])


def _pair():
    return U.copy(), sl.procrustes_align(U, V_RAW, scaling=False)


def _brute_q(theta, vel, lam, width):
    kmat = np.exp(-cdist(theta, theta, "sqeuclidean") / (2 * width ** 2))
    a = kmat + lam * np.eye(len(theta))
    return sum(lam * vel[:, i] @ np.linalg.solve(a, vel[:, i]) for i in range(theta.shape[1]))


@pytest.mark.parametrize("lam, width, d", [(10.0, 1.0, 2), (0.5, 0.7, 2), (3.0, 1.6, 3)])
def test_quadratic_form_is_per_coordinate_linear_algebra(lam, width, d):
    rng = np.random.default_rng(d)
    theta, vel = rng.normal(size=(5, d)), rng.normal(size=(5, d))
    q = diffeomorphism_quadratic_form(theta, vel, lam=lam, kernel_width=width)
    assert isinstance(q, float)
    assert q == pytest.approx(_brute_q(theta, vel, lam, width), rel=1e-12)


def test_quadratic_form_defaults_and_the_far_apart_limit():
    theta = np.array([[0.0, 0.0], [50.0, 0.0], [0.0, 50.0]])
    vel = np.array([[1.0, 2.0], [0.5, 0.0], [0.0, -1.0]])
    # far apart: K = I, Q = λ/(1+λ)|v|² with the default λ = 10
    assert diffeomorphism_quadratic_form(theta, vel) == pytest.approx(10 / 11 * np.sum(vel ** 2), rel=1e-12)
    close = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.5]])
    assert diffeomorphism_quadratic_form(close, vel) == pytest.approx(_brute_q(close, vel, 10.0, 1.0), rel=1e-12)


def test_quadratic_form_bad_input_names_it():
    with pytest.raises(ValueError, match=r"velocity must have the shape of theta \(3, 2\); got \(2, 2\)"):
        diffeomorphism_quadratic_form(np.zeros((3, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="lam"):
        diffeomorphism_quadratic_form(np.zeros((3, 2)), np.zeros((3, 2)), lam=0.0)
    with pytest.raises(ValueError, match="kernel_width"):
        diffeomorphism_quadratic_form(np.zeros((3, 2)), np.zeros((3, 2)), kernel_width=-1.0)
    with pytest.raises(ValueError, match="^theta contains non-finite values"):
        diffeomorphism_quadratic_form([[np.nan, 0.0]], [[0.0, 0.0]])
    with pytest.raises(ValueError, match="^velocity contains non-finite values"):
        diffeomorphism_quadratic_form([[0.0, 0.0]], [[np.inf, 0.0]])


def test_gradient_against_central_differences():
    rng = np.random.default_rng(7)
    m = DiffeomorphismPathMetric(2.0, 0.8)
    theta, vel = rng.normal(size=(2, 4, 2)), rng.normal(size=(2, 4, 2))  # two path points at once
    q, d_theta, d_vel = m.qform_grad(theta, vel, None)
    np.testing.assert_allclose(q, m.qform(theta, vel, None), rtol=1e-12)
    eps = 1e-6
    for arr, grad in ((theta, d_theta), (vel, d_vel)):
        fd = np.zeros_like(arr)
        for idx in np.ndindex(arr.shape[1:]):
            plus, minus = arr.copy(), arr.copy()
            plus[(slice(None), *idx)] += eps
            minus[(slice(None), *idx)] -= eps
            args_p = (plus, vel) if arr is theta else (theta, plus)
            args_m = (minus, vel) if arr is theta else (theta, minus)
            fd[(slice(None), *idx)] = (m.qform(*args_p, None) - m.qform(*args_m, None)) / (2 * eps)
        np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-7)


def test_tensor_reproduces_the_form_and_is_symmetric_positive_definite():
    rng = np.random.default_rng(8)
    m = DiffeomorphismPathMetric(1.5, 0.9)
    theta, vel = rng.normal(size=(3, 4, 2)), rng.normal(size=(3, 4, 2))
    g = m.tensors(theta, None)
    assert g.shape == (3, 8, 8)
    np.testing.assert_allclose(g, np.swapaxes(g, 1, 2), atol=1e-13)
    assert np.all(np.linalg.eigvalsh(g) > 0)
    v = vel.reshape(3, 8)
    np.testing.assert_allclose(np.einsum("mi,mij,mj->m", v, g, v), m.qform(theta, vel, None), rtol=1e-12)
    assert m.prepare(theta) is None and m.name == "diffeomorphism"
    assert m.settings() == {"lam": 1.5, "kernel_width": 0.9}


def test_lower_bound_is_the_smallest_metric_over_configurations():
    # the smallest eigenvalue of the tensor over all configurations is reached when the landmarks
    # coincide (K the all-ones matrix): λ/(λ + K); the bound is its square root times ‖v − u‖
    m = DiffeomorphismPathMetric(3.0, 1.0)
    rng = np.random.default_rng(9)
    for k in (2, 5):
        smallest = np.linalg.eigvalsh(m.tensors(np.zeros((1, k, 2)), None)[0]).min()
        u, v = rng.normal(size=(2, k, 2))
        assert m.lower_bound(u, v) == pytest.approx(np.sqrt(smallest) * np.linalg.norm(v - u), rel=1e-10)
        for _ in range(5):  # never above the metric anywhere
            g = m.tensors(rng.normal(size=(1, k, 2)), None)[0]
            assert np.linalg.eigvalsh(g).min() >= smallest * (1 - 1e-12)


def test_options_are_checked():
    with pytest.raises(ValueError, match="lam"):
        _path_metric(-1.0, 1.0)
    with pytest.raises(ValueError, match="kernel_width"):
        _path_metric(1.0, 0.0)
    m = _path_metric(2, 3)
    assert (m.lam, m.width) == (2.0, 3.0)


def _energy(path, lam, width):
    """Path energy by brute force: n Σ Q at the three Gauss–Legendre nodes of every segment, which are exact
    for a segment where K is constant (far-apart landmarks)."""
    n = len(path) - 1
    nodes, weights = np.polynomial.legendre.leggauss(3)
    total = 0.0
    for t in range(n):
        vel = n * (path[t + 1] - path[t])
        for x, w in zip((nodes + 1) / 2, weights / 2):
            total += w * _brute_q(path[t] + x * (path[t + 1] - path[t]), vel, lam, width) / n
    return total


def test_far_apart_landmarks_move_in_straight_lines_at_the_closed_form_distance():
    u = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]])
    v = u + np.array([[0.3, -0.2], [-0.1, 0.4], [0.2, 0.1], [-0.4, -0.3]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.PoseWarning)
        r = landmark_diffeomorphism(u, v, lam=4.0, kernel_width=1.0, n_steps=4)
    expected = np.sqrt(4.0 / 5.0) * np.linalg.norm(v - u)
    assert r.converged and r.length == pytest.approx(expected, rel=1e-8)
    assert r.energy == pytest.approx(expected ** 2, rel=1e-8)
    assert r.energy == pytest.approx(_energy(r.path, 4.0, 1.0), rel=1e-8)
    t = np.linspace(0, 1, 5)[:, None, None]
    np.testing.assert_allclose(r.path, u + t * (v - u), atol=1e-6)
    assert r.lower_bound == pytest.approx(np.sqrt(4.0 / 8.0) * np.linalg.norm(v - u))


def test_a_geodesic_ends_at_its_shapes_is_shorter_than_the_straight_line_and_symmetric():
    u, v = _pair()
    r = landmark_diffeomorphism(u, v, lam=2.0, kernel_width=0.8, n_steps=6, tol=1e-10)
    assert r.converged and r.path.shape == (7, 4, 2) and r.metric == "diffeomorphism"
    np.testing.assert_array_equal(r.path[0], u)
    np.testing.assert_allclose(r.path[-1], v, atol=1e-15)
    assert r.log["lam"] == 2.0 and r.log["kernel_width"] == 0.8
    line = u + np.linspace(0, 1, 7)[:, None, None] * (v - u)
    assert r.energy <= _energy(line, 2.0, 0.8) * (1 + 1e-9)
    assert r.lower_bound <= r.length <= np.sqrt(r.energy) * (1 + 1e-9)
    back = landmark_diffeomorphism(v, u, lam=2.0, kernel_width=0.8, n_steps=6, tol=1e-10)
    assert back.length == pytest.approx(r.length, rel=1e-5)


def test_solver_options_reach_the_solver():
    u, v = _pair()
    with pytest.warns(sl.GeodesicWarning):
        stopped = landmark_diffeomorphism(u, v, n_steps=3, max_iter=0)
    assert not stopped.converged and stopped.n_iter == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.GeodesicWarning)
        quiet = landmark_diffeomorphism(u, v, n_steps=3, max_iter=0, warn=False)
    assert not quiet.converged
    r = landmark_diffeomorphism(u, v, n_steps=3)
    warm = landmark_diffeomorphism(u, v, n_steps=3, init=r.path)
    assert warm.n_iter <= 1 and warm.length == pytest.approx(r.length, rel=1e-6)
    loose = landmark_diffeomorphism(u, v, n_steps=3, tol=1e-1, window=1)
    assert loose.n_iter <= r.n_iter


def test_default_options_are_those_of_the_signature():
    u, v = _pair()
    r = landmark_diffeomorphism(u, v)
    assert r.path.shape[0] == 17 and r.log["lam"] == 10.0 and r.log["kernel_width"] == 1.0 and r.log["tol"] == 1e-6
    assert r.energy == pytest.approx(_energy(r.path, 10.0, 1.0), rel=1e-6)
    explicit = landmark_diffeomorphism(u, v, lam=10.0, kernel_width=1.0, n_steps=16, tol=1e-6, max_iter=500, window=5)
    np.testing.assert_array_equal(r.path, explicit.path)
    assert r.n_iter == explicit.n_iter
    # converged: the tight solve is no shorter, the straight line longer
    tight = landmark_diffeomorphism(u, v, tol=1e-12)
    assert r.length == pytest.approx(tight.length, rel=1e-6)
    line = u + np.linspace(0, 1, 17)[:, None, None] * (v - u)
    assert _energy(line, 10.0, 1.0) > r.energy * (1 + 5e-6)  # (λ = 10: a nearly flat metric)


def test_default_solver_options_on_a_solve_that_needs_them():
    # λ = 0.1 and eight close landmarks: the energy-window stop decides after 16 iterations, so a different
    # tol or window would change the path
    rng = np.random.default_rng(0)
    u = rng.normal(size=(8, 2)) * 0.8
    v = sl.procrustes_align(u, u + 0.6 * rng.normal(size=(8, 2)), scaling=False)
    r = landmark_diffeomorphism(u, v, lam=0.1)
    explicit = landmark_diffeomorphism(u, v, lam=0.1, tol=1e-6, max_iter=500, window=5)
    assert r.n_iter == explicit.n_iter > 5
    np.testing.assert_array_equal(r.path, explicit.path)
    tight = landmark_diffeomorphism(u, v, lam=0.1, tol=1e-12)
    assert r.length == pytest.approx(tight.length, rel=1e-6)


def test_misaligned_shapes_warn_naming_the_metric():
    u, v = _pair()
    with pytest.warns(sl.PoseWarning, match="^diffeomorphism depends on the pose of the shapes"):
        landmark_diffeomorphism(u, v @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + 5.0, n_steps=2, max_iter=3,
                                warn=False)


def test_the_solver_warning_points_at_the_callers_line():
    u, v = _pair()
    with pytest.warns(sl.GeodesicWarning) as caught:
        landmark_diffeomorphism(u, v, n_steps=3, max_iter=0)
    if not UNDER_MUTMUT:
        assert [w.filename for w in caught if issubclass(w.category, sl.GeodesicWarning)] == [__file__]


def _field_brute(x, phi, vel, lam, width):
    kmat = np.exp(-cdist(phi, phi, "sqeuclidean") / (2 * width ** 2))
    w = np.linalg.solve(kmat + lam * np.eye(len(phi)), vel)
    return np.exp(-cdist(x, phi, "sqeuclidean") / (2 * width ** 2)) @ w


def _flow(points, path, lam, width):
    """The points at every path time, by SciPy's adaptive RK45 on ẋ = f_t(x), tight tolerances."""
    n = len(path) - 1
    out = [np.array(points, dtype=float)]
    x = out[0].ravel()
    for t in range(n):
        vel = n * (path[t + 1] - path[t])

        def rhs(s, y, t=t, vel=vel):
            phi = path[t] + (s - t / n) * n * (path[t + 1] - path[t])
            return _field_brute(y.reshape(-1, 2), phi, vel, lam, width).ravel()

        x = solve_ivp(rhs, (t / n, (t + 1) / n), x, rtol=1e-12, atol=1e-13, method="DOP853").y[:, -1]
        out.append(x.reshape(-1, 2))
    return np.stack(out)


def _result():
    u, v = _pair()
    return landmark_diffeomorphism(u, v, lam=2.0, kernel_width=0.8, n_steps=3)


POINTS = np.array([[0.5, 0.5], [0.2, 0.8], [1.4, -0.3], [0.9, 0.1]])


def test_warp_is_the_flow_solved_by_scipy_to_second_order_in_the_substeps():
    r = _result()
    exact = _flow(POINTS, r.path, 2.0, 0.8)
    errors = []
    for sub in (2, 4, 8):
        w = diffeomorphism_warp(POINTS, r, substeps=sub)
        assert w.shape == (4, 4, 2)
        np.testing.assert_array_equal(w[0], POINTS)
        errors.append(np.abs(w - exact).max())
    assert errors[-1] < 1e-4
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 3.0) & (ratios < 5.5))  # RK2: halving the step quarters the error


def test_warp_takes_lam_and_width_from_the_result_unless_given():
    r = _result()
    default = diffeomorphism_warp(POINTS, r)
    np.testing.assert_allclose(default, diffeomorphism_warp(POINTS, r, lam=2.0, kernel_width=0.8, substeps=4),
                               rtol=0, atol=0)
    other = diffeomorphism_warp(POINTS, r, lam=0.5, kernel_width=1.3, substeps=8)
    np.testing.assert_allclose(other, _flow(POINTS, r.path, 0.5, 1.3), atol=1e-4)
    assert np.abs(other - default).max() > 1e-3


def test_the_reversed_path_carries_the_points_back():
    r = _result()
    fwd = diffeomorphism_warp(POINTS, r, substeps=8)
    back_result = dataclasses.replace(r, path=r.path[::-1].copy())
    back = diffeomorphism_warp(fwd[-1], back_result, substeps=8)
    np.testing.assert_allclose(back[-1], POINTS, atol=1e-5)


def test_the_warp_has_a_positive_jacobian_determinant():
    r = _result()
    eps = 1e-6
    for p in POINTS:
        jac = np.zeros((2, 2))
        for i in range(2):
            dp = np.zeros(2)
            dp[i] = eps
            jac[:, i] = (diffeomorphism_warp([p + dp], r)[-1, 0] - diffeomorphism_warp([p - dp], r)[-1, 0]) / (2 * eps)
        assert np.linalg.det(jac) > 0.1


def test_warp_bad_input_names_it():
    r = _result()
    with pytest.raises(ValueError, match="^substeps must be a positive integer; got 0"):
        diffeomorphism_warp(POINTS, r, substeps=0)
    with pytest.raises(ValueError, match="lam"):
        diffeomorphism_warp(POINTS, r, lam=-1.0)
    with pytest.raises(ValueError, match="kernel_width"):
        diffeomorphism_warp(POINTS, r, kernel_width=0.0)
    with pytest.raises(ValueError, match="^points contains non-finite values"):
        diffeomorphism_warp([[np.nan, 0.0]], r)


def test_warp_does_not_change_its_input():
    r = _result()
    pts = POINTS.copy()
    diffeomorphism_warp(pts, r)
    np.testing.assert_array_equal(pts, POINTS)
