"""Log and exp maps by discrete geodesic calculus (shapelib.solver.logexp): limits, round trips,
agreement with an independent integration of the geodesic equation, the tangent space."""

import warnings

import numpy as np
import pytest

import shapelib
from shapelib.solver.geodesic import shoot
from shapelib.solver.logexp import GeodesicOptions, exp_map, exp_path, log_map, tangent_space
from shapelib.solver.path_metric import path_metric
from tests.conftest import ellipse




@pytest.fixture
def pair(rng):
    u = ellipse(10)
    v = u + 0.35 * rng.normal(size=u.shape)
    v = shapelib.procrustes_align(u, v, scaling=False)  # a pair in pose
    return u, v


def test_log_of_the_base_is_zero_and_exp_of_zero_is_the_base(pair):
    u, _ = pair
    assert np.array_equal(log_map(u, u, sigma2=1.0), np.zeros_like(u))
    assert np.array_equal(exp_map(u, np.zeros_like(u), sigma2=1.0), u)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_small_sigma_limit_log_and_exp_are_differences(metric, rng):
    # landmarks 10 apart, sigma = 0.3: the metric is constant (Euclidean up to a factor), geodesics straight
    u = 10.0 * np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 1.7]])
    v = u + 0.2 * rng.normal(size=u.shape)
    v = shapelib.procrustes_align(u, v, scaling=False)  # a pair in pose
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.ScaleWarning)
        vec = log_map(u, v, metric=metric, sigma2=0.09)
        back = exp_map(u, 0.7 * vec, metric=metric, sigma2=0.09)
    assert np.allclose(vec, v - u, atol=1e-8)
    assert np.allclose(back, u + 0.7 * (v - u), atol=1e-8)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
@pytest.mark.parametrize("n_steps", [4, 8])
def test_exp_of_log_returns_the_shape_in_density(pair, metric, n_steps):
    u, v = pair
    res = log_map(u, v, metric=metric, sigma2=1.0, n_steps=n_steps, tol=1e-10, return_result=True)
    back = exp_map(u, res.vector, metric=metric, sigma2=1.0, n_steps=n_steps)
    # the chord of the embedding (L2 for alpha, the sphere of sqrt(p) for Fisher-Rao) vanishes only
    # for equal densities; relative to the distance the round trip is exact up to the solves
    chord = path_metric(metric, 1.0).lower_bound(back, v)
    assert chord <= 1e-3 * np.sqrt(res.energy)
    # the landmarks themselves come back too for this well-conditioned shape
    assert np.abs(back - v).max() < 1e-3 * np.abs(v - u).max()


@pytest.mark.parametrize("d", [2, 3])
def test_log_of_exp_returns_the_vector_in_the_metric(d, rng):
    u = ellipse(9, d=d)
    ts = tangent_space(u, sigma2=1.0)
    w = ts.project(0.4 * rng.normal(size=u.shape))
    y = exp_map(u, w, sigma2=1.0, n_steps=8)
    back = log_map(u, y, sigma2=1.0, n_steps=8, tol=1e-12)
    assert ts.norm(back - w) <= 1e-4 * ts.norm(w)


def test_log_norm_is_the_geodesic_distance(pair):
    u, v = pair
    res = log_map(u, v, sigma2=1.0, n_steps=8, tol=1e-10, return_result=True)
    geo = shapelib.geodesic(u, v, sigma2=1.0, n_steps=8, tol=1e-10)
    norm = tangent_space(u, sigma2=1.0).norm(res.vector)
    assert np.isclose(res.energy, geo.energy, rtol=1e-6)
    assert geo.lower_bound <= norm * (1 + 1e-9)
    assert abs(norm / geo.length - 1) < 0.05  # the O(1/n) error of a one-sided difference


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_exp_converges_to_the_integrated_geodesic_equation(metric, rng):
    # few, well separated landmarks: the metric is well conditioned and shoot's RK4 on eq. 11 is reliable
    u = np.array([[0, 0], [1.5, 0.2], [1.2, 1.6], [-0.3, 1.1]], float)
    v = 0.8 * np.random.default_rng(0).normal(size=u.shape)
    ref = shoot(u, v, metric=metric, sigma2=1.0, n_steps=400)[-1]
    err = [np.abs(exp_map(u, v, metric=metric, sigma2=1.0, n_steps=n) - ref).max() for n in (4, 16, 64)]
    assert err[0] > err[1] > err[2]
    assert err[2] < 0.05 * np.abs(v).max()
    assert np.abs(ref - u - v).max() > 10 * err[2]  # the geodesic is far from straight


def test_exp_path_is_a_discrete_geodesic(pair):
    u, v = pair
    opts = GeodesicOptions("alpha", 1.0, n_steps=6)
    res = log_map(u, v, sigma2=1.0, n_steps=6, tol=1e-10, return_result=True)
    path, info = exp_path(u, res.vector, options=opts)
    assert info["converged"]
    assert np.abs(path - res.path).max() < 1e-3 * np.abs(v - u).max()


def test_tangent_space_coordinates_are_isometric(pair, rng):
    u, _ = pair
    ts = tangent_space(u, metric="alpha", sigma2=1.0)
    a, b = ts.project(rng.normal(size=u.shape)), ts.project(rng.normal(size=u.shape))
    assert np.isclose(ts.coords(a) @ ts.coords(b), ts.inner(a, b), rtol=1e-10)
    assert np.allclose(ts.vectors(ts.coords(a)), a)
    assert np.allclose(ts.project(a), a)
    g = shapelib.alpha_metric(u, sigma2=1.0)
    assert np.isclose(ts.inner(a, b), a.ravel() @ g @ b.ravel())
    assert ts.discarded_fraction(a[None]) < 1e-12


def test_flat_directions_are_dropped_on_a_dense_contour():
    u = ellipse(60, a=6, b=3)  # spacing ~0.5, sigma = 1.1: sliding barely changes the density
    ts = tangent_space(u, sigma2=1.2, rcond=1e-6)
    assert ts.rank < 0.8 * u.size
    assert ts.eigenvalues[-1] / ts.eigenvalues[0] < 1e-10
    slide = np.roll(u, -1, axis=0) - np.roll(u, 1, axis=0)  # tangent to the contour
    radial = u / np.linalg.norm(u, axis=1, keepdims=True)
    assert ts.norm(slide) / np.linalg.norm(slide) < 1e-2 * ts.norm(radial) / np.linalg.norm(radial)


def test_bad_input_is_named():
    u = ellipse(6)
    with pytest.raises(ValueError, match="base and shape"):
        log_map(u, u[:5], sigma2=1.0)
    with pytest.raises(ValueError, match="metric"):
        log_map(u, u, metric="procrustes", sigma2=1.0)
    with pytest.raises(ValueError, match="d = 2 or 3"):
        exp_map(np.zeros((5, 4)), np.zeros((5, 4)), sigma2=1.0)
    with pytest.raises(ValueError, match="rcond"):
        exp_map(u, u, sigma2=1.0, rcond=2.0)
    with pytest.raises(ValueError, match="sigma2"):
        log_map(u, u, sigma2=-1.0)


def test_magnify_retraces_and_extends_the_geodesic(pair):
    from shapelib.solver.logexp import magnify

    u, v = pair
    geo = shapelib.geodesic(u, v, sigma2=1.0, n_steps=8, tol=1e-11)
    big = magnify(geo, 2.0)
    assert big.n_steps == 16
    assert np.abs(big.path[:9] - geo.path).max() < 1e-3 * np.abs(v - u).max()
    assert np.isclose(big.length, 2 * geo.length, rtol=0.02)
    small = magnify(geo, 0.5)
    assert np.abs(small.path - geo.path[:5]).max() < 1e-3 * np.abs(v - u).max()
    assert magnify(geo, 1.0) is geo
    with pytest.raises(ValueError, match="mag"):
        magnify(geo, 0.0)
