import numpy as np
import pytest

from shapelib.comparison.diffeomorphism import (
    DiffeomorphismPathMetric,
    diffeomorphism_quadratic_form,
    diffeomorphism_warp,
    landmark_diffeomorphism,
)
from shapelib.solver.geodesic import path_length  # noqa: F401  (same solver family)


@pytest.fixture
def pair(rng):
    u = np.array([[0.0, 0.0], [1.0, 0.3], [2.0, 0.0], [1.0, -0.8]])
    return u, u + 0.3 * rng.normal(size=u.shape)


def test_single_landmark_is_flat():
    lam = 10.0
    u, v = np.array([[0.0, 0.0]]), np.array([[2.0, 1.0]])
    r = landmark_diffeomorphism(u, v, lam=lam, n_steps=4)
    assert r.length == pytest.approx(np.sqrt(lam / (1 + lam)) * np.sqrt(5), rel=1e-10)
    assert np.allclose(r.path[:, 0], np.linspace(u[0], v[0], 5))


def test_quadratic_form_closed_form(rng):
    theta, vel = rng.normal(size=(2, 5, 2))
    lam, s = 3.0, 0.7
    d = theta[:, None] - theta[None]
    kmat = np.exp(-(d**2).sum(-1) / (2 * s * s))
    expect = lam * np.sum(vel * np.linalg.solve(kmat + lam * np.eye(5), vel))
    assert diffeomorphism_quadratic_form(theta, vel, lam=lam, kernel_width=s) == pytest.approx(expect, rel=1e-12)


def test_gradients_against_finite_differences(rng):
    theta, vel = rng.normal(size=(2, 4, 2))
    m = DiffeomorphismPathMetric(5.0, 0.9)
    q, dt, dv = m.qform_grad(theta[None], vel[None], None)
    eps = 1e-6
    for arr, grad, which in ((theta, dt[0], 0), (vel, dv[0], 1)):
        fd = np.zeros_like(arr)
        for idx in np.ndindex(arr.shape):
            e = np.zeros_like(arr)
            e[idx] = eps
            args_p = (theta + e, vel) if which == 0 else (theta, vel + e)
            args_m = (theta - e, vel) if which == 0 else (theta, vel - e)
            fd[idx] = (m.qform(args_p[0][None], args_p[1][None], None)[0] - m.qform(args_m[0][None], args_m[1][None], None)[0]) / (2 * eps)
        assert np.allclose(grad, fd, rtol=1e-6, atol=1e-9)


def test_translation_bounds_symmetry_and_descent(pair):
    u, v = pair
    r = landmark_diffeomorphism(u, v, lam=10.0, kernel_width=1.0, n_steps=8)
    assert r.converged
    assert r.lower_bound <= r.length <= np.sqrt(r.log["energy"][0]) * (1 + 1e-9)
    back = landmark_diffeomorphism(v, u, lam=10.0, kernel_width=1.0, n_steps=8)
    assert back.length == pytest.approx(r.length, rel=1e-4)
    shift = landmark_diffeomorphism(u, u + [1.0, 0.5], lam=10.0, kernel_width=1.0, n_steps=8)
    straight = np.sqrt(diffeomorphism_quadratic_form(u, np.tile([1.0, 0.5], (4, 1)), lam=10.0, kernel_width=1.0))
    assert shift.length <= straight * (1 + 1e-9)


def test_warp_identity_and_landmark_tracking(pair):
    u, v = pair
    still = landmark_diffeomorphism(u, u, n_steps=4)
    pts = np.random.default_rng(0).normal(size=(10, 2))
    assert np.allclose(diffeomorphism_warp(pts, still), pts)
    r = landmark_diffeomorphism(u, v, lam=0.01, kernel_width=1.0, n_steps=8)
    # with small λ the spline nearly interpolates: landmarks carried by the flow land near v
    moved = diffeomorphism_warp(u, r, substeps=8)[-1]
    assert np.abs(moved - v).max() < 0.05 * np.abs(v - u).max() + 1e-3


def test_errors(pair):
    u, v = pair
    with pytest.raises(ValueError, match="lam"):
        landmark_diffeomorphism(u, v, lam=0)
    with pytest.raises(ValueError, match="kernel_width"):
        landmark_diffeomorphism(u, v, kernel_width=-1)
    with pytest.raises(ValueError, match="same number of landmarks"):
        landmark_diffeomorphism(u, v[:2])
    r = landmark_diffeomorphism(u, v, n_steps=4)
    for bad in ({"lam": 0.0}, {"kernel_width": -1.0}, {"lam": float("nan")}):  # the warp checks what it is given
        with pytest.raises(ValueError, match=f"{next(iter(bad))} must be a positive finite number"):
            diffeomorphism_warp(u, r, **bad)
    for bad in (0, -2, 1.5):  # substeps divide each segment: never zero, never fractional
        with pytest.raises(ValueError, match="substeps"):
            diffeomorphism_warp(u, r, substeps=bad)
