"""One name per option and one vocabulary for results: the former names still work for one release,
each with a DeprecationWarning, and give the same result as the new ones."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.geometry import gmm, metrics, quadrature, scale
from shapelib.statistics import distance_based, sweep


@pytest.fixture
def pair(rng):
    u = rng.normal(size=(6, 2))
    return u, u + 0.1 * rng.normal(size=u.shape)


#: (old call with σ² positional, the same call with σ² by keyword)
CALLS = {
    "l2_distance": (lambda u, v: gmm.l2_distance(u, v, 0.7), lambda u, v: gmm.l2_distance(u, v, sigma2=0.7)),
    "l2_inner": (lambda u, v: gmm.l2_inner(u, v, 0.7), lambda u, v: gmm.l2_inner(u, v, sigma2=0.7)),
    "gaussian_overlap": (lambda u, v: gmm.gaussian_overlap(u, v, 0.7),
                         lambda u, v: gmm.gaussian_overlap(u, v, sigma2=0.7)),
    "gmm_density": (lambda u, v: gmm.gmm_density(v, u, 0.7), lambda u, v: gmm.gmm_density(v, u, sigma2=0.7)),
    "gmm_log_density": (lambda u, v: gmm.gmm_log_density(v, u, 0.7),
                        lambda u, v: gmm.gmm_log_density(v, u, sigma2=0.7)),
    "alpha_metric": (lambda u, v: metrics.alpha_metric(u, 0.7), lambda u, v: metrics.alpha_metric(u, sigma2=0.7)),
    "alpha_quadratic_form": (lambda u, v: metrics.alpha_quadratic_form(u, v - u, 0.7),
                             lambda u, v: metrics.alpha_quadratic_form(u, v - u, sigma2=0.7)),
    "fisher_rao_metric": (lambda u, v: metrics.fisher_rao_metric(u, 0.7),
                          lambda u, v: metrics.fisher_rao_metric(u, sigma2=0.7)),
    "fisher_rao_quadratic_form": (lambda u, v: metrics.fisher_rao_quadratic_form(u, v - u, 0.7),
                                  lambda u, v: metrics.fisher_rao_quadratic_form(u, v - u, sigma2=0.7)),
    "sigma_ratio": (lambda u, v: scale.sigma_ratio(np.stack([u, v]), 0.7),
                    lambda u, v: scale.sigma_ratio(np.stack([u, v]), sigma2=0.7)),
}


@pytest.mark.parametrize("name", sorted(CALLS))
def test_positional_sigma2_warns_and_gives_the_keyword_result(pair, name):
    u, v = pair
    old_call, new_call = CALLS[name]
    with pytest.warns(DeprecationWarning, match=r"sigma2=\.\.\. by keyword"):
        old = old_call(u, v)
    with _no_deprecation():
        new = new_call(u, v)
    np.testing.assert_array_equal(old, new)
    with pytest.raises(TypeError, match="multiple values for argument 'sigma2'"):
        gmm.l2_distance(u, v, 0.7, sigma2=0.7)


def _no_deprecation():
    import warnings

    ctx = warnings.catch_warnings()
    ctx.__enter__()
    warnings.simplefilter("error", DeprecationWarning)
    return _Exit(ctx)


class _Exit:
    def __init__(self, ctx):
        self.ctx = ctx

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.ctx.__exit__(*exc)
        return False


def test_spacing_and_margin_are_now_grid_spacing_and_grid_margin(pair):
    u, v = pair
    with pytest.warns(DeprecationWarning, match="(spacing|margin)= is deprecated, use grid_(spacing|margin)="):
        old = metrics.fisher_rao_metric(u, sigma2=0.5, spacing=0.4, margin=7.0)
    with _no_deprecation():
        new = metrics.fisher_rao_metric(u, sigma2=0.5, grid_spacing=0.4, grid_margin=7.0)
        default = metrics.fisher_rao_metric(u, sigma2=0.5)
    np.testing.assert_array_equal(old, new)
    assert not np.array_equal(new, default)  # the renamed option is really used
    with pytest.warns(DeprecationWarning, match="margin= is deprecated"):
        g = quadrature.make_grid(u, sigma2=0.5, margin=3.0)
    with _no_deprecation():
        np.testing.assert_array_equal(g.nodes, quadrature.make_grid(u, sigma2=0.5, grid_margin=3.0).nodes)
    with pytest.raises(TypeError, match="both spacing= .deprecated. and grid_spacing="):
        metrics.fisher_rao_metric(u, sigma2=0.5, spacing=0.4, grid_spacing=0.4)


def test_permutations_is_now_n_permutations(rng):
    x = rng.normal(size=(12, 3))
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    g = np.arange(12) % 2
    with pytest.warns(DeprecationWarning, match="permutations= is deprecated, use n_permutations="):
        old = distance_based.permanova(d, {"g": g}, permutations=49, seed=2)
    with _no_deprecation():
        new = distance_based.permanova(d, {"g": g}, n_permutations=49, seed=2)
    assert old.table.equals(new.table) and new.n_permutations == 49
    with pytest.warns(DeprecationWarning, match="PermanovaResult.permutations is deprecated"):
        assert new.permutations == 49
    with pytest.warns(DeprecationWarning):
        k_old = distance_based.knn_loo_accuracy(d, g, n_neighbors=3, permutations=19, seed=0)
    k_new = distance_based.knn_loo_accuracy(d, g, n_neighbors=3, n_permutations=19, seed=0)
    assert k_old.p_value == k_new.p_value and np.array_equal(k_old.null, k_new.null)
    with pytest.warns(DeprecationWarning):
        m_old = distance_based.mantel_test(d, d ** 2, permutations=19)
    assert m_old == distance_based.mantel_test(d, d ** 2, n_permutations=19)
    with pytest.warns(DeprecationWarning):
        s_old = sweep.knn_sweep([d, 2 * d], g, n_neighbors=3, permutations=19, seed=0)
    s_new = sweep.knn_sweep([d, 2 * d], g, n_neighbors=3, n_permutations=19, seed=0)
    assert s_old.p_family == s_new.p_family and s_new.n_permutations == 19
    with pytest.warns(DeprecationWarning, match="SweepTest.permutations"):
        assert s_new.permutations == 19


def _ellipses(rng, n=5):
    t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    return np.stack([np.c_[2 * np.cos(t), np.sin(t)] + 0.05 * rng.normal(size=(8, 2)) for _ in range(n)])


def test_statistics_results_speak_of_log_not_history(rng):
    x = _ellipses(rng)
    res = sl.frechet_mean(x, sigma2=0.5, n_jobs=1)
    with pytest.warns(DeprecationWarning, match="FrechetMeanResult.history is deprecated, use FrechetMeanResult.log"):
        assert res.history is res.log
    assert res.log[-1]["mode"] == "in-process" and res.stop_reason == "converged" and res.converged


def test_tangent_pca_estimator_needs_sigma2_as_the_function_does(rng):
    x = _ellipses(rng).reshape(5, -1)
    with pytest.warns(DeprecationWarning, match="TangentPCA needs sigma2"):
        old = sl.TangentPCA(n_components=2).fit(x)
    with _no_deprecation():
        new = sl.TangentPCA(sigma2=1.0, n_components=2).fit(x)
    np.testing.assert_allclose(old.explained_variance_, new.explained_variance_, rtol=1e-12)
    with pytest.raises(ValueError, match="needs sigma2"):
        sl.tangent_pca(x.reshape(5, 8, 2), n_jobs=1)


def test_result_vocabulary(rng):
    """value, lower, upper, converged, stop_reason, log, summary() on the results of a path, a
    bracket and a matrix; the pairwise summary() replaces convergence_summary()."""
    u, v = _ellipses(rng, 2)
    geo = sl.geodesic(u, v, sigma2=0.5, n_steps=4)
    assert geo.value == geo.length == geo.upper and geo.lower == geo.lower_bound <= geo.value
    assert geo.stop_reason is not None and isinstance(geo.log, dict) and geo.summary()
    from shapelib.solver.bracket import distance_bracket

    b = distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=0.05)
    assert b.value == b.upper and b.lower <= b.value and b.converged and str(b.stop_reason)
    x = _ellipses(rng, 4)
    r = sl.pairwise_distances(x, metric="alpha_bound", sigma2=0.5, n_jobs=1, progress=False, return_result=True)
    assert r.value is r.matrix and r.stop_reason == "complete"
    assert r.summary() == "4 × 4 alpha_bound matrix: 6 of 6 pairs computed, all converged"
    with pytest.warns(DeprecationWarning, match="convergence_summary"):
        assert r.convergence_summary() == ""
    frame = r.to_frame()
    assert list(frame.columns[:5]) == ["i", "j", "value", "lower", "upper"]
