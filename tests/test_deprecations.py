"""One name per option and one vocabulary for results. The former names (deprecated in the release
before 0.2.0) are gone: calling them is a TypeError (an unknown keyword, a keyword-only option given
by position) or an AttributeError (a renamed result attribute), and the new names give the results."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.geometry import gmm, metrics, quadrature, scale
from shapelib.statistics import distance_based, sweep


@pytest.fixture
def pair(rng):
    u = rng.normal(size=(6, 2))
    return u, u + 0.1 * rng.normal(size=u.shape)


#: (the former call with σ² by position, the call with σ² by keyword)
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
    "make_grid": (lambda u, v: quadrature.make_grid(u, 0.7).nodes, lambda u, v: quadrature.make_grid(u, sigma2=0.7).nodes),
}


@pytest.mark.parametrize("name", sorted(CALLS))
def test_sigma2_by_position_is_a_type_error(pair, name):
    u, v = pair
    old_call, new_call = CALLS[name]
    with pytest.raises(TypeError, match="positional argument"):
        old_call(u, v)
    value = np.asarray(new_call(u, v))
    assert value.size and np.all(np.isfinite(value))


def test_spacing_and_margin_are_only_grid_spacing_and_grid_margin(pair):
    u, _ = pair
    for old in ("spacing", "margin"):
        with pytest.raises(TypeError, match=f"unexpected keyword argument '{old}'"):
            metrics.fisher_rao_metric(u, sigma2=0.5, **{old: 0.4})
        with pytest.raises(TypeError, match=f"unexpected keyword argument '{old}'"):
            quadrature.make_grid(u, sigma2=0.5, **{old: 3.0})
    new = metrics.fisher_rao_metric(u, sigma2=0.5, grid_spacing=0.4, grid_margin=7.0)
    assert not np.array_equal(new, metrics.fisher_rao_metric(u, sigma2=0.5))  # the option is really used
    narrow, wide = (quadrature.make_grid(u, sigma2=0.5, grid_margin=m) for m in (3.0, 6.0))
    assert len(narrow.nodes) < len(wide.nodes)


def test_permutations_is_only_n_permutations(rng):
    x = rng.normal(size=(12, 3))
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    g = np.arange(12) % 2
    calls = [lambda **kw: distance_based.permanova(d, {"g": g}, seed=2, **kw),
             lambda **kw: distance_based.knn_loo_accuracy(d, g, n_neighbors=3, seed=0, **kw),
             lambda **kw: distance_based.mantel_test(d, d ** 2, **kw),
             lambda **kw: sweep.knn_sweep([d, 2 * d], g, n_neighbors=3, seed=0, **kw)]
    for call in calls:
        with pytest.raises(TypeError, match="unexpected keyword argument 'permutations'"):
            call(permutations=19)
    res = distance_based.permanova(d, {"g": g}, n_permutations=49, seed=2)
    s = sweep.knn_sweep([d, 2 * d], g, n_neighbors=3, n_permutations=19, seed=0)
    assert res.n_permutations == 49 and s.n_permutations == 19
    assert not hasattr(res, "permutations") and not hasattr(s, "permutations")


def _ellipses(rng, n=5):
    t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    x = np.stack([np.c_[2 * np.cos(t), np.sin(t)] + 0.05 * rng.normal(size=(8, 2)) for _ in range(n)])
    return sl.pose_align(x)[0]  # the α metric depends on pose: aligned, as the PoseWarning asks


def test_statistics_results_speak_of_log_not_history(rng):
    x = _ellipses(rng)
    res = sl.frechet_mean(x, sigma2=0.5, n_jobs=1)
    assert not hasattr(res, "history")
    assert res.log[-1]["mode"] == "in-process" and res.stop_reason == "converged" and res.converged


def test_tangent_pca_estimator_needs_sigma2_as_the_function_does(rng):
    x = _ellipses(rng).reshape(5, -1)
    with pytest.raises(ValueError, match="TangentPCA needs sigma2"):
        sl.TangentPCA(n_components=2).fit(x)
    with pytest.raises(ValueError, match="needs sigma2"):
        sl.tangent_pca(x.reshape(5, 8, 2), n_jobs=1)
    fitted = sl.TangentPCA(sigma2=1.0, n_components=2).fit(x)
    assert fitted.explained_variance_.shape == (2,) and np.all(np.diff(fitted.explained_variance_) <= 0)


def test_result_vocabulary(rng):
    """value, lower, upper, converged, stop_reason, log, summary() on the results of a path, a
    bracket and a matrix; the pairwise summary() has replaced convergence_summary()."""
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
    assert not hasattr(r, "convergence_summary")
    frame = r.to_frame()
    assert list(frame.columns[:5]) == ["i", "j", "value", "lower", "upper"]
