"""Checks of shapelib.statistics.sweep against independent values: the plain and min-P p-values counted by
brute force (a loop over every row and value, straight from their definitions in Westfall & Young 1993),
the sweeps against a loop that calls permanova / knn_loo_accuracy one matrix at a time, the best value by
its documented rule (smallest p, ties: largest statistic), and the summary against the fields."""

import numpy as np
import pandas as pd
import pytest

from shapelib.statistics.distance_based import TIE_RTOL, knn_loo_accuracy, permanova
from shapelib.statistics.sweep import SweepTest, knn_sweep, min_p_adjusted, permanova_sweep


def _brute(observed, null, rtol=0.0):
    rows = np.vstack([observed, null])
    n, s_count = rows.shape
    p_all = np.zeros(rows.shape)
    for k in range(n):
        for s in range(s_count):
            p_all[k, s] = sum(rows[j, s] >= rows[k, s] - rtol * abs(rows[k, s]) for j in range(n)) / n
    p = np.array([(1 + sum(null[j, s] >= observed[s] - rtol * abs(observed[s]) for j in range(len(null)))) / n
                  for s in range(s_count)])
    mins = p_all.min(axis=1)
    return p, sum(mins[k] <= mins[0] for k in range(n)) / n


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_min_p_adjusted_is_its_definition_counted_by_brute_force(seed):
    rng = np.random.default_rng(seed)
    null = rng.normal(size=(29, 4))
    observed = rng.normal(size=4) + [0.0, 1.5, 0.3, -0.5]
    p, pf = min_p_adjusted(observed, null)
    bp, bpf = _brute(observed, null)
    np.testing.assert_allclose(p, bp, rtol=0, atol=1e-15)
    assert pf == pytest.approx(bpf, abs=1e-15)


def test_min_p_adjusted_with_ties_counts_them_as_at_least_as_large():
    # integer statistics (accuracies of a k-NN): many exact ties within a column and across rows
    rng = np.random.default_rng(4)
    null = rng.integers(0, 4, size=(19, 3)).astype(float)
    observed = np.array([2.0, 3.0, 1.0])
    p, pf = min_p_adjusted(observed, null)
    bp, bpf = _brute(observed, null)
    np.testing.assert_allclose(p, bp, atol=1e-15)
    assert pf == pytest.approx(bpf, abs=1e-15)


def test_min_p_adjusted_rtol_counts_near_ties_from_below():
    observed = np.array([1.0, -2.0])
    null = np.array([[1.0 - 5e-10, -2.0 - 5e-10], [1.0 - 5e-8, -2.0 - 5e-8], [0.5, -3.0], [2.0, 0.0]])
    # without rtol only the larger values count
    p0, pf0 = min_p_adjusted(observed, null)
    bp0, bpf0 = _brute(observed, null)
    np.testing.assert_allclose(p0, bp0, atol=1e-15) and pytest.approx(bpf0) == pf0
    np.testing.assert_allclose(p0, [2 / 5, 2 / 5])
    # rtol 1e-9: a value within 1e-9 |value| below counts (for a negative value too), 5e-8 below does not
    p, pf = min_p_adjusted(observed, null, rtol=1e-9)
    bp, bpf = _brute(observed, null, rtol=1e-9)
    np.testing.assert_allclose(p, bp, atol=1e-15)
    assert pf == pytest.approx(bpf, abs=1e-15)
    np.testing.assert_allclose(p, [3 / 5, 3 / 5])


@pytest.mark.parametrize("seed", range(6))
def test_min_p_adjusted_rtol_with_near_ties_everywhere(seed):
    # values from {0, 1, 2, 3}, each nudged by at most 5e-10 of itself: with rtol = 1e-9 every nudged copy of a
    # value ties with it, in the plain p-values and in every permuted row's p-values of the min-P test
    rng = np.random.default_rng(seed)
    rows = rng.integers(0, 4, size=(12, 3)) * (1 + rng.choice([-5e-10, 0.0, 5e-10], size=(12, 3)))
    p, pf = min_p_adjusted(rows[0], rows[1:], rtol=1e-9)
    bp, bpf = _brute(rows[0], rows[1:], rtol=1e-9)
    np.testing.assert_allclose(p, bp, atol=1e-15)
    assert pf == pytest.approx(bpf, abs=1e-15)


def test_integer_statistics_give_the_float_answer():
    rng = np.random.default_rng(9)
    null = rng.integers(0, 5, size=(15, 3))
    observed = np.array([3, 4, 2])
    p, pf = min_p_adjusted(observed, null)
    pf_float = min_p_adjusted(observed.astype(float), null.astype(float))[1]
    bp, bpf = _brute(observed.astype(float), null.astype(float))
    np.testing.assert_allclose(p, bp, atol=1e-15)
    assert pf == pytest.approx(bpf, abs=1e-15) and pf == pf_float


def test_one_permutation_and_an_observed_row_that_is_the_largest():
    p, pf = min_p_adjusted([3.0, 4.0], [[1.0, 2.0]])
    np.testing.assert_allclose(p, [0.5, 0.5])
    assert pf == 0.5
    p, pf = min_p_adjusted([0.0, 0.0], [[1.0, 2.0]])
    np.testing.assert_allclose(p, [1.0, 1.0])
    assert pf == 1.0


@pytest.mark.parametrize("obs, null", [([1.0, 2.0], np.zeros((5, 3))), ([[1.0, 2.0]], np.zeros((5, 2))),
                                       ([1.0, 2.0], np.zeros(2)), ([1.0, 2.0], np.zeros((0, 2)))])
def test_min_p_adjusted_shapes_are_checked(obs, null):
    with pytest.raises(ValueError, match=r"observed must be \(S,\) and null \(P, S\) with P >= 1"):
        min_p_adjusted(obs, null)


def _mats(rng, n=16):
    labels = np.repeat(["a", "b"], n // 2)
    y = rng.normal(size=(n, 3))
    out = []
    for shift in (0.0, 0.8, 2.5):
        z = y + shift * (labels == "b")[:, None] * [1.0, 0.0, 0.0]
        out.append(np.sqrt(((z[:, None] - z[None]) ** 2).sum(-1)))
    return out, labels


def test_permanova_sweep_is_a_loop_of_permanova_with_the_same_permutations():
    mats, labels = _mats(np.random.default_rng(5))
    cov = pd.DataFrame({"group": labels, "x": np.arange(len(labels)) % 3})
    sweep = permanova_sweep(mats, cov, term="group", n_permutations=49, seed=7, by="terms")
    loop = [permanova(d, cov, n_permutations=49, seed=7, by="terms") for d in mats]
    stat = np.array([r.table.loc["group", "pseudo_F"] for r in loop])
    null = np.column_stack([r.null["group"] for r in loop])
    np.testing.assert_allclose(sweep.statistic, stat, rtol=1e-12)
    assert len(sweep.results) == 3 and sweep.n_permutations == 49 and type(sweep.n_permutations) is int
    for a, b in zip(sweep.results, loop):
        pd.testing.assert_frame_equal(a.table, b.table)
    bp, bpf = _brute(stat, null, rtol=TIE_RTOL)
    np.testing.assert_allclose(sweep.p_values, bp, atol=1e-15)
    assert sweep.p_family == pytest.approx(bpf, abs=1e-15)
    # each plain p is that matrix's own PERMANOVA p-value
    np.testing.assert_allclose(sweep.p_values, [r.table.loc["group", "p_value"] for r in loop], atol=1e-12)
    assert sweep.best == int(np.lexsort((-stat, bp))[0]) == 2
    assert sweep.name == "PERMANOVA pseudo-F of group"


def test_permanova_sweep_counts_recomputed_ties_as_permanova_does():
    # six objects, two groups of three: many permutations give the observed split again, with a pseudo-F
    # that differs from the observed one by rounding only; each plain p is still that matrix's own p-value
    rng = np.random.default_rng(0)
    labels = np.repeat(["a", "b"], 3)
    mats = []
    for _ in range(4):
        y = rng.normal(size=(6, 2))
        mats.append(np.sqrt(((y[:, None] - y[None]) ** 2).sum(-1)))
    sweep = permanova_sweep(mats, {"group": labels}, term="group", n_permutations=99, seed=2)
    own = [permanova(d, {"group": labels}, n_permutations=99, seed=2).table.loc["group", "p_value"] for d in mats]
    np.testing.assert_allclose(sweep.p_values, own, atol=1e-12)


def test_permanova_sweep_bad_input():
    mats, labels = _mats(np.random.default_rng(0))
    with pytest.raises(ValueError, match="term 'sex' is not a column of covariates"):
        permanova_sweep(mats, {"group": labels}, term="sex")
    with pytest.raises(ValueError, match="^distances: the sweep is empty$"):
        permanova_sweep([], {"group": labels}, term="group")


def test_permanova_sweep_default_permutations_and_seed():
    mats, labels = _mats(np.random.default_rng(1))
    sweep = permanova_sweep(mats[:1], {"group": labels}, term="group")
    one = permanova(mats[0], {"group": labels})
    assert sweep.n_permutations == 999 == len(one.null["group"])
    np.testing.assert_array_equal(sweep.results[0].null["group"], one.null["group"])


def test_knn_sweep_is_a_loop_of_knn_loo_accuracy():
    mats, labels = _mats(np.random.default_rng(6))
    sweep = knn_sweep(mats, labels, n_neighbors=3, n_permutations=39, seed=2)
    loop = [knn_loo_accuracy(d, labels, n_neighbors=3, n_permutations=39, seed=2) for d in mats]
    stat = np.array([r.accuracy for r in loop])
    null = np.column_stack([r.null for r in loop])
    np.testing.assert_array_equal(sweep.statistic, stat)
    bp, bpf = _brute(stat, null)
    np.testing.assert_allclose(sweep.p_values, bp, atol=1e-15)
    assert sweep.p_family == pytest.approx(bpf, abs=1e-15)
    assert sweep.best == int(np.lexsort((-stat, bp))[0])
    assert sweep.name == "3-NN leave-one-out accuracy" and sweep.n_permutations == 39
    assert all(np.array_equal(a.null, b.null) for a, b in zip(sweep.results, loop))


def test_knn_sweep_defaults():
    mats, labels = _mats(np.random.default_rng(3))
    sweep = knn_sweep(mats[:1], labels)
    one = knn_loo_accuracy(mats[0], labels)
    assert sweep.n_permutations == 999 and sweep.name.startswith("5-NN")
    assert sweep.statistic[0] == one.accuracy
    np.testing.assert_array_equal(sweep.results[0].null, one.null)
    with pytest.raises(ValueError, match="^distances: the sweep is empty$"):
        knn_sweep([], labels)


def test_the_best_value_is_the_smallest_p_and_among_equal_p_the_largest_statistic():
    # three values with the same plain p (the observed row largest everywhere): the largest statistic wins
    observed = np.array([5.0, 9.0, 7.0])
    null = np.zeros((9, 3))
    from shapelib.statistics.sweep import _best
    p, _ = min_p_adjusted(observed, null)
    assert np.all(p == p[0]) and _best(p, observed) == 1
    # a smaller p wins over a larger statistic
    assert _best(np.array([0.2, 0.1, 0.1]), np.array([10.0, 1.0, 2.0])) == 2


def test_summary_reports_the_fields():
    t = SweepTest(statistic=np.array([1.5, 33.3612]), p_values=np.array([0.2, 0.0123]), best=1, p_family=0.0246,
                  name="stat", n_permutations=81)
    assert t.summary() == ("stat: best at sweep value 1 (33.36, plain p = 0.0123); over the whole sweep of 2 values "
                           "p = 0.0246 (Westfall-Young min-P, 81 permutations)")
    assert t.results == [] and "results" not in repr(t)
