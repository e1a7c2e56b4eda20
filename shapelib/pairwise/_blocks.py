"""Blocks of pairs, the engine's unit of work: which blocks, one block's pairs, the block size."""

from __future__ import annotations

import contextlib
import math
import time
import warnings

import numpy as np

from .._executor import in_dask_worker
from .._validate import as_shapes, set_checked
from ..distances import check_metric_params, is_builtin, metric_info
from ..pointsets.registration_distance import registration_distance, registration_misfits_many
from ..geometry.procrustes import PoseWarning
from ..geometry.scale import ScaleWarning
from ..solver.bracket import distance_brackets
from ..solver.geodesic import GeodesicWarning, geodesics
from ..solver.linalg import one_blas_thread
from ._pointsets import point_set_block
from ._results import PairError

#: seconds one task should take (sets the default block size)
TASK_SECONDS = 2.0
#: at least this many tasks per worker, for load balance
TASKS_PER_WORKER = 4


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


def _pair_record(info, x_u, x_v, i, j, *, rtol, params):
    """The unchecked :meth:`~shapelib.distances.MetricInfo.record` of one pair of a checked set,
    naming the pair in the metric's input errors."""
    try:
        return info.record(x_u, x_v, rtol=rtol, **params)
    except ValueError as exc:
        raise PairError(i, j, exc) from exc


def _n_blocks(n: int, b: int) -> int:
    return -(-n // b)


def block_pairs(n: int, block_size: int, *, symmetric: bool) -> list[tuple[int, int]]:
    """Block indices ``(I, J)`` of the tasks: ``I ≤ J`` for symmetric metrics, all for asymmetric ones.

    Block ``(I, J)`` holds rows ``I·b … (I+1)·b − 1`` and columns ``J·b … (J+1)·b − 1`` of the
    ``n × n`` matrix (``b = block_size``; the last block of a side may be smaller), so there are
    ``⌈n / b⌉`` blocks a side.

    Parameters
    ----------
    n : int
        Shapes (the matrix is ``n × n``).
    block_size : int
        Shapes per block side.
    symmetric : bool
        Whether the metric is symmetric: then only the blocks on and above the diagonal are
        tasks (the others are their mirror images).

    Returns
    -------
    list of tuple of int
        ``(I, J)`` in row-major order.

    See Also
    --------
    compute_block : One task's pairs.
    default_block_size : How ``block_size`` is chosen.

    Examples
    --------
    Five shapes in blocks of two: three blocks a side.

    >>> from shapelib.pairwise import block_pairs
    >>> block_pairs(5, 2, symmetric=True)
    [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    >>> len(block_pairs(5, 2, symmetric=False))
    9
    """
    nb = _n_blocks(n, block_size)
    return [(a, b) for a in range(nb) for b in range(nb) if not symmetric or a <= b]


def compute_block(xi, xj, *, diagonal: bool, symmetric: bool, metric, rtol, params: dict,
                  offset=(0, 0)) -> dict:
    r"""All pairs of one block: ``{array: (bi, bj)}`` (the arrays of :data:`ARRAYS`).

    Entry ``[a, b]`` of each array is the metric's record of the pair
    ``(xi[a], xj[b])``: its distance :math:`D_{ij} = d(\mathbf{x}_i, \mathbf{x}_j)` (``matrix``,
    the record's ``value``), the certified ``lower`` and ``upper`` bounds, the path ``energy``,
    ``seconds``, ``converged`` and ``n_iter``.

    ``metric`` is a name or a :class:`~shapelib.distances.MetricInfo` record: the engine sends
    the record with each task, so a metric registered in the client runs on workers that can
    import its function's module, registered there or not. A record with a ``block`` function
    (the closed-form bounds) computes the block in one batched call (without ``rtol``); every
    other block goes pair by pair through the record's unchecked
    :meth:`~shapelib.distances.MetricInfo.record`, the options and the block's shapes being
    checked once here.

    ``xi``, ``xj`` are the block's row and column shapes, starting at rows/columns ``offset`` of
    the matrix (used to name a pair in a :class:`PairError`). On a diagonal block only the pairs
    ``i ≠ j`` are computed (``i < j``, then mirrored, for symmetric metrics) and the diagonal is
    zero. Solver warnings are not emitted: convergence is recorded per pair instead; nor are
    scale and pose warnings, which :func:`compute_pairwise` gives once for all the shapes.

    Parameters
    ----------
    xi : array_like, shape (bi, K, d)
        The block's row shapes.
    xj : array_like, shape (bj, K, d)
        Its column shapes (the same object as ``xi`` on a diagonal block).
    diagonal : bool
        Whether this is a diagonal block (``xi`` and ``xj`` are the same shapes).
    symmetric : bool
        Whether the metric is symmetric (a diagonal block then computes ``i < j`` and mirrors).
    metric : str or MetricInfo
        A registered metric's name or its record.
    rtol : float or None
        The certified relative tolerance of the geodesic metrics' brackets; None for none.
    params : dict
        The metric's options (e.g. ``{"sigma2": 0.5}``).
    offset : tuple of int
        Row and column of ``xi[0]`` and ``xj[0]`` in the whole matrix.

    Returns
    -------
    dict of str to ndarray
        One ``(bi, bj)`` array per name of :data:`ARRAYS`: ``matrix`` (float64), ``lower``,
        ``upper``, ``energy``, ``seconds`` (float64), ``converged`` (bool), ``n_iter`` (int64).

    Raises
    ------
    PairError
        When the metric rejects a pair, naming its row and column of the whole matrix.

    See Also
    --------
    block_pairs : Which blocks there are.
    compute_pairwise : Runs the blocks and stores them.

    Examples
    --------
    The off-diagonal block of rows 0–1 and columns 2–4 of five shapes:

    >>> import numpy as np
    >>> from shapelib.distances import distance
    >>> from shapelib.pairwise import compute_block
    >>> x = np.random.default_rng(0).normal(size=(5, 6, 2))
    >>> out = compute_block(x[:2], x[2:], diagonal=False, symmetric=True, metric="procrustes",
    ...                     rtol=None, params={}, offset=(0, 2))
    >>> sorted(out), out["matrix"].shape
    (['converged', 'energy', 'lower', 'matrix', 'n_iter', 'seconds', 'upper'], (2, 3))
    >>> bool(np.isclose(out["matrix"][1, 0], distance(x[1], x[2], metric="procrustes")))
    True
    >>> bool(out["converged"].all()), np.array_equal(out["lower"], out["matrix"])
    (True, True)
    """
    info = metric_info(metric)
    if params.get("modulo") is not None:  # point sets of any sizes, modulo a group (:mod:`._pointsets`),
        t0 = time.perf_counter()  # checked and normalised once by the driver
        with _pair_work():
            d = point_set_block(xi, xj, diagonal=diagonal, metric=info.name, params=params)
        return _matrix_block(d, diagonal=diagonal, seconds=time.perf_counter() - t0)
    if info.point_sets:  # point sets without correspondence (checked once by the driver), pair by pair
        with _pair_work():
            return pair_block(xi, xj, diagonal=diagonal, symmetric=symmetric, info=info, params=params)
    check_metric_params(info, params, rtol=rtol)
    xi = as_shapes(xi, name="rows")
    xj = xi if xj is xi else as_shapes(xj, name="cols")
    bi, bj = len(xi), len(xj)
    if _batched(info, rtol):
        out = _batched_block(xi, xj, diagonal=diagonal, info=info, params=params)
        if out is not None:
            return out
    out = {name: np.full((bi, bj), fill, dtype=dtype) for name, (dtype, fill) in ARRAYS.items()}
    todo = [(a, b) for a in range(bi) for b in range(bj) if not (diagonal and (a == b or (symmetric and b < a)))]
    if not (_batched_jax(info, params) and _jax_block(xi, xj, todo, out, metric=info, rtol=rtol, params=params)):
        with _pair_work():
            for a, b in todo:
                rec = _pair_record(info, xi[a], xj[b], offset[0] + a, offset[1] + b, rtol=rtol, params=params)
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


def _batched(metric, rtol) -> bool:
    """Whether a block of ``metric`` (a name or a :class:`~shapelib.distances.MetricInfo`) is one
    batched call: its record carries a ``block`` function, and no bracket's ``rtol`` is asked."""
    return rtol is None and metric_info(metric).block is not None


#: with ``backend="jax"`` a block has this many shapes a side unless ``block_size`` says (up to ~1,000 pairs: one
#: batched solve on the device per block, which the store saves as it does any block)
JAX_BLOCK_SIDE = 32


def _batched_jax(metric, params) -> bool:
    """Whether a block's pairs go to the device as one batch: shapelib's own α and Fisher–Rao
    geodesics (or brackets) with ``backend="jax"``."""
    info = metric_info(metric)
    return params.get("backend") == "jax" and info.name in ("alpha", "fisher_rao") and is_builtin(info)


def _jax_block(xi, xj, todo, out, *, metric, rtol, params) -> bool:
    """The pairs ``todo`` of a block as one batched call on the JAX device
    (:func:`shapelib.solver.bracket.distance_brackets` with ``rtol``, else
    :func:`shapelib.solver.geodesic.geodesics`) into ``out``; each pair's ``seconds`` is the call's wall
    time over its pairs. False (nothing written) when the call rejects an input, so that
    :func:`compute_block` goes pair by pair and names the bad pair."""
    if not todo:
        return True
    name = metric_info(metric).name
    a_idx, b_idx = np.array([p[0] for p in todo]), np.array([p[1] for p in todo])
    t0 = time.perf_counter()
    try:
        with _pair_work():
            if rtol is not None:
                res = distance_brackets(xi[a_idx], xj[b_idx], metric=name, rtol=rtol, **params)
                rec = [(r.upper, r.lower, r.upper, r.energy, r.converged, r.n_iter) for r in res]
            else:
                res = geodesics(xi[a_idx], xj[b_idx], metric=name, **params)
                rec = [(r.length, r.lower_bound, r.length, r.energy, r.converged, r.n_iter) for r in res]
    except ValueError:
        return False
    seconds = (time.perf_counter() - t0) / len(todo)
    for (a, b), (value, lower, upper, energy, converged, n_iter) in zip(todo, rec):
        for key, val in (("matrix", value), ("lower", lower), ("upper", upper), ("energy", energy),
                         ("converged", converged), ("n_iter", n_iter), ("seconds", seconds)):
            out[key][a, b] = val
    return True


#: a batched metric's matrix in this process is one block of at most this many shapes a side
#: (one call of its block function, e.g. :mod:`shapelib.geometry.bound_matrices`)
BOUND_BLOCK_MAX = 2048


def _batched_block(xi, xj, *, diagonal, info, params):
    """A block as one call of the record's ``block`` function, in :func:`compute_block`'s format
    (each pair's ``seconds`` is the block's wall time over its pairs). ``None`` when the call rejects
    the block — e.g. a Fisher–Rao grid over all its shapes too large, or an input error — so that
    :func:`compute_block` goes pair by pair, on each pair's own grid, naming a bad pair."""
    t0 = time.perf_counter()
    try:
        with _pair_work():  # one BLAS thread, as every task; all the cores in this process's own run
            d = info.block(xi, None if diagonal else xj, n_threads=1 if in_dask_worker() else None, **params)
    except ValueError:
        return None
    return _matrix_block(np.asarray(d, dtype=np.float64), diagonal=diagonal, seconds=time.perf_counter() - t0)


def _matrix_block(d: np.ndarray, *, diagonal: bool, seconds: float) -> dict:
    """A block computed as one matrix ``d``, in :func:`compute_block`'s format: every pair converged,
    no iterations, each pair's ``seconds`` the block's wall time over its pairs."""
    bi, bj = d.shape
    n_pairs = bi * (bi - 1) // 2 if diagonal else bi * bj
    out = {name: np.full((bi, bj), fill, dtype=dtype) for name, (dtype, fill) in ARRAYS.items()}
    for name in ("matrix", "lower", "upper"):
        out[name][...] = d
    out["seconds"][...] = seconds / max(1, n_pairs)
    out["converged"][...] = True
    out["n_iter"][...] = 0
    if diagonal:
        idx = np.diag_indices(bi)
        for name in ("energy", "seconds"):
            out[name][idx] = 0
    return out


def default_block_size(seconds_per_pair: float, n: int, *, n_workers: int = 1, symmetric: bool = True) -> int:
    r"""Block side ``b`` with ``b² · seconds_per_pair ≤ TASK_SECONDS`` and ≥ ``TASKS_PER_WORKER`` tasks
    per worker (see the module docstring).

    A task of ``b²`` pairs then takes about :data:`TASK_SECONDS` (:math:`T`):

    .. math::

        b = \min\Big(n,\ \max\Big(1,\ \Big\lfloor \sqrt{T / t_\text{pair}} \Big\rfloor\Big)\Big),

    made smaller, with ``W > 1`` workers, until there are at least ``TASKS_PER_WORKER · W``
    blocks (``⌈n/b⌉ (⌈n/b⌉ + 1) / 2`` of them for a symmetric metric).

    Parameters
    ----------
    seconds_per_pair : float
        :math:`t_\text{pair}`, the measured seconds of one pair.
    n : int
        Shapes.
    n_workers : int
        Worker processes the blocks are shared among.
    symmetric : bool
        Whether the metric is symmetric (only the blocks on and above the diagonal are tasks).

    Returns
    -------
    int
        The block side, between 1 and ``n``.

    See Also
    --------
    block_pairs : The blocks of that side.

    Examples
    --------
    At 1 ms a pair a two-second task holds 44² pairs; with two workers, 100 shapes are cut
    finer so that each worker gets at least four tasks:

    >>> from shapelib.pairwise import default_block_size
    >>> default_block_size(1e-3, 1000), default_block_size(1e-3, 100, n_workers=2)
    (44, 25)
    >>> default_block_size(30.0, 100)   # a pair longer than a task: one pair per block
    1
    """
    b = max(1, int(math.sqrt(TASK_SECONDS / max(seconds_per_pair, 1e-9))))
    if n_workers > 1:
        want = TASKS_PER_WORKER * n_workers
        nb = 1
        while (nb * (nb + 1) // 2 if symmetric else nb * nb) < want and nb < n:
            nb += 1
        b = min(b, _n_blocks(n, nb))
    return max(1, min(b, n))


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
    info = metric_info(metric)
    if _batched(info, rtol):  # the cost of a pair within a block
        m = min(len(x), 64)
        best = math.inf
        for _ in range(2):  # the first call also pays one-off costs
            t0 = time.perf_counter()
            out = _batched_block(x[:m], x[:m], diagonal=True, info=info, params=params)
            best = min(best, time.perf_counter() - t0)
        if out is not None:
            return best / max(1, m * (m - 1) // 2)
    if _batched_jax(metric, params):  # not timed: a block is one batch on the device (JAX_BLOCK_SIDE), and a
        return 0.0  # lone pair would compile programs the blocks do not use
    times = []
    with _pair_work():
        # a pair far above TASK_SECONDS gets a block of its own either way: no second call
        while not times or (len(times) < 2 and times[0] < 10 * TASK_SECONDS) or (
                len(times) < 3 and sum(times) < budget):
            t0 = time.perf_counter()
            _pair_record(info, x[0], x[1 % len(x)], 0, 1 % len(x), rtol=rtol, params=params)
            times.append(time.perf_counter() - t0)
    return min(times)


# -- point sets without correspondence (``MetricInfo.point_sets``: ``"registration"``) ------------------

def pair_block(xi, xj, *, diagonal: bool, symmetric: bool, info, params: dict) -> dict:
    """All pairs of one block of a point-set metric, in :func:`~shapelib.pairwise.compute_block`'s
    format. ``"registration"``: ``matrix`` the distance, ``lower`` / ``upper`` the smaller and larger
    directed misfit, ``converged`` both EMs, ``n_iter`` their iterations together. A pair off the
    shortlist (neither set among the other's) is not computed: ``+inf`` in ``matrix``, ``lower`` and
    ``upper`` (the driver fills it from the rigid bound)."""
    bi, bj = len(xi), len(xj)
    out = {name: np.full((bi, bj), fill, dtype=dtype) for name, (dtype, fill) in ARRAYS.items()}
    todo = []
    for a in range(bi):
        for b in range(bj):
            if diagonal and (a == b or (symmetric and b < a)):
                continue
            (u, i, near_i), (v, j, near_j) = xi[a], xj[b]
            if near_i is not None and j not in near_i and i not in near_j:
                _put(out, a, b, (np.inf, np.inf, np.inf, True, 0), 0.0)  # off the shortlist
            else:
                todo.append((a, b, u, v))
    if info.name == "registration" and info.function is registration_distance and todo:
        # the block's pairs, both directions, in one register_many call (batched on the device with
        # backend="jax"); each pair's seconds is the call's time over its pairs
        combine = params.get("combine", "mean")
        opts = {k: v for k, v in params.items() if k != "combine"}
        t0 = time.perf_counter()
        misfits = registration_misfits_many([(u, v) for _, _, u, v in todo], **opts)
        seconds = (time.perf_counter() - t0) / len(todo)
        for (a, b, _, _), (m_uv, m_vu, converged, n_iter) in zip(todo, misfits):
            value = 0.5 * (m_uv + m_vu) if combine == "mean" else max(m_uv, m_vu)
            _put(out, a, b, (value, min(m_uv, m_vu), max(m_uv, m_vu), converged, n_iter), seconds)
    else:  # any other point-set metric: its function's value
        for a, b, u, v in todo:
            t0 = time.perf_counter()
            value = float((info.core or info.function)(u, v, **params))
            _put(out, a, b, (value, value, value, True, 0), time.perf_counter() - t0)
    if diagonal:
        if symmetric:
            low = np.tril_indices(bi, -1)
            for arr in out.values():
                arr[low] = arr.T[low]
        d = np.diag_indices(bi)
        for name in ("matrix", "lower", "upper", "seconds", "n_iter"):
            out[name][d] = 0
        out["converged"][d] = True
    return out


def _put(out, a, b, rec, seconds):
    value, lower, upper, converged, n_iter = rec
    out["matrix"][a, b], out["lower"][a, b], out["upper"][a, b] = value, lower, upper
    out["converged"][a, b], out["n_iter"][a, b], out["seconds"][a, b] = converged, n_iter, seconds


def time_pair_sets(items, info, params: dict) -> float:
    """Seconds of one pair (the first two sets, whatever the shortlist)."""
    t0 = time.perf_counter()
    pair_block([(items[0][0], 0, None)], [(items[1][0], 1, None)], diagonal=False, symmetric=True, info=info,
               params=params)
    return time.perf_counter() - t0
