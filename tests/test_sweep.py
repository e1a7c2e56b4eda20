"""Statistics across a sweep (shapelib.statistics.sweep): the min-P family-wise p-value is a
p-value where the smallest plain p over the sweep is not, and reduces to the plain test for one value."""

import numpy as np
import pandas as pd
import pytest

from shapelib.statistics.distance_based import knn_loo_accuracy, permanova
from shapelib.statistics.sweep import knn_sweep, min_p_adjusted, permanova_sweep


def _euclid(y):
    return np.sqrt(((y[:, None, :] - y[None, :, :]) ** 2).sum(-1))


def test_min_p_is_calibrated_where_the_smallest_plain_p_is_not(rng):
    """Observed and permuted statistics exchangeable (no effect), 20 independent sweep values:
    the smallest plain p falls to 0.05 in ~64 % of the data sets, the min-P p in ~5 % (a little
    less: its smallest attainable value is about 20 / (1 + permutations))."""
    sims, perms, values = 600, 999, 20
    fam, naive = [], []
    for _ in range(sims):
        rows = rng.normal(size=(perms + 1, values))
        p, pf = min_p_adjusted(rows[0], rows[1:])
        fam.append(pf)
        naive.append(p.min())
    fam, naive = np.array(fam), np.array(naive)
    assert np.mean(naive <= 0.05) > 0.5
    assert 0.02 <= np.mean(fam <= 0.05) <= 0.07
    assert 0.15 <= np.mean(fam <= 0.2) <= 0.25
    assert fam.min() > 0.5 * values / (perms + 1)  # about S / (1 + P) at best


def test_min_p_never_below_the_plain_p_at_the_best_value_and_one_value_is_the_plain_test(rng):
    for _ in range(50):
        rows = rng.normal(size=(60, 5)) + np.array([0, 0, 1.5, 0, 0])[None, :] * (np.arange(60) == 0)[:, None]
        p, pf = min_p_adjusted(rows[0], rows[1:])
        assert p.min() <= pf <= 1
    p, pf = min_p_adjusted(rows[0, :1], rows[1:, :1])
    assert pf == pytest.approx(p[0])


def _population(rng, n=40, effect=0.0):
    labels = np.repeat(["a", "b"], n // 2)
    y = rng.normal(size=(n, 6))
    y[labels == "b", 0] += effect
    return y, labels


def test_permanova_sweep_equals_permanova_per_matrix_and_finds_the_informative_scale(rng):
    """Three 'scales': noise only, the group effect, noise only. Each is the plain PERMANOVA; the
    sweep's best is the informative one and survives the family-wise test."""
    y, labels = _population(rng, effect=2.0)
    noise = rng.normal(size=y.shape)
    mats = [_euclid(noise), _euclid(y), _euclid(rng.normal(size=y.shape))]
    cov = pd.DataFrame({"group": labels})
    sweep = permanova_sweep(mats, cov, term="group", n_permutations=199, seed=3)
    for d, res in zip(mats, sweep.results):
        one = permanova(d, cov, n_permutations=199, seed=3)
        assert res.table.loc["group", "pseudo_F"] == one.table.loc["group", "pseudo_F"]
    assert sweep.best == 1 and sweep.p_values[1] == pytest.approx(1 / 200)
    assert sweep.p_family <= 3 / 200 and "min-P" in sweep.summary()


def test_knn_sweep_one_matrix_is_the_plain_test(rng):
    y, labels = _population(rng, effect=1.0)
    d = _euclid(y)
    sweep = knn_sweep([d], labels, n_neighbors=3, n_permutations=99, seed=1)
    plain = knn_loo_accuracy(d, labels, n_neighbors=3, n_permutations=99, seed=1)
    assert sweep.statistic[0] == plain.accuracy and sweep.p_values[0] == pytest.approx(plain.p_value)
    assert sweep.p_family == pytest.approx(plain.p_value)


def test_bad_input(rng):
    with pytest.raises(ValueError, match=r"observed must be \(S,\)"):
        min_p_adjusted([1.0, 2.0], np.zeros((5, 3)))
    y, labels = _population(rng)
    with pytest.raises(ValueError, match="not a column"):
        permanova_sweep([_euclid(y)], pd.DataFrame({"group": labels}), term="sex")
    with pytest.raises(ValueError, match="sweep is empty"):
        knn_sweep([], labels)
