"""Log maps of a whole population at one base shape, in this process or on any executor.

The intrinsic statistics (:mod:`shapelib.statistics.frechet`, :mod:`~shapelib.statistics.tangent_pca`,
:mod:`~shapelib.statistics.regression`, :mod:`~shapelib.statistics.group`) spend nearly all their
time in log maps, one path solve per shape (:func:`shapelib.solver.logexp.log_maps`). They take an
``executor``: any :class:`concurrent.futures.Executor` (``submit`` returning futures with
``result()``), e.g. a :class:`~concurrent.futures.ProcessPoolExecutor` or a Dask cluster's
``client.get_executor()``. The shapes are cut into chunks, one task per chunk, and the results
come back in order. ``executor=None`` runs them here.

This area does not import the engine: :func:`shapelib._executor.engine_executor` builds the
executor from ``n_jobs=`` / ``client=`` / ``scheduler=`` the way
:func:`shapelib.pairwise_distances` does, and the statistics pass it in.
"""

from __future__ import annotations

import math

import numpy as np

from ..solver.logexp import GeodesicOptions, LogResult, log_maps

__all__ = ["population_logs", "shifted_paths", "DEFAULT_CHUNKS"]

#: tasks per population when the caller does not size the chunks
DEFAULT_CHUNKS = 16


def population_logs(base, shapes, *, options: GeodesicOptions, inits=None, executor=None,
                    chunk_size: int | None = None) -> list[LogResult]:
    """:func:`shapelib.solver.logexp.log_maps` of ``shapes`` (N, K, d) at ``base``, chunked over
    ``executor``.

    Parameters
    ----------
    base : ndarray (K, d) or (N, K, d)
        One base for all, or one per shape.
    shapes : ndarray (N, K, d)
    options : GeodesicOptions
    inits : sequence of N paths or None, optional
        Warm starts (:func:`shifted_paths`).
    executor : concurrent.futures.Executor, optional
    chunk_size : int, optional
        Shapes per task (default: N / :data:`DEFAULT_CHUNKS`, rounded up).

    Returns
    -------
    list of LogResult, in the order of ``shapes``
    """
    n = len(shapes)
    inits = [None] * n if inits is None else list(inits)
    if executor is None or n == 0:
        return log_maps(base, shapes, options=options, inits=inits)
    size = chunk_size or max(1, math.ceil(n / DEFAULT_CHUNKS))
    base = np.asarray(base, dtype=np.float64)
    futures = [executor.submit(log_maps, base if base.ndim == 2 else base[a:a + size], shapes[a:a + size],
                               options=options, inits=inits[a:a + size])
               for a in range(0, n, size)]
    out = []
    for fut in futures:
        out.extend(fut.result())
    return out


def shifted_paths(results, old_base, new_base) -> list:
    """Warm starts at ``new_base``: each path of ``results`` with its start moved from ``old_base``
    to ``new_base`` and the move tapered linearly to zero at its (fixed) end. The bases are one
    shape (K, d) or one per result (N, K, d)."""
    delta = np.asarray(new_base, dtype=np.float64) - np.asarray(old_base, dtype=np.float64)
    deltas = np.broadcast_to(delta, (len(results), *results[0].path.shape[1:])) if len(results) else []
    out = []
    for r, dl in zip(results, deltas):
        n = len(r.path) - 1
        taper = (1.0 - np.arange(n + 1) / n)[:, None, None]
        out.append(r.path + taper * dl)
    return out
