"""Running a matrix: checks once for all the shapes, the block size, in process or on Dask, progress."""

from __future__ import annotations

import itertools
import logging
import time
import warnings
from pathlib import Path

import numpy as np

from .._executor import (CLUSTER_OVERHEAD_SECONDS, POLL_SECONDS, Interrupts, check_where, cluster_size, connect,
                         ignore_sigint, local_cluster, n_cores)
from .._validate import as_shapes, check_positive_int
from .._version import __version__
from ..distances import check_metric_params, metric_info, pose_dependent
from ..geometry.procrustes import check_pose
from ..geometry.scale import check_fisher_rao_scale, check_scale
from ..solver.batched import check_backend
from ..solver.geodesic import GeodesicWarning
from . import _pointsets
from ._blocks import (BOUND_BLOCK_MAX, JAX_BLOCK_SIDE, _batched, _batched_jax, _time_one_pair, block_pairs,
                      compute_block, default_block_size, time_pair_sets)
from ._results import BlockProgress, PairwiseResult
from ._store import (_FORMAT, _Store, _block_n_pairs, _check_same, _full_params, _pairs_left, _result, _rows,
                     _stored_seconds_per_pair, _token, shapes_sha256)

#: a run whose estimate (pairs × seconds per pair ÷ workers) reaches this is announced up front:
#: logged at INFO on the ``shapelib.pairwise`` logger (the CLI prints it) and shown on the progress bar
LONG_RUN_SECONDS = 10.0
#: the logger of the engine's run estimates
logger = logging.getLogger("shapelib.pairwise")


def compute_pairwise(shapes, *, metric: str, n_jobs: int | None = None, client=None, scheduler=None,
                     store=None, block_size: int | None = None, progress: bool = True,
                     rtol: float | None = None, callback=None, modulo: str | None = None,
                     **params) -> PairwiseResult:
    r"""Distances (and diagnostics) of every pair of ``shapes``; see the module docstring and
    :func:`pairwise_distances` for the parameters.

    The matrix is :math:`D_{ij} = d(\mathbf{x}_i, \mathbf{x}_j)` for the metric :math:`d`
    (one entry per unordered pair for a symmetric one, :math:`D_{ji} = D_{ij}`), zero on the
    diagonal, with each pair's record (``value``, ``lower``, ``upper``, ``converged``, …).

    ``callback(progress)`` is called in this process after each block is written, with a
    :class:`BlockProgress`; a true return value stops the run: in-flight tasks are cancelled, the
    local cluster is closed, the store keeps the blocks written (rerun to resume) and the partial
    result is returned (``complete`` False unless that was the last block, ``log["stopped"]`` True).

    A Ctrl-C (SIGINT) raises KeyboardInterrupt whenever it comes (see :class:`Interrupts`), with
    the same clean-up and the finished blocks kept.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d), or list of array_like
        The shapes (d = 2 or 3); with ``modulo``, planar point sets of any sizes.
    metric : str
        A registered metric (:data:`shapelib.distances.METRICS`).
    n_jobs : int, optional
        ``1``: in this process; ``k > 1``: a local cluster of ``k`` worker processes; ``None``
        or ``-1``: chosen from a measured pair.
    client : distributed.Client, optional
        Run on this Dask cluster.
    scheduler : str, optional
        Address of a running Dask scheduler.
    store : path-like, optional
        Zarr directory the finished blocks are written to; rerunning with it resumes.
    block_size : int, optional
        Shapes per block side; default :func:`default_block_size` of the measured pair.
    progress : bool
        Progress bar.
    rtol : float, optional
        Certified relative tolerance of the ``"alpha"`` / ``"fisher_rao"`` brackets.
    callback : callable, optional
        ``callback(progress)`` after each block is written, with a :class:`BlockProgress`; a
        true return value stops the run.
    modulo : {"similarity"}, optional
        Compare point sets modulo the similarity group (see :func:`pairwise_distances`).
    **params
        Options of the metric (e.g. ``sigma2``).

    Returns
    -------
    PairwiseResult
        ``matrix`` (the distances :math:`D`) with every pair's ``lower``, ``upper``,
        ``converged``, ``energy``, ``n_iter`` and ``seconds``; ``computed``, ``complete`` and
        ``log`` (blocks, block size, where it ran, seconds).

    See Also
    --------
    pairwise_distances : The matrix alone.
    open_store : Reads a store back.

    Examples
    --------
    Four shapes, in this process; the Procrustes distance is exact, so its bounds are the value:

    >>> import numpy as np
    >>> from shapelib.pairwise import compute_pairwise
    >>> x = np.random.default_rng(0).normal(size=(4, 6, 2))
    >>> r = compute_pairwise(x, metric="procrustes", n_jobs=1, progress=False)
    >>> r.matrix.shape, r.complete, r.log["mode"]
    ((4, 4), True, 'in-process')
    >>> np.array_equal(r.matrix, r.matrix.T), bool(r.converged.all()), np.array_equal(r.lower, r.upper)
    (True, True, True)
    >>> sorted(r.to_frame().columns)[:4]
    ['converged', 'energy', 'i', 'j']
    """
    info = metric_info(metric)
    metric = info.name
    if callback is not None and not callable(callback):
        raise ValueError(f"callback must be callable; got {callback!r}")
    point_sets = modulo is not None
    pair_sets = not point_sets and info.point_sets
    shortlist, pair_fraction = None, 1.0
    if point_sets:  # a list of point sets of any sizes, each normalised once (:mod:`._pointsets`)
        if rtol is not None:
            raise ValueError("rtol applies to the certified geodesic metrics, not to point sets modulo a group")
        x, params, recorded, (sha, sizes) = _pointsets.prepare(shapes, metric, modulo, params)
        n, k, d = len(x), 0, 2  # K: the sizes differ (the fingerprint covers them)
    elif pair_sets:  # point sets without correspondence, each pair by the metric's function (registration)
        if rtol is not None:
            raise ValueError(f"rtol applies to the certified geodesic metrics, not to {metric!r}")
        sets, params, shortlist, (sha, sizes) = _pointsets.prepare_pairs(shapes, info, params)
        recorded = {**_full_params(info, None, params), **(shortlist or {"shortlist": None})}
        n, k, d = len(sets), 0, sets[0].shape[1]
        neighbours = None
        if shortlist is not None:  # the rigid bound first (its own store beside this one: resumable too)
            rigid = compute_pairwise(sets, metric=shortlist["shortlist_metric"], modulo="similarity",
                                     sigma2=shortlist["shortlist_sigma2"], n_jobs=n_jobs, client=client,
                                     scheduler=scheduler, store=None if store is None else f"{store}.shortlist",
                                     progress=progress).matrix
            neighbours = _pointsets.shortlist_neighbours(rigid, shortlist["shortlist"])
            # the pairs off the shortlist cost nothing: the mean pair costs this fraction of a registered one
            pair_fraction = float(_pointsets.shortlist_mask(neighbours)[np.triu_indices(n, 1)].mean())
        x = _pointsets.items_of(sets, neighbours)
    else:
        check_metric_params(info, params, rtol=rtol)
        x = as_shapes(shapes, name="shapes")
        n, k, d = x.shape
        if "sigma2" in params:  # every σ² metric, the bounds too: once for all the shapes, not once per pair
            ratio = check_scale(x, params["sigma2"], stacklevel=4)
            if info.quadrature:  # a degenerate quadrature: an error before any work
                check_fisher_rao_scale(x, sigma2=params["sigma2"], metric=metric, ratio=ratio)
        if pose_dependent(info, params):  # likewise (check_pose: a pair, or a whole set to align)
            check_pose(x, metric=metric, stacklevel=4)
    symmetric = info.symmetric
    check_where(n_jobs, client, scheduler)
    if block_size is not None:
        block_size = check_positive_int(block_size, name="block_size")
    want = {"format": _FORMAT, "metric": metric,
            "params": recorded if point_sets or pair_sets else _full_params(info, rtol, params),
            "rtol": None if rtol is None else float(rtol),
            "shapes_sha256": sha if point_sets or pair_sets else shapes_sha256(x),
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
    n_workers = n_cores() if n_jobs in (None, -1) else int(n_jobs)
    seconds_per_pair = None
    if (st is None and block_size is None) or (local and n_jobs in (None, -1)):
        timed = (lambda: _pointsets.time_one_pair(x, metric, params)) if point_sets else (
            (lambda: time_pair_sets(x, info, params)) if pair_sets else (
                lambda: _time_one_pair(x, info, rtol, params)))
        seconds_per_pair = (_stored_seconds_per_pair(st) if st is not None else None) or (
            timed() * pair_fraction if n > 2 else 0.0)  # one pair: in-process whatever it costs
    jax_batches = not point_sets and _batched_jax(info, params)
    # a point-set metric's registrations batched on the JAX device (registration_misfits_many)
    jax_registrations = pair_sets and params.get("backend") == "jax"
    if jax_batches or jax_registrations:  # JAX installed and the device there, before any block (one-line errors)
        check_backend(params["backend"], params.get("device"))
    if local and n_jobs in (None, -1) and (jax_batches or jax_registrations):
        n_workers = 1  # one device, fed by this process (worker processes would each claim it)
    elif local and n_jobs in (None, -1):
        left = _pairs_left(st, n, symmetric)
        n_workers = 1 if n_workers < 2 or seconds_per_pair * left < (
            CLUSTER_OVERHEAD_SECONDS * n_workers / (n_workers - 1)) else n_workers
    if st is None:
        b = int(block_size) if block_size is not None else default_block_size(
            seconds_per_pair, n, n_workers=n_workers if local else max(2, cluster_size(client)),
            symmetric=symmetric)
        if block_size is None and not point_sets and _batched(info, rtol) and local and n_workers == 1:
            b = min(n, BOUND_BLOCK_MAX)  # one batched call for a population this process holds
        if block_size is None and jax_batches:
            b = min(n, JAX_BLOCK_SIDE)  # blocks of pairs that fill the device, stored as they finish
        if block_size is None and jax_registrations:  # about JAX_BLOCK_SIDE² registered pairs a block
            b = min(n, int(np.ceil(JAX_BLOCK_SIDE / np.sqrt(pair_fraction))))
        st = _Store.create(store, {**want, "block_size": b})
    done = st.task_done()
    todo = [t for t in block_pairs(n, st.b, symmetric=symmetric) if t not in done]
    n_todo = sum(_block_n_pairs(st, a, b) for a, b in todo)
    mode = "in-process" if local and n_workers == 1 else (
        f"LocalCluster({n_workers} processes)" if local else "cluster")
    log = {"blocks_total": len(done) + len(todo), "blocks_found_done": len(done), "blocks_computed": 0,
           "block_size": st.b, "mode": mode, "seconds_per_pair_estimate": seconds_per_pair, "stopped": False}
    if point_sets:
        log["spectra_seconds"] = params["spectra_seconds"]  # the one-off per-set work, done here
    total_pairs = sum(_block_n_pairs(st, a, b) for a, b in block_pairs(n, st.b, symmetric=symmetric))
    workers = n_workers if local else (cluster_size(client) if client is not None else None)
    eta = _announce(metric, n_todo, seconds_per_pair or _stored_seconds_per_pair(st), workers, log)
    bar = _progress(progress, total=total_pairs, initial=total_pairs - n_todo, metric=metric, eta=eta)
    kw = dict(symmetric=symmetric, metric=info, rtol=rtol, params=params)  # the record travels with each task
    pairs_done = [total_pairs - n_todo]
    t0 = time.perf_counter()
    with Interrupts() as interrupts:

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
                with interrupts.deferred():  # never inside the Dask client's calls (see Interrupts)
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
    if shortlist is not None:  # the pairs off the shortlist: the rigid bound, ranked after the registered ones
        registered = np.isfinite(result.matrix) & ~np.eye(n, dtype=bool)
        result.matrix, shift = _pointsets.fill_off_shortlist(result.matrix, rigid)
        result.log["shortlist"] = {**shortlist, "pairs_registered": int(registered.sum()) // (2 if symmetric else 1),
                                   "shift": shift}
    words = result._nonconverged()
    if words:
        warnings.warn(f"{words}; see PairwiseResult.to_frame() (status, rel_gap)", GeodesicWarning, stacklevel=3)
    return result


def pairwise_distances(shapes, *, metric: str, n_jobs: int | None = None, client=None, scheduler=None,
                       store=None, block_size: int | None = None, progress: bool = True,
                       rtol: float | None = None, return_result: bool = False, callback=None,
                       modulo: str | None = None, **params):
    """Matrix of distances between every pair of ``shapes`` (N, K, d), on Dask, with a resumable store.

    With ``metric="registration"``, ``shapes`` is a list of point sets of any sizes and each pair's
    value the misfit left after registering the sets onto each other
    (:func:`shapelib.pointsets.registration_distance.registration_distance`; options ``combine``, ``reflection``, ``lam``,
    ``sigma2_metric``, ``max_iter``, ``tol``, ``energy_weight``); ``lower`` and ``upper`` of the result hold the two
    directed misfits. ``shortlist=k`` registers only the pairs where one set is among the other's
    ``k`` nearest by the rigid bound ``shortlist_metric`` (default ``"fisher_rao_bound"``) modulo
    similarity at ``shortlist_sigma2`` (default 0.01; computed first, in ``store + ".shortlist"``
    when there is a store); the returned matrix holds that bound shifted above every registered
    value for the other pairs (each row ranks its shortlist first; ``log["shortlist"]`` and
    :meth:`PairwiseResult.summary` say so), the store ``+inf`` for them.

    With ``modulo="similarity"``, ``shapes`` is a list of planar point sets of any sizes (e.g.
    outlines, :func:`shapelib.trace_outline`) and ``metric`` ``"alpha_bound"`` or
    ``"fisher_rao_bound"``: the density distances minimised over translation, scale, rotation
    and (``reflection=True``, the default) reflection, :func:`shapelib.invariant_distance_matrix`,
    with ``sigma2`` in units of each set's RMS radius. Each set is normalised and its polar
    spectrum computed once, in this process; the blocks run as for every other metric.

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
    modulo : {"similarity"}, optional
        Compare a list of point sets modulo the similarity group (above).
    **params
        Options of the metric (point sets modulo a group: ``sigma2``, ``reflection`` and ``exact``,
        as :func:`shapelib.invariant_distance_matrix` takes them).

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

    See Also
    --------
    compute_pairwise : The engine, with the per-pair diagnostics.
    shapelib.distance : One pair.

    Examples
    --------
    Five ellipses of 12 landmarks at centroid size 20 (the study's scale), by the closed-form
    α-order lower bound (σ² = 0.5), in this process:

    >>> import numpy as np
    >>> from shapelib import pairwise_distances, to_centroid_size
    >>> t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    >>> shapes = np.stack([np.c_[np.cos(t), a * np.sin(t)] for a in (0.4, 0.5, 0.6, 0.8, 1.0)])
    >>> D = pairwise_distances(to_centroid_size(shapes, 20.0), metric="alpha_bound", sigma2=0.5,
    ...                        n_jobs=1, progress=False)
    >>> D.shape, np.array_equal(D, D.T), bool((np.diag(D) == 0).all())
    ((5, 5), True, True)
    >>> bool(D[0, 1] < D[0, 2] < D[0, 4])   # farther apart the more the ellipses differ
    True
    """
    result = compute_pairwise(shapes, metric=metric, n_jobs=n_jobs, client=client, scheduler=scheduler,
                              store=store, block_size=block_size, progress=progress, rtol=rtol, callback=callback,
                              modulo=modulo, **params)
    if return_result:
        return result
    if not result.complete:
        warnings.warn(f"the callback stopped the run after {result.log.get('blocks_done')} of "
                      f"{result.log.get('blocks_total')} blocks: the matrix is NaN where pairs were not computed"
                      + (f"; rerun with store={result.store!r} to resume" if result.store else ""),
                      UserWarning, stacklevel=2)
    return result.matrix


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
                own_client = connect(scheduler)
            else:
                cluster = local_cluster(n_workers)
                own_client = Client(cluster)
                own_client.run(ignore_sigint)  # see local_cluster: Ctrl-C is the caller's
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
