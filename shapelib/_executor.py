"""Where the engine's work runs: a Dask cluster as an executor, the local cluster, Ctrl-C.

One small module low in the house, used by the pairwise engine (:mod:`shapelib.pairwise`) and by
every statistic that takes ``n_jobs`` / ``client`` / ``scheduler``. Dask is imported only inside
the functions that start or join a cluster, so importing this module (and the mathematics that
uses it) stays light and in-process work never touches Dask.

``n_jobs=1`` runs in this process; ``n_jobs=k > 1`` on a :class:`distributed.LocalCluster` of ``k``
single-threaded worker processes (:func:`local_cluster`); ``client=`` or ``scheduler=`` on a running
Dask cluster; ``n_jobs=None`` (or ``-1``) in this process when the caller's projected serial time is
below the break-even ``CLUSTER_OVERHEAD_SECONDS · W / (W − 1)`` on ``W`` cores, else on one worker
per core (:func:`engine_executor`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import warnings

import numpy as np

from ._validate import check_positive_int

__all__ = ["CLUSTER_OVERHEAD_SECONDS", "WORKER_ENVIRON", "NANNY_CLOSE_SECONDS", "POLL_SECONDS", "Interrupts",
           "n_cores", "in_dask_worker", "cluster_size", "local_cluster", "nanny_class", "ignore_sigint",
           "check_where", "engine_executor", "connect"]

#: measured cost of starting a LocalCluster and importing shapelib in its workers (2-core machine)
CLUSTER_OVERHEAD_SECONDS = 5.0
#: glibc malloc settings of the workers of the LocalCluster the engine starts (Dask's
#: ``distributed.nanny.pre-spawn-environ``). Dask's default ``MALLOC_TRIM_THRESHOLD_=65536`` also
#: freezes glibc's mmap threshold at 128 KiB, so every array above it (a Fisher–Rao integrand on
#: its grid: ~1 MB) is mmapped and its pages faulted in again on every pair: measured in one
#: process on ADHD-200 pairs (σ² = 0.5), Fisher–Rao bound 1,330 pairs/s with glibc's defaults, 560
#: with Dask's, 1,620 with these; α bracket 50 vs 45 pairs/s.
WORKER_ENVIRON = {"distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": 64 * 2**20,
                  "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 128 * 2**20}
#: seconds a nanny of the engine's LocalCluster gives its worker process to close (:func:`nanny_class`)
NANNY_CLOSE_SECONDS = 1.0


#: seconds between two looks for a Ctrl-C while the engine waits for Dask (:class:`Interrupts`)
POLL_SECONDS = 0.2


class Interrupts:
    """Ctrl-C during a run stops it, whatever code it lands in.

    Python runs a SIGINT handler in the main thread between two bytecodes, wherever the thread
    is. Two places went wrong: inside a finalizer or weakref callback (``__del__`` of a Dask
    future the loop lets go, ``WeakSet._remove``), where the KeyboardInterrupt is printed as
    "Exception ignored" and lost — the run went on to the end; and inside the Dask client's own
    calls (e.g. half-way through ``IOLoop.add_callback``), which left a caller's
    :class:`distributed.Client` cancelling every later future. While the engine runs (main
    thread only) the handler is wrapped: the exception the previous handler raises is recorded;
    in process it is also raised at once (the thread is computing pairs), while Dask is in use
    (:meth:`deferred`) it is only raised by :meth:`check`, which the engine calls after every
    block, every :data:`POLL_SECONDS` while it waits for Dask, and before returning — so a
    Ctrl-C stops the run within that time, from a point where the client is consistent. A
    handler that does not raise (a program that handles Ctrl-C its own way) is left to decide;
    ``SIG_IGN``/``SIG_DFL`` are kept.
    """

    def __init__(self):
        self.exc = None
        self.defer = False
        self._previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            previous = signal.getsignal(signal.SIGINT)
            if callable(previous):
                self._previous = previous
                signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame):
        try:
            self._previous(signum, frame)
        except BaseException as exc:
            self.exc = exc
            if not self.defer:
                raise

    @contextlib.contextmanager
    def deferred(self):
        """Within: a Ctrl-C is recorded, and raised by the next :meth:`check`."""
        self.defer = True
        try:
            yield self
        finally:
            self.defer = False

    def check(self):
        """Raise the interrupt recorded if it has not stopped the run yet."""
        exc, self.exc = self.exc, None
        if exc is not None:
            raise exc

    def __exit__(self, kind, value, tb):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None
        if value is not self.exc:  # a Ctrl-C swallowed or deferred after the last check, or one that
            self.check()           # the code it landed in turned into another error
        return False


def n_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def in_dask_worker() -> bool:
    import sys

    if "distributed" not in sys.modules:
        return False
    try:
        sys.modules["distributed"].get_worker()
    except ValueError:
        return False
    return True


def cluster_size(client) -> int:
    """Worker threads of ``client``'s cluster (1 if unknown, e.g. a scheduler address not yet joined)."""
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:
        return 1


def local_cluster(n_workers: int):
    """The :class:`distributed.LocalCluster` the engine starts for ``n_jobs=k``: ``k`` worker
    processes of one thread each, no dashboard, glibc malloc tuned (:data:`WORKER_ENVIRON`).

    Its logs are at CRITICAL only: a worker whose heartbeat races the scheduler's shutdown at the
    end of a run logs a CommClosedError traceback at ERROR. Failures that matter still reach the
    caller: a task's exception is raised by the client, a lost worker's tasks are rerun by the
    scheduler. Use it as a context manager, or ``close()`` it.

    Ctrl-C: a Ctrl-C while the cluster was starting left it half-started (an atexit traceback),
    so SIGINT is blocked in the calling (main) thread while the cluster starts, and one pressed
    meanwhile is delivered, as KeyboardInterrupt, once the cluster is up — which is then closed.
    A terminal also sends SIGINT to the worker processes (same process group), which printed
    their own KeyboardInterrupt tracebacks: the engine has its workers ignore SIGINT
    (:func:`ignore_sigint`, run on them once they are up; spawned processes do not inherit a
    blocked mask), since the caller stops the run and closing the cluster ends them.

    Parameters
    ----------
    n_workers : int
        Worker processes (one thread each), a positive integer.

    Returns
    -------
    distributed.LocalCluster
        The running cluster; close it (or leave its ``with`` block) to end the worker processes.

    See Also
    --------
    engine_executor : The same cluster as an executor, for maps over shapes.
    shapelib.pairwise.compute_pairwise : Starts one for ``n_jobs=k > 1``.

    Examples
    --------
    Starting worker processes takes a few seconds (each imports shapelib), so this example is
    not run in the doctests:

    >>> from distributed import Client
    >>> from shapelib.pairwise import local_cluster
    >>> with local_cluster(2) as cluster, Client(cluster) as client:  # doctest: +SKIP
    ...     print(len(cluster.workers), client.submit(sum, [1, 2, 3]).result())
    2 6
    """
    import dask
    from distributed import LocalCluster

    check_positive_int(n_workers, name="n_workers")
    block = hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if block else None
    cluster = None
    try:
        with warnings.catch_warnings(), dask.config.set(WORKER_ENVIRON):
            warnings.filterwarnings("ignore", message="Port .* is already in use")  # the HTTP port moves
            cluster = LocalCluster(n_workers=int(n_workers), threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.CRITICAL,
                                   worker_class=nanny_class())
    finally:
        if block:
            try:  # a pending Ctrl-C is raised by this call (it runs the signal handlers)
                signal.pthread_sigmask(signal.SIG_SETMASK, old)
            except BaseException:
                if cluster is not None:
                    cluster.close()
                raise
    return cluster


def nanny_class():
    """Dask's Nanny, closing its worker process within :data:`NANNY_CLOSE_SECONDS`.

    A worker asked to close first waits for the task it is running; Dask's nanny gives it 4 s
    (``0.8 × 5``) before killing it, so a Ctrl-C or a stopping ``callback`` in the middle of a
    long pair (a Fisher–Rao geodesic takes half a minute) kept the caller waiting those seconds
    for a result that is thrown away. The engine's cluster holds nothing but running tasks (every
    finished block is already in the client), so its nannies wait less."""
    from distributed import Nanny

    class _Nanny(Nanny):
        async def close(self, timeout: float = NANNY_CLOSE_SECONDS, reason: str = "nanny-close"):
            return await super().close(timeout=timeout, reason=reason)

    return _Nanny


def ignore_sigint():
    """Run on a worker of the engine's own LocalCluster: leave Ctrl-C to the process that started it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def check_where(n_jobs, client, scheduler) -> None:
    """Where the work runs: ``n_jobs`` (a positive int, -1 or None), or a ``client``, or a ``scheduler``."""
    if client is not None and scheduler is not None:
        raise ValueError("give client or scheduler, not both")
    if n_jobs is not None and n_jobs != -1 and (isinstance(n_jobs, bool) or not isinstance(n_jobs, (int, np.integer))
                                                or n_jobs < 1):
        raise ValueError(f"n_jobs must be a positive integer, -1 or None; got {n_jobs!r}")
    if (client is not None or scheduler is not None) and n_jobs not in (None, -1):
        raise ValueError("n_jobs sizes a local cluster; it cannot be combined with client or scheduler")


@contextlib.contextmanager
def engine_executor(*, n_jobs=None, client=None, scheduler=None, serial_seconds=None):
    """The engine's workers as a :class:`concurrent.futures.Executor`, for work that is a map over
    shapes rather than pairs (the intrinsic statistics' log maps, :mod:`shapelib.statistics`).

    Yields ``(executor, n_workers, mode)``; ``executor`` is None for in-process work. ``client=``
    or ``scheduler=`` use that Dask cluster (``client.get_executor()``); ``n_jobs=k > 1`` starts a
    :func:`local_cluster` of ``k`` workers for the duration of the ``with`` block; ``n_jobs=1`` runs
    in this process; ``n_jobs=None`` or ``-1`` runs in this process when ``serial_seconds`` (the
    caller's projection of the serial time) is below the break-even
    ``CLUSTER_OVERHEAD_SECONDS · W / (W − 1)`` on ``W`` cores, else on one worker per core — the
    rule :func:`compute_pairwise` applies to matrices.

    Parameters
    ----------
    n_jobs : int, optional
        ``1``: in this process; ``k > 1``: a local cluster of ``k`` worker processes; ``None``
        or ``-1``: chosen from ``serial_seconds``.
    client : distributed.Client, optional
        Use this Dask cluster.
    scheduler : str, optional
        Address of a running Dask scheduler (``"tcp://host:8786"``).
    serial_seconds : float, optional
        The caller's projection of the work's serial time, for ``n_jobs=None``; None: in this
        process.

    Yields
    ------
    executor : concurrent.futures.Executor or None
        Where to ``submit`` or ``map`` the work; None: run it in this process.
    n_workers : int
        Workers it has (1 in this process).
    mode : str
        ``"in-process"``, ``"LocalCluster(k processes)"`` or ``"cluster"``, for the caller's log.

    Raises
    ------
    ValueError
        For ``n_jobs`` not a positive integer, -1 or None, for both ``client`` and
        ``scheduler``, or ``n_jobs`` with either; when the scheduler cannot be reached.

    See Also
    --------
    local_cluster : The cluster started for ``n_jobs=k > 1``.

    Examples
    --------
    A second of serial work is below the break-even of starting a cluster, so it runs here:

    >>> from shapelib.pairwise import engine_executor
    >>> with engine_executor(n_jobs=None, serial_seconds=1.0) as (executor, n_workers, mode):
    ...     results = (list(executor.map(abs, [-1, 2, -3])) if executor is not None
    ...                else [abs(v) for v in [-1, 2, -3]])
    >>> executor, n_workers, mode, results
    (None, 1, 'in-process', [1, 2, 3])
    """
    from distributed import Client

    check_where(n_jobs, client, scheduler)
    if client is not None:
        yield client.get_executor(pure=False), cluster_size(client), "cluster"
        return
    if scheduler is not None:
        own = connect(scheduler)
        try:
            yield own.get_executor(pure=False), cluster_size(own), "cluster"
        finally:
            own.close()
        return
    n_workers = n_cores() if n_jobs in (None, -1) else int(n_jobs)
    if n_jobs in (None, -1) and (n_workers < 2 or serial_seconds is None
                                 or serial_seconds < CLUSTER_OVERHEAD_SECONDS * n_workers / (n_workers - 1)):
        n_workers = 1
    if n_workers == 1:
        yield None, 1, "in-process"
        return
    with local_cluster(n_workers) as cluster, Client(cluster) as own:
        own.run(ignore_sigint)  # see local_cluster: Ctrl-C is the caller's
        yield own.get_executor(pure=False), n_workers, f"LocalCluster({n_workers} processes)"


def connect(scheduler):
    """A Dask client of the running scheduler at ``scheduler``; ValueError naming it if it cannot be reached."""
    from distributed import Client

    try:
        return Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise ValueError(f"cannot reach the Dask scheduler {scheduler!r}: {exc}") from exc
