import numpy as np
import pytest

from shapelib import distance, pairwise_distances
from shapelib.geometry.procrustes import procrustes_distance
from shapelib.comparison.splines import tps_bending_energy


@pytest.fixture
def shapes(rng):
    base = np.array([[0.0, 0.0], [1.0, 0.1], [2.0, 0.0], [1.0, -0.9], [0.5, 0.6]])
    return np.stack([base + 0.15 * rng.normal(size=base.shape) for _ in range(4)])


def test_distance_dispatch(shapes):
    u, v = shapes[:2]
    assert distance(u, v, metric="procrustes") == procrustes_distance(u, v)
    assert distance(u, v, metric="tps") == tps_bending_energy(u, v)
    assert distance(u, v, metric="alpha", sigma2=0.5, n_steps=4) > 0
    with pytest.raises(ValueError, match="unknown metric"):
        distance(u, v, metric="cosine")
    with pytest.raises(ValueError, match="needs sigma2"):
        distance(u, v, metric="fisher_rao")


def test_pairwise_symmetric_and_directional(shapes):
    d = pairwise_distances(shapes, metric="procrustes")
    assert np.allclose(d, d.T) and np.all(np.diag(d) == 0)
    assert d[0, 1] == pytest.approx(procrustes_distance(shapes[0], shapes[1]))
    t = pairwise_distances(shapes, metric="tps")
    assert t[0, 1] == pytest.approx(tps_bending_energy(shapes[0], shapes[1]))
    assert t[1, 0] == pytest.approx(tps_bending_energy(shapes[1], shapes[0]))


def test_pairwise_default_runs_a_tiny_job_in_process_and_equals_pair_by_pair(shapes):
    r = pairwise_distances(shapes, metric="alpha", sigma2=0.5, n_steps=4, return_result=True, progress=False)
    assert r.log["mode"] == "in-process"  # a few ms of work: no cluster is started
    for i in range(4):
        for j in range(i + 1, 4):
            assert r.matrix[i, j] == r.matrix[j, i] == pytest.approx(
                distance(shapes[i], shapes[j], metric="alpha", sigma2=0.5, n_steps=4), rel=1e-12)


def test_path_result_gives_the_full_geodesic(shapes):
    from shapelib.distances import path_result

    u, v = shapes[:2]
    r = path_result(u, v, metric="diffeomorphism", n_steps=4)
    assert r.length == pytest.approx(distance(u, v, metric="diffeomorphism", n_steps=4))
    assert r.path.shape == (5, 5, 2)
    with pytest.raises(ValueError, match="not a path metric"):
        path_result(u, v, metric="procrustes")


def test_bound_metrics_are_the_closed_forms_and_bound_the_geodesics(shapes):
    from shapelib import fisher_rao_lower_bound, l2_distance
    from shapelib.distances import SYMMETRIC, pair_record

    u, v = shapes[:2]
    assert distance(u, v, metric="alpha_bound", sigma2=0.5) == l2_distance(u, v, sigma2=0.5)
    assert distance(u, v, metric="fisher_rao_bound", sigma2=0.5) == fisher_rao_lower_bound(u, v, sigma2=0.5)
    assert {"alpha_bound", "fisher_rao_bound"} <= SYMMETRIC
    for metric in ("alpha", "fisher_rao"):
        rec = pair_record(u, v, metric=metric, sigma2=0.5, n_steps=4)
        bound = distance(u, v, metric=f"{metric}_bound", sigma2=0.5)
        assert rec["lower"] == pytest.approx(bound, rel=1e-12)
        assert bound <= rec["upper"] == rec["value"]
        assert rec["energy"] >= rec["upper"] ** 2 * (1 - 1e-9)  # Cauchy-Schwarz: E >= L^2
        assert rec["n_iter"] > 0 and rec["seconds"] > 0 and isinstance(rec["converged"], bool)


def test_pair_record_of_a_non_path_metric(shapes):
    from shapelib.distances import RECORD_FIELDS, pair_record

    u, v = shapes[:2]
    rec = pair_record(u, v, metric="tps")
    assert tuple(rec) == RECORD_FIELDS
    assert rec["value"] == rec["lower"] == rec["upper"] == tps_bending_energy(u, v)
    assert np.isnan(rec["energy"]) and rec["converged"] is True and rec["n_iter"] == 0


def test_unknown_metric_parameter_or_rtol_is_named(shapes):
    from shapelib.distances import pair_record

    u, v = shapes[:2]
    with pytest.raises(ValueError, match=r"'procrustes' has no parameter\(s\) \['sigma2'\]"):
        distance(u, v, metric="procrustes", sigma2=0.5)
    with pytest.raises(ValueError, match="n_stpes"):
        pair_record(u, v, metric="alpha", sigma2=0.5, n_stpes=4)
    with pytest.raises(ValueError, match="needs sigma2"):
        pair_record(u, v, metric="alpha_bound")
    with pytest.raises(ValueError, match="unknown metric 'cosine'"):
        pair_record(u, v, metric="cosine")
    with pytest.raises(ValueError, match="rtol applies"):
        pair_record(u, v, metric="tps", rtol=1e-3)
    for bad in (0.0, -1e-3, float("nan"), True, "1e-3"):  # the bracket's own check and words, before any work
        with pytest.raises(ValueError, match="rtol must be a positive finite number"):
            distance(u, v, metric="alpha", sigma2=0.5, rtol=bad)
    with pytest.raises(ValueError, match="unknown metric"):
        pairwise_distances(np.stack([u, v]), metric="cosine")


@pytest.mark.filterwarnings("ignore::shapelib.solver.geodesic.GeodesicWarning")  # a stalled bracket says so; checked below
def test_rtol_gives_the_certified_bracket(shapes):
    from shapelib import l2_distance
    from shapelib.distances import pair_record

    u, v = shapes[:2]
    rec = pair_record(u, v, metric="alpha", sigma2=0.5, rtol=1e-3)
    assert rec["lower"] == pytest.approx(l2_distance(u, v, sigma2=0.5), rel=1e-12)
    assert rec["lower"] <= rec["upper"] == rec["value"]
    assert rec["converged"] == (rec["upper"] / rec["lower"] - 1 <= 1e-3)
    assert rec["n_iter"] > 0 and rec["seconds"] > 0
    assert distance(u, v, metric="alpha", sigma2=0.5, rtol=1e-3) == pytest.approx(rec["value"], rel=1e-12)
    with pytest.raises(ValueError, match="has no parameter"):
        pair_record(u, v, metric="alpha", sigma2=0.5, rtol=1e-3, bogus=1)


def test_pairwise_with_rtol_records_it_in_the_store(shapes, tmp_path):
    from shapelib.pairwise import compute_pairwise

    x = shapes[:3]
    r = compute_pairwise(x, metric="alpha", sigma2=0.5, rtol=1e-2, n_jobs=1, store=tmp_path / "D.zarr",
                         progress=False)
    assert r.params["rtol"] == 1e-2 and np.all(r.lower <= r.upper)
    bound = pairwise_distances(x, metric="alpha_bound", sigma2=0.5, n_jobs=1, progress=False)
    np.testing.assert_allclose(r.lower, bound, rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="rtol 0.01, not 0.001"):
        compute_pairwise(x, metric="alpha", sigma2=0.5, rtol=1e-3, n_jobs=1, store=tmp_path / "D.zarr",
                         progress=False)


def _chebyshev(u, v, *, power=1.0):
    """A user's metric: the largest landmark displacement, to a power (for the option check)."""
    return float(np.max(np.linalg.norm(np.asarray(u) - np.asarray(v), axis=1))) ** power


@pytest.fixture
def registered():
    from shapelib import distances

    names = set(distances._REGISTRY)
    yield distances
    for name in set(distances._REGISTRY) - names:  # leave the registry as the other tests know it
        del distances._REGISTRY[name]


def test_a_registered_metric_works_everywhere_a_builtin_does(shapes, registered):
    from shapelib.pairwise import compute_pairwise

    d = registered
    info = d.register_metric("chebyshev", _chebyshev, description="largest landmark displacement")
    assert d.metric_info("chebyshev") is info and info.symmetric and not info.path and info.bracket is None
    assert "chebyshev" in d.METRICS and "chebyshev" in d.SYMMETRIC and "chebyshev" not in d.PATH_METRICS
    u, v = shapes[:2]
    want = float(np.max(np.linalg.norm(u - v, axis=1)))
    assert distance(u, v, metric="chebyshev") == want == d.METRICS["chebyshev"](u, v)
    assert d.pair_record(u, v, metric="chebyshev", power=2.0)["value"] == pytest.approx(want ** 2, rel=1e-15)
    r = compute_pairwise(shapes, metric="chebyshev", n_jobs=1, block_size=3, progress=False)
    assert r.matrix[1, 0] == r.matrix[0, 1] == want and r.params == {"power": 1.0}
    # its options are its function's keywords, checked as a built-in's are
    with pytest.raises(ValueError, match=r"'chebyshev' has no parameter\(s\) \['sigma2'\]; it takes \['power'\]"):
        distance(u, v, metric="chebyshev", sigma2=0.5)
    with pytest.raises(ValueError, match="rtol applies to the certified metrics"):
        distance(u, v, metric="chebyshev", rtol=1e-3)
    # a taken name needs replace=True; an asymmetric one is computed in both orders
    with pytest.raises(ValueError, match="already registered"):
        d.register_metric("chebyshev", _chebyshev)
    d.register_metric("chebyshev", _chebyshev, symmetric=False, replace=True)
    assert "chebyshev" not in d.SYMMETRIC
    assert len(compute_pairwise(shapes, metric="chebyshev", n_jobs=1, progress=False).to_frame()) == 12
    for bad, message in ((dict(name="two words"), "identifier"), (dict(function=3), "must be callable"),
                         (dict(lower_bound="nope"), "lower_bound 'nope' is not a registered metric")):
        kw = {"name": "other", "function": _chebyshev, **bad}
        with pytest.raises(ValueError, match=message):
            d.register_metric(kw.pop("name"), kw.pop("function"), **kw)


def test_the_registry_describes_the_builtin_metrics():
    import pickle
    from functools import partial

    from shapelib import distances as d
    from shapelib.solver.bracket import distance_bracket

    builtin = ["alpha", "fisher_rao", "diffeomorphism", "alpha_bound", "fisher_rao_bound", "procrustes",
               "hausdorff", "tps", "wendland"]
    assert list(d.METRICS)[:9] == builtin  # (other tests register metrics of their own after them)
    assert d.PATH_METRICS[:3] == ("alpha", "fisher_rao", "diffeomorphism")
    assert d.BRACKET_METRICS == ("alpha", "fisher_rao")
    assert set(builtin) - set(d.SYMMETRIC) == {"tps", "wendland"}
    for name in builtin:
        info = d.metric_info(name)
        assert info.name == name and info.description and "\n" not in info.description
        assert info.lower_bound is None or info.lower_bound in d.METRICS
        # what the engine sends to Dask workers: the record, its functions pickled by reference
        again = pickle.loads(pickle.dumps(info))
        same = lambda f: (f.func, f.keywords) if isinstance(f, partial) else f  # noqa: E731
        assert same(again.function) == same(info.function) and same(again.bracket) == same(info.bracket)
        assert len(pickle.dumps(info)) < 1000
    assert d.metric_info("alpha").lower_bound == "alpha_bound"
    assert d.metric_info("fisher_rao").options_of(rtol=1e-3).func is distance_bracket
