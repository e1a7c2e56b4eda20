"""The discrete path energy (eq. 8 on piecewise-linear paths), its gradient and Hessian, and
the length of a path — for any :class:`~shapelib.solver.path_metric.PathMetric`.

On each of the ``n`` segments the landmarks move at constant velocity and the energy is
integrated in time with a 3-point Gauss–Legendre rule::

    E_n = Σ_t (1/n) Σ_k w_k  V_tᵀ g(θ_t + τ_k Δ_t) V_t,     Δ_t = θ_{t+1} − θ_t,  V_t = n Δ_t.

The Hessian over the interior points is block tridiagonal: ``(diag, upper)`` with blocks
``H[t, t]`` (n-1, q, q) and ``H[t, t+1]`` (n-2, q, q), q = K d.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .path_metric import GL3_NODES, GL3_WEIGHTS, GL5_NODES, GL5_WEIGHTS

__all__ = ["segment_nodes", "path_energy", "path_hessian_weights", "exact_path_hessian", "metric_length"]


def segment_nodes(path, nodes):
    """Positions at the quadrature nodes of every segment (n, q, K, d) and velocities (n, K, d)."""
    n = len(path) - 1
    seg = np.diff(path, axis=0)
    return path[:-1, None] + nodes[None, :, None, None] * seg[:, None], n * seg


def path_energy(model, path, *, gradient=True, hessian=None):
    """Energy of the piecewise-linear path, its gradient (interior points) and a Hessian.

    ``hessian`` is ``None``, ``"model"`` (metric-weighted time Laplacian, Gauss–Newton-like) or
    ``"exact"`` (needs ``model.has_exact_hessian``). It is returned as ``(diag, upper)``: blocks
    ``H[t, t]`` (n-1, q, q) and ``H[t, t+1]`` (n-2, q, q), q = K d.
    """
    n = len(path) - 1
    k, d = path.shape[1:]
    nq = len(GL3_NODES)
    ctx = model.prepare(path)
    node_hessian, blocks = None, None
    if hessian == "exact" and gradient and model.has_path_pass:  # α: one compiled pass
        q, dq_t, dq_v, blocks = model.path_grad_hessian(path, ctx)
    else:
        theta, vel = segment_nodes(path, GL3_NODES)
        flat_t = theta.reshape(-1, k, d)
        flat_v = np.repeat(vel, nq, axis=0)
        if not gradient:
            q = model.qform(flat_t, flat_v, ctx).reshape(n, nq)
            return float(np.sum(q * GL3_WEIGHTS) / n), None, None
        if hessian == "exact":  # one call, which may share work between the two
            q, dq_t, dq_v, node_hessian = model.qform_grad_hessian(flat_t, flat_v, ctx)
        else:
            q, dq_t, dq_v = model.qform_grad(flat_t, flat_v, ctx)
    energy = float(np.sum(q.reshape(n, nq) * GL3_WEIGHTS) / n)
    w = GL3_WEIGHTS[None, :, None, None]
    tau = GL3_NODES[None, :, None, None]
    dq_t = dq_t.reshape(n, nq, k, d) * w
    dq_v = dq_v.reshape(n, nq, k, d) * w
    # θ_t enters segment t through the position (weight 1 − τ) and the velocity (−n);
    # θ_{t+1} through the position (τ) and the velocity (+n)
    g_left = (np.sum((1 - tau) * dq_t, axis=1) - n * np.sum(dq_v, axis=1)) / n
    g_right = (np.sum(tau * dq_t, axis=1) + n * np.sum(dq_v, axis=1)) / n
    grad = g_left[1:] + g_right[:-1]
    if hessian == "model":
        gbar = model.tensors(path[:-1] + 0.5 * np.diff(path, axis=0), ctx)
        blocks = (2 * n * (gbar[:-1] + gbar[1:]), -2 * n * gbar[1:-1])
    elif hessian == "exact":
        if blocks is None:
            blocks = exact_path_hessian(model, flat_t, flat_v, ctx, n, node_hessian)
    elif hessian is not None:
        raise ValueError(f"unknown hessian {hessian!r}")
    return energy, grad, blocks


@lru_cache(maxsize=64)
def path_hessian_weights(n):
    """``coef[x, k] = (k_a, k_b, k_bᵀ, k_c)·w_k/n``: the weights of ``(Q_θθ, Q_θv, Q_θvᵀ, Q_vv)`` at
    Gauss–Legendre node k in the segment blocks x = (t, t), (t, t+1), (t+1, t+1).

    On segment t, ``∂/∂θ_t = (1 − τ) ∂_θ − n ∂_v`` and ``∂/∂θ_{t+1} = τ ∂_θ + n ∂_v``.
    """
    tau, w = GL3_NODES, GL3_WEIGHTS / n
    coef = np.stack([
        np.stack([(1 - tau) ** 2, -(1 - tau) * n, -(1 - tau) * n, np.full_like(tau, n * n)], axis=1),
        np.stack([(1 - tau) * tau, (1 - tau) * n, -tau * n, np.full_like(tau, -n * n)], axis=1),
        np.stack([tau**2, tau * n, tau * n, np.full_like(tau, n * n)], axis=1),
    ]) * w[None, :, None]
    coef.setflags(write=False)
    return coef


def exact_path_hessian(model, theta, vel, ctx, n, node_hessian=None):
    """Exact Hessian of the piecewise-linear path energy from the Hessian of ``Q = vᵀg(θ)v``.

    Returns ``(diag, upper)`` as :func:`path_energy`; the segment blocks are combined with the
    weights of :func:`path_hessian_weights` (models with a compiled ``path_grad_hessian`` do the
    same in one pass). ``node_hessian``: ``model.qform_hessian(theta, vel, ctx)`` if already computed.
    """
    if node_hessian is None:
        node_hessian = model.qform_hessian(theta, vel, ctx)
    a, b, c = (x.reshape(n, len(GL3_NODES), *x.shape[1:]) for x in node_hessian)
    bt = b.transpose(0, 1, 3, 2)
    coef = path_hessian_weights(n)
    h00, h01, h11 = (np.einsum("k,tkij->tij", cx[:, 0], a) + np.einsum("k,tkij->tij", cx[:, 1], b)
                     + np.einsum("k,tkij->tij", cx[:, 2], bt) + np.einsum("k,tkij->tij", cx[:, 3], c) for cx in coef)
    return h11[:-1] + h00[1:], h01[1:-1]



def metric_length(model, path):
    """``∫ √(θ̇ᵀgθ̇) dt`` of the piecewise-linear path, 5-point Gauss–Legendre on each segment."""
    n = len(path) - 1
    k, d = path.shape[1:]
    theta, vel = segment_nodes(path, GL5_NODES)
    q = model.qform(theta.reshape(-1, k, d), np.repeat(vel, len(GL5_NODES), axis=0), model.prepare(path))
    return float(np.sum(np.sqrt(np.maximum(q, 0.0)).reshape(n, -1) * GL5_WEIGHTS) / n)
