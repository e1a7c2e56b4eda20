"""Distance matrices at population scale: blocks of pairs as Dask tasks, finished blocks in a zarr store.

:func:`compute_pairwise` (what :func:`pairwise_distances` calls) cuts the N×N
matrix into ``block_size × block_size`` blocks — the upper-triangle blocks for symmetric metrics,
every block (without the diagonal pairs) for the bending energies ``"tps"`` / ``"wendland"`` — and
computes each block as one task, every pair through :func:`shapelib.distances.pair_record`. The
closed-form bounds ``"alpha_bound"`` and ``"fisher_rao_bound"`` are the exception: a block of them is
one batched call (matrix products, :mod:`shapelib.geometry.bound_matrices`), and in this process a
population of up to :data:`BOUND_BLOCK_MAX` shapes is a single block.

Where the tasks run
    ``client=`` (a :class:`distributed.Client`) or ``scheduler="tcp://host:port"`` runs them on
    that Dask cluster; ``n_jobs=k > 1`` on a :class:`distributed.LocalCluster` of ``k`` single-threaded
    worker processes started and shut down by the call (also on ``KeyboardInterrupt``);
    ``n_jobs=1`` in this process, through the same block and store code. ``n_jobs=None`` measures one
    pair and decides: starting a two-process LocalCluster and importing shapelib in its workers
    costs about :data:`CLUSTER_OVERHEAD_SECONDS` (5 s; measured on the 2-core development machine:
    cluster start 0.9 s, importing distributed + shapelib 2.2 s per spawned worker, shutdown 0.4 s —
    3–4 s when quiet, 8 s at load average 4.5), so a matrix whose projected serial time is below
    ``CLUSTER_OVERHEAD_SECONDS · W / (W − 1)`` (the break-even on ``W`` cores: 10 s on 2 cores) runs
    in this process, a larger one on one worker per core.
    Dask does the scheduling: a worker that dies has its tasks rerun elsewhere by the scheduler
    (``distributed.scheduler.allowed-failures``); nothing here retries by hand. BLAS runs on one
    thread inside every task (one single-threaded worker process per core).

Block size
    Default: the largest ``b`` with ``b² · t_pair ≤`` :data:`TASK_SECONDS` (2 s), ``t_pair`` the
    measured seconds of one pair (one pair timed in this process, or the mean of a resumed store's
    pairs), and small enough that there are at least :data:`TASKS_PER_WORKER` tasks per worker.
    Measured per pair on ADHD-200 shapes (K = 50, centroid size 20, σ² = 0.5): Procrustes 0.2 ms,
    TPS 0.4 ms, Hausdorff 0.07 ms, α bound 0.2 ms, Fisher–Rao bound 5 ms, α geodesic ≈ 1.2 s,
    Fisher–Rao geodesic ≈ 27 s (tol 1e-6), as certified brackets at ``rtol=1e-3`` α 0.03 s and
    Fisher–Rao 1.5 s (``benchmarks/bench_pairwise.py``, 2-core VM under load) — so the cheap metrics get blocks of ~60–160 shapes and the geodesics
    one or two (a task of a few seconds: scheduling costs of ~ms per task vanish, a lost worker or a
    killed run costs a few seconds of work).

The store
    A zarr v3 directory (client-side writes only: workers need no shared disk). Arrays ``matrix``,
    ``lower``, ``upper``, ``energy``, ``seconds`` (float64, NaN where not computed), ``converged``
    (bool), ``n_iter`` (int64, −1 where not computed), each N×N; ``done`` (bool, one entry per block,
    written after the block's data, so a block counts only once all its data are on disk). Every
    chunk carries a CRC32C checksum (zarr's ``crc32c`` codec), and zarr's local store replaces chunk
    files atomically. Attributes (``shapelib_pairwise``): metric, every parameter (defaults filled in),
    rtol, SHA-256 of the shapes, N, K, d, block size, symmetric, shapelib version. Reopening it with
    other shapes, metric or parameters raises ``ValueError`` saying what differs; rerunning with the
    same ones computes only the blocks not done. A checksum mismatch, unreadable or missing chunk
    raises ``ValueError`` naming the store, the array and the block. Without a store the same
    arrays live in memory (NumPy) for the duration of the call.
"""

from __future__ import annotations

import contextlib
import hashlib
import inspect
import itertools
import json
import logging
import math
import os
import signal
import threading
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._validate import InputError, as_shapes, check_positive_int, set_checked
from ._version import __version__
from .geometry.procrustes import PoseWarning, check_pose
from .geometry.scale import ScaleWarning, check_fisher_rao_scale, check_scale
from .solver.geodesic import GeodesicWarning
from .solver.linalg import one_blas_thread
from .distances import SYMMETRIC, check_metric_params, is_builtin, metric_info, pair_record, pose_dependent
from .geometry.bound_matrices import BOUND_METRICS, bound_block

__all__ = ["PairwiseResult", "PairError", "BlockProgress", "compute_pairwise", "pairwise_distances", "open_store",
           "compute_block", "block_pairs", "local_cluster", "engine_executor", "default_block_size", "ARRAYS"]

#: seconds one task should take (sets the default block size)
TASK_SECONDS = 2.0
#: at least this many tasks per worker, for load balance
TASKS_PER_WORKER = 4
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
#: seconds a nanny of the engine's LocalCluster gives its worker process to close (:func:`_nanny_class`)
NANNY_CLOSE_SECONDS = 1.0
#: a run whose estimate (pairs × seconds per pair ÷ workers) reaches this is announced up front:
#: logged at INFO on the ``shapelib.pairwise`` logger (the CLI prints it) and shown on the progress bar
LONG_RUN_SECONDS = 10.0
#: the logger of the engine's run estimates
logger = logging.getLogger("shapelib.pairwise")
#: seconds between two looks for a Ctrl-C while the engine waits for Dask (:class:`_Interrupts`)
POLL_SECONDS = 0.2
#: side of the stored chunks (a multiple of the block size near this)
CHUNK_SIDE = 64
#: the per-pair arrays of the store: name -> (dtype, fill value)
ARRAYS = {
    "matrix": ("float64", math.nan),
    "lower": ("float64", math.nan),
    "upper": ("float64", math.nan),
    "energy": ("float64", math.nan),
    "seconds": ("float64", math.nan),
    "converged": ("bool", False),
    "n_iter": ("int64", -1),
}
_FIELD = {"matrix": "value"}  # pair_record key of each array (same name otherwise)
_ATTR = "shapelib_pairwise"
_FORMAT = 1


class PairError(ValueError):
    """A pair's input was rejected by its metric: which pair and why.

    ``i``, ``j`` are the row and column of the matrix, i.e. ``shapes[i]`` is the metric's ``u``
    and ``shapes[j]`` its ``v``; ``reason`` is the metric's own message (which speaks of ``u``
    and ``v`` and counts landmarks from 0); ``landmarks``: the landmark indices it names (from 0),
    empty if none. Raised in-process and, unchanged, through Dask.
    """

    def __init__(self, i, j, reason, landmarks=()):
        if not landmarks and isinstance(reason, InputError):
            landmarks = reason.facts.get("landmarks", ())
        landmarks = tuple(int(k) for k in landmarks)
        super().__init__(int(i), int(j), str(reason), landmarks)  # args: what pickling (Dask) rebuilds it from
        self.i, self.j, self.reason, self.landmarks = int(i), int(j), str(reason), landmarks

    def __str__(self):
        return f"pair (shapes[{self.i}], shapes[{self.j}]) as (u, v): {self.reason}"


def _pair_record(x_u, x_v, i, j, **kw):
    """:func:`~shapelib.distances.pair_record` naming the pair in its input errors."""
    try:
        return pair_record(x_u, x_v, **kw)
    except ValueError as exc:
        raise PairError(i, j, exc) from exc


# ---------------------------------------------------------------------------------------------
# Result
# ---------------------------------------------------------------------------------------------


@dataclass
class PairwiseResult:
    """A distance matrix with the diagnostics of every pair.

    Attributes
    ----------
    matrix : ndarray, shape (N, N)
        Distances, zero diagonal; for asymmetric metrics ``[i, j]`` is the map from ``i`` onto ``j``.
        NaN where a partial store has no value yet (see ``computed``).
    lower, upper : ndarray, shape (N, N)
        Certified bounds ``lower ≤ d ≤ upper`` (= ``matrix`` for non-path metrics).
    energy : ndarray, shape (N, N)
        Path energy (eq. 8) of the computed path; NaN for non-path metrics.
    seconds : ndarray, shape (N, N)
        Wall time of each pair.
    converged : ndarray of bool, shape (N, N)
        In words per pair: :meth:`status` (converged / bracket wider than rtol / solver failed).
    n_iter : ndarray of int, shape (N, N)
        Solver iterations (0 for non-path metrics, −1 where not computed).
    metric : str
    params : dict
        Every parameter of the metric, defaults filled in (and ``rtol`` if given).
    store : str or None
        Path of the zarr store.
    computed : ndarray of bool, shape (N, N)
        Pairs whose values are present (all, for a finished run).
    log : dict
        Blocks in total / computed by this call / found done, block size, where it ran, wall
        seconds, ``stopped`` (True when a ``callback`` stopped the run), ``estimated_seconds``
        (pairs × timed seconds per pair ÷ workers, when a pair was timed).
    symmetric : bool or None
        Whether the metric is symmetric (pairs ``i < j`` only); None: looked up by name.
    """

    matrix: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    energy: np.ndarray
    seconds: np.ndarray
    converged: np.ndarray
    n_iter: np.ndarray
    metric: str
    params: dict
    store: str | None = None
    computed: np.ndarray | None = None
    log: dict = field(default_factory=dict, repr=False)
    symmetric: bool | None = None

    @property
    def complete(self) -> bool:
        """True when every pair is computed."""
        return bool(self.computed is None or self.computed.all())

    def _pairs(self):
        n = len(self.matrix)
        symmetric = self.metric in SYMMETRIC if self.symmetric is None else self.symmetric
        i, j = np.triu_indices(n, 1) if symmetric else np.nonzero(~np.eye(n, dtype=bool))
        keep = self.computed[i, j] if self.computed is not None else np.ones(len(i), bool)
        return i[keep], j[keep]

    def nonconverged_pairs(self) -> list[tuple[int, int]]:
        """Computed pairs ``(i, j)`` (``i < j`` for symmetric metrics) whose solver did not converge."""
        i, j = self._pairs()
        bad = ~self.converged[i, j]
        return [(int(a), int(b)) for a, b in zip(i[bad], j[bad])]

    def rel_gap(self, i=None, j=None) -> np.ndarray:
        """``upper / lower − 1`` of pairs ``(i, j)`` (default: every computed pair, as :meth:`to_frame`
        orders them): the relative width of each certified bracket (0 for non-path metrics, ``inf``
        where the bound is 0 but the path is not)."""
        if i is None:
            i, j = self._pairs()
        lo, up = self.lower[i, j], self.upper[i, j]
        with np.errstate(divide="ignore", invalid="ignore"):
            gap = np.where(lo > 0, up / lo - 1.0, np.where(up > 0, np.inf, 0.0))
        return np.maximum(gap, 0.0)

    def status(self, i=None, j=None) -> np.ndarray:
        """Per pair, in words: ``"converged"``; ``"bracket wider than rtol"`` (with ``rtol``: the
        distance is certified to lie in its bracket ``[lower, upper]``, whose relative width
        :meth:`rel_gap` is above ``rtol``, the value being its upper end); ``"solver failed"`` (no
        ``rtol``: the geodesic solver stopped before its tolerance, so ``value`` is the length of
        the path it had, still an upper bound on the distance)."""
        if i is None:
            i, j = self._pairs()
        bad = "bracket wider than rtol" if self.params.get("rtol") is not None else "solver failed"
        return np.where(self.converged[i, j], "converged", bad)

    def convergence_summary(self) -> str:
        """One line on the pairs that did not converge, in :meth:`status`'s words with how wide the
        brackets are; ``""`` if every computed pair converged."""
        i, j = self._pairs()
        bad = ~self.converged[i, j]
        if not bad.any():
            return ""
        n, total = int(bad.sum()), len(bad)
        first = [(int(a), int(b)) for a, b in zip(i[bad][:3], j[bad][:3])]
        rtol = self.params.get("rtol")
        if rtol is None:
            return (f"{n} of {total} {self.metric} pairs: solver failed (the geodesic solver stopped before its "
                    f"tolerance; each value is the length of the path it had, an upper bound), first {first}")
        gap = self.rel_gap(i[bad], j[bad])
        return (f"{n} of {total} {self.metric} pairs: the certified bracket is wider than rtol = {rtol:g} (relative "
                f"gap median {100 * float(np.median(gap)):.3g} %, max {100 * float(np.max(gap)):.3g} %): each distance "
                f"lies in its bracket [lower, upper] and the value is its upper end; not a solver failure")

    def to_frame(self):
        """One row per computed pair (``i < j`` for symmetric metrics) with all diagnostics,
        :meth:`status` and :meth:`rel_gap` included."""
        import pandas as pd

        i, j = self._pairs()
        return pd.DataFrame({"i": i, "j": j, "value": self.matrix[i, j], "lower": self.lower[i, j],
                             "upper": self.upper[i, j], "rel_gap": self.rel_gap(i, j), "energy": self.energy[i, j],
                             "converged": self.converged[i, j], "status": self.status(i, j),
                             "n_iter": self.n_iter[i, j], "seconds": self.seconds[i, j]})


# ---------------------------------------------------------------------------------------------
# Blocks: the unit of work
# ---------------------------------------------------------------------------------------------


def _n_blocks(n: int, b: int) -> int:
    return -(-n // b)


def block_pairs(n: int, block_size: int, *, symmetric: bool) -> list[tuple[int, int]]:
    """Block indices ``(I, J)`` of the tasks: ``I ≤ J`` for symmetric metrics, all for asymmetric ones."""
    nb = _n_blocks(n, block_size)
    return [(a, b) for a in range(nb) for b in range(nb) if not symmetric or a <= b]


def compute_block(xi, xj, *, diagonal: bool, symmetric: bool, metric, rtol, params: dict,
                  offset=(0, 0)) -> dict:
    """All pairs of one block through :func:`shapelib.distances.pair_record`: ``{array: (bi, bj)}``.

    ``metric`` is a name or a :class:`~shapelib.distances.MetricInfo` record: the engine sends
    the record with each task, so a metric registered in the client runs on workers that can
    import its function's module, registered there or not.

    ``xi``, ``xj`` are the block's row and column shapes, starting at rows/columns ``offset`` of
    the matrix (used to name a pair in a :class:`PairError`). On a diagonal block only the pairs
    ``i ≠ j`` are computed (``i < j``, then mirrored, for symmetric metrics) and the diagonal is
    zero. Solver warnings are not emitted: convergence is recorded per pair instead; nor are
    scale and pose warnings, which :func:`compute_pairwise` gives once for all the shapes.
    """
    bi, bj = len(xi), len(xj)
    bound = _batched_bound(metric, rtol)
    if bound:
        out = _bound_block(xi, xj, diagonal=diagonal, metric=bound, params=params)
        if out is not None:
            return out
    out = {name: np.full((bi, bj), fill, dtype=dtype) for name, (dtype, fill) in ARRAYS.items()}
    with _pair_work():
        for a in range(bi):
            for b in range(bj):
                if diagonal and (a == b or (symmetric and b < a)):
                    continue
                rec = _pair_record(xi[a], xj[b], offset[0] + a, offset[1] + b, metric=metric, rtol=rtol, **params)
                for name in ARRAYS:
                    out[name][a, b] = rec[_FIELD.get(name, name)]
    if diagonal:
        if symmetric:
            low = np.tril_indices(bi, -1)
            for arr in out.values():
                arr[low] = arr.T[low]
        d = np.diag_indices(bi)
        for name in ("matrix", "lower", "upper", "energy", "seconds", "n_iter"):
            out[name][d] = 0
        out["converged"][d] = True
    return out


def _batched_bound(metric, rtol) -> str | None:
    """The bound whose blocks are one batched call, or None: shapelib's own closed-form bounds (not a
    function registered in their place), without a bracket's ``rtol``. ``metric``: a name or a
    :class:`~shapelib.distances.MetricInfo` record (what tasks carry)."""
    info = metric_info(metric)
    return info.name if rtol is None and info.name in BOUND_METRICS and is_builtin(info) else None


#: a closed-form bound's matrix in this process is one block of at most this many shapes a side
#: (one batched call, :mod:`shapelib.geometry.bound_matrices`)
BOUND_BLOCK_MAX = 2048


def _bound_block(xi, xj, *, diagonal, metric, params):
    """A block of ``"alpha_bound"`` / ``"fisher_rao_bound"`` as one batched call
    (:func:`shapelib.geometry.bound_matrices.bound_block`), in :func:`compute_block`'s format (each
    pair's ``seconds`` is the block's wall time over its pairs). ``None`` when the call rejects
    the block — a Fisher–Rao grid over all its shapes too large, or an input error — so that
    :func:`compute_block` goes pair by pair, on each pair's own grid, naming a bad pair."""
    t0 = time.perf_counter()
    try:
        with _pair_work():  # one BLAS thread, as every task; all the cores in this process's own run
            d = bound_block(metric, xi, None if diagonal else xj, n_threads=1 if _in_dask_worker() else None,
                            **params)
    except ValueError:
        return None
    bi, bj = d.shape
    n_pairs = bi * (bi - 1) // 2 if diagonal else bi * bj
    out = {name: np.full((bi, bj), fill, dtype=dtype) for name, (dtype, fill) in ARRAYS.items()}
    for name in ("matrix", "lower", "upper"):
        out[name][...] = d
    out["seconds"][...] = (time.perf_counter() - t0) / max(1, n_pairs)
    out["converged"][...] = True
    out["n_iter"][...] = 0
    if diagonal:
        idx = np.diag_indices(bi)
        for name in ("energy", "seconds"):
            out[name][idx] = 0
    return out


def _in_dask_worker() -> bool:
    import sys

    if "distributed" not in sys.modules:
        return False
    try:
        sys.modules["distributed"].get_worker()
    except ValueError:
        return False
    return True


def default_block_size(seconds_per_pair: float, n: int, *, n_workers: int = 1, symmetric: bool = True) -> int:
    """Block side ``b`` with ``b² · seconds_per_pair ≤ TASK_SECONDS`` and ≥ ``TASKS_PER_WORKER`` tasks
    per worker (see the module docstring)."""
    b = max(1, int(math.sqrt(TASK_SECONDS / max(seconds_per_pair, 1e-9))))
    if n_workers > 1:
        want = TASKS_PER_WORKER * n_workers
        nb = 1
        while (nb * (nb + 1) // 2 if symmetric else nb * nb) < want and nb < n:
            nb += 1
        b = min(b, _n_blocks(n, nb))
    return max(1, min(b, n))


# ---------------------------------------------------------------------------------------------
# Parameters and fingerprints
# ---------------------------------------------------------------------------------------------


def _jsonable(name, value):
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value)
    if value is None or isinstance(value, str):
        return value
    raise ValueError(f"parameter {name}={value!r} cannot be recorded in a pairwise store "
                     "(numbers, strings, booleans and None only)")


def _full_params(metric, rtol, params: dict) -> dict:
    """``params`` with the computing function's defaults filled in (so n_steps=16 == omitted)."""
    full = {}
    for name, p in inspect.signature(metric_info(metric).options_of(rtol)).parameters.items():
        if name in ("u", "v", "metric", "rtol") or p.kind in (p.VAR_KEYWORD, p.VAR_POSITIONAL):
            continue
        if name in params:
            full[name] = params[name]
        elif p.default is not p.empty:
            full[name] = p.default
    full.update(params)
    return {k: _jsonable(k, v) for k, v in sorted(full.items())}


def shapes_sha256(x: np.ndarray) -> str:
    """SHA-256 of the float64 shapes array and its shape."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    h = hashlib.sha256(repr(x.shape).encode())
    h.update(x.tobytes())
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------
# The store
# ---------------------------------------------------------------------------------------------


class _Store:
    """The zarr group of one matrix in a directory; without a path, the same arrays in memory
    (NumPy: nothing to resume from, so nothing to gain from zarr's chunks and checksums)."""

    def __init__(self, group, path, attrs):
        self.group, self.path, self.attrs = group, path, attrs
        self.n, self.b = attrs["N"], attrs["block_size"]
        self.symmetric = attrs["symmetric"]
        self.nb = _n_blocks(self.n, self.b)
        if group is None:
            self.arrays = {name: np.full((self.n, self.n), fill, dtype=dtype) for name, (dtype, fill) in ARRAYS.items()}
            self.arrays["done"] = np.zeros((self.nb, self.nb), dtype=bool)
            return
        # every chunk is written, also one equal to the fill value (e.g. the all-NaN ``energy`` of a
        # non-path metric): a done block's chunk files must exist, which is how truncation is detected
        self.arrays = {name: group[name].with_config({"write_empty_chunks": True}) for name in (*ARRAYS, "done")}

    @property
    def where(self) -> str:
        return f"pairwise store {self.path}" if self.path else "in-memory pairwise store"

    @classmethod
    def create(cls, path, attrs):
        if path is None:
            return cls(None, None, attrs)
        import zarr
        from zarr.codecs import BytesCodec, Crc32cCodec, ZstdCodec

        store = zarr.storage.LocalStore(str(path))
        group = zarr.open_group(store, mode="w", zarr_format=3)
        b = attrs["block_size"]
        n = attrs["N"]
        chunk = min(n, b * max(1, CHUNK_SIDE // b))
        nb = _n_blocks(n, b)
        kw = dict(serializer=BytesCodec(), compressors=[ZstdCodec(level=3), Crc32cCodec()])
        for name, (dtype, fill) in ARRAYS.items():
            group.create_array(name, shape=(n, n), chunks=(chunk, chunk), dtype=dtype, fill_value=fill, **kw)
        group.create_array("done", shape=(nb, nb), chunks=(min(nb, CHUNK_SIDE),) * 2, dtype="bool",
                           fill_value=False, **kw)
        group.attrs[_ATTR] = attrs  # written last: a store without it is not a store
        return cls(group, str(path), attrs)

    @classmethod
    def open(cls, path):
        import zarr

        path = str(path)
        meta = Path(path) / "zarr.json"
        if not meta.is_file():
            raise ValueError(f"pairwise store {path}: no zarr.json (not a zarr v3 group, or truncated)")
        try:
            group = zarr.open_group(zarr.storage.LocalStore(path), mode="r+", zarr_format=3)
            attrs = dict(group.attrs[_ATTR])
        except KeyError as exc:
            raise ValueError(f"pairwise store {path}: a zarr group without the {_ATTR!r} attributes "
                             "(not a shapelib pairwise store, or its creation was interrupted)") from exc
        except Exception as exc:
            raise ValueError(f"pairwise store {path}: unreadable group metadata or attributes "
                             f"({type(exc).__name__}: {exc})") from exc
        for name in (*ARRAYS, "done"):
            try:
                group[name]
            except Exception as exc:
                raise ValueError(f"pairwise store {path}: array {name!r} is missing or its metadata is "
                                 f"unreadable ({type(exc).__name__}: {exc})") from exc
        return cls(group, path, attrs)

    # -- reading, with corruption named --------------------------------------------------------

    def _chunk_file(self, name, ci, cj):
        return Path(self.path) / name / "c" / str(ci) / str(cj)

    def _read(self, name, what_block):
        """The whole array; on failure, find and name the bad chunk(s)."""
        arr = self.arrays[name]
        try:
            return arr[...]
        except Exception as exc:
            cs = arr.chunks
            bad = []
            for ci in range(_n_blocks(arr.shape[0], cs[0])):
                for cj in range(_n_blocks(arr.shape[1], cs[1])):
                    try:
                        arr[ci * cs[0]:(ci + 1) * cs[0], cj * cs[1]:(cj + 1) * cs[1]]
                    except Exception:
                        bad.append((ci, cj))
            where = "; ".join(what_block(name, ci, cj) for ci, cj in bad) or "unknown chunk"
            raise ValueError(f"{self.where}: array {name!r} is corrupt or truncated ({where}): "
                             f"{type(exc).__name__}: {exc}. Delete the store (or that chunk file and the "
                             "matching 'done' entries) and rerun to recompute.") from exc

    def _describe_data_chunk(self, name, ci, cj):
        c = self.arrays[name].chunks[0]
        rows = f"{ci * c}:{min((ci + 1) * c, self.n)}"
        cols = f"{cj * c}:{min((cj + 1) * c, self.n)}"
        k = c // self.b
        return (f"chunk {name}/c/{ci}/{cj}, pairs [{rows}, {cols}], blocks "
                f"[{ci * k}:{min((ci + 1) * k, self.nb)}, {cj * k}:{min((cj + 1) * k, self.nb)}]")

    def _describe_done_chunk(self, name, ci, cj):
        c = self.arrays["done"].chunks[0]
        return f"chunk done/c/{ci}/{cj}, blocks [{ci * c}:{(ci + 1) * c}, {cj * c}:{(cj + 1) * c}]"

    def done(self) -> np.ndarray:
        return self._read("done", self._describe_done_chunk)

    def task_done(self, done=None) -> set:
        done = self.done() if done is None else done
        return {(a, b) for a, b in block_pairs(self.n, self.b, symmetric=self.symmetric) if done[a, b]}

    def read(self) -> tuple[dict, np.ndarray]:
        """All arrays and the pair-level ``computed`` mask; checks every done block is really there."""
        done = self.done()
        computed = np.zeros((self.n, self.n), dtype=bool)
        for a, b in self.task_done(done):
            for p, q in ((a, b), (b, a)) if self.symmetric else ((a, b),):
                computed[p * self.b:(p + 1) * self.b, q * self.b:(q + 1) * self.b] = True
        if self.path is not None:  # a done block must have its chunk files on disk
            for name in ARRAYS:
                c = self.arrays[name].chunks[0]
                for ci, cj in {(p * self.b // c, q * self.b // c) for p, q in zip(*np.nonzero(done))}:
                    if not self._chunk_file(name, ci, cj).is_file():
                        raise ValueError(f"{self.where}: array {name!r} is truncated: "
                                         f"{self._describe_data_chunk(name, ci, cj)} of a done block is missing")
        data = {name: self._read(name, self._describe_data_chunk) for name in ARRAYS}
        # a done pair must have a value: a NaN there is damage, never a result
        holes = computed & (np.isnan(data["matrix"]) | np.isnan(data["upper"]) | (data["n_iter"] < 0))
        if holes.any():
            i, j = np.argwhere(holes)[0]
            raise ValueError(f"{self.where}: pair ({i}, {j}) of done block ({i // self.b}, {j // self.b}) "
                             "has no value: the store is corrupt")
        return data, computed

    # -- writing --------------------------------------------------------------------------------

    def write_block(self, a: int, b: int, out: dict) -> None:
        """Write block ``(a, b)``'s data (and its mirror for symmetric metrics), then its done flag."""
        s = self.b
        ra, rb = slice(a * s, min((a + 1) * s, self.n)), slice(b * s, min((b + 1) * s, self.n))
        for name in ARRAYS:
            self.arrays[name][ra, rb] = out[name]
            if self.symmetric and a != b:
                self.arrays[name][rb, ra] = out[name].T
        if self.symmetric and a != b:
            self.arrays["done"][b, a] = True
        self.arrays["done"][a, b] = True


def _check_same(store: _Store, want: dict, *, block_size_given) -> None:
    have = store.attrs
    for key, what in (("N", "number of shapes"), ("K", "landmarks per shape"), ("d", "dimension"),
                      ("shapes_sha256", "shapes (SHA-256)"), ("metric", "metric"), ("rtol", "rtol")):
        if have.get(key) != want[key]:
            raise ValueError(f"{store.where} was computed with {what} {have.get(key)!r}, "
                             f"not {want[key]!r}: use another store (or delete this one)")
    if have.get("params") != want["params"]:
        old, new = have.get("params") or {}, want["params"]
        diff = {k: (old.get(k), new.get(k)) for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)}
        text = ", ".join(f"{k}: stored {o!r}, given {n!r}" for k, (o, n) in diff.items())
        raise ValueError(f"{store.where} was computed with other parameters ({text}): use another store "
                         "(or delete this one)")
    if block_size_given is not None and block_size_given != have["block_size"]:
        raise ValueError(f"{store.where} has block_size {have['block_size']}, not {block_size_given}: "
                         "omit block_size to resume it")
    if have.get("shapelib_version") != want["shapelib_version"]:
        warnings.warn(f"{store.where} was written by shapelib {have.get('shapelib_version')}, this is "
                      f"{want['shapelib_version']}: resuming mixes the two versions' results", stacklevel=3)


def open_store(path) -> PairwiseResult:
    """Read a finished or partial pairwise store (see the module docstring).

    Raises ``ValueError`` naming the store and the array/block when it is corrupt or truncated.
    Pairs not yet computed are NaN in the float arrays and ``False`` in ``result.computed``.
    """
    store = _Store.open(path)
    data, computed = store.read()
    return _result(store, data, computed, log={"blocks_total": len(block_pairs(store.n, store.b,
                                                                               symmetric=store.symmetric)),
                                               "blocks_done": len(store.task_done())})


def _result(store: _Store, data: dict, computed, log) -> PairwiseResult:
    params = dict(store.attrs["params"])
    if store.attrs.get("rtol") is not None:
        params["rtol"] = store.attrs["rtol"]
    return PairwiseResult(matrix=data["matrix"], lower=data["lower"], upper=data["upper"],
                          energy=data["energy"], seconds=data["seconds"], converged=data["converged"],
                          n_iter=data["n_iter"], metric=store.attrs["metric"], params=params,
                          store=store.path, computed=computed, log=log, symmetric=bool(store.symmetric))


# ---------------------------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BlockProgress:
    """What ``compute_pairwise(..., callback=)`` is called with after each block is written.

    Attributes
    ----------
    block : tuple of int
        Block indices ``(I, J)`` of the block just written.
    rows, cols : range
        Its rows and columns of the matrix.
    blocks_done, blocks_total : int
        Blocks in the store now (this run's and those found done) and in all.
    blocks_computed : int
        Blocks computed by this call so far.
    pairs_done, pairs_total : int
        The same counted in pairs (one per unordered pair for symmetric metrics).
    """

    block: tuple
    rows: range
    cols: range
    blocks_done: int
    blocks_total: int
    blocks_computed: int
    pairs_done: int
    pairs_total: int


class _Interrupts:
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


def _n_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def _pair_work():
    """Around the engine's per-pair calls (a block's, the timing pair's): BLAS on one thread
    (workers are single-threaded processes, one per core), and no per-pair warnings — solver
    convergence is recorded per pair, and :func:`compute_pairwise` gives the scale and pose
    warnings once for all the shapes."""
    with one_blas_thread(), set_checked(), warnings.catch_warnings():
        warnings.simplefilter("ignore", GeodesicWarning)
        warnings.simplefilter("ignore", ScaleWarning)
        warnings.simplefilter("ignore", PoseWarning)
        yield


def _time_one_pair(x, metric, rtol, params, *, budget: float = 0.5) -> float:
    """Seconds for one pair, warm: the first call in a process also pays one-off costs (loading
    compiled kernels, building quadrature grids: 0.2 s against 2.5 ms warm for a Fisher–Rao
    bound, ~2 s against 50 ms for a Fisher–Rao bracket), so the pair is timed twice (once if the
    first call took over ``10 · TASK_SECONDS``: a block of one pair either way), a third time while
    the calls took under ``budget`` seconds, and the fastest call counts."""
    bound = _batched_bound(metric, rtol)
    if bound:  # the cost of a pair within a block
        m = min(len(x), 64)
        best = math.inf
        for _ in range(2):  # the first call also pays one-off costs
            t0 = time.perf_counter()
            out = _bound_block(x[:m], x[:m], diagonal=True, metric=bound, params=params)
            best = min(best, time.perf_counter() - t0)
        if out is not None:
            return best / max(1, m * (m - 1) // 2)
    times = []
    with _pair_work():
        # a pair far above TASK_SECONDS gets a block of its own either way: no second call
        while not times or (len(times) < 2 and times[0] < 10 * TASK_SECONDS) or (
                len(times) < 3 and sum(times) < budget):
            t0 = time.perf_counter()
            _pair_record(x[0], x[1 % len(x)], 0, 1 % len(x), metric=metric, rtol=rtol, **params)
            times.append(time.perf_counter() - t0)
    return min(times)


def _stored_seconds_per_pair(store: _Store) -> float | None:
    done = store.task_done()
    if not done:
        return None
    a, b = next(iter(done))
    s = store.b
    try:
        sec = store.arrays["seconds"][a * s:(a + 1) * s, b * s:(b + 1) * s]
    except Exception:
        return None  # read() names the damage later
    sec = sec[np.isfinite(sec) & (sec > 0)]
    return float(sec.mean()) if sec.size else None


def compute_pairwise(shapes, *, metric: str, n_jobs: int | None = None, client=None, scheduler=None,
                     store=None, block_size: int | None = None, progress: bool = True,
                     rtol: float | None = None, callback=None, **params) -> PairwiseResult:
    """Distances (and diagnostics) of every pair of ``shapes``; see the module docstring and
    :func:`pairwise_distances` for the parameters.

    ``callback(progress)`` is called in this process after each block is written, with a
    :class:`BlockProgress`; a true return value stops the run: in-flight tasks are cancelled, the
    local cluster is closed, the store keeps the blocks written (rerun to resume) and the partial
    result is returned (``complete`` False unless that was the last block, ``log["stopped"]`` True).

    A Ctrl-C (SIGINT) raises KeyboardInterrupt whenever it comes (see :class:`_Interrupts`), with
    the same clean-up and the finished blocks kept.

    Returns
    -------
    PairwiseResult
    """
    info = metric_info(metric)
    metric = info.name
    check_metric_params(info, params, rtol=rtol)
    if callback is not None and not callable(callback):
        raise ValueError(f"callback must be callable; got {callback!r}")
    x = as_shapes(shapes, name="shapes")
    n, k, d = x.shape
    if "sigma2" in params:  # every σ² metric, the bounds too: once for all the shapes, not once per pair
        ratio = check_scale(x, params["sigma2"], stacklevel=4)
        if metric in ("fisher_rao", "fisher_rao_bound"):  # a degenerate quadrature: an error before any work
            check_fisher_rao_scale(x, params["sigma2"], metric=metric, ratio=ratio)
    if pose_dependent(metric, params):  # likewise (check_pose: a pair, or a whole set to align)
        check_pose(x, metric=metric, stacklevel=4)
    symmetric = info.symmetric
    _check_where(n_jobs, client, scheduler)
    if block_size is not None:
        block_size = check_positive_int(block_size, name="block_size")
    want = {"format": _FORMAT, "metric": metric, "params": _full_params(info, rtol, params),
            "rtol": None if rtol is None else float(rtol), "shapes_sha256": shapes_sha256(x),
            "N": int(n), "K": int(k), "d": int(d), "symmetric": symmetric, "shapelib_version": __version__}

    st, found = None, None
    if store is not None and Path(store).exists() and not (Path(store) / "zarr.json").exists() and (
            not Path(store).is_dir() or any(Path(store).iterdir())):
        raise ValueError(f"store {str(store)!r} exists and is not a pairwise store (no zarr.json); "
                         "give a new path")
    if store is not None and (Path(store) / "zarr.json").exists():
        st = _Store.open(store)
        _check_same(st, want, block_size_given=block_size)
        found = st.read()  # damage in the done blocks is named now, not after hours of new work
    local = client is None and scheduler is None
    n_workers = _n_cores() if n_jobs in (None, -1) else int(n_jobs)
    seconds_per_pair = None
    if (st is None and block_size is None) or (local and n_jobs in (None, -1)):
        seconds_per_pair = (_stored_seconds_per_pair(st) if st is not None else None) or (
            _time_one_pair(x, info, rtol, params) if n > 2 else 0.0)  # one pair: in-process whatever it costs
    if local and n_jobs in (None, -1):
        left = _pairs_left(st, n, symmetric)
        n_workers = 1 if n_workers < 2 or seconds_per_pair * left < (
            CLUSTER_OVERHEAD_SECONDS * n_workers / (n_workers - 1)) else n_workers
    if st is None:
        b = int(block_size) if block_size is not None else default_block_size(
            seconds_per_pair, n, n_workers=n_workers if local else max(2, _cluster_size(client)),
            symmetric=symmetric)
        if block_size is None and _batched_bound(metric, rtol) and local and n_workers == 1:
            b = min(n, BOUND_BLOCK_MAX)  # one batched call for a population this process holds
        st = _Store.create(store, {**want, "block_size": b})
    done = st.task_done()
    todo = [t for t in block_pairs(n, st.b, symmetric=symmetric) if t not in done]
    n_todo = sum(_block_n_pairs(st, a, b) for a, b in todo)
    mode = "in-process" if local and n_workers == 1 else (
        f"LocalCluster({n_workers} processes)" if local else "cluster")
    log = {"blocks_total": len(done) + len(todo), "blocks_found_done": len(done), "blocks_computed": 0,
           "block_size": st.b, "mode": mode, "seconds_per_pair_estimate": seconds_per_pair, "stopped": False}
    total_pairs = sum(_block_n_pairs(st, a, b) for a, b in block_pairs(n, st.b, symmetric=symmetric))
    workers = n_workers if local else (_cluster_size(client) if client is not None else None)
    eta = _announce(metric, n_todo, seconds_per_pair or _stored_seconds_per_pair(st), workers, log)
    bar = _progress(progress, total=total_pairs, initial=total_pairs - n_todo, metric=metric, eta=eta)
    kw = dict(symmetric=symmetric, metric=info, rtol=rtol, params=params)  # the record travels with each task
    pairs_done = [total_pairs - n_todo]
    t0 = time.perf_counter()
    with _Interrupts() as interrupts:

        def written(a, b) -> bool:
            """After block (a, b) is in the store: progress, Ctrl-C, the callback; True: stop."""
            log["blocks_computed"] += 1
            pairs_done[0] += _block_n_pairs(st, a, b)
            bar.update(_block_n_pairs(st, a, b))
            interrupts.check()
            if callback is not None and callback(BlockProgress(
                    block=(a, b), rows=range(*_rows(st, a).indices(n)), cols=range(*_rows(st, b).indices(n)),
                    blocks_done=len(done) + log["blocks_computed"], blocks_total=log["blocks_total"],
                    blocks_computed=log["blocks_computed"], pairs_done=pairs_done[0], pairs_total=total_pairs)):
                log["stopped"] = True
            interrupts.check()
            return log["stopped"]

        try:
            if todo and mode == "in-process":
                for a, b in todo:
                    out = compute_block(x[_rows(st, a)], x[_rows(st, b)], diagonal=a == b,
                                        offset=(a * st.b, b * st.b), **kw)
                    st.write_block(a, b, out)
                    if written(a, b):
                        break
            elif todo:
                with interrupts.deferred():  # never inside the Dask client's calls (see _Interrupts)
                    _run_dask(x, st, todo, kw, client=client, scheduler=scheduler, n_workers=n_workers,
                              written=written, interrupts=interrupts, token=_token(want, st.b))
        finally:
            bar.close()
        log["seconds"] = time.perf_counter() - t0
        data, computed = found if found is not None and not todo else st.read()  # a finished store is read once
    log["blocks_done"] = len(done) + log["blocks_computed"]
    if not computed.all() and not log["stopped"]:
        raise RuntimeError(f"{st.where}: {int((~computed).sum())} pairs missing after the run")
    result = _result(st, data, computed, log)
    words = result.convergence_summary()
    if words:
        warnings.warn(f"{words}; see PairwiseResult.to_frame() (status, rel_gap)", GeodesicWarning, stacklevel=3)
    return result


def pairwise_distances(shapes, *, metric: str, n_jobs: int | None = None, client=None, scheduler=None,
                       store=None, block_size: int | None = None, progress: bool = True,
                       rtol: float | None = None, return_result: bool = False, callback=None, **params):
    """Matrix of distances between every pair of ``shapes`` (N, K, d), on Dask, with a resumable store.

    Symmetric metrics are computed once per unordered pair; for the bending energies (``"tps"``,
    ``"wendland"``) entry ``[i, j]`` is the energy of the map taking shape ``i`` onto shape ``j``.
    The work is done by :func:`compute_pairwise` (blocks of pairs, one Dask task
    per block; see there for how the local cluster and the block size are chosen).

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
    metric : str
        A registered metric (:data:`shapelib.distances.METRICS`,
        :func:`shapelib.distances.register_metric`).
    n_jobs : int, optional
        ``1``: in this process. ``k > 1``: a local cluster of ``k`` worker processes. ``None`` or
        ``-1``: chosen from a measured pair (in this process when the whole matrix takes a few
        seconds, else one worker per core).
    client : distributed.Client, optional
        Run on this Dask cluster.
    scheduler : str, optional
        Address of a running Dask scheduler (``"tcp://host:8786"``).
    store : path-like, optional
        Zarr directory the finished blocks are written to; rerunning with the same store resumes.
    block_size : int, optional
        Shapes per block side (a task computes up to ``block_size²`` pairs). Default from the
        measured cost of one pair.
    progress : bool
        Progress bar (pairs done, pairs/s, ETA).
    rtol : float, optional
        Certified relative tolerance for ``"alpha"`` / ``"fisher_rao"`` (see :func:`shapelib.distance`).
    return_result : bool
        Return the :class:`PairwiseResult` (bounds, convergence, iterations,
        seconds per pair) instead of the matrix.
    callback : callable, optional
        ``callback(progress)``, called in this process after each block is written, with a
        :class:`BlockProgress` (the block, blocks and pairs done and in total). A true return
        value stops the run, as SciPy's halting callbacks do: the blocks written so far stay in
        ``store`` (rerun to resume), running tasks are cancelled, the local cluster is closed,
        and the partial result is returned (``complete`` False, ``log["stopped"]`` True; the
        matrix is NaN where pairs were not computed, with a warning unless ``return_result``).
    **params
        Options of the metric.

    Returns
    -------
    ndarray, shape (N, N), or PairwiseResult
        Zero diagonal.

    Warns
    -----
    ScaleWarning
        Once, when σ² does not fit the landmarks' spacing (every metric that takes ``sigma2``).
    PoseWarning
        Once, when the metric depends on pose (:data:`shapelib.distances.POSE_DEPENDENT`) and the
        shapes are not aligned (:func:`shapelib.geometry.procrustes.check_pose`; align them with
        :func:`shapelib.pose_align`).
    GeodesicWarning
        When pairs did not converge, in :meth:`PairwiseResult.status`'s words.

    Raises
    ------
    ValueError
        Before any work: shapes not ``(N, K, d)`` with d = 2 or 3; a σ that leaves the
        Fisher–Rao quadrature nothing to resolve (:func:`shapelib.geometry.scale.check_fisher_rao_scale`).
    """
    result = compute_pairwise(shapes, metric=metric, n_jobs=n_jobs, client=client, scheduler=scheduler,
                              store=store, block_size=block_size, progress=progress, rtol=rtol, callback=callback,
                              **params)
    if return_result:
        return result
    if not result.complete:
        warnings.warn(f"the callback stopped the run after {result.log.get('blocks_done')} of "
                      f"{result.log.get('blocks_total')} blocks: the matrix is NaN where pairs were not computed"
                      + (f"; rerun with store={result.store!r} to resume" if result.store else ""),
                      UserWarning, stacklevel=2)
    return result.matrix


def _pairs_left(st, n, symmetric) -> int:
    if st is None:
        return n * (n - 1) // 2 if symmetric else n * (n - 1)
    done = st.task_done()
    return sum(_block_n_pairs(st, a, b) for a, b in block_pairs(n, st.b, symmetric=symmetric)
               if (a, b) not in done)


def _cluster_size(client) -> int:
    """Worker threads of ``client``'s cluster (1 if unknown, e.g. a scheduler address not yet joined)."""
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:
        return 1


def _token(want: dict, block_size: int) -> str:
    """Task-key prefix: the same computation (shapes, metric, parameters, blocks) has the same keys."""
    body = {k: v for k, v in want.items() if k != "shapelib_version"}
    return hashlib.sha256(json.dumps({**body, "block_size": block_size}, sort_keys=True).encode()).hexdigest()[:16]


def _rows(st: _Store, a: int) -> slice:
    return slice(a * st.b, min((a + 1) * st.b, st.n))


def _block_n_pairs(st: _Store, a: int, b: int) -> int:
    ra, rb = _rows(st, a), _rows(st, b)
    na, nb = ra.stop - ra.start, rb.stop - rb.start
    if a != b:
        return na * nb
    return na * (na - 1) // 2 if st.symmetric else na * (na - 1)


def _progress(enabled: bool, *, total: int, initial: int, metric: str, eta: str | None = None):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, unit="pair", desc=f"{metric} pairs" + (f" (est. {eta})" if eta else ""),
                disable=not enabled, smoothing=0.1, dynamic_ncols=True)


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.2g} s"
    if seconds < 5400:
        return f"{seconds / 60:.2g} min"
    return f"{seconds / 3600:.2g} h"


def _announce(metric, n_pairs, seconds_per_pair, workers, log) -> str | None:
    """The run's cost up front: ``n_pairs × seconds_per_pair ÷ workers`` into ``log["estimated_seconds"]``,
    logged at INFO (DEBUG below :data:`LONG_RUN_SECONDS`); returns the duration for the progress bar
    of a long run. Nothing when no pair was timed (``block_size`` and ``n_jobs`` given, fresh store):
    the progress bar's ETA follows the first blocks."""
    if not n_pairs or not seconds_per_pair:
        return None
    serial = n_pairs * seconds_per_pair
    total = serial / workers if workers else serial
    log["estimated_seconds"] = total
    per = (f"÷ {workers} worker{'s' if workers != 1 else ''}" if workers else "÷ the cluster's workers")
    text = (f"{metric}: {n_pairs:,} pairs × {seconds_per_pair:.2g} s per pair (timed) {per} ≈ {_duration(total)}")
    long = total >= LONG_RUN_SECONDS
    logger.log(logging.INFO if long else logging.DEBUG, text)
    return _duration(total) if long else None


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
    (:func:`_ignore_sigint`, run on them once they are up; spawned processes do not inherit a
    blocked mask), since the caller stops the run and closing the cluster ends them.
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
                                   worker_class=_nanny_class())
    finally:
        if block:
            try:  # a pending Ctrl-C is raised by this call (it runs the signal handlers)
                signal.pthread_sigmask(signal.SIG_SETMASK, old)
            except BaseException:
                if cluster is not None:
                    cluster.close()
                raise
    return cluster


def _nanny_class():
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


def _ignore_sigint():
    """Run on a worker of the engine's own LocalCluster: leave Ctrl-C to the process that started it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _check_where(n_jobs, client, scheduler) -> None:
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
    shapes rather than pairs (the intrinsic statistics' log maps, :mod:`shapelib.population`).

    Yields ``(executor, n_workers, mode)``; ``executor`` is None for in-process work. ``client=``
    or ``scheduler=`` use that Dask cluster (``client.get_executor()``); ``n_jobs=k > 1`` starts a
    :func:`local_cluster` of ``k`` workers for the duration of the ``with`` block; ``n_jobs=1`` runs
    in this process; ``n_jobs=None`` or ``-1`` runs in this process when ``serial_seconds`` (the
    caller's projection of the serial time) is below the break-even
    ``CLUSTER_OVERHEAD_SECONDS · W / (W − 1)`` on ``W`` cores, else on one worker per core — the
    rule :func:`compute_pairwise` applies to matrices.
    """
    from distributed import Client

    _check_where(n_jobs, client, scheduler)
    if client is not None:
        yield client.get_executor(pure=False), _cluster_size(client), "cluster"
        return
    if scheduler is not None:
        own = _connect(scheduler)
        try:
            yield own.get_executor(pure=False), _cluster_size(own), "cluster"
        finally:
            own.close()
        return
    n_workers = _n_cores() if n_jobs in (None, -1) else int(n_jobs)
    if n_jobs in (None, -1) and (n_workers < 2 or serial_seconds is None
                                 or serial_seconds < CLUSTER_OVERHEAD_SECONDS * n_workers / (n_workers - 1)):
        n_workers = 1
    if n_workers == 1:
        yield None, 1, "in-process"
        return
    with local_cluster(n_workers) as cluster, Client(cluster) as own:
        own.run(_ignore_sigint)  # see local_cluster: Ctrl-C is the caller's
        yield own.get_executor(pure=False), n_workers, f"LocalCluster({n_workers} processes)"


def _connect(scheduler):
    """A Dask client of the running scheduler at ``scheduler``; ValueError naming it if it cannot be reached."""
    from distributed import Client

    try:
        return Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise ValueError(f"cannot reach the Dask scheduler {scheduler!r}: {exc}") from exc


def _run_dask(x, st, todo, kw, *, client, scheduler, n_workers, written, interrupts, token):
    """Submit the blocks to Dask and write each one as it finishes (client side); ``written(a, b)``
    after each block (True: stop). While waiting, ``interrupts.check()`` every :data:`POLL_SECONDS`;
    once the cluster is up, before anything is submitted."""
    import queue

    from distributed import Client

    cluster = own_client = None
    inflight = {}
    try:
        if client is None:
            if scheduler is not None:
                own_client = _connect(scheduler)
            else:
                cluster = local_cluster(n_workers)
                own_client = Client(cluster)
                own_client.run(_ignore_sigint)  # see local_cluster: Ctrl-C is the caller's
            client = own_client
        interrupts.check()  # a Ctrl-C while the cluster started
        # keep a bounded number of blocks in flight (the shapes of each travel with its task)
        limit = max(64, 8 * max(1, sum(client.nthreads().values())))
        pending = iter(todo)
        finished = queue.SimpleQueue()  # futures, put there by Dask's callback thread as they finish

        def submit(a, b):
            fut = client.submit(compute_block, x[_rows(st, a)], x[_rows(st, b)], diagonal=a == b,
                                offset=(a * st.b, b * st.b), **kw, key=f"shapelib-pairwise-{token}-{a}-{b}")
            inflight[fut.key] = (fut, (a, b))
            fut.add_done_callback(finished.put)
            return fut

        for t in itertools.islice(pending, limit):
            submit(*t)
        while inflight:
            try:
                fut = finished.get(timeout=POLL_SECONDS)
            except queue.Empty:
                interrupts.check()  # a Ctrl-C lost while waiting still stops the run
                continue
            out = fut.result()
            _, (a, b) = inflight.pop(fut.key)
            fut.release()
            st.write_block(a, b, out)
            if written(a, b):
                break
            nxt = next(pending, None)
            if nxt is not None:
                submit(*nxt)
    finally:
        if client is not None and inflight:  # stopped, interrupted or failed: nothing more to compute
            try:
                client.cancel([f for f, _ in inflight.values()])
            except Exception:  # the cluster may be gone already; closing below still runs
                pass
        if own_client is not None:
            own_client.close()
        if cluster is not None:
            cluster.close()
