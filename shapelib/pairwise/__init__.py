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

The package's private modules, one job each: ``_results`` (:class:`PairwiseResult`,
:class:`PairError`, :class:`BlockProgress`), ``_blocks`` (a block's pairs, the block size),
``_store`` (the zarr store, fingerprints, resume) and ``_driver`` (:func:`compute_pairwise`,
:func:`pairwise_distances`); where the tasks run (Dask, the local cluster, Ctrl-C) is
:mod:`shapelib._executor`, shared with the statistics.
"""

from .._executor import (CLUSTER_OVERHEAD_SECONDS, NANNY_CLOSE_SECONDS, POLL_SECONDS, WORKER_ENVIRON, engine_executor,
                         local_cluster)
from ._blocks import (ARRAYS, BOUND_BLOCK_MAX, TASK_SECONDS, TASKS_PER_WORKER, block_pairs, compute_block,
                      default_block_size)
from ._driver import LONG_RUN_SECONDS, compute_pairwise, logger, pairwise_distances
from ._results import BlockProgress, PairError, PairwiseResult
from ._store import CHUNK_SIDE, _Store, open_store, shapes_sha256

__all__ = ["PairwiseResult", "PairError", "BlockProgress", "compute_pairwise", "pairwise_distances", "open_store",
           "compute_block", "block_pairs", "local_cluster", "engine_executor", "default_block_size", "ARRAYS"]
