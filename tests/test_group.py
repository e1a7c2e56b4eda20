"""The group test (shapelib.statistics.group): size within its binomial band under the null, power
on a real difference, the statistic against the distance of the groups' Fréchet means."""

import warnings

import numpy as np
import pytest
from scipy.stats import binom

import shapelib
from shapelib.statistics.frechet import frechet_mean
from shapelib.statistics.group import mean_difference_test
from tests.conftest import ellipse




def sample(rng, n, shift=0.0, k=7, d=2):
    base = ellipse(k, d=d)
    mode = np.zeros_like(base)
    mode[:, 0] = 0.2 * base[:, 0]
    return np.stack([base + shift * mode + 0.2 * rng.normal(size=base.shape) for _ in range(n)])


def aligned(x):
    return shapelib.pose_align(x)[0]  # the statistics take aligned populations


def test_size_is_within_its_binomial_band_under_the_null():
    rng = np.random.default_rng(2026)
    n_sets, alpha = 100, 0.05
    pvals = []
    for _ in range(n_sets):
        x = aligned(sample(rng, 12))  # one population, labels assigned at random: no group difference
        groups = np.array(["a"] * 6 + ["b"] * 6)
        res = mean_difference_test(x, groups, sigma2=1.0, n_permutations=999, seed=rng, group_means=False,
                                   n_steps=2, n_jobs=1)
        pvals.append(res.p_value)
    pvals = np.array(pvals)
    lo, hi = binom.ppf([0.0005, 0.9995], n_sets, alpha)
    assert lo <= np.sum(pvals <= alpha) <= hi
    lo, hi = binom.ppf([0.0005, 0.9995], n_sets, 0.5)
    assert lo <= np.sum(pvals <= 0.5) <= hi  # the p-values are uniform, not only in the tail
    assert pvals.min() >= 1 / 1000


def test_a_real_difference_is_found_and_measured():
    rng = np.random.default_rng(5)
    x = aligned(np.concatenate([sample(rng, 10), sample(rng, 10, shift=1.0)]))
    groups = np.array(["ctrl"] * 10 + ["case"] * 10)
    res = mean_difference_test(x, groups, sigma2=1.0, order=("ctrl", "case"), n_permutations=999, seed=1, n_jobs=1)
    assert res.labels == ("ctrl", "case") and res.sizes == (10, 10)
    assert res.p_value == 1 / 1000
    # the tangent statistic approximates the distance between the groups' Fréchet means
    assert res.means[0].converged and res.means[1].converged
    assert abs(res.statistic / res.distance - 1) < 0.1
    assert res.geodesic.lower_bound <= res.distance
    assert np.allclose(res.geodesic.path[0], res.means[0].mean) and np.allclose(res.geodesic.path[-1],
                                                                                res.means[1].mean)
    # each group mean is the Fréchet mean of its group, computed independently
    with warnings.catch_warnings():  # one group of an aligned set, in the set's frame
        warnings.simplefilter("ignore", shapelib.PoseWarning)
        alone = frechet_mean(x[10:], sigma2=1.0, n_jobs=1)
    assert shapelib.path_metric("alpha", 1.0).lower_bound(alone.mean, res.means[1].mean) < 1e-2 * res.distance
    # the difference points from ctrl to case: the x-stretch of the shift
    assert res.difference[:, 0] @ ellipse(7)[:, 0] > 0
    assert "p = 0.001" in res.summary()


def test_statistic_is_symmetric_and_label_free():
    rng = np.random.default_rng(8)
    x = aligned(np.concatenate([sample(rng, 6), sample(rng, 6, shift=0.5)]))
    pooled = frechet_mean(x, sigma2=1.0, n_jobs=1)
    g = np.array([0] * 6 + [1] * 6)
    r1 = mean_difference_test(x, g, sigma2=1.0, pooled=pooled, group_means=False, n_permutations=99, seed=3, n_jobs=1)
    r2 = mean_difference_test(x, 1 - g, sigma2=1.0, pooled=pooled, group_means=False, n_permutations=99, seed=3, n_jobs=1)
    assert np.isclose(r1.statistic, r2.statistic) and np.allclose(r1.null, r2.null)
    # the statistic is the metric norm of the difference vector
    assert np.isclose(r1.statistic, pooled.tangent.norm(r1.difference))


def test_three_dimensional_landmarks():
    rng = np.random.default_rng(9)
    x = aligned(np.concatenate([sample(rng, 5, d=3), sample(rng, 5, shift=1.0, d=3)]))
    res = mean_difference_test(x, [0] * 5 + [1] * 5, sigma2=1.0, n_permutations=199, seed=0, geodesic_steps=8, n_jobs=1)
    assert res.geodesic.path.shape == (9, 7, 3) and res.p_value < 0.05


def test_bad_input():
    x = sample(np.random.default_rng(0), 6)
    with pytest.raises(ValueError, match="exactly two labels"):
        mean_difference_test(x, [0, 1, 2, 0, 1, 2], sigma2=1.0, n_jobs=1)
    with pytest.raises(ValueError, match="one label per shape"):
        mean_difference_test(x, [0, 1], sigma2=1.0, n_jobs=1)
    with pytest.raises(ValueError, match="n_permutations"):
        mean_difference_test(x, [0, 1] * 3, sigma2=1.0, n_permutations=5, n_jobs=1)
    with pytest.raises(ValueError, match="exactly two labels"):
        mean_difference_test(x, [0, 1] * 3, sigma2=1.0, order=("a", "b"), n_jobs=1)
