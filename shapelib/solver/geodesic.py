"""Geodesics between GMM shapes (paper eqs. 8–12) with certified lengths.

The paper minimises the path energy ``s = ∫₀¹ g_ij θ̇^i θ̇^j dt`` (eq. 8) between two landmark
shapes by gradient descent on the Euler–Lagrange equations (eqs. 10–12). We minimise the same
energy over **piecewise-linear paths** through ``n + 1`` points (ends fixed): on each segment
the landmarks move at constant velocity and the energy is integrated in time with a 3-point
Gauss–Legendre rule,

    E_n = Σ_t (1/n) Σ_k w_k  V_tᵀ g(θ_t + τ_k Δ_t) V_t,     Δ_t = θ_{t+1} − θ_t,  V_t = n Δ_t.

This is the energy of an actual path, so ``E_n ≥ length² ≥ d(u, v)² ≥ lower_bound²``: the
optimiser cannot exploit the discretisation the way it can a midpoint rule with few steps
(which lets two landmarks cross at the one instant where the metric is evaluated). As ``n``
grows the minimum decreases to the squared geodesic distance.

Both metrics are pull-backs of the flat L² metric, which gives lower bounds:

* α-order (eq. 22): ``θ̇ᵀgθ̇ = ‖∂_t p‖²``, so ``d(u, v) ≥ ‖p_u − p_v‖`` (closed form);
* Fisher–Rao (eq. 6): ``θ̇ᵀgθ̇ = ‖∂_t (2√p)‖²`` and ``2√p`` lies on the sphere of radius 2,
  so ``d(u, v) ≥ 2 arccos ∫ √(p_u p_v) dx``.

The reported ``length`` (``∫ √(θ̇ᵀgθ̇) dt`` of the computed path, 5-point Gauss–Legendre) is an
upper bound on the geodesic distance: ``lower_bound ≤ d(u, v) ≤ length``.

Solver: Levenberg–Marquardt (a trust-region Newton method) on a block-tridiagonal Hessian,
factorised by block Cholesky in O(n (Kd)³):

* by default the **exact** Hessian of the path energy, assembled from the second derivatives
  of ``Q = vᵀg(θ)v`` — in closed form for α (:func:`shapelib.geometry.metrics.alpha_qform_hessian`, run
  as one compiled pass over the path, with the gradient, by
  :func:`shapelib.geometry._kernels.alpha_path_grad_hessian`),
  by the same quadrature as the metric for Fisher–Rao (:func:`shapelib.geometry.metrics._fr_qform_hessian`).
  Where it is positive definite the Newton decrement ``½ gᵀH⁻¹g`` estimates the energy still
  to be gained; the solver stops when it falls below ``tol · E`` (``log["stopped_by"] ==
  "newton_decrement"``), which certifies a local minimum, or when the relative energy decrease
  over ``window`` iterations falls below ``tol``.
* ``hessian="model"`` (and always for landmark diffeomorphisms): the model Hessian obtained by
  freezing the metric at each segment's midpoint, ``2n [[ḡ_t, −ḡ_t], [−ḡ_t, ḡ_t]]`` per
  segment (a metric-weighted Laplacian in time), with the energy-window stop only. For
  Fisher–Rao it is 4× cheaper per iteration but converges linearly: on the benchmark pair it
  stops at tol 1e-6 with an energy 2.6e-5 above the minimum and does not reach 1e-9 in 3,000
  iterations, where the exact Hessian certifies 1e-9 in 133.

Gradients are analytic vector–Jacobian products through the densities
(:mod:`shapelib.geometry.metrics`); no Christoffel symbols are needed.

Why it takes tens to hundreds of iterations (measured, ``benchmarks/bench_geodesic.py``): the
energy is strongly non-convex around the straight-line start — for the corpus callosum pair
1–2 at σ² = 0.5 the exact Hessian has 213 negative eigenvalues out of 378 at ``n = 4`` (down
to −0.5 % of the largest), and the path must then slide the landmarks along the contour, a
valley whose curvature is ~1e-7 of the largest. Different starts end in different local
minima whose energies differ by ~1e-5 (relative): far below the time-discretisation error
(``energy − lower_bound²`` ≈ 5e-4 relative at ``n = 16``) and irrelevant at the study's 1 %
level, but a reason to read ``tol`` as a local-convergence criterion only. It is the landscape,
not this solver: SciPy's ``trust-exact``, saddle-free Newton and coarse-to-fine in ``n`` all need
200–280 iterations to the same certificate at ``tol = 1e-9`` (``benchmarks/bench_solvers.py``).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.linalg.blas import dsyrk, dtrsm, dtrsv
from scipy.linalg.lapack import dpotrf
from threadpoolctl import ThreadpoolController

from ..geometry import _kernels
from .._validate import (as_shape_pair, check_dimension, check_nonnegative_int, check_positive, check_positive_int,
                        check_sigma2, set_was_checked)
from ..geometry.procrustes import check_pose
from ..geometry.scale import SIGMA_RATIO_MIN, check_fisher_rao_scale, check_scale
from ..geometry.gmm import l2_distance
from ..geometry.metrics import (
    alpha_qform_hessian,
    alpha_tensor_batch,
    fr_qform_compiled,
    fr_qform_grad_compiled,
    fr_qform_grad_hessian_compiled,
    fr_qform_hessian_compiled,
    fr_tensor_batch,
    psi_coef,
)
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING, make_grid

__all__ = ["geodesic", "minimise_path", "shoot", "geodesic_acceleration", "GeodesicResult", "GeodesicWarning", "fisher_rao_lower_bound", "alpha_lower_bound", "path_length"]

METRICS = ("alpha", "fisher_rao")


def _gauss_legendre01(q):
    x, w = np.polynomial.legendre.leggauss(q)
    return 0.5 * (x + 1.0), 0.5 * w


_GL3_NODES, _GL3_WEIGHTS = _gauss_legendre01(3)  # energy
_GL5_NODES, _GL5_WEIGHTS = _gauss_legendre01(5)  # reported length


class GeodesicWarning(RuntimeWarning):
    """The geodesic solver stopped before meeting its tolerance."""


@dataclass
class GeodesicResult:
    """A computed geodesic and its certificate.

    Attributes
    ----------
    path : ndarray, shape (n_steps + 1, K, d)
        Landmarks at times ``t = 0, 1/n, …, 1``; ``path[0]`` and ``path[-1]`` are the inputs.
        The intermediate shapes are the intrinsic deformation (Figs. 4–8).
    length : float
        Riemannian length ``∫ √(θ̇ᵀ g θ̇) dt`` of the piecewise-linear path (an upper bound on
        the geodesic distance).
    energy : float
        Path energy (eq. 8) of the piecewise-linear path, 3-point Gauss–Legendre per segment
        (≥ length² ≥ lower_bound²; ≈ length² for a converged, constant-speed geodesic).
    lower_bound : float
        Closed-form (α) or great-circle (Fisher–Rao) lower bound on the geodesic distance.
    converged : bool
    n_iter : int
        Levenberg–Marquardt iterations.
    grad_norm : float or None
        Euclidean norm of the energy gradient at the solution; None when the solve stopped on
        ``target_energy`` (the start or the last step met it), where the gradient at the final
        path is not evaluated.
    rel_energy_change : float
        Relative energy decrease of the last accepted step.
    max_step_over_sigma : float
        Largest landmark displacement between consecutive path points, in units of σ (of the
        kernel width for landmark diffeomorphisms).
    log : dict
        Energy per iteration, damping, timings, the metric's settings; ``hessian`` ("exact"
        or "model"), ``stopped_by`` ("newton_decrement", "energy_window", "no_decrease",
        "max_iter", "target_energy", "trivial", or "underflow" — not converged, with the
        ``reason`` — when σ is so small that the landmarks' Gaussians do not interact) and the
        last ``newton_decrement`` (exact Hessian only, None where it was not positive definite,
        or not computed because the damped decrement, a lower bound on it, was already above
        ``tol · E``).
    """

    path: np.ndarray
    length: float
    energy: float
    lower_bound: float
    converged: bool
    n_iter: int
    grad_norm: float | None
    rel_energy_change: float
    max_step_over_sigma: float
    metric: str
    sigma2: float | None
    log: dict = field(default_factory=dict, repr=False)

    @property
    def n_steps(self) -> int:
        return len(self.path) - 1

    @property
    def times(self) -> np.ndarray:
        return np.linspace(0.0, 1.0, len(self.path))

    @property
    def velocities(self) -> np.ndarray:
        """Landmark velocities on each segment, shape (n_steps, K, d)."""
        return self.n_steps * np.diff(self.path, axis=0)

    def summary(self) -> str:
        """One line: metric, length with its certified lower bound, convergence."""
        return (f"{self.metric}: length {self.length:.6g} (lower bound {self.lower_bound:.6g}), "
                f"converged {self.converged} in {self.n_iter} iterations")

    def shape_at(self, t: float) -> np.ndarray:
        """Landmarks at time ``t ∈ [0, 1]`` (linear between path points)."""
        if not 0.0 <= t <= 1.0:
            raise ValueError(f"t must lie in [0, 1]; got {t!r}")
        s = t * self.n_steps
        i = min(int(np.floor(s)), self.n_steps - 1)
        return self.path[i] + (s - i) * (self.path[i + 1] - self.path[i])


# ---------------------------------------------------------------------------------------------
# The two metrics as the solver sees them: Q = vᵀ g(θ) v with gradients, tensors, lower bound
# ---------------------------------------------------------------------------------------------


class _AlphaModel:
    name = "alpha"

    def __init__(self, s2: float):
        self.s2 = s2

    def prepare(self, points):
        return None

    def qform_grad(self, theta, vel, ctx):
        return _kernels.alpha_qform_grad(np.ascontiguousarray(theta), np.ascontiguousarray(vel), self.s2)

    def qform(self, theta, vel, ctx):
        return _kernels.alpha_qform(np.ascontiguousarray(theta), np.ascontiguousarray(vel), self.s2)

    def tensors(self, theta, ctx):
        return alpha_tensor_batch(theta, self.s2)

    def qform_hessian(self, theta, vel, ctx):
        return alpha_qform_hessian(theta, vel, self.s2)

    def path_grad_hessian(self, path, ctx):
        """``qform_grad`` at the segments' Gauss–Legendre nodes and :func:`_exact_path_hessian`, in
        one compiled pass (:func:`shapelib.geometry._kernels.alpha_path_grad_hessian`)."""
        n = len(path) - 1
        q = path[0].size
        tau, w = _GL3_NODES, _GL3_WEIGHTS
        tw = np.stack([w * (1 - tau) ** 2 / n, w * (1 - tau) * tau / n, w * tau**2 / n, w * (1 - tau), w * tau, w * n])
        qf, d_theta, d_vel, diag, upper = _kernels.alpha_path_grad_hessian(
            np.ascontiguousarray(path), self.s2, tau, tw, np.array([1.0, -1.0, 1.0]))
        return qf, d_theta, d_vel, (diag.reshape(-1, q, q), upper.reshape(-1, q, q))

    def lower_bound(self, u, v):
        return l2_distance(u, v, self.s2)

    def settings(self):
        return {}


class _FisherRaoModel:
    name = "fisher_rao"

    def __init__(self, s2: float, spacing: float, margin: float):
        self.s2, self.spacing, self.margin = s2, spacing, margin

    def prepare(self, points):
        """One quadrature grid covering every shape the path passes through."""
        return make_grid(points, self.s2, spacing=self.spacing, margin=self.margin)

    def qform_grad(self, theta, vel, grid):
        return fr_qform_grad_compiled(theta, vel, self.s2, grid)

    def qform(self, theta, vel, grid):
        return fr_qform_compiled(theta, vel, self.s2, grid)

    def tensors(self, theta, grid):
        return fr_tensor_batch(theta, self.s2, grid)

    def qform_hessian(self, theta, vel, grid):
        return fr_qform_hessian_compiled(theta, vel, self.s2, grid)

    def qform_grad_hessian(self, theta, vel, grid):
        return fr_qform_grad_hessian_compiled(theta, vel, self.s2, grid)

    def lower_bound(self, u, v):
        grid = self.prepare(np.stack([u, v]))
        pu, _ = psi_coef(u, self.s2, grid)
        pv, _ = psi_coef(v, self.s2, grid)
        c = np.sqrt(grid.integrate((pu - pv) ** 2))
        # great circle on the sphere of radius 2: 4 arcsin(c/4) = 2 arccos ∫√(p_u p_v)
        return float(4.0 * np.arcsin(min(c / 4.0, 1.0)))

    def settings(self):
        return {"grid_spacing": self.spacing, "grid_margin": self.margin}


def _model(metric, s2, spacing, margin):
    if metric == "alpha":
        return _AlphaModel(s2)
    if metric == "fisher_rao":
        return _FisherRaoModel(s2, check_positive(spacing, name="grid_spacing"),
                               check_positive(margin, name="grid_margin"))
    raise ValueError(f"metric must be one of {METRICS}; got {metric!r}")


# ---------------------------------------------------------------------------------------------
# Path energy (eq. 8 on piecewise-linear paths), gradient, model Hessian
# ---------------------------------------------------------------------------------------------


def _segment_nodes(path, nodes):
    """Positions at the quadrature nodes of every segment (n, q, K, d) and velocities (n, K, d)."""
    n = len(path) - 1
    seg = np.diff(path, axis=0)
    return path[:-1, None] + nodes[None, :, None, None] * seg[:, None], n * seg


def _energy(model, path, *, gradient=True, hessian=None):
    """Energy of the piecewise-linear path, its gradient (interior points) and a Hessian.

    ``hessian`` is ``None``, ``"model"`` (metric-weighted time Laplacian, Gauss–Newton-like) or
    ``"exact"`` (needs ``model.qform_hessian``). It is returned as ``(diag, upper)``: blocks
    ``H[t, t]`` (n-1, q, q) and ``H[t, t+1]`` (n-2, q, q), q = K d.
    """
    n = len(path) - 1
    k, d = path.shape[1:]
    nq = len(_GL3_NODES)
    ctx = model.prepare(path)
    node_hessian, blocks = None, None
    if hessian == "exact" and gradient and hasattr(model, "path_grad_hessian"):  # α: one compiled pass
        q, dq_t, dq_v, blocks = model.path_grad_hessian(path, ctx)
    else:
        theta, vel = _segment_nodes(path, _GL3_NODES)
        flat_t = theta.reshape(-1, k, d)
        flat_v = np.repeat(vel, nq, axis=0)
        if not gradient:
            q = model.qform(flat_t, flat_v, ctx).reshape(n, nq)
            return float(np.sum(q * _GL3_WEIGHTS) / n), None, None
        if hessian == "exact" and hasattr(model, "qform_grad_hessian"):  # shares work between the two
            q, dq_t, dq_v, node_hessian = model.qform_grad_hessian(flat_t, flat_v, ctx)
        else:
            q, dq_t, dq_v = model.qform_grad(flat_t, flat_v, ctx)
    energy = float(np.sum(q.reshape(n, nq) * _GL3_WEIGHTS) / n)
    w = _GL3_WEIGHTS[None, :, None, None]
    tau = _GL3_NODES[None, :, None, None]
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
            blocks = _exact_path_hessian(model, flat_t, flat_v, ctx, n, node_hessian)
    elif hessian is not None:
        raise ValueError(f"unknown hessian {hessian!r}")
    return energy, grad, blocks


@lru_cache(maxsize=64)
def _path_hessian_weights(n):
    """``coef[x, k] = (k_a, k_b, k_bᵀ, k_c)·w_k/n``: the weights of ``(Q_θθ, Q_θv, Q_θvᵀ, Q_vv)`` at
    Gauss–Legendre node k in the segment blocks x = (t, t), (t, t+1), (t+1, t+1).

    On segment t, ``∂/∂θ_t = (1 − τ) ∂_θ − n ∂_v`` and ``∂/∂θ_{t+1} = τ ∂_θ + n ∂_v``.
    """
    tau, w = _GL3_NODES, _GL3_WEIGHTS / n
    coef = np.stack([
        np.stack([(1 - tau) ** 2, -(1 - tau) * n, -(1 - tau) * n, np.full_like(tau, n * n)], axis=1),
        np.stack([(1 - tau) * tau, (1 - tau) * n, -tau * n, np.full_like(tau, -n * n)], axis=1),
        np.stack([tau**2, tau * n, tau * n, np.full_like(tau, n * n)], axis=1),
    ]) * w[None, :, None]
    coef.setflags(write=False)
    return coef


def _exact_path_hessian(model, theta, vel, ctx, n, node_hessian=None):
    """Exact Hessian of the piecewise-linear path energy from the Hessian of ``Q = vᵀg(θ)v``.

    Returns ``(diag, upper)`` as :func:`_energy`; the segment blocks are combined with the
    weights of :func:`_path_hessian_weights` (models with a compiled ``path_grad_hessian`` do the
    same in one pass). ``node_hessian``: ``model.qform_hessian(theta, vel, ctx)`` if already computed.
    """
    if node_hessian is None:
        node_hessian = model.qform_hessian(theta, vel, ctx)
    a, b, c = (x.reshape(n, len(_GL3_NODES), *x.shape[1:]) for x in node_hessian)
    bt = b.transpose(0, 1, 3, 2)
    coef = _path_hessian_weights(n)
    h00, h01, h11 = (np.einsum("k,tkij->tij", cx[:, 0], a) + np.einsum("k,tkij->tij", cx[:, 1], b)
                     + np.einsum("k,tkij->tij", cx[:, 2], bt) + np.einsum("k,tkij->tij", cx[:, 3], c) for cx in coef)
    return h11[:-1] + h00[1:], h01[1:-1]


@lru_cache(maxsize=1)
def _blas_controller():
    return ThreadpoolController()


def one_blas_thread():
    """Context manager: BLAS/LAPACK on one thread for the solver's small dense blocks.

    The path Hessian is factorised block by block ((K d)² blocks, 126² for K = 63); with the
    default two OpenBLAS threads on this 2-core machine each small call pays thread hand-off
    costs (measured: block Cholesky for n = 16, K = 63 takes 115 ms with two threads, 5 ms
    with one).
    """
    return _blas_controller().limit(limits=1, user_api="blas")


def _block_cholesky(diag, upper, shift):
    """Cholesky factors of the block-tridiagonal ``H + shift·I`` (LinAlgError if not PD).

    ``H = L Lᵀ`` with lower-triangular diagonal blocks ``L_t`` and sub-diagonal blocks
    ``W_t = (L_t⁻¹ U_t)ᵀ``; O(n q³) instead of O(n q³ · 4) for a banded solver of width 2q.
    Straight LAPACK/BLAS calls (``potrf``, ``trsm``, and ``syrk`` for the Schur complement
    ``D_{t+1} − W_tᵀ W_t``, half a general product): the blocks are small (q = 126 for the
    corpus callosum), so the wrappers' checks were a large part of the cost. Stored: ``L_t``
    and ``W_tᵀ`` (as ``trsm`` returns it).
    """
    m, q, _ = diag.shape
    idx = np.arange(q)
    lows, subs = [], []
    if m == 0:
        return lows, subs
    block = np.array(diag[0], order="F")  # only the lower triangle is read and updated
    for t in range(m):
        if shift:
            block[idx, idx] += shift
        low, info = dpotrf(block, lower=1, clean=1, overwrite_a=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"block {t} of the shifted path Hessian is not positive definite")
        lows.append(low)
        if t < m - 1:
            wt = dtrsm(1.0, low, upper[t].T, side=1, lower=1, trans_a=1)  # W_tᵀ = U_tᵀ L_t⁻ᵀ
            subs.append(wt)
            block = dsyrk(-1.0, wt, beta=1.0, c=np.array(diag[t + 1], order="F"), lower=1, overwrite_c=1)
    return lows, subs


def _block_solve(factors, rhs):
    """Solve ``H x = rhs`` (rhs (m, q)) with the factors of :func:`_block_cholesky`."""
    lows, subs = factors
    m = len(lows)
    y = np.empty_like(rhs)
    for t in range(m):
        r = rhs[t] if t == 0 else rhs[t] - subs[t - 1] @ y[t - 1]
        y[t] = dtrsv(lows[t], r, lower=1)
    x = np.empty_like(rhs)
    for t in range(m - 1, -1, -1):
        r = y[t] if t == m - 1 else y[t] - subs[t].T @ x[t + 1]
        x[t] = dtrsv(lows[t], r, lower=1, trans=1)
    return x


def _hess_vec(diag, upper, x):
    hx = np.einsum("tij,tj->ti", diag, x)
    if len(upper):
        hx[:-1] += np.einsum("tij,tj->ti", upper, x[1:])
        hx[1:] += np.einsum("tji,tj->ti", upper, x[:-1])
    return hx


def path_length(path, *, metric: str = "alpha", sigma2, grid_spacing: float = DEFAULT_SPACING,
                grid_margin: float = DEFAULT_MARGIN) -> float:
    """Riemannian length ``∫ √(θ̇ᵀ g θ̇) dt`` of the piecewise-linear path through ``path``.

    Parameters
    ----------
    path : array_like, shape (n + 1, K, d)
    metric : {"alpha", "fisher_rao"}
    sigma2 : float
    """
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 3 or len(path) < 2:
        raise ValueError(f"path must have shape (n + 1, K, d) with n >= 1; got {path.shape}")
    if not np.all(np.isfinite(path)):
        raise ValueError("path contains non-finite values")
    return _length(_model(metric, check_sigma2(sigma2), grid_spacing, grid_margin), path)


def _length(model, path):
    """``∫ √(θ̇ᵀgθ̇) dt`` of the piecewise-linear path, 5-point Gauss–Legendre on each segment."""
    n = len(path) - 1
    k, d = path.shape[1:]
    theta, vel = _segment_nodes(path, _GL5_NODES)
    q = model.qform(theta.reshape(-1, k, d), np.repeat(vel, len(_GL5_NODES), axis=0), model.prepare(path))
    return float(np.sum(np.sqrt(np.maximum(q, 0.0)).reshape(n, -1) * _GL5_WEIGHTS) / n)


def fisher_rao_lower_bound(u, v, *, sigma2, grid_spacing: float = DEFAULT_SPACING,
                           grid_margin: float = DEFAULT_MARGIN) -> float:
    """Great-circle lower bound ``2 arccos ∫ √(p_u p_v) dx`` on the Fisher–Rao geodesic distance.

    ``2√p`` lies on the sphere of radius 2 in L² and the Fisher–Rao metric is the pull-back of
    L² by ``θ ↦ 2√p``, so no path of GMMs is shorter than the great circle. Computed stably as
    ``4 arcsin(‖√p_u − √p_v‖ / 2)`` by quadrature.

    Checked at entry as :func:`geodesic` is: landmark dimension, σ against the landmarks' scale
    (:class:`~shapelib.geometry.scale.ScaleWarning`) and their pose
    (:class:`~shapelib.geometry.procrustes.PoseWarning`).
    """
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    _check_entry(u, v, s2, metric="fisher_rao", stacklevel=3, what="fisher_rao_bound")
    return _FisherRaoModel(s2, check_positive(grid_spacing, name="grid_spacing"),
                           check_positive(grid_margin, name="grid_margin")).lower_bound(u, v)


def alpha_lower_bound(u, v, *, sigma2) -> float:
    """Closed-form lower bound ``‖p_u − p_v‖`` on the α-order geodesic distance (eq. 22): the L²
    distance of the eq. 5 densities (:func:`shapelib.geometry.gmm.l2_distance`), checked at entry
    as :func:`geodesic` is (landmark dimension, scale, pose)."""
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    _check_entry(u, v, s2, metric="alpha", stacklevel=3, what="alpha_bound")
    return l2_distance(u, v, s2)


# ---------------------------------------------------------------------------------------------
# The solver
# ---------------------------------------------------------------------------------------------


def _check_entry(u, v, s2, *, metric, stacklevel, what=None):
    """Checks shared by :func:`geodesic`, :func:`shapelib.solver.bracket.distance_bracket` and the
    two bounds at entry: landmark dimension 2 or 3, σ against the landmarks' scale
    (:mod:`shapelib.geometry.scale`) and their pose (:func:`shapelib.geometry.procrustes.check_pose`:
    both metrics depend on it). ``stacklevel`` counts from here (3: the caller of the entry point);
    ``what``: a bound's name in the warnings. Returns σ / spacing (the bounds, which do not use it,
    skip the scale warning where the pairwise engine has checked the whole set); ``ValueError`` for a
    σ that leaves the Fisher–Rao quadrature nothing to resolve (:func:`~shapelib.geometry.scale.check_fisher_rao_scale`)."""
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}; got {metric!r}")
    check_dimension(u, name="u")
    pair = np.stack([u, v])
    check_pose(pair, metric=what or metric, stacklevel=stacklevel + 1)
    if metric == "alpha" and what is not None and set_was_checked():
        return None
    ratio = check_scale(pair, s2, stacklevel=stacklevel + 1)
    if metric == "fisher_rao":  # degenerate quadrature: an error before any work
        check_fisher_rao_scale(pair, s2, metric=what or metric, ratio=ratio)
    return ratio


def _underflow(result, ratio):
    """Why a "converged" result is not, or None.

    A solver that stops before its first step on a path of several landmarks far longer than the
    bound, with σ below :data:`shapelib.geometry.scale.SIGMA_RATIO_MIN` landmark spacings, has not found a
    geodesic: the Gaussians of different landmarks do not interact (their overlaps underflow), so
    the gradient that would bend the path is zero to machine precision. Same for an energy that
    underflows to zero between distinct shapes.
    """

    if not result.converged or result.log.get("stopped_by") == "trivial":
        return None
    if not result.energy > 0:
        return (f"the path energy underflows to {result.energy!r} between distinct shapes "
                f"(sigma = {np.sqrt(result.sigma2):.3g} is {ratio:.3g} landmark spacings)")
    if result.n_iter > 0:
        return None
    if ratio < SIGMA_RATIO_MIN and result.path.shape[1] > 1 and result.length > 2 * result.lower_bound:
        return (f"the solver stopped before its first step with length {result.length:.4g}, "
                f"{result.length / result.lower_bound:.3g} times the lower bound {result.lower_bound:.4g}, "
                f"because the gradient underflows (norm {result.grad_norm or 0.0:.2e}): sigma = {np.sqrt(result.sigma2):.3g} "
                f"is {ratio:.3g} landmark spacings, so the Gaussians of different landmarks do not interact")


def geodesic(u, v, *, metric: str = "alpha", sigma2, n_steps: int = 16, tol: float = 1e-6,
             max_iter: int = 500, window: int = 5, init=None, grid_spacing: float = DEFAULT_SPACING,
             grid_margin: float = DEFAULT_MARGIN, hessian: str = "exact", warn: bool = True) -> GeodesicResult:
    """Geodesic between two landmark shapes under the α-order or Fisher–Rao metric (eqs. 8–12).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Start and end shapes, landmarks in correspondence (eq. 9).
    metric : {"alpha", "fisher_rao"}
        α-order entropy metric (eq. 22, closed form) or Fisher–Rao metric (eq. 6, quadrature).
    sigma2 : float
        σ² of the GMM representation (eq. 5).
    n_steps : int
        Number of time steps ``n`` (``n + 1`` path points). The minimal piecewise-linear energy
        decreases to the squared geodesic distance as ``n`` grows (``tests/test_geodesic.py``).
    tol : float
        Convergence: the Newton decrement on the exact Hessian is below ``tol · E``, or the
        relative energy decrease over the last ``window`` iterations is below ``tol``. (The
        energy is nearly flat along "sliding" directions of dense landmarks, so the last
        digits come slowly; the discretisation error in ``n_steps``, visible in
        ``length − lower_bound``, is usually far larger than ``tol``.)
    window : int
        Number of iterations over which the energy decrease is measured.
    max_iter : int
        Maximum Levenberg–Marquardt iterations.
    init : array_like, shape (n_steps + 1, K, d), optional
        Initial path (default: the straight line in landmark space, as in the paper's figures).
    grid_spacing, grid_margin : float
        Fisher–Rao quadrature grid step and margin in units of σ (:mod:`shapelib.geometry.quadrature`).
    hessian : {"exact", "model"}
        Newton steps on the exact Hessian of the path energy (certified stop by the Newton
        decrement), or on the model Hessian that freezes the metric at each segment's midpoint
        (cheaper per iteration for Fisher–Rao — ~0.3 s against ~1.2 s for 63 landmarks at
        ``n_steps = 16`` — but many more iterations, and it only stops on the energy window).
    warn : bool
        Emit a :class:`GeodesicWarning` when the solver stops before converging.

    Returns
    -------
    GeodesicResult
        ``path``, ``length``, ``energy``, ``lower_bound``, ``converged``, ``n_iter``,
        ``grad_norm`` and a ``log``. The geodesic distance lies in ``[lower_bound, length]``.
    """
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    ratio = _check_entry(u, v, s2, metric=metric, stacklevel=3)
    model = _model(metric, s2, grid_spacing, grid_margin)
    result = minimise_path(model, u, v, n_steps=n_steps, tol=tol, max_iter=max_iter, window=window, init=init,
                           warn=warn, length_scale=np.sqrt(s2), sigma2=s2, hessian=hessian, stacklevel=3)
    reason = _underflow(result, ratio)
    if reason is not None:
        result.converged = False
        result.log["stopped_by"] = "underflow"
        result.log["reason"] = reason
        if warn:
            warnings.warn(f"{metric} geodesic not converged: {reason}. Bring the shapes to a scale that fits "
                          f"sigma2 (shapelib.to_centroid_size) or choose a larger sigma2.",
                          GeodesicWarning, stacklevel=2)
    return result


def minimise_path(model, u, v, *, n_steps, tol, max_iter, window, init, warn, length_scale, sigma2=None,
                  hessian=None, stacklevel=2, target_energy=None, lower_bound=None) -> GeodesicResult:
    """Minimise the piecewise-linear path energy of any metric ``model`` between ``u`` and ``v``.

    ``model`` provides ``prepare(points)``, ``qform``/``qform_grad`` (``vᵀ g(θ) v`` and its
    gradients, batched), ``tensors`` (metric tensors for the model Hessian), ``lower_bound`` and
    ``settings`` — see :class:`_AlphaModel`; models with ``qform_hessian`` get exact Newton
    steps unless ``hessian="model"``. The α-order, Fisher–Rao and landmark-diffeomorphism
    (:mod:`shapelib.comparison.diffeomorphism`) metrics all go through here.

    ``target_energy``: stop as soon as the energy is at or below it (``stopped_by ==
    "target_energy"``, counted as converged) — :func:`shapelib.solver.bracket.distance_bracket` passes
    ``(lower · (1 + rtol))²``, since ``length ≤ √E``. ``lower_bound``: ``model.lower_bound(u, v)``
    when the caller has it already (the bracket computes it once per pair, not once per level).
    """
    n = check_positive_int(n_steps, name="n_steps")
    window = check_positive_int(window, name="window")
    max_iter = check_nonnegative_int(max_iter, name="max_iter")  # 0: evaluate the start only
    tol = check_positive(tol, name="tol")
    if hessian not in (None, "exact", "model"):
        raise ValueError(f"hessian must be 'exact' or 'model'; got {hessian!r}")
    k, d = u.shape
    if init is None:
        t = np.linspace(0.0, 1.0, n + 1)[:, None, None]
        path = (1 - t) * u + t * v
    else:
        path = np.array(init, dtype=np.float64)
        if path.shape != (n + 1, k, d):
            raise ValueError(f"init must have shape {(n + 1, k, d)}; got {path.shape}")
        if not np.all(np.isfinite(path)):
            raise ValueError("init contains non-finite values")
        path[0], path[-1] = u, v
    with one_blas_thread():  # many small dense blocks: see one_blas_thread
        t0 = time.perf_counter()
        energies, dampings = [], []
        converged = n == 1 or np.array_equal(u, v)
        rel_change = 0.0
        it = 0
        kind = "exact" if hessian in (None, "exact") and hasattr(model, "qform_hessian") else "model"
        trivial = converged
        energy, grad, hess = None, None, None
        if target_energy is not None and not converged:  # the start may do
            energy = _energy(model, path, gradient=False)[0]
            converged = energy <= target_energy
        if energy is None or not converged:
            energy, grad, hess = _energy(model, path, gradient=not converged, hessian=None if converged else kind)
        energies.append(energy)
        stopped_by = ("target_energy" if target_energy is not None and not trivial else "trivial") if converged \
            else "max_iter"
        newton_decrement = None
        lam = 1e-3  # damping, relative to the mean diagonal of the Hessian
        while not converged and it < max_iter:
            hd, ho = hess
            g2 = grad.reshape(n - 1, -1)
            scale = float(np.mean(np.einsum("tii->t", hd))) / hd.shape[1]
            # The first damped factorisation of the Levenberg–Marquardt loop below, done first:
            # it also tells whether the certificate can pass (failed attempts count towards the
            # loop's 60).
            pending, tries = None, 0
            while tries < 60:
                try:
                    pending = -_block_solve(_block_cholesky(hd, ho, lam * scale), g2)
                    break
                except np.linalg.LinAlgError:  # Hessian + damping not positive definite
                    lam = max(lam * 2, 1e-12)
                    tries += 1
            if kind == "exact":
                # Certificate: where the exact Hessian is positive definite, the Newton decrement
                # ½ gᵀH⁻¹g estimates the energy still to gain; below tol·E this is a local minimum.
                # For H ≻ 0 and μ > 0, gᵀH⁻¹g ≥ gᵀ(H + μI)⁻¹g: if the damped decrement already
                # exceeds tol·E the certificate cannot pass, and the unshifted factorisation (which
                # fails in most iterations) is skipped. Same iterates and stop as attempting it.
                newton_decrement = None
                if pending is None or -0.5 * float(np.sum(g2 * pending)) < tol * energy * (1 + 1e-6):
                    try:
                        newton = -_block_solve(_block_cholesky(hd, ho, 0.0), g2)
                        newton_decrement = -0.5 * float(np.sum(g2 * newton))
                    except np.linalg.LinAlgError:
                        newton_decrement = None
                if newton_decrement is not None and newton_decrement < tol * energy:
                    trial = path.copy()
                    trial[1:-1] += newton.reshape(n - 1, k, d)
                    if _energy(model, trial, gradient=False)[0] < energy:
                        path = trial
                        energy, grad, _ = _energy(model, path)
                        energies.append(energy)
                    converged, stopped_by = True, "newton_decrement"
                    break
            it += 1
            accepted = False
            for _ in range(60 - tries):
                if pending is not None:
                    step, pending = pending, None
                else:
                    try:
                        step = -_block_solve(_block_cholesky(hd, ho, lam * scale), g2)
                    except np.linalg.LinAlgError:  # Hessian + damping not positive definite
                        lam = max(lam * 2, 1e-12)
                        continue
                predicted = -float(np.sum(g2 * step)) - 0.5 * float(np.sum(step * _hess_vec(hd, ho, step)))
                trial = path.copy()
                trial[1:-1] += step.reshape(n - 1, k, d)
                e_trial = _energy(model, trial, gradient=False)[0]
                actual = energy - e_trial
                if np.isfinite(e_trial) and actual > 0:
                    accepted = True
                    rho = actual / predicted if predicted > 0 else 0.0
                    lam = lam / 3 if rho > 0.75 else (lam * 4 if rho < 0.25 else lam)
                    lam = max(lam, 1e-14)
                    break
                lam = max(lam * 10, 1e-12)
            if not accepted:
                # no decrease possible at machine precision: a (local) minimum
                converged, stopped_by = True, "no_decrease"
                break
            rel_change = actual / energy
            path = trial
            done = target_energy is not None and e_trial <= target_energy
            if done:  # the loop stops here: no gradient or Hessian at the new path
                energy, grad = e_trial, None
            else:
                energy, grad, hess = _energy(model, path, hessian=kind)
            energies.append(energy)
            dampings.append(lam)
            if done:
                converged, stopped_by = True, "target_energy"
            elif len(energies) > window and (energies[-1 - window] - energy) < tol * energy:
                converged, stopped_by = True, "energy_window"
    if trivial:
        grad_norm = 0.0
    else:  # None: stopped on target_energy, where no gradient is evaluated
        grad_norm = float(np.linalg.norm(grad)) if grad is not None else None
    window_change = (energies[-1 - min(window, len(energies) - 1)] - energy) / energy if energy > 0 else 0.0
    if not converged and warn:
        warnings.warn(
            f"{model.name} geodesic did not converge in {it} iterations (relative energy change "
            f"over the last {window} iterations {window_change:.2e} > tol {tol:.1e}; gradient norm {grad_norm:.2e})",
            GeodesicWarning, stacklevel=stacklevel,
        )
    length = _length(model, path)
    steps = np.linalg.norm(np.diff(path, axis=0), axis=2)
    return GeodesicResult(
        path=path, length=length, energy=energy,
        lower_bound=model.lower_bound(u, v) if lower_bound is None else float(lower_bound), converged=bool(converged),
        n_iter=it, grad_norm=grad_norm, rel_energy_change=float(rel_change),
        max_step_over_sigma=float(steps.max() / length_scale), metric=model.name, sigma2=sigma2,
        log={"energy": energies, "damping": dampings, "hessian": kind, "stopped_by": stopped_by,
             "newton_decrement": newton_decrement,
             "seconds": time.perf_counter() - t0,
             "n_steps": n, "tol": tol, **model.settings()},
    )


# ---------------------------------------------------------------------------------------------
# Independent check: integrate the geodesic equation (eq. 11) from an initial velocity
# ---------------------------------------------------------------------------------------------


def geodesic_acceleration(theta, velocity, *, metric: str = "alpha", sigma2, grid=None, eps: float = 1e-6,
                          grid_spacing: float = DEFAULT_SPACING, grid_margin: float = DEFAULT_MARGIN):
    """``θ̈`` from the geodesic equation ``g θ̈ + Γ(θ̇, θ̇) = 0`` (eqs. 10–11).

    With ``Q(θ, v) = vᵀ g(θ) v``, the Christoffel term is
    ``Γ_k(v, v) = [∂_θ (g v) · v]_k − ½ ∂Q/∂θ_k`` (the first-kind symbols contracted twice). The
    gradient ``∂Q/∂θ`` is analytic; the directional derivative of ``g v = ½ ∂Q/∂v`` along ``v`` is
    a central difference of that analytic gradient with step ``eps``.
    """
    model = _model(metric, check_sigma2(sigma2), grid_spacing, grid_margin)
    th = np.asarray(theta, dtype=np.float64)
    v = np.asarray(velocity, dtype=np.float64)
    ctx = model.prepare(th) if grid is None else grid
    _, dq_t, _ = model.qform_grad(th[None], v[None], ctx)
    _, _, dv_p = model.qform_grad((th + eps * v)[None], v[None], ctx)
    _, _, dv_m = model.qform_grad((th - eps * v)[None], v[None], ctx)
    d_gv = 0.25 * (dv_p[0] - dv_m[0]) / eps  # ∂_θ(g v)·v, since g v = ½ ∂Q/∂v
    gamma = d_gv - 0.5 * dq_t[0]
    g = model.tensors(th[None], ctx)[0]
    return -np.linalg.solve(g, gamma.ravel()).reshape(th.shape)


def shoot(u, velocity, *, metric: str = "alpha", sigma2, n_steps: int = 200,
          grid_spacing: float = DEFAULT_SPACING, grid_margin: float = DEFAULT_MARGIN) -> np.ndarray:
    """Integrate the geodesic ODE (eq. 11) from ``u`` with initial velocity ``velocity`` over
    ``t ∈ [0, 1]`` with classical RK4; returns the trajectory ``(n_steps + 1, K, d)``.

    Only meaningful where the metric is well conditioned (few, well separated landmarks): the
    ODE needs ``g⁻¹``, which for dense contours has a condition number ~1e16.
    """
    u = as_shape_pair(u, velocity, names=("u", "velocity"))[0]
    s2 = check_sigma2(sigma2)
    acc = lambda th, v: geodesic_acceleration(th, v, metric=metric, sigma2=s2, grid_spacing=grid_spacing,
                                              grid_margin=grid_margin)
    th, v = u.copy(), np.asarray(velocity, dtype=np.float64).copy()
    h = 1.0 / n_steps
    out = [th.copy()]
    for _ in range(n_steps):
        k1x, k1v = v, acc(th, v)
        k2x, k2v = v + 0.5 * h * k1v, acc(th + 0.5 * h * k1x, v + 0.5 * h * k1v)
        k3x, k3v = v + 0.5 * h * k2v, acc(th + 0.5 * h * k2x, v + 0.5 * h * k2v)
        k4x, k4v = v + h * k3v, acc(th + h * k3x, v + h * k3v)
        th = th + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        out.append(th.copy())
    return np.stack(out)
