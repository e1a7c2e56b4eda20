"""Geodesics and certified brackets for many pairs at once on an accelerator (``backend="jax"``).

The energy and its gradient are the JAX implementation of the CPU solver's discrete path energy
(:mod:`shapelib.geometry._jax_kernels`: the same piecewise-linear path, 3-point Gauss–Legendre time
rule and trapezoid grid), vmapped over a batch of pairs of the same ``K``, ``d`` and ``n_steps``. The
minimiser is a limited-memory BFGS (:func:`lbfgs_solve`), written here in JAX so that the whole batch
iterates on the device with no host round trip: ``lax.while_loop`` per pair under ``vmap`` (a pair that
has stopped is frozen while the others go on).

What is certified is what the CPU path certifies (:func:`shapelib.geodesic`,
:func:`shapelib.distance_bracket`): the lower bound is the closed form (α: ``‖p_u − p_v‖``;
Fisher–Rao: the great circle), and the upper bound is the length ``∫ √(θ̇ᵀgθ̇) dt`` of the returned
path by the CPU code's quadrature — 5-point Gauss–Legendre in time on the grid
:func:`shapelib.geometry.quadrature.make_grid` places around the returned path — evaluated on the
device. The result objects and stop words are the CPU ones.

Fisher–Rao grids. During a solve each pair's grid is fixed: the grid of its starting path with
:data:`GRID_PAD` σ more margin (nodes on the same lattice, so it is the CPU grid plus a border where
the integrands have vanished). If the returned path has moved beyond it, the pair is solved again
from there on a new grid (at most :data:`MAX_REGRIDS` times). Grids of the pairs of one batch are
padded to a common size with zero-weight nodes (:func:`stack_grids`).

Devices. ``device=None`` runs on JAX's default device (a GPU when JAX sees one, else the CPU);
``device="gpu"`` demands a GPU and raises a one-line error when there is none (never a silent CPU
fallback); ``device="cpu"`` runs JAX on the CPU (what the tests do).
"""

from __future__ import annotations

import contextlib
import functools
import time
import warnings

import numpy as np

from .._validate import as_pair_batch, check_nonnegative_int, check_positive, check_positive_int
from ..geometry import _jax_kernels as jk
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING, make_grid
from .path_metric import GL5_NODES, GL5_WEIGHTS, METRICS, path_metric
from .result import GeodesicResult, GeodesicWarning, StopReason

# check_backend, jax_device, stack_grids, lbfgs_solve and bucket are the solvers' internal helpers: importable
# by the other solver modules, not user API
__all__ = ["BACKENDS", "DEVICES", "batched_geodesics", "batched_lengths", "GRID_PAD", "MAX_REGRIDS", "LBFGS_HISTORY"]

#: the values of ``backend=``
BACKENDS = ("cpu", "jax")
#: the values of ``device=`` (with ``backend="jax"``); None: JAX's default device
DEVICES = (None, "cpu", "gpu")
#: extra margin (in σ) of the fixed Fisher–Rao grid of a batched solve, beyond the grid's margin
GRID_PAD = 2.0
#: times a pair whose path left its grid is solved again on a new one
MAX_REGRIDS = 3
#: L-BFGS memory (pairs of steps and gradient changes kept)
LBFGS_HISTORY = 10
#: the first L-BFGS step moves no landmark by more than this (in σ)
FIRST_STEP = 0.1
#: shortest energy trace of a device solve (longer for larger ``max_iter``, rounded by :func:`bucket`)
TRACE_MIN = 1024
#: step halvings of the backtracking (Armijo) line search before "no_decrease"
MAX_HALVINGS = 40

# status codes of the device loop -> stop words
_RUNNING, _WINDOW, _NO_DECREASE, _TARGET = 0, 1, 2, 3
_STOP = {_WINDOW: StopReason.ENERGY_WINDOW, _NO_DECREASE: StopReason.NO_DECREASE,
         _TARGET: StopReason.TARGET_ENERGY, _RUNNING: StopReason.MAX_ITER}


def check_backend(backend, device=None):
    """Validate ``backend`` and ``device``; ``(backend, device)``.

    ``backend="cpu"`` is the compiled CPU solver (``device`` must be None or "cpu");
    ``backend="jax"`` needs JAX (``ImportError`` naming the extra to install otherwise) and with
    ``device="gpu"`` a GPU that JAX sees (``RuntimeError`` otherwise).
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}; got {backend!r}")
    if device not in DEVICES:
        raise ValueError(f"device must be None, 'cpu' or 'gpu'; got {device!r}")
    if backend == "cpu":
        if device == "gpu":
            raise ValueError('device="gpu" needs backend="jax" (the CPU backend runs on the CPU only)')
        return backend, device
    jk.require_jax()
    jax_device(device)  # fail now, before any work, if the device is not there
    return backend, device


def jax_device(device=None):
    """The JAX device of ``device`` (None: JAX's default; "cpu"; "gpu", refused in one line if JAX
    sees no GPU)."""
    jax = jk.require_jax()
    if device is None:
        return jax.devices()[0]
    if device == "cpu":
        return jax.devices("cpu")[0]
    try:
        gpus = jax.devices("gpu")
    except RuntimeError:
        gpus = []
    if not gpus:
        raise RuntimeError(f'device="gpu" but JAX sees no GPU (JAX {jax.__version__}, devices: '
                           f'{", ".join(str(d) for d in jax.devices())}); on a CUDA 12 machine: {jk.INSTALL_HINT.split(" (")[0]}')
    return gpus[0]


@contextlib.contextmanager
def _on(device):
    """float64 JAX computations on ``device`` inside the block."""
    with jk.x64() as jax:
        with jax.default_device(jax_device(device)):
            yield jax


# -------------------------------------------------------------------------------------------------
# Grids
# -------------------------------------------------------------------------------------------------


def bucket(m: int) -> int:
    """``m`` rounded up to the next ``{4, 5, 6, 7} · 2^j``: the sizes (grid nodes, pairs per call)
    the compiled programs are specialised to, so a few programs serve every pair (≤ 25 % padding)."""
    m = int(m)
    if m <= 4:
        return max(m, 1)
    j = max(int(np.floor(np.log2(m))) - 2, 0)
    for c in (4, 5, 6, 7, 8):
        if c << j >= m:
            return c << j
    return 8 << j  # pragma: no cover - unreachable


def stack_grids(grids, d):
    """Nodes (B, M, d) and weights (B, M) of several :class:`~shapelib.geometry.quadrature.Grid`,
    padded to a common size (the largest, rounded up by :func:`bucket`) with nodes of weight 0 (at
    the first node, so no integrand is evaluated anywhere new)."""
    size = bucket(max(len(g.nodes) for g in grids))
    nodes = np.zeros((len(grids), size, d))
    weights = np.zeros((len(grids), size))
    for i, g in enumerate(grids):
        m = len(g.nodes)
        nodes[i, :m] = g.nodes
        nodes[i, m:] = g.nodes[0]
        weights[i, :m] = g.weight
    return nodes, weights


def _solve_grid(path, s2, spacing, margin):
    return make_grid(path, sigma2=s2, grid_spacing=spacing, grid_margin=margin + GRID_PAD)


def _covers(grid, path, s2, spacing, margin):
    """Whether ``grid`` contains every node of the CPU grid of ``path``."""
    need = make_grid(path, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    h = spacing * np.sqrt(s2)
    return all(ax[0] <= nd[0] + 1e-9 * h and ax[-1] >= nd[-1] - 1e-9 * h for ax, nd in zip(grid.axes, need.axes))


# -------------------------------------------------------------------------------------------------
# L-BFGS on the device, one pair per vmap lane
# -------------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=None)
def _compiled_solver(metric, trace, history):
    """jit(vmap(one pair's L-BFGS)) for static ``metric``, energy-trace length ``trace`` (> max_iter)
    and ``history``; ``max_iter`` and ``window`` are arguments, so one program serves them all."""
    import jax
    import jax.numpy as jnp
    from jax import lax

    value_and_grad = jax.value_and_grad(functools.partial(jk._interior_energy, metric=metric))

    def solve_one(x0, ends, s2, nodes, weights, tol, target, step0, f, g, max_iter, window):
        # the start's energy and gradient come in (jk._compiled): one copy of the energy in this program
        shape = x0.shape
        fg = lambda x: value_and_grad(x.reshape(shape), ends, s2, nodes, weights)  # noqa: E731
        lap_inv = jnp.asarray(laplacian_inverse(shape[0]))
        precond = lambda w: (lap_inv @ w.reshape(shape[0], -1)).reshape(-1)  # noqa: E731
        x = x0.reshape(-1)
        g = g.reshape(-1)
        p = x.size
        energies = jnp.full(trace, jnp.nan).at[0].set(f)
        status = jnp.where(f <= target, _TARGET, _RUNNING)
        state = dict(x=x, f=f, g=g, s=jnp.zeros((history, p)), y=jnp.zeros((history, p)), rho=jnp.zeros(history),
                     count=jnp.array(0), it=jnp.array(0), energies=energies, status=status, gamma=jnp.array(0.0),
                     last=jnp.array(0.0))

        def direction(st):
            q = -st["g"]
            count = st["count"]
            n_valid = jnp.minimum(count, history)

            def first(j, c):
                q, alphas = c
                idx = (count - 1 - j) % history
                a = jnp.where(j < n_valid, st["rho"][idx] * jnp.dot(st["s"][idx], q), 0.0)
                return q - a * st["y"][idx], alphas.at[j].set(a)

            q, alphas = lax.fori_loop(0, history, first, (q, jnp.zeros(history)))
            pg = precond(st["g"])
            scale0 = step0 / jnp.maximum(jnp.max(jnp.abs(pg)), 1e-300)
            r = precond(q) * jnp.where(count > 0, st["gamma"], scale0)

            def second(jj, r):
                j = history - 1 - jj
                idx = (count - 1 - j) % history
                b = st["rho"][idx] * jnp.dot(st["y"][idx], r)
                return r + jnp.where(j < n_valid, alphas[j] - b, 0.0) * st["s"][idx]

            r = lax.fori_loop(0, history, second, r)
            gd = jnp.dot(st["g"], r)
            ok = (gd < 0) & jnp.all(jnp.isfinite(r))
            # not a descent direction: restart from the scaled, preconditioned steepest descent
            return jnp.where(ok, r, -pg * scale0), jnp.where(ok, gd, -jnp.dot(st["g"], pg) * scale0), ok

        def body(st):
            d, gd, ok = direction(st)
            count = jnp.where(ok, st["count"], 0)

            def ls_cond(c):
                return (~c[3]) & (c[4] < MAX_HALVINGS)

            def ls_body(c):
                a, _, _, _, k = c
                fn, gn = fg(st["x"] + a * d)
                good = jnp.isfinite(fn) & (fn <= st["f"] + 1e-4 * a * gd) & (fn < st["f"])
                return jnp.where(good, a, 0.5 * a), fn, gn.reshape(-1), good, k + 1

            a, fn, gn, good, _ = lax.while_loop(ls_cond, ls_body, (jnp.array(1.0), st["f"], st["g"], jnp.array(False),
                                                                   jnp.array(0)))
            x_new = jnp.where(good, st["x"] + a * d, st["x"])
            f_new = jnp.where(good, fn, st["f"])
            g_new = jnp.where(good, gn, st["g"])
            s_vec, y_vec = x_new - st["x"], g_new - st["g"]
            sy = jnp.dot(s_vec, y_vec)
            update = good & (sy > 1e-12 * jnp.linalg.norm(s_vec) * jnp.linalg.norm(y_vec))
            slot = count % history
            it = st["it"] + jnp.where(good, 1, 0)
            energies = st["energies"].at[it].set(f_new)
            prev = energies[jnp.maximum(it - window, 0)]
            status = jnp.where(~good, _NO_DECREASE,
                               jnp.where(f_new <= target, _TARGET,
                                         jnp.where((it >= window) & (prev - f_new < tol * f_new), _WINDOW, _RUNNING)))
            return dict(
                x=x_new, f=f_new, g=g_new,
                s=jnp.where(update, st["s"].at[slot].set(s_vec), st["s"]),
                y=jnp.where(update, st["y"].at[slot].set(y_vec), st["y"]),
                rho=jnp.where(update, st["rho"].at[slot].set(1.0 / jnp.where(update, sy, 1.0)), st["rho"]),
                count=jnp.where(update, count + 1, count),
                it=it, energies=energies, status=status,
                gamma=jnp.where(update, sy / jnp.dot(y_vec, precond(y_vec)), st["gamma"]),
                last=jnp.where(good, (st["f"] - f_new) / st["f"], 0.0),
            )

        def cond(st):
            return (st["status"] == _RUNNING) & (st["it"] < max_iter)

        st = lax.while_loop(cond, body, state)
        return (st["x"].reshape(shape), st["f"], jnp.linalg.norm(st["g"]), st["it"], st["status"], st["energies"],
                st["last"])

    return jax.jit(jax.vmap(solve_one, in_axes=(0, 0, None, 0, 0, None, 0, None, 0, 0, None, None)))


def laplacian_inverse(m: int) -> np.ndarray:
    """Inverse of the (m, m) second-difference matrix ``tridiag(−1, 2, −1)``:
    ``min(i, j) (m + 1 − max(i, j)) / (m + 1)`` (1-based). The path energy's Hessian over the
    interior points is this time Laplacian coupled with the metric, so L-BFGS starts from it
    (its initial inverse Hessian ``γ L⁻¹ ⊗ I``): the iterations no longer grow with ``n_steps²``."""
    i = np.arange(1, m + 1)
    return np.minimum.outer(i, i) * (m + 1 - np.maximum.outer(i, i)) / (m + 1)


def lbfgs_solve(paths, *, metric, sigma2, nodes=None, weights=None, tol=1e-6, max_iter=500, window=5,
                target_energy=None, device=None, history=LBFGS_HISTORY):
    """Minimise the discrete path energy of a batch of paths (B, n + 1, K, d), ends fixed, by L-BFGS on
    the device (one vmap lane per pair), preconditioned by the time Laplacian (:func:`laplacian_inverse`).

    Stops per pair (the CPU solver's stop words): the energy at or below ``target_energy`` (B,)
    (``"target_energy"``), a relative energy decrease over ``window`` iterations below ``tol``
    (``"energy_window"``), no step of the line search lowers the energy (``"no_decrease"``), or
    ``max_iter`` iterations (``"max_iter"``).

    Returns
    -------
    dict of numpy arrays
        ``path`` (B, n + 1, K, d), ``energy`` (B,) on the solve's grid, ``grad_norm``, ``n_iter``,
        ``stopped_by`` (list of :class:`~shapelib.solver.result.StopReason`), ``energies``
        (B, at least max_iter + 1; NaN after the last iteration), ``rel_change`` (last accepted step).
    """
    paths = np.asarray(paths, dtype=np.float64)
    b = len(paths)
    target = np.full(b, -np.inf) if target_energy is None else np.broadcast_to(np.asarray(target_energy, float), (b,))
    if nodes is None:
        nodes, weights = np.zeros((b, 1, 1)), np.zeros((b, 1))
    pad = bucket(b) - b  # idle lanes (copies of the first pair, stopped at once) keep the programs few
    if pad:
        paths, nodes, weights = (np.concatenate([a, np.repeat(a[:1], pad, axis=0)]) for a in (paths, nodes, weights))
        target = np.concatenate([target, np.full(pad, np.inf)])
    solver = _compiled_solver(metric, max(TRACE_MIN, bucket(int(max_iter) + 1)), int(history))
    with _on(device):
        x0, ends = paths[:, 1:-1], paths[:, [0, -1]]
        f0, g0 = jk._compiled(metric, "value_and_grad")(x0, ends, float(sigma2), nodes, weights)
        x, f, gn, it, status, energies, last = solver(
            x0, ends, float(sigma2), nodes, weights, float(tol), target, float(FIRST_STEP * np.sqrt(sigma2)), f0, g0,
            int(max_iter), int(window))
        x, f, gn, it, status, energies, last = (np.asarray(a) for a in (x, f, gn, it, status, energies, last))
    paths, x, f, gn, it, status, energies, last = (a[:b] for a in (paths, x, f, gn, it, status, energies, last))
    out = paths.copy()
    out[:, 1:-1] = x
    return {"path": out, "energy": f, "grad_norm": gn, "n_iter": it,
            "stopped_by": [_STOP[int(s)] for s in status], "energies": energies, "rel_change": last}


# -------------------------------------------------------------------------------------------------
# Certified lengths: the CPU quadrature, on the device
# -------------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=None)
def _compiled_length(metric):
    import jax
    import jax.numpy as jnp

    def one(path, s2, nodes, weights):
        n = path.shape[0] - 1
        seg = path[1:] - path[:-1]
        theta = path[:-1, None] + GL5_NODES[None, :, None, None] * seg[:, None]
        vel = n * seg
        if metric == "alpha":
            qf = lambda t, v: jk.alpha_qform(t, v, s2)  # noqa: E731
        else:
            qf = lambda t, v: jk.fisher_rao_qform(t, v, s2, nodes, weights)  # noqa: E731
        q = jax.vmap(lambda th, v: jax.vmap(lambda t: qf(t, v))(th))(theta, vel)
        length = jnp.sum(jnp.sqrt(jnp.maximum(q, 0.0)) * GL5_WEIGHTS[None, :]) / n
        energy = jk.path_energy(path, s2, nodes, weights, metric=metric)
        return length, energy

    return jax.jit(jax.vmap(one, in_axes=(0, None, 0, 0)))


def _cpu_grids(paths, metric, s2, spacing, margin):
    if metric == "alpha":
        return np.zeros((len(paths), 1, 1)), np.zeros((len(paths), 1))
    return stack_grids([make_grid(p, sigma2=s2, grid_spacing=spacing, grid_margin=margin) for p in paths], paths.shape[-1])


def batched_lengths(paths, *, metric, sigma2, grid_spacing=DEFAULT_SPACING, grid_margin=DEFAULT_MARGIN, device=None):
    """Lengths and energies of a batch of piecewise-linear paths (B, n + 1, K, d), by the CPU code's
    quadrature (:func:`shapelib.solver.energy.metric_length` and
    :func:`shapelib.solver.energy.path_energy`: 5- and 3-point Gauss–Legendre per segment, for
    Fisher–Rao on the grid :func:`~shapelib.geometry.quadrature.make_grid` places around each path),
    evaluated with JAX on ``device``.

    Parameters
    ----------
    paths : array_like, shape (B, n + 1, K, d)
        Piecewise-linear paths of one size, ``n`` segments each.
    metric : {"alpha", "fisher_rao"}
        The metric of eq. (22) or eq. (6).
    sigma2 : float
        σ² > 0 of eq. (5).
    grid_spacing, grid_margin : float
        The Fisher–Rao quadrature grid, as in :func:`shapelib.path_length`.
    device : {None, "cpu", "gpu"}
        JAX device (module docstring).

    Returns
    -------
    length, energy : ndarray (B,)
        Each path's length and discrete path energy, equal to the CPU code's to rounding.

    See Also
    --------
    shapelib.solver.geodesic.path_length : One path's length on the CPU.
    shapelib.solver.energy.path_energy : One path's energy on the CPU.
    batched_geodesics : Geodesics of many pairs.

    Notes
    -----
    The length is that of the paper's infinitesimal element, eq. (8) of [1]_, along the path; the quadrature
    runs in JAX [2]_.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] J. Bradbury, R. Frostig, P. Hawkins, M. J. Johnson, C. Leary, D. Maclaurin, G. Necula, A. Paszke,
       J. VanderPlas, S. Wanderman-Milne and Q. Zhang, "JAX: composable transformations of Python+NumPy
       programs", 2018, https://github.com/jax-ml/jax.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.batched import batched_lengths
    >>> from shapelib import path_length
    >>> u = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.5]]); v = u + [0.3, -0.2]
    >>> paths = np.linspace(u, v, 5)[None]
    >>> length, energy = batched_lengths(paths, metric="fisher_rao", sigma2=0.5, device="cpu")
    >>> bool(np.isclose(length[0], path_length(paths[0], metric="fisher_rao", sigma2=0.5), rtol=1e-10))
    True
    """
    paths = np.asarray(paths, dtype=np.float64)
    b = len(paths)
    nodes, weights = _cpu_grids(paths, metric, sigma2, grid_spacing, grid_margin)
    pad = bucket(b) - b
    if pad:
        paths, nodes, weights = (np.concatenate([a, np.repeat(a[:1], pad, axis=0)]) for a in (paths, nodes, weights))
    with _on(device):
        length, energy = _compiled_length(metric)(paths, float(sigma2), nodes, weights)
        return np.asarray(length)[:b], np.asarray(energy)[:b]


# -------------------------------------------------------------------------------------------------
# Batched geodesics
# -------------------------------------------------------------------------------------------------


def _entries_per_pair(metric, n, k, grid_size):
    """float64 entries of the largest arrays one pair's energy and gradient hold at once."""
    nodes = 3 * n
    return nodes * k * (grid_size if metric == "fisher_rao" else k) * 8


def _auto_batch(metric, n, k, grid_size, device):
    """Pairs per device call: the most pairs whose arrays (:func:`_entries_per_pair` entries of 8 bytes each)
    fit in 40 % of the memory the device reports (``memory_stats()["bytes_limit"]``), or in 2 GiB where JAX
    does not report it; at least 1, at most 1024."""
    budget = 2 * 2**30
    try:
        stats = jax_device(device).memory_stats() or {}
        if "bytes_limit" in stats:
            budget = 0.4 * stats["bytes_limit"]
    except Exception:  # noqa: BLE001 - memory_stats is optional per platform
        pass
    return int(max(1, min(1024, budget // (8 * _entries_per_pair(metric, n, k, grid_size)))))


def batched_geodesics(us, vs, *, metric: str = "alpha", sigma2, n_steps: int = 16, tol: float = 1e-6,
                      max_iter: int = 500, window: int = 5, init=None, grid_spacing: float = DEFAULT_SPACING,
                      grid_margin: float = DEFAULT_MARGIN, target_energy=None, lower_bounds=None,
                      device=None, batch_size: int | None = None, warn: bool = True):
    """Geodesics for many pairs ``(us[i], vs[i])`` at once with JAX: what :func:`shapelib.geodesic`
    with ``backend="jax"`` computes for one pair.

    Parameters
    ----------
    us, vs : array_like, shape (B, K, d)
        Start and end shapes (already validated: :func:`shapelib.geodesic` checks each pair).
    metric, sigma2, n_steps, tol, max_iter, window, grid_spacing, grid_margin
        As in :func:`shapelib.geodesic`; ``max_iter`` counts L-BFGS iterations.
    init : array_like, shape (B, n_steps + 1, K, d), optional
        Starting paths (default: straight lines).
    target_energy : array_like (B,), optional
        Stop a pair as soon as its energy is at or below (the bracket's stop).
    lower_bounds : array_like (B,), optional
        The pairs' closed-form lower bounds if already known.
    device : {None, "cpu", "gpu"}
        JAX device (module docstring).
    batch_size : int, optional
        Pairs per device call; default: as many as fit in 40 % of the device's memory (2 GiB where JAX does
        not report it), estimated from the largest Fisher–Rao grid among the pairs, at most 1024.
    warn : bool
        One :class:`~shapelib.solver.result.GeodesicWarning` if any pair stopped before converging.

    Returns
    -------
    list of GeodesicResult
        As the CPU solver's, with ``n_iter`` counting L-BFGS iterations, ``log["hessian"] = None``,
        ``log["solver"] = "lbfgs"`` and ``log["device"]``; ``length`` is certified as on the CPU
        (the returned path's length by the CPU quadrature).

    See Also
    --------
    shapelib.solver.geodesic.geodesics : The checked public entry for many pairs.
    shapelib.solver.geodesic.geodesic : One pair.
    batched_lengths : Certified lengths of many paths.

    Notes
    -----
    Each pair's path minimises the discrete path energy of eq. (8) of [1]_; the minimiser is a limited-memory
    BFGS [2]_ with a backtracking (Armijo) line search, written in JAX [3]_ so that the whole batch iterates
    on the device.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., Springer, 2006.
    .. [3] J. Bradbury, R. Frostig, P. Hawkins, M. J. Johnson, C. Leary, D. Maclaurin, G. Necula, A. Paszke,
       J. VanderPlas, S. Wanderman-Milne and Q. Zhang, "JAX: composable transformations of Python+NumPy
       programs", 2018, https://github.com/jax-ml/jax.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.batched import batched_geodesics
    >>> u = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.5]])
    >>> vs = np.stack([u + [0.3, -0.2], u[[1, 2, 0]] * 0.9])
    >>> res = batched_geodesics(np.stack([u, u]), vs, metric="alpha", sigma2=0.5, n_steps=8, device="cpu")
    >>> [bool(r.lower_bound <= r.length) for r in res]
    [True, True]
    """
    t0 = time.perf_counter()
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}; got {metric!r}")
    us, vs = as_pair_batch(us, vs)
    b, k, d = us.shape
    n = check_positive_int(n_steps, name="n_steps")
    tol = check_positive(tol, name="tol")
    max_iter = check_nonnegative_int(max_iter, name="max_iter")
    window = check_positive_int(window, name="window")
    s2 = float(sigma2)
    model = path_metric(metric, s2, grid_spacing=grid_spacing, grid_margin=grid_margin)
    if init is None:
        t = np.linspace(0.0, 1.0, n + 1)[None, :, None, None]
        paths = (1 - t) * us[:, None] + t * vs[:, None]
    else:
        paths = np.array(init, dtype=np.float64)
        if paths.shape != (b, n + 1, k, d):
            raise ValueError(f"init must have shape {(b, n + 1, k, d)}; got {paths.shape}")
        if not np.all(np.isfinite(paths)):
            raise ValueError("init contains non-finite values")
        paths[:, 0], paths[:, -1] = us, vs
    target = None if target_energy is None else np.broadcast_to(np.asarray(target_energy, float), (b,))
    lower = (np.array([model.lower_bound(u, v) for u, v in zip(us, vs)]) if lower_bounds is None
             else np.asarray(lower_bounds, float))
    trivial = np.array([n == 1 or np.array_equal(u, v) for u, v in zip(us, vs)])
    dev_name = str(jax_device(device))
    out = {"path": paths.copy(), "energy": np.zeros(b), "grad_norm": np.zeros(b), "n_iter": np.zeros(b, int),
           "stopped_by": [StopReason.TRIVIAL] * b, "energies": [None] * b, "rel_change": np.zeros(b),
           "regrids": np.zeros(b, int)}
    todo = np.flatnonzero(~trivial)
    if metric == "fisher_rao" and len(todo) > 1:  # device batches of similar grid sizes: little padding
        sizes = [np.prod([len(ax) for ax in _solve_grid(paths[i], s2, grid_spacing, grid_margin).axes]) for i in todo]
        todo = todo[np.argsort(sizes, kind="stable")]
    if batch_size is None:
        size = 1 if metric == "alpha" else len(_solve_grid(paths[todo[-1]], s2, grid_spacing, grid_margin).nodes) \
            if len(todo) else 1
        batch_size = _auto_batch(metric, n, k, size, device)
    batch_size = check_positive_int(batch_size, name="batch_size")
    for start in range(0, len(todo), batch_size):
        idx = todo[start:start + batch_size]
        cur = paths[idx]
        grids = None
        for round_ in range(MAX_REGRIDS + 1):
            if metric == "fisher_rao":
                grids = [_solve_grid(p, s2, grid_spacing, grid_margin) for p in cur]
                nodes, weights = stack_grids(grids, d)
            else:
                nodes = weights = None
            r = lbfgs_solve(cur, metric=metric, sigma2=s2, nodes=nodes, weights=weights, tol=tol, max_iter=max_iter,
                            window=window, target_energy=None if target is None else target[idx], device=device)
            for j, i in enumerate(idx):
                prev = out["energies"][i]
                trace = r["energies"][j][: r["n_iter"][j] + 1]
                out["energies"][i] = list(trace) if prev is None else prev + list(trace[1:])
                out["n_iter"][i] += r["n_iter"][j]
                out["grad_norm"][i] = r["grad_norm"][j]
                out["stopped_by"][i] = r["stopped_by"][j]
                out["rel_change"][i] = r["rel_change"][j]
                out["path"][i] = r["path"][j]
            if metric == "alpha":
                break
            left = [j for j, p in enumerate(r["path"]) if not _covers(grids[j], p, s2, grid_spacing, grid_margin)]
            if not left or round_ == MAX_REGRIDS:
                break
            out["regrids"][idx[left]] += 1
            idx, cur = idx[left], r["path"][left]  # again from where it stopped, on a grid around it
    length, energy = np.zeros(b), np.zeros(b)
    if len(todo):
        length[todo], energy[todo] = batched_lengths(out["path"][todo], metric=metric, sigma2=s2,
                                                     grid_spacing=grid_spacing, grid_margin=grid_margin, device=device)
    seconds = time.perf_counter() - t0
    results = []
    for i in range(b):
        path = out["path"][i]
        stop = out["stopped_by"][i]
        if trivial[i]:
            length[i] = batched_lengths(path[None], metric=metric, sigma2=s2, grid_spacing=grid_spacing,
                                        grid_margin=grid_margin, device=device)[0][0] if n == 1 else 0.0
            energy[i] = length[i] ** 2
        steps = np.linalg.norm(np.diff(path, axis=0), axis=2)
        results.append(GeodesicResult(
            path=path, length=float(length[i]), energy=float(energy[i]), lower_bound=float(lower[i]),
            converged=stop.converged, n_iter=int(out["n_iter"][i]),
            grad_norm=0.0 if trivial[i] else float(out["grad_norm"][i]),
            rel_energy_change=float(out["rel_change"][i]), max_step_over_sigma=float(steps.max() / np.sqrt(s2)),
            metric=metric, sigma2=s2,
            log={"energy": [float(e) for e in (out["energies"][i] or [energy[i]])], "damping": [], "hessian": None,
                 "stopped_by": stop.value, "newton_decrement": None, "seconds": seconds / b, "n_steps": n, "tol": tol,
                 "solver": "lbfgs", "backend": "jax", "device": dev_name, "regrids": int(out["regrids"][i]),
                 **model.settings()}))
    failed = sum(not r.converged for r in results)
    if failed and warn:
        worst = next(r for r in results if not r.converged)
        warnings.warn(f"{metric} geodesic did not converge for {failed} of {b} pairs in {max_iter} L-BFGS iterations "
                      f"(first: {worst.summary()})", GeodesicWarning, stacklevel=2)
    return results
