"""Intrinsic statistics of a population on the engine: ``n_jobs=``, ``client=``, ``scheduler=``.

The statistics themselves live in :mod:`shapelib.statistics` (Fréchet mean, tangent PCA, geodesic
regression, the group test) and run their log maps on any :class:`concurrent.futures.Executor`
they are given. The mathematics does not import the engine, so this module — at the engine's rank —
is where ``n_jobs`` / ``client`` / ``scheduler`` become an executor
(:func:`shapelib._executor.engine_executor`): a Dask ``LocalCluster`` of one single-threaded worker
per core, or a running Dask cluster, exactly as for :func:`shapelib.pairwise_distances`. With
``n_jobs=None`` one log map is timed here and the work stays in this process when the projected
serial time is below the cluster's start-up cost.

These are the functions exported as ``shapelib.frechet_mean``, ``shapelib.tangent_pca``,
``shapelib.geodesic_regression`` and ``shapelib.mean_difference_test``.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from ._validate import as_shapes
from .geometry.scale import ScaleWarning
from ._executor import engine_executor
from .solver.logexp import log_maps
from .statistics import frechet as _frechet
from .statistics import group as _group
from .statistics import regression as _regression
from .statistics.tangent_pca import TangentPCAResult
from .statistics.tangent_pca import tangent_pca as _tangent_pca

__all__ = ["frechet_mean", "tangent_pca", "geodesic_regression", "mean_difference_test", "projected_seconds"]

#: log-map rounds a Fréchet mean costs, in units of the first round from straight lines (the
#: later, warm-started rounds are 2–5 times cheaper; measured on ADHD-200, α and Fisher–Rao)
MEAN_ROUNDS = 2.0


def projected_seconds(shapes, base, options, *, rounds: float = MEAN_ROUNDS) -> float:
    """Serial seconds of ``rounds`` rounds of log maps of all ``shapes`` at ``base``, from one timed
    log map (the faster of two calls: the first in a process also loads compiled kernels)."""
    x = np.asarray(shapes, dtype=np.float64)
    times = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        for _ in range(2):
            t0 = time.perf_counter()
            log_maps(base, x[:1], options=options)
            times.append(time.perf_counter() - t0)
            if times[0] > 10:
                break
    return min(times) * len(x) * rounds


def _chunk_size(n, n_workers):
    """Four tasks per worker: load balance without many tiny tasks."""
    return max(1, -(-n // (4 * max(1, n_workers))))


def _where(x, metric, sigma2, options, n_jobs, client, scheduler, *, rounds=MEAN_ROUNDS, base=None):
    """``engine_executor`` for log maps of ``x``: with ``n_jobs=None`` the serial time is projected
    from one timed log map."""
    serial = None
    if n_jobs in (None, -1) and client is None and scheduler is None and len(x) > 2 and rounds > 0:
        opts = _frechet.geodesic_options(metric, sigma2, **{k: options[k] for k in (
            "n_steps", "log_tol", "log_max_iter", "rcond", "grid_spacing", "grid_margin") if k in options})
        serial = projected_seconds(x, _frechet.procrustes_mean(x) if base is None else base, opts, rounds=rounds)
    return engine_executor(n_jobs=n_jobs, client=client, scheduler=scheduler, serial_seconds=serial)


def frechet_mean(shapes, *, metric: str = "alpha", sigma2, n_jobs: int | None = None, client=None,
                 scheduler=None, **options) -> _frechet.FrechetMeanResult:
    """Fréchet (Karcher) mean of ``shapes`` (N, K, d) under the α-order or Fisher–Rao metric, its
    log maps on the engine.

    Every option of :func:`shapelib.statistics.frechet.frechet_mean` (``tol``, ``max_iter``,
    ``n_steps``, ``init``, ``rcond``, …) is accepted; ``n_jobs``, ``client``, ``scheduler`` say
    where the log maps run (:func:`shapelib.pairwise_distances`). The result's ``history[-1]``
    gains ``mode`` and ``n_workers``.

    Returns
    -------
    FrechetMeanResult
    """
    x = as_shapes(shapes, name="shapes")
    with _where(x, metric, sigma2, options, n_jobs, client, scheduler) as (ex, workers, mode):
        options.setdefault("chunk_size", _chunk_size(len(x), workers))
        res = _frechet.frechet_mean(x, metric=metric, sigma2=sigma2, executor=ex, **options)
    res.history[-1].update(mode=mode, n_workers=workers)
    return res


def tangent_pca(shapes, *, metric: str = "alpha", sigma2=None, mean=None, n_jobs: int | None = None, client=None,
                scheduler=None, **options) -> TangentPCAResult:
    """Tangent PCA of ``shapes`` at their Fréchet mean (:func:`shapelib.statistics.tangent_pca.tangent_pca`,
    every option accepted), the log maps on the engine. Given ``mean=`` a
    :class:`~shapelib.statistics.frechet.FrechetMeanResult`, no log map is computed and the work
    stays in this process.

    Returns
    -------
    TangentPCAResult
    """
    x = as_shapes(shapes, name="shapes")
    if isinstance(mean, _frechet.FrechetMeanResult):
        return _tangent_pca(x, metric=metric, sigma2=sigma2, mean=mean, **options)
    rounds = MEAN_ROUNDS if mean is None else 1.0
    with _where(x, metric, sigma2, options, n_jobs, client, scheduler, rounds=rounds,
                base=None if mean is None else np.asarray(mean, dtype=np.float64)) as (ex, workers, mode):
        options.setdefault("chunk_size", _chunk_size(len(x), workers))
        return _tangent_pca(x, metric=metric, sigma2=sigma2, mean=mean, executor=ex, **options)


def geodesic_regression(shapes, t, *, metric: str = "alpha", sigma2, n_jobs: int | None = None, client=None,
                        scheduler=None, **options) -> _regression.GeodesicRegressionResult:
    """Geodesic regression of ``shapes`` on ``t`` (:func:`shapelib.statistics.regression.geodesic_regression`,
    every option accepted), the residual log maps (and the Fréchet mean for R², unless ``mean=``
    is given) on the engine.

    Returns
    -------
    GeodesicRegressionResult
    """
    x = as_shapes(shapes, name="shapes")
    rounds = 6.0 if options.get("mean") is None else 4.0  # the mean's rounds and Gauss–Newton's
    with _where(x, metric, sigma2, options, n_jobs, client, scheduler, rounds=rounds) as (ex, workers, mode):
        options.setdefault("chunk_size", _chunk_size(len(x), workers))
        res = _regression.geodesic_regression(x, t, metric=metric, sigma2=sigma2, executor=ex, **options)
    res.history[-1].update(mode=mode, n_workers=workers)
    return res


def mean_difference_test(shapes, groups, *, metric: str = "alpha", sigma2, n_jobs: int | None = None, client=None,
                         scheduler=None, **options) -> _group.MeanDifferenceResult:
    """Two-group test of a difference in mean shape with the groups' Fréchet means and the geodesic
    between them (:func:`shapelib.statistics.group.mean_difference_test`, every option accepted),
    the log maps on the engine.

    Returns
    -------
    MeanDifferenceResult
    """
    x = as_shapes(shapes, name="shapes")
    rounds = (0.0 if options.get("pooled") is not None else MEAN_ROUNDS) + (
        MEAN_ROUNDS if options.get("group_means", True) else 0.0)
    with _where(x, metric, sigma2, options, n_jobs, client, scheduler, rounds=rounds) as (ex, workers, mode):
        options.setdefault("chunk_size", _chunk_size(len(x), workers))
        return _group.mean_difference_test(x, groups, metric=metric, sigma2=sigma2, executor=ex, **options)
