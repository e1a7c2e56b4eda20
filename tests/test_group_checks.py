"""Checks of shapelib.statistics.group against independent values: the statistic and its permutation null
from the log maps themselves (the norm of the difference of the groups' mean vectors, relabelling by
relabelling with the same random draws), the p-value counted by hand, the difference vector as NumPy's
mean of each group's log maps, the group means and the geodesic between them against frechet_mean-style
Karcher iterations and shapelib.geodesic called on their own, the small-group warning against math.comb,
and the summary against the fields it was built from."""

import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import shapelib
from shapelib.statistics import group as group_module
from shapelib.statistics.frechet import frechet_mean
from shapelib.statistics.group import (MIN_PERMUTATIONS, MeanDifferenceResult, mean_difference_test,
                                       permutation_statistics)
from tests.conftest import ellipse

S2 = 1.0
#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions go through a
#: trampoline, more stack frames between the caller and the code: the warnings' lines are checked outside it
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(group_module))


def _population(n_a=4, n_b=4, shift=0.6, seed=3, k=6):
    rng = np.random.default_rng(seed)
    base = ellipse(k)
    mode = np.zeros_like(base)
    mode[:, 0] = 0.2 * base[:, 0]
    x = np.stack([base + (i >= n_a) * shift * mode + 0.15 * rng.normal(size=base.shape) for i in range(n_a + n_b)])
    return shapelib.pose_align(x)[0]


def _pooled(x):
    return frechet_mean(x, sigma2=S2, n_steps=2, n_jobs=1)


def test_permutation_statistics_are_norms_of_mean_differences_relabelling_by_relabelling():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(9, 5))
    gram = v @ v.T
    labels = np.array([0, 1, 1, 0, 0, 1, 0, 1, 1], dtype=bool)
    observed, null = permutation_statistics(gram, labels, 30, np.random.default_rng(4))

    def norm(lab):
        return np.linalg.norm(v[lab].mean(axis=0) - v[~lab].mean(axis=0))

    assert observed == pytest.approx(norm(labels), rel=1e-12)
    draws = np.random.default_rng(4)
    expected = [norm(draws.permutation(labels)) for _ in range(30)]
    np.testing.assert_allclose(null, expected, rtol=1e-10)
    obs0, null0 = permutation_statistics(gram, labels, 0, np.random.default_rng(4))
    assert obs0 == pytest.approx(observed) and null0.shape == (0,)


def test_a_gram_of_equal_vectors_gives_zero_not_nan():
    gram = np.full((4, 4), 2.0) - 1e-15 * np.eye(4)  # rounding may make the quadratic form slightly negative
    observed, null = permutation_statistics(gram, np.array([0, 0, 1, 1], dtype=bool), 5, np.random.default_rng(0))
    assert observed >= 0.0 and np.all(null >= 0.0) and np.isfinite(null).all()


def test_statistic_null_p_value_and_difference_from_the_pooled_log_maps():
    x = _population()
    pooled = _pooled(x)
    groups = np.array(["b", "a", "b", "a", "a", "b", "a", "b"])
    res = mean_difference_test(x, groups, sigma2=S2, pooled=pooled, group_means=False, n_permutations=59, seed=11,
                               n_jobs=1)
    assert res.labels == ("a", "b") and res.sizes == (4, 4) and res.n_permutations == 59
    is_b = groups == "b"
    diff = pooled.logs[is_b].mean(axis=0) - pooled.logs[~is_b].mean(axis=0)
    np.testing.assert_allclose(res.difference, diff, rtol=1e-12, atol=1e-14)
    assert res.statistic == pytest.approx(pooled.tangent.norm(diff), rel=1e-8)
    draws = np.random.default_rng(11)
    null = []
    for _ in range(59):
        lab = draws.permutation(is_b)
        null.append(pooled.tangent.norm(pooled.logs[lab].mean(axis=0) - pooled.logs[~lab].mean(axis=0)))
    np.testing.assert_allclose(res.null, null, rtol=1e-8)
    assert res.p_value == pytest.approx((1 + sum(t >= res.statistic * (1 - 1e-9) for t in null)) / 60, abs=1e-15)
    assert res.means is None and res.distance is None and res.geodesic is None
    # a Generator seed draws the same relabellings as its integer
    again = mean_difference_test(x, groups, sigma2=S2, pooled=pooled, group_means=False, n_permutations=59,
                                 seed=np.random.default_rng(11), n_jobs=1)
    np.testing.assert_array_equal(again.null, res.null)


def test_order_reverses_the_difference_and_keeps_the_statistic():
    x = _population()
    pooled = _pooled(x)
    g = np.array([1, 1, 1, 1, 2, 2, 2, 2])
    ab = mean_difference_test(x, g, sigma2=S2, pooled=pooled, group_means=False, n_permutations=19, n_jobs=1)
    ba = mean_difference_test(x, g, sigma2=S2, pooled=pooled, group_means=False, n_permutations=19, order=(2, 1),
                              n_jobs=1)
    assert ab.labels == (1, 2) and ba.labels == (2, 1)
    np.testing.assert_allclose(ba.difference, -ab.difference, atol=1e-14)
    assert ba.statistic == pytest.approx(ab.statistic) and ba.p_value == pytest.approx(ab.p_value)


def test_a_clear_difference_gets_the_smallest_p_value():
    x = _population(shift=3.0)
    res = mean_difference_test(x, [0] * 4 + [1] * 4, sigma2=S2, pooled=_pooled(x), group_means=False,
                               n_permutations=MIN_PERMUTATIONS, seed=0, n_jobs=1)
    # the observed split is the most extreme of the 70 relabellings: no random one exceeds it
    assert res.p_value == pytest.approx(1 / 20) or res.p_value == pytest.approx(2 / 20)
    assert res.statistic >= res.null.max() * (1 - 1e-9)


def test_group_means_and_the_geodesic_between_them():
    x = _population(shift=1.0)
    g = np.array([0] * 4 + [1] * 4)
    res = mean_difference_test(x, g, sigma2=S2, n_permutations=19, geodesic_steps=3, n_steps=2, max_iter=3,
                               n_jobs=1)
    assert res.pooled.options.n_steps == 2
    assert len(res.means) == 2 and all(m.n_iter <= 3 for m in res.means)
    for sel, m in zip((g == 0, g == 1), res.means):
        assert m.logs.shape == x[sel].shape
    # the geodesic between the means, computed on its own
    geo = shapelib.geodesic(res.means[0].mean, res.means[1].mean, metric="alpha", sigma2=S2, n_steps=3, tol=1e-8)
    assert res.geodesic.path.shape == (4, 6, 2)
    np.testing.assert_allclose(res.geodesic.path[0], res.means[0].mean, atol=1e-12)
    np.testing.assert_allclose(res.geodesic.path[-1], res.means[1].mean, atol=1e-12)
    assert res.distance == pytest.approx(geo.length, rel=1e-6) and isinstance(res.distance, float)
    assert res.geodesic.metric == geo.metric and res.geodesic.sigma2 == S2


def test_rounds_and_base_of_the_timed_log_map(monkeypatch):
    seen = []
    real = group_module.where_logs_run

    def spy(x, options, *, base, rounds, **kw):
        seen.append((base(), rounds))
        return real(x, options, base=base, rounds=rounds, **kw)

    monkeypatch.setattr(group_module, "where_logs_run", spy)
    x = _population()
    pooled = _pooled(x)
    g = [0] * 4 + [1] * 4
    mean_difference_test(x, g, sigma2=S2, pooled=pooled, group_means=False, n_permutations=19, n_jobs=1)
    np.testing.assert_array_equal(seen[-1][0], pooled.mean)
    assert seen[-1][1] == 0.0
    init = x[0] + 0.01
    with pytest.raises(RuntimeError, match="stop"):
        monkeypatch.setattr(group_module, "_test", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("stop")))
        mean_difference_test(x, g, sigma2=S2, group_means=True, n_permutations=19, init=init, n_jobs=1)
    np.testing.assert_array_equal(seen[-1][0], init)
    assert seen[-1][1] == 2 * group_module.MEAN_ROUNDS
    with pytest.raises(RuntimeError, match="stop"):
        mean_difference_test(x, g, sigma2=S2, group_means=False, n_permutations=19, n_jobs=1)
    np.testing.assert_allclose(seen[-1][0], shapelib.statistics.frechet.procrustes_mean(x))
    assert seen[-1][1] == group_module.MEAN_ROUNDS


def test_a_small_group_warns_with_its_number_of_relabellings():
    x = _population(n_a=2, n_b=5)
    with pytest.warns(UserWarning) as caught:
        mean_difference_test(x, ["p"] * 2 + ["q"] * 5, sigma2=S2, pooled=_pooled(x), group_means=False,
                             n_permutations=19, n_jobs=1)
    msg = next(str(w.message) for w in caught if "relabellings" in str(w.message))
    assert msg == (f"group 'p' has 2 shape(s) against 5: its mean is barely estimated and the permutation test has "
                   f"only {math.comb(7, 2)} distinct relabellings (smallest possible p {1 / math.comb(7, 2):.3g})")
    x = _population(n_a=3, n_b=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        mean_difference_test(x, [0] * 3 + [1] * 3, sigma2=S2, pooled=_pooled(x), group_means=False,
                             n_permutations=19, n_jobs=1)


def test_bad_input_is_a_value_error_naming_it():
    x = _population()
    g = [0] * 4 + [1] * 4
    with pytest.raises(ValueError, match=r"groups must have one label per shape \(8\); got shape \(7,\)"):
        mean_difference_test(x, g[:7], sigma2=S2, n_jobs=1)
    with pytest.raises(ValueError, match=r"groups must hold exactly two labels; found 3: \[0, 1, 2\]"):
        mean_difference_test(x, [0, 1, 2] * 2 + [0, 1], sigma2=S2, n_jobs=1)
    with pytest.raises(ValueError, match=r"exactly two labels \(those of order\); found 2"):
        mean_difference_test(x, g, sigma2=S2, order=(0, 5), n_jobs=1)
    with pytest.raises(ValueError, match=r"found 1: \[0\]"):
        mean_difference_test(x, [0] * 8, sigma2=S2, n_jobs=1)
    with pytest.raises(ValueError, match=r"both groups need shapes; sizes \{0: 0, 1: 8\}|both groups need shapes"):
        mean_difference_test(x, [1] * 8, sigma2=S2, order=(1, 1), n_jobs=1)
    with pytest.raises(ValueError, match=f"n_permutations must be at least {MIN_PERMUTATIONS}; got 18"):
        mean_difference_test(x, g, sigma2=S2, n_permutations=18, n_jobs=1)
    with pytest.raises(ValueError, match="n_permutations"):
        mean_difference_test(x, g, sigma2=S2, n_permutations=0, n_jobs=1)
    with pytest.raises(ValueError, match="pooled must be the FrechetMeanResult of these shapes"):
        mean_difference_test(x, g, sigma2=S2, pooled=_pooled(x[:6]), n_permutations=19, n_jobs=1)
    with pytest.raises(ValueError, match="shapes"):
        mean_difference_test(x[..., :1], g, sigma2=S2, n_jobs=1)


def _record(pooled_ok=True, means=None, geodesic=None, distance=None):
    pooled = SimpleNamespace(options=SimpleNamespace(metric="fisher_rao"), converged=pooled_ok, n_iter=30)
    return MeanDifferenceResult(labels=("ctrl", "case"), sizes=(5, 7), statistic=0.123456, p_value=0.0123456,
                                n_permutations=81, null=np.zeros(81), difference=np.zeros((3, 2)), pooled=pooled,
                                means=means, distance=distance, geodesic=geodesic)


def test_summary_and_converged_report_the_fields():
    head = ("ctrl (n = 5) vs case (n = 7), fisher_rao: tangent distance between the group means 0.1235, "
            "permutation p = 0.01235 (81 permutations)")
    r = _record()
    assert r.summary() == head and r.converged
    r = _record(pooled_ok=False)
    assert r.summary() == head + (" [the pooled mean did not converge in 30 iterations: the tangent distance is "
                                  "measured at its last iterate]") and not r.converged
    ok, late = SimpleNamespace(converged=True, n_iter=4), SimpleNamespace(converged=False, n_iter=9)
    geo_ok = SimpleNamespace(converged=True, lower_bound=0.1)
    geo_late = SimpleNamespace(converged=False, lower_bound=0.0987654)
    r = _record(means=(ok, ok), geodesic=geo_ok, distance=0.1111111)
    assert r.summary() == head + "; geodesic distance between the Fréchet means 0.1111" and r.converged
    r = _record(means=(late, late), geodesic=geo_ok, distance=0.1111111)
    assert r.summary() == head + ("; geodesic distance between the Fréchet means 0.1111 [not converged: the Fréchet "
                                  "mean of ctrl (after 9 iterations) and case (after 9 iterations); the distance is "
                                  "between the last iterates, not the means]") and not r.converged
    r = _record(means=(ok, late), geodesic=geo_late, distance=0.1111111)
    assert r.summary().endswith("the Fréchet mean of case (after 9 iterations); the distance is between the last "
                                "iterates, not the means]")
    r = _record(means=(ok, ok), geodesic=geo_late, distance=0.1111111)
    assert r.summary() == head + ("; geodesic distance between the Fréchet means 0.1111 [the geodesic between the "
                                  "means did not converge: the distance is the length of the path it had, an upper "
                                  "bound; lower bound 0.09877]") and not r.converged
    r = _record(means=(ok, ok), geodesic=None, distance=0.1111111)
    assert r.summary() == head + "; geodesic distance between the Fréchet means 0.1111" and r.converged


def test_default_labels_are_sorted_naturally_and_as_text_only_where_they_do_not_compare():
    # a defect found by mutation testing: the labels were sorted as text, so groups 9 and 10 went (10, 9)
    x = _population()
    pooled = _pooled(x)
    res = mean_difference_test(x, [10] * 4 + [9] * 4, sigma2=S2, pooled=pooled, group_means=False, n_permutations=19,
                               n_jobs=1)
    assert res.labels == (9, 10)
    np.testing.assert_allclose(res.difference, pooled.logs[:4].mean(axis=0) - pooled.logs[4:].mean(axis=0),
                               atol=1e-14)
    mixed = mean_difference_test(x, np.array(["b"] * 4 + [1] * 4, dtype=object), sigma2=S2, pooled=pooled, group_means=False,
                                 n_permutations=19, n_jobs=1)
    assert mixed.labels == (1, "b")  # "1" < "b"
    with pytest.raises(ValueError, match=r"found 3: \[9, 10, 11\]$"):
        mean_difference_test(x, [10, 9, 11, 9, 10, 9, 10, 9], sigma2=S2, n_jobs=1)
    with pytest.raises(ValueError, match=r"found 8: \[0, 1, 2, 3, 4, 5\]$"):  # the first six
        mean_difference_test(x, list(range(8)), sigma2=S2, n_jobs=1)


def test_the_documented_defaults():
    x = _population(n_a=3, n_b=4, shift=1.0)
    g = [0] * 3 + [1] * 4
    res = mean_difference_test(x, g, sigma2=S2, n_steps=2, n_jobs=1)
    assert res.n_permutations == 999 and res.null.shape == (999,)
    assert res.pooled.tol == 1e-3 and res.geodesic.path.shape[0] == 17
    seeded = mean_difference_test(x, g, sigma2=S2, pooled=res.pooled, group_means=False, seed=0, n_jobs=1)
    np.testing.assert_array_equal(seeded.null, res.null)


def test_options_reach_the_pooled_mean():
    x = _population(n_a=3, n_b=4)
    res = mean_difference_test(x, [0] * 3 + [1] * 4, sigma2=S2, n_steps=2, tol=0.05, rcond=1e-5, grid_spacing=0.4,
                               grid_margin=5.0, max_iter=1, log_tol=1e-7, log_max_iter=50, group_means=False,
                               n_permutations=19, n_jobs=1)
    o = res.pooled.options
    assert (o.rcond, o.grid_spacing, o.grid_margin, o.tol, o.max_iter, o.n_steps) == (1e-5, 0.4, 5.0, 1e-7, 50, 2)
    assert res.pooled.tol == 0.05 and res.pooled.n_iter <= 1


def test_a_fisher_rao_geodesic_between_the_means_uses_the_pooled_options():
    x = _population(n_a=2, n_b=3, shift=1.0, k=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a group of two
        res = mean_difference_test(x, [0, 0, 1, 1, 1], metric="fisher_rao", sigma2=S2, n_steps=2, geodesic_steps=2,
                                   grid_spacing=0.5, grid_margin=4.0, max_iter=1, n_permutations=19, n_jobs=1)
    geo = shapelib.geodesic(res.means[0].mean, res.means[1].mean, metric="fisher_rao", sigma2=S2, n_steps=2, tol=1e-8,
                            grid_spacing=0.5, grid_margin=4.0)
    assert res.geodesic.metric == "fisher_rao" and res.geodesic.log["tol"] == 1e-8
    assert res.geodesic.log["grid_spacing"] == 0.5 and res.geodesic.log["grid_margin"] == 4.0
    np.testing.assert_allclose(res.geodesic.path, geo.path, rtol=1e-10, atol=1e-12)
    assert res.distance == pytest.approx(geo.length, rel=1e-10)


class _Executor:
    """A synchronous executor (the log maps run here), so a test can see it was handed on."""

    def submit(self, fn, *args, **kwargs):
        from concurrent.futures import Future

        fut = Future()
        fut.set_result(fn(*args, **kwargs))
        return fut


def test_group_means_are_karcher_iterations_of_each_group_warm_started_from_the_pooled_paths(monkeypatch):
    calls = []
    real = group_module.karcher_iteration

    def spy(xs, m0, **kw):
        calls.append(dict(kw, x=xs, m0=m0))
        return real(xs, m0, **kw)

    monkeypatch.setattr(group_module, "karcher_iteration", spy)
    x = _population(n_a=3, n_b=5, shift=1.0)
    g = np.array([0, 1, 0, 1, 1, 0, 1, 1])
    ex = _Executor()
    res = mean_difference_test(x, g, sigma2=S2, n_steps=2, tol=0.01, n_permutations=19, executor=ex, chunk_size=3)
    assert len(calls) == 2
    for sel, call, m in zip((g == 0, g == 1), calls, res.means):
        np.testing.assert_array_equal(call["x"], x[sel])
        np.testing.assert_array_equal(call["m0"], res.pooled.mean)
        assert len(call["inits"]) == sel.sum()
        for init, path in zip(call["inits"], [p for p, s in zip(res.pooled.paths, sel) if s]):
            np.testing.assert_array_equal(init, path)
        assert call["executor"] is ex and call["chunk_size"] == 3 and call["max_iter"] == 30 and call["tol"] == 0.01
        assert call["options"] is res.pooled.options
        assert m.logs.shape == x[sel].shape
    calls.clear()
    mean_difference_test(x, g, sigma2=S2, pooled=res.pooled, n_permutations=19, max_iter=2, n_jobs=1)
    assert [c["max_iter"] for c in calls] == [2, 2]


def test_where_the_log_maps_run_is_handed_on(monkeypatch):
    seen = {}

    def spy(x, options, **kw):
        seen.update(kw, options=options)
        raise RuntimeError("stop")

    monkeypatch.setattr(group_module, "where_logs_run", spy)
    x = _population()
    g = [0] * 4 + [1] * 4
    ex = _Executor()
    with pytest.raises(RuntimeError, match="stop"):
        mean_difference_test(x, g, sigma2=S2, n_steps=2, executor=ex, chunk_size=3, log_tol=1e-7, log_max_iter=40)
    assert seen["executor"] is ex and seen["chunk_size"] == 3 and seen["n_jobs"] is None
    assert seen["client"] is None and seen["scheduler"] is None
    assert (seen["options"].tol, seen["options"].max_iter, seen["options"].n_steps) == (1e-7, 40, 2)
    with pytest.raises(RuntimeError, match="stop"):
        mean_difference_test(x, g, sigma2=S2, n_jobs=3, client="C", scheduler="S")
    assert (seen["n_jobs"], seen["client"], seen["scheduler"], seen["executor"]) == (3, "C", "S", None)
    monkeypatch.undo()  # the real where_logs_run for the pooled mean
    pooled = _pooled(x)
    monkeypatch.setattr(group_module, "where_logs_run", spy)
    with pytest.raises(RuntimeError, match="stop"):
        mean_difference_test(x, g, sigma2=S2, pooled=pooled)
    assert seen["options"] is pooled.options


def test_a_group_of_one_is_accepted_and_the_small_group_named_wherever_it_is():
    x = _population(n_a=5, n_b=1)
    with pytest.warns(UserWarning, match=r"^group 'q' has 1 shape\(s\) against 5") as caught:
        res = mean_difference_test(x, ["p"] * 5 + ["q"], sigma2=S2, pooled=_pooled(x), group_means=False,
                                   n_permutations=19, n_jobs=1)
    assert res.sizes == (5, 1)
    if not UNDER_MUTMUT:  # the caller's line
        assert [w.filename for w in caught if "relabellings" in str(w.message)] == [__file__]


def test_bad_shapes_are_named_and_the_pose_warning_names_the_metric():
    x = _population()
    with pytest.raises(ValueError, match="^shapes must have shape"):
        mean_difference_test(x[0], [0, 1] * 3, sigma2=S2, n_jobs=1)
    with pytest.raises(ValueError, match="^pooled must be the FrechetMeanResult of these shapes$"):
        mean_difference_test(x, [0] * 4 + [1] * 4, sigma2=S2, pooled="mean", n_permutations=19, n_jobs=1)
    with pytest.raises(ValueError, match="^n_permutations must be a positive integer"):
        mean_difference_test(x, [0] * 4 + [1] * 4, sigma2=S2, n_permutations=0, n_jobs=1)
    turned = x.copy()
    turned[::2] = turned[::2] @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + 3.0
    with pytest.warns(shapelib.PoseWarning, match="^alpha") as caught:
        with pytest.raises(RuntimeError, match="stop"):
            with pytest.MonkeyPatch.context() as mp:
                mp.setattr(group_module, "where_logs_run", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("stop")))
                mean_difference_test(turned, [0] * 4 + [1] * 4, sigma2=S2, n_jobs=1)
    if not UNDER_MUTMUT:  # the caller's line
        assert [w.filename for w in caught if issubclass(w.category, shapelib.PoseWarning)] == [__file__]
