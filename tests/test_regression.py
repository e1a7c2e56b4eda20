"""Geodesic regression (shapelib.statistics.regression): recovery of a geodesic from noiseless data,
the exact gradient, the small-σ limit (linear regression), R², prediction, 3-D."""

import warnings

import numpy as np
import pytest

import shapelib
from shapelib.statistics.regression import geodesic_regression

# the data lie on a geodesic between two aligned shapes (or near it): a set the pose check finds
# "not aligned" at its 0.1 % tolerance, as are the perturbed ends the tests solve geodesics for
pytestmark = pytest.mark.filterwarnings("ignore::shapelib.PoseWarning")
from tests.conftest import ellipse




@pytest.fixture(scope="module")
def geodesic_data():
    rng = np.random.default_rng(0)
    u = ellipse(10)
    v = u + 0.6 * rng.normal(size=u.shape)
    v = shapelib.procrustes_align(u, v, scaling=False)  # a pair in pose
    geo = shapelib.geodesic(u, v, sigma2=1.0, n_steps=16, tol=1e-12)
    idx = np.array([0, 1, 3, 4, 6, 8, 9, 11, 13, 16])
    return geo, geo.path[idx], 2.0 + idx / 16 * 10


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_noiseless_data_on_a_geodesic_are_recovered(metric):
    rng = np.random.default_rng(1)
    u = ellipse(8)
    v = u + 0.5 * rng.normal(size=u.shape)
    v = shapelib.procrustes_align(u, v, scaling=False)  # a pair in pose
    geo = shapelib.geodesic(u, v, metric=metric, sigma2=1.0, n_steps=8, tol=1e-12)
    idx = np.array([0, 2, 3, 5, 8])
    y, t = geo.path[idx], 10.0 + idx / 8 * 4
    res = geodesic_regression(y, t, metric=metric, sigma2=1.0, path_steps=8, tol=1e-6, n_jobs=1)
    assert res.converged and res.r2 > 1 - 1e-9
    assert np.abs(res.fitted - y).max() < 1e-6
    assert np.abs(res.path - geo.path).max() < 1e-6  # the whole geodesic, between the data too
    assert np.allclose(res.predict(t[2]), y[2], atol=1e-6)


def test_half_way_points_and_velocity(geodesic_data):
    geo, y, t = geodesic_data
    res = geodesic_regression(y, t, sigma2=1.0, tol=1e-6, path_steps=16, n_jobs=1)
    assert res.r2 > 1 - 1e-9
    # the geodesic's speed in t: its length over the covariate range
    assert np.isclose(res.speed * (t.max() - t.min()), geo.length, rtol=0.02)
    mid = res.predict(7.0)  # t = 7 is path point 8 of 16
    assert np.abs(mid - geo.path[8]).max() < 1e-6
    # outside the range: the exponential map continues the geodesic
    ext = res.predict([12.0, 13.0])
    assert np.allclose(ext[0], res.path[-1], atol=1e-12) and np.allclose(ext[0], geo.path[-1], atol=1e-6)
    assert shapelib.path_length(np.stack([geo.path[-1], ext[1]]), sigma2=1.0) > 0


def test_noisy_fit_is_stationary_and_r2_is_fletchers(geodesic_data):
    geo, y, t = geodesic_data
    rng = np.random.default_rng(2)
    noisy = y + 0.1 * rng.normal(size=y.shape)
    res = geodesic_regression(noisy, t, sigma2=1.0, tol=1e-4, n_jobs=1)
    assert res.converged and 0 < res.r2 < 1
    # R² = 1 − Σd²(y, ŷ) / Σd²(y, mean), every d² a geodesic energy recomputed independently
    ss_res = sum(shapelib.geodesic(f, x, sigma2=1.0, n_steps=4, tol=1e-10).energy
                 for f, x in zip(res.fitted, noisy))
    ss_tot = sum(shapelib.geodesic(res.mean.mean, x, sigma2=1.0, n_steps=4, tol=1e-10).energy for x in noisy)
    assert np.isclose(res.r2, 1 - ss_res / ss_tot, atol=1e-5)
    # a perturbed geodesic (moved ends) fits worse: the fit is a minimum
    for k in range(2):
        step = 0.02 * np.random.default_rng(k).normal(size=res.path[0].shape)
        m = res.path.shape[0] - 1
        path = shapelib.geodesic(res.path[0] + step, res.path[-1] - step, sigma2=1.0, n_steps=m, tol=1e-10).path
        s = (t - t.min()) / (t.max() - t.min()) * m
        j = np.minimum(np.floor(s).astype(int), m - 1)
        pred = (1 - (s - j))[:, None, None] * path[j] + (s - j)[:, None, None] * path[j + 1]
        worse = sum(shapelib.geodesic(p, x, sigma2=1.0, n_steps=4, tol=1e-10).energy for p, x in zip(pred, noisy))
        assert worse > ss_res


def test_small_sigma_limit_is_linear_regression():
    rng = np.random.default_rng(3)
    base = 5.0 * np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 1.7]])  # overlaps ~exp(-50)
    slope = 0.2 * rng.normal(size=base.shape)
    t = np.linspace(8, 20, 9)
    y = base + (t - 14)[:, None, None] * slope / 6 + 0.05 * rng.normal(size=(9, *base.shape))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.ScaleWarning)
        res = geodesic_regression(y, t, sigma2=0.09, tol=1e-9, n_jobs=1)
    tc = t - t.mean()
    b = np.einsum("n,nkd->kd", tc, y) / (tc @ tc)
    a = y.mean(axis=0)
    assert np.allclose(res.intercept, a, atol=1e-7) and np.allclose(res.velocity, b, atol=1e-7)
    ss_res = np.sum((y - a - tc[:, None, None] * b) ** 2)
    ss_tot = np.sum((y - a) ** 2)
    assert np.isclose(res.r2, 1 - ss_res / ss_tot, atol=1e-7)


def test_three_dimensional_landmarks():
    rng = np.random.default_rng(4)
    u = ellipse(8, d=3)
    v = u + 0.4 * rng.normal(size=u.shape)
    v = shapelib.procrustes_align(u, v, scaling=False)  # a pair in pose
    geo = shapelib.geodesic(u, v, sigma2=1.0, n_steps=8, tol=1e-12)
    idx = np.array([0, 3, 5, 8])
    res = geodesic_regression(geo.path[idx], idx / 8.0, sigma2=1.0, path_steps=8, tol=1e-6, n_jobs=1)
    assert res.r2 > 1 - 1e-9 and res.intercept.shape == (8, 3)


def test_bad_input(geodesic_data):
    _, y, t = geodesic_data
    with pytest.raises(ValueError, match="one value per shape"):
        geodesic_regression(y, t[:-1], sigma2=1.0, n_jobs=1)
    with pytest.raises(ValueError, match="constant"):
        geodesic_regression(y, np.ones(len(y)), sigma2=1.0, n_jobs=1)
    with pytest.raises(ValueError, match="non-finite"):
        geodesic_regression(y, np.where(np.arange(len(t)) == 3, np.nan, t), sigma2=1.0, n_jobs=1)
    with pytest.raises(ValueError, match="mean must be"):
        geodesic_regression(y, t, sigma2=1.0, mean=y[0], n_jobs=1)
