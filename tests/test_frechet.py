"""Fréchet mean (shapelib.statistics.frechet): first-order condition checked with independent
geodesics, invariances, the small-σ (Euclidean) limit, optimality, 2-D and 3-D."""

import warnings
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import shapelib
from shapelib.solver.logexp import tangent_space
from shapelib.statistics.frechet import frechet_mean, mean_certificate, procrustes_mean
from tests.conftest import ellipse_population


def population(rng, n=8, k=10, d=2, noise=0.3):
    """A common deformation mode plus noise: a population with structure."""
    return ellipse_population(rng, n, k, d, noise=noise)


@pytest.fixture(scope="module")
def shapes():
    return population(np.random.default_rng(7))


@pytest.fixture(scope="module")
def result(shapes):
    return frechet_mean(shapes, sigma2=1.0, tol=1e-4, n_jobs=1)


def test_first_order_condition_with_independent_geodesics(shapes, result):
    assert result.converged and result.certificate <= 1e-4
    # log maps recomputed from scratch by the geodesic solver (straight-line start, tight tolerance)
    n = result.options.n_steps
    logs = []
    for x in shapes:
        geo = shapelib.geodesic(result.mean, x, sigma2=1.0, n_steps=n, tol=1e-11, max_iter=2000)
        logs.append(n * (geo.path[1] - geo.path[0]))
    grad, spread, cert = mean_certificate(tangent_space(result.mean, sigma2=1.0), np.stack(logs))
    assert cert < 1e-3
    assert np.isclose(spread, result.spread, rtol=1e-3)


def test_variance_is_the_mean_squared_distance_and_is_minimal(shapes, result):
    def frechet_function(m):
        return np.mean([shapelib.geodesic(m, x, sigma2=1.0, n_steps=result.options.n_steps, tol=1e-10).energy
                        for x in shapes])

    f0 = frechet_function(result.mean)
    assert np.isclose(result.variance, f0, rtol=1e-5)
    assert f0 < frechet_function(result.init)
    ts = result.tangent
    rng = np.random.default_rng(3)
    for _ in range(2):
        step = ts.project(rng.normal(size=result.mean.shape))
        step *= 0.2 * result.spread / ts.norm(step)
        assert frechet_function(result.mean + step) > f0


def test_mean_of_copies_is_the_shape(shapes):
    res = frechet_mean(np.repeat(shapes[:1], 5, axis=0), sigma2=1.0, n_jobs=1)
    assert res.converged and res.n_iter == 0
    assert np.array_equal(res.mean, shapes[0])
    assert res.variance == 0 and res.certificate == 0


def test_mean_does_not_depend_on_the_order(shapes, result):
    perm = np.random.default_rng(1).permutation(len(shapes))
    res = frechet_mean(shapes[perm], sigma2=1.0, tol=1e-4, n_jobs=1)
    assert np.allclose(procrustes_mean(shapes[perm]), procrustes_mean(shapes), atol=1e-9)
    assert np.abs(res.mean - result.mean).max() < 1e-6
    assert np.allclose(res.logs, result.logs[perm], atol=1e-5)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_small_sigma_limit_is_the_arithmetic_mean(metric):
    rng = np.random.default_rng(5)
    base = 10.0 * np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 1.7]])
    aligned, _ = shapelib.generalized_procrustes(base + 0.3 * rng.normal(size=(6, *base.shape)))
    x = 6 * aligned  # landmarks ~3.5 apart, sigma = 0.3: overlaps ~exp(-34)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.ScaleWarning)
        res = frechet_mean(x, metric=metric, sigma2=0.09, tol=1e-8, n_jobs=1)
    assert res.converged
    assert np.abs(res.mean - x.mean(axis=0)).max() < 1e-6
    assert np.allclose(res.logs, x - x.mean(axis=0), atol=1e-6)


def test_three_dimensional_landmarks():
    x = population(np.random.default_rng(11), n=6, k=9, d=3)
    res = frechet_mean(x, sigma2=1.0, tol=1e-4, n_jobs=1)
    assert res.converged and res.mean.shape == (9, 3)
    assert res.variance < np.mean([shapelib.geodesic(res.init, s, sigma2=1.0, n_steps=4, tol=1e-9).energy for s in x])


def test_executor_gives_the_in_process_answer(shapes, result):
    with ProcessPoolExecutor(2) as ex:
        res = frechet_mean(shapes, sigma2=1.0, tol=1e-4, executor=ex, chunk_size=3)
    assert np.allclose(res.mean, result.mean, atol=1e-12)
    assert res.n_iter == result.n_iter


def test_summary_and_history(result):
    text = result.summary()
    assert "certificate" in text and "alpha" in text
    certs = [h["certificate"] for h in result.log]
    assert certs[-1] == result.certificate and certs[0] > certs[-1]
    assert result.n_log_maps >= len(result.logs) * (result.n_iter + 1)


def test_not_converged_warns(shapes):
    with pytest.warns(shapelib.GeodesicWarning, match="certificate"):
        res = frechet_mean(shapes, sigma2=1.0, tol=1e-12, max_iter=1, n_jobs=1)
    assert not res.converged and res.n_iter == 1


def test_bad_input(shapes):
    with pytest.raises(ValueError, match="init must have shape"):
        frechet_mean(shapes, sigma2=1.0, init=shapes[0, :5], n_jobs=1)
    with pytest.raises(ValueError, match="shapes"):
        frechet_mean(shapes[0], sigma2=1.0, n_jobs=1)
    with pytest.raises(ValueError, match="tol"):
        frechet_mean(shapes, sigma2=1.0, tol=0, n_jobs=1)


def test_a_population_out_of_pose_is_warned_once(shapes):
    aligned = shapelib.pose_align(shapes)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", shapelib.PoseWarning)
        frechet_mean(aligned, sigma2=1.0, n_jobs=1)
    turned = aligned.copy()
    c, s = np.cos(0.3), np.sin(0.3)
    turned[0] = aligned[0] @ np.array([[c, -s], [s, c]])
    with pytest.warns(shapelib.PoseWarning, match="not aligned") as record:
        frechet_mean(turned, sigma2=1.0, n_jobs=1)
    assert sum(issubclass(w.category, shapelib.PoseWarning) for w in record) == 1
