"""The discrete path energy of the α-order (eq. 22) and Fisher–Rao (eq. 6) metrics in JAX: one
implementation of each formula for the accelerator, beside the compiled CPU kernels
(:mod:`shapelib.geometry._kernels`), with gradients by ``jax.grad`` and batches by ``jax.vmap``.

The discretisation is the CPU solver's (:mod:`shapelib.solver.energy`): a piecewise-linear path
through ``n + 1`` points, on each segment the landmarks move at constant velocity ``V_t = n Δ_t``
and the energy is integrated in time with the 3-point Gauss–Legendre rule,

    E_n = Σ_t (1/n) Σ_k w_k  Q(θ_t + τ_k Δ_t, V_t),     Q(θ, V) = Vᵀ g(θ) V.

α-order (eq. 22), closed form (:mod:`shapelib.geometry.metrics`)::

    Q = Σ_ab c_ab [V_a·V_b/(2σ²) − (Δ_ab·V_a)(Δ_ab·V_b)/(4σ⁴)],
    c_ab = exp(−|Δ_ab|²/4σ²) / ((4πσ²)^{d/2} K²),   Δ_ab = φ_a − φ_b.

Fisher–Rao (eq. 6), by the trapezoid rule on the grid of :mod:`shapelib.geometry.quadrature`::

    Q = ∫ (∂_t ψ)² dx ≈ Σ_m w_m ψ̇(x_m)²,   ψ = 2√p,   ψ̇ = Σ_a coef_a (r_a·V_a),
    coef_a = N_a / (K σ² √p),   r_a = x − φ_a,

with ``w_m`` the grid's weight ``h^d`` at every node (0 at padding nodes, so grids of different
sizes share one batch). ``coef`` is evaluated in log space (``log p`` by log-sum-exp), so nodes far
from every landmark give 0, never 0/0 (the CPU kernels floor ψ at
:data:`shapelib.geometry._kernels.PSI_FLOOR` for the same reason).

Everything here runs in float64: the public functions are called inside :func:`x64`, which enables
JAX's 64-bit mode for shapelib's calls only. JAX is imported on first use (``import shapelib``
never imports it); without it :func:`require_jax` raises an ``ImportError`` naming the extra.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util

import numpy as np

__all__ = ["require_jax", "x64", "alpha_qform", "fisher_rao_qform", "path_energy", "batched_energy",
           "batched_value_and_grad", "GL3_NODES", "GL3_WEIGHTS", "INSTALL_HINT"]

INSTALL_HINT = 'pip install "shapelib[gpu]" (CUDA 12 GPUs) or pip install "shapelib[jax]" (CPU)'

_x, _w = np.polynomial.legendre.leggauss(3)
#: the 3-point Gauss–Legendre rule on [0, 1] of :mod:`shapelib.solver.path_metric`
GL3_NODES, GL3_WEIGHTS = 0.5 * (_x + 1.0), 0.5 * _w


def jax_available() -> bool:
    """Whether JAX can be imported (without importing it)."""
    return importlib.util.find_spec("jax") is not None


def require_jax():
    """Import and return ``jax``; ``ImportError`` with the install command when it is missing."""
    try:
        import jax
    except ImportError:
        raise ImportError(f'backend="jax" needs JAX, which is not installed: {INSTALL_HINT}') from None
    return jax


@contextlib.contextmanager
def x64():
    """Enable JAX's 64-bit mode inside the block only (shapelib computes in float64)."""
    jax = require_jax()
    try:
        manager = jax.enable_x64(True)
    except (AttributeError, TypeError):  # JAX < 0.7: the experimental context manager
        from jax.experimental import enable_x64
        manager = enable_x64()
    with manager:
        yield jax


# -------------------------------------------------------------------------------------------------
# The quadratic forms Q(θ, V) = Vᵀ g(θ) V for one shape (K, d)
# -------------------------------------------------------------------------------------------------


def alpha_qform(theta, vel, s2):
    """``Vᵀ g_α(θ) V`` (eq. 22) for one shape ``theta`` (K, d) moving with ``vel`` (K, d)."""
    import jax.numpy as jnp
    k, d = theta.shape
    # one coordinate at a time: (K, K) arrays, no small batched matrix products (3x faster on a CPU)
    delta = [theta[:, None, i] - theta[None, :, i] for i in range(d)]
    c = jnp.exp(-sum(x * x for x in delta) / (4 * s2)) / ((4 * np.pi * s2) ** (d / 2) * k * k)
    dva = sum(delta[i] * vel[:, None, i] for i in range(d))
    dvb = sum(delta[i] * vel[None, :, i] for i in range(d))
    vv = sum(vel[:, None, i] * vel[None, :, i] for i in range(d))
    return jnp.sum(c * (vv / (2 * s2) - dva * dvb / (4 * s2 * s2)))


def fisher_rao_qform(theta, vel, s2, nodes, weights):
    """``Vᵀ g_FR(θ) V = ∫ ψ̇²`` (eq. 6) on the grid ``nodes`` (M, d) with per-node ``weights`` (M,)."""
    import jax.numpy as jnp
    from jax.scipy.special import logsumexp
    k, d = theta.shape
    # −|x − φ_a|² / 2σ², one coordinate at a time (no (M, K, d) temporary)
    expo = -sum((nodes[:, i, None] - theta[None, :, i]) ** 2 for i in range(d)) / (2 * s2)  # (M, K)
    log_norm = -0.5 * d * jnp.log(2 * np.pi * s2)
    lse = logsumexp(expo, axis=1)  # log Σ_a exp(expo): log p = lse + log_norm − log K
    # coef_a = N_a / (K σ² √p) = exp(expo_a + log_norm − ½ log p) / (K σ²)
    coef = jnp.exp(expo - 0.5 * lse[:, None] + 0.5 * (log_norm + np.log(k))) / (k * s2)
    rv = sum((nodes[:, i, None] - theta[None, :, i]) * vel[None, :, i] for i in range(d))  # r_a·V_a (M, K)
    psidot = jnp.sum(coef * rv, axis=1)
    return jnp.sum(weights * psidot * psidot)


# -------------------------------------------------------------------------------------------------
# The path energy of one pair, and its batches
# -------------------------------------------------------------------------------------------------


def _segment_nodes(path):
    """Positions at the Gauss–Legendre nodes (n, 3, K, d) and velocities (n, K, d)."""
    n = path.shape[0] - 1
    seg = path[1:] - path[:-1]
    return path[:-1, None] + GL3_NODES[None, :, None, None] * seg[:, None], n * seg


def path_energy(path, s2, nodes=None, weights=None, *, metric):
    """``E_n`` of one piecewise-linear path ``path`` (n + 1, K, d) (module docstring); ``nodes`` and
    ``weights``: the Fisher–Rao grid (ignored for α)."""
    import jax
    import jax.numpy as jnp
    n = path.shape[0] - 1
    theta, vel = _segment_nodes(path)
    if metric == "alpha":
        q = jax.vmap(lambda th, v: jax.vmap(lambda t: alpha_qform(t, v, s2))(th))(theta, vel)
    elif metric == "fisher_rao":
        q = jax.vmap(lambda th, v: jax.vmap(lambda t: fisher_rao_qform(t, v, s2, nodes, weights))(th))(theta, vel)
    else:
        raise ValueError(f"metric must be 'alpha' or 'fisher_rao'; got {metric!r}")
    return jnp.sum(q * GL3_WEIGHTS[None, :]) / n


def _interior_energy(x, ends, s2, nodes, weights, metric):
    """Energy as a function of the interior points ``x`` (n − 1, K, d), ends (2, K, d) fixed."""
    import jax.numpy as jnp
    path = jnp.concatenate([ends[:1], x, ends[1:]], axis=0)
    return path_energy(path, s2, nodes, weights, metric=metric)


@functools.lru_cache(maxsize=None)
def _compiled(metric: str, what: str):
    """jit-compiled, vmapped energy (``what="value"``) or energy and gradient (``"value_and_grad"``)
    over a batch of pairs: ``f(x (B, n−1, K, d), ends (B, 2, K, d), s2, nodes (B, M, d), weights (B, M))``."""
    import jax
    one = functools.partial(_interior_energy, metric=metric)
    if what == "value_and_grad":
        one = jax.value_and_grad(one)
    return jax.jit(jax.vmap(one, in_axes=(0, 0, None, 0, 0)))


def _dummy_grid(batch):
    return np.zeros((batch, 1, 1)), np.zeros((batch, 1))


def _path_args(paths, s2, nodes, weights):
    """The compiled energy's arguments for a batch of paths: interiors, ends, σ², grid (a dummy one for α)."""
    paths = np.asarray(paths, dtype=np.float64)
    if nodes is None:
        nodes, weights = _dummy_grid(len(paths))
    return paths[:, 1:-1], paths[:, [0, -1]], float(s2), nodes, weights


def batched_energy(paths, s2, nodes=None, weights=None, *, metric):
    """``E_n`` of a batch of paths (B, n + 1, K, d) as a numpy array (B,).

    ``nodes`` (B, M, d) and ``weights`` (B, M): each pair's Fisher–Rao grid, padded to a common M
    with zero weights (:func:`shapelib.solver.batched.stack_grids`); ignored for α.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry._jax_kernels import batched_energy
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0]]); v = u + [0.0, 0.5]
    >>> path = np.linspace(u, v, 5)[None]
    >>> e = batched_energy(path, 0.5, metric="alpha")
    >>> e.shape
    (1,)
    """
    with x64():
        return np.asarray(_compiled(metric, "value")(*_path_args(paths, s2, nodes, weights)))


def batched_value_and_grad(paths, s2, nodes=None, weights=None, *, metric):
    """``(E_n (B,), ∂E_n/∂interior (B, n − 1, K, d))`` of a batch of paths, by ``jax.grad``; as
    :func:`batched_energy`."""
    with x64():
        e, g = _compiled(metric, "value_and_grad")(*_path_args(paths, s2, nodes, weights))
        return np.asarray(e), np.asarray(g)
