"""The intrinsic statistics on the engine (n_jobs=, client=, scheduler=): a real Dask LocalCluster started by
``n_jobs=2`` or given as ``client=``, against the in-process answer."""

from pathlib import Path

import numpy as np
import pytest

import shapelib
from shapelib.statistics import frechet
from tests.conftest import ellipse




@pytest.fixture(scope="module")
def shapes():
    rng = np.random.default_rng(2)
    return shapelib.pose_align(np.stack([ellipse(10) + 0.3 * rng.normal(size=(10, 2)) for _ in range(10)]))[0]


@pytest.fixture(scope="module")
def reference(shapes):
    return frechet.frechet_mean(shapes, sigma2=1.0, tol=1e-4, n_jobs=1)


@pytest.fixture(scope="module")
def client():
    from distributed import Client

    from shapelib.pairwise import local_cluster

    with local_cluster(2) as cluster, Client(cluster) as c:
        yield c


@pytest.mark.processes
def test_frechet_mean_on_a_local_cluster_started_by_n_jobs(shapes, reference):
    res = shapelib.frechet_mean(shapes, sigma2=1.0, tol=1e-4, n_jobs=2)
    assert res.log[-1]["mode"] == "LocalCluster(2 processes)"
    assert np.allclose(res.mean, reference.mean, atol=1e-12)
    assert res.n_iter == reference.n_iter


@pytest.mark.processes
def test_frechet_mean_on_a_given_client(shapes, reference, client):
    res = shapelib.frechet_mean(shapes, sigma2=1.0, tol=1e-4, client=client)
    assert res.log[-1]["mode"] == "cluster" and res.log[-1]["n_workers"] == 2
    assert np.allclose(res.mean, reference.mean, atol=1e-12)


def test_small_work_stays_in_process(shapes, reference):
    res = shapelib.frechet_mean(shapes, sigma2=1.0, tol=1e-4)  # n_jobs=None: a few seconds at most
    assert res.log[-1]["mode"] == "in-process"
    assert np.array_equal(res.mean, reference.mean)


def test_where_it_runs_is_checked(shapes, client):
    with pytest.raises(ValueError, match="n_jobs"):
        shapelib.frechet_mean(shapes, sigma2=1.0, n_jobs=0)
    with pytest.raises(ValueError, match="not both"):
        shapelib.frechet_mean(shapes, sigma2=1.0, client=client, scheduler="tcp://127.0.0.1:1")


def test_regression_and_group_test_on_a_given_client(shapes, reference, client):
    from shapelib.statistics import group, regression

    t = np.linspace(0.0, 1.0, len(shapes))
    here = regression.geodesic_regression(shapes, t, sigma2=1.0, mean=reference, n_jobs=1)
    there = shapelib.geodesic_regression(shapes, t, sigma2=1.0, mean=reference, client=client)
    assert there.log[-1]["mode"] == "cluster"
    assert np.allclose(here.path, there.path, atol=1e-12) and here.r2 == there.r2
    labels = np.arange(len(shapes)) % 2
    here = group.mean_difference_test(shapes, labels, sigma2=1.0, pooled=reference, seed=0, n_jobs=1)
    there = shapelib.mean_difference_test(shapes, labels, sigma2=1.0, pooled=reference, seed=0, client=client)
    assert here.p_value == there.p_value and np.allclose(here.means[1].mean, there.means[1].mean, atol=1e-12)


def test_tangent_pca_through_the_package(shapes, reference):
    from shapelib.statistics.tangent_pca import tangent_pca

    a = shapelib.tangent_pca(shapes, sigma2=1.0, mean=reference, modes=())
    b = tangent_pca(shapes, sigma2=1.0, mean=reference, modes=())
    assert np.array_equal(a.scores, b.scores)
    c = shapelib.tangent_pca(shapes, sigma2=1.0, mean=reference.mean, modes=(), n_jobs=1)
    assert np.allclose(c.explained_variance, a.explained_variance, rtol=1e-4)


def test_one_public_function_per_statistic():
    """The statistics take the engine keywords themselves: one object under every name."""
    import shapelib.statistics

    for name in ("frechet_mean", "tangent_pca", "geodesic_regression", "mean_difference_test"):
        assert getattr(shapelib, name) is getattr(shapelib.statistics, name)
    # the alias module shapelib.population is retired: no file, no lazy name
    assert not (Path(shapelib.__file__).parent / "population.py").exists() and "population" not in dir(shapelib)
    with pytest.raises(AttributeError):
        shapelib.population


def test_an_executor_and_the_engine_keywords_are_exclusive(shapes):
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as ex, pytest.raises(ValueError, match="not both"):
        shapelib.frechet_mean(shapes, sigma2=1.0, executor=ex, n_jobs=1)


def test_the_procrustes_mean_is_computed_once(shapes, monkeypatch):
    """n_jobs=None times a log map at the Procrustes mean, which is also where the Karcher iteration
    starts: one GPA, not one for the projection and another for the start."""
    from shapelib.statistics import frechet, group, regression

    calls = []
    original = frechet.procrustes_mean

    def counted(x):
        calls.append(len(x))
        return original(x)

    for module in (frechet, group, regression):
        monkeypatch.setattr(module, "procrustes_mean", counted)
    res = shapelib.frechet_mean(shapes, sigma2=1.0, tol=1e-4)
    assert res.log[-1]["mode"] == "in-process" and calls == [len(shapes)]
    calls.clear()
    t = np.linspace(0.0, 1.0, len(shapes))
    shapelib.geodesic_regression(shapes, t, sigma2=1.0, max_iter=2, warn=False)
    assert calls == [len(shapes)]
    calls.clear()
    shapelib.mean_difference_test(shapes, np.arange(len(shapes)) % 2, sigma2=1.0, group_means=False)
    assert calls == [len(shapes)]
