"""Where a statistic's log maps run: ``executor=``, or ``n_jobs`` / ``client`` / ``scheduler`` turned
into one by :func:`shapelib._executor.engine_executor` (a Dask ``LocalCluster`` of one single-threaded
worker per core, or a running Dask cluster, exactly as for :func:`shapelib.pairwise_distances`).

With ``n_jobs=None`` (the default) one log map is timed at the statistic's own starting point and the
work stays in this process when the projected serial time is below the cluster's start-up cost.
Every statistic takes these keywords itself (``shapelib.frechet_mean`` is
:func:`shapelib.statistics.frechet_mean`); a statistic that calls another hands it the executor it
runs on (:attr:`Where.passed_on`), so a nested call neither times again nor starts a second cluster.
"""

from __future__ import annotations

import contextlib
import time
import warnings
from dataclasses import dataclass

import numpy as np

from .._executor import check_where, engine_executor
from ..geometry.scale import ScaleWarning
from ..solver.logexp import log_maps

__all__ = ["MEAN_ROUNDS", "projected_seconds", "Where", "where_logs_run"]

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


@dataclass(frozen=True)
class Where:
    """Where the log maps of one statistic run.

    Attributes
    ----------
    executor : concurrent.futures.Executor or None
        None: in this process.
    n_workers : int or None
        Workers (None for a caller's own ``executor``).
    mode : str
        ``"in-process"``, ``"LocalCluster(k processes)"``, ``"cluster"`` or ``"executor"``.
    chunk_size : int or None
        Shapes per task.
    """

    executor: object
    n_workers: int | None
    mode: str
    chunk_size: int | None

    @property
    def passed_on(self) -> dict:
        """The keywords a nested statistic gets: this executor, or ``n_jobs=1`` for in-process work."""
        if self.executor is None:
            return {"n_jobs": 1, "chunk_size": self.chunk_size}
        return {"executor": self.executor, "chunk_size": self.chunk_size}

    def record(self, history: list) -> None:
        """Add ``mode`` and ``n_workers`` to the last entry of a result's ``history``."""
        if history and self.mode != "executor":
            history[-1].update(mode=self.mode, n_workers=self.n_workers)


@contextlib.contextmanager
def where_logs_run(x, options, *, base, rounds, executor=None, n_jobs=None, client=None, scheduler=None,
                   chunk_size=None):
    """Yield the :class:`Where` of a statistic's log maps of ``x`` (N, K, d).

    ``base``: the point the first round of log maps starts from (an array, or a callable returning
    it, called only when a log map is timed); ``rounds``: how many rounds of ``N`` log maps the
    statistic costs (:data:`MEAN_ROUNDS` per Fréchet mean; 0: no log map, stay in process).
    ``executor`` and the engine keywords are exclusive.
    """
    if executor is not None:
        if n_jobs is not None or client is not None or scheduler is not None:
            raise ValueError("give executor, or n_jobs / client / scheduler, not both")
        yield Where(executor, None, "executor", chunk_size)
        return
    check_where(n_jobs, client, scheduler)
    serial = None
    if n_jobs in (None, -1) and client is None and scheduler is None:
        if len(x) <= 2 or rounds <= 0:
            n_jobs = 1
        else:
            serial = projected_seconds(x, base() if callable(base) else base, options, rounds=rounds)
    with engine_executor(n_jobs=n_jobs, client=client, scheduler=scheduler, serial_seconds=serial) as (ex, workers,
                                                                                                       mode):
        yield Where(ex, workers, mode, _chunk_size(len(x), workers) if chunk_size is None else chunk_size)
