"""Landmark diffeomorphisms (Camion & Younes 2001, "Geodesic interpolating splines"; paper ref. [8], eq. 3).

The paper's comparison metric minimises, over landmark trajectories ``φ_a(t)`` and velocity
fields ``f_t``, ::

    Σ_a ∫ |φ̇_a − f_t(φ_a)|² dt + λ ∫ ‖L f_t‖² dt                                   (eq. 3)

For fixed trajectories the optimal field is the smoothing spline
``f_t(x) = Σ_a k(x − φ_a) w_a`` with ``w = (K(φ) + λI)⁻¹ φ̇`` (per coordinate), where ``k`` is the
Green's function of ``L*L`` and ``K_ab = k(φ_a − φ_b)``. Substituting it, the energy becomes

    ∫ λ φ̇ᵀ (K(φ) + λI)⁻¹ φ̇ dt,

a Riemannian metric on landmark configurations: the same boundary-value problem as the GMM
geodesics, solved by the same path minimiser (:func:`shapelib.solver.geodesic.minimise_path`). The
kernel must be positive definite; we use the Gaussian ``k(r) = exp(−|r|² / (2 s²))`` (with a
thin-plate kernel and a free affine part, affine motions cost nothing and an optimised path
collapses the shape). Since ``K ≼ K_max I`` with ``K_max ≤`` the number of landmarks, the metric
is at least ``λ/(λ + K_max)`` times the Euclidean one: ``d(u, v) ≥ √(λ/(λ + K_max)) ‖v − u‖``.

Intermediate warps of any point set (Fig. 9) follow the flow ``ẋ = f_t(x)``
(:func:`diffeomorphism_warp`).
"""

from __future__ import annotations

import numpy as np

from .._validate import as_shape, as_shape_pair, check_positive
from ..geometry.procrustes import check_pose
from ..solver.minimise import minimise_path
from ..solver.path_metric import PathMetric
from ..solver.result import GeodesicResult

__all__ = ["landmark_diffeomorphism", "diffeomorphism_warp", "diffeomorphism_quadratic_form"]


def _kernel(x, y, width):
    delta = x[..., :, None, :] - y[..., None, :, :]
    return np.exp(-np.einsum("...abi,...abi->...ab", delta, delta) / (2 * width**2)), delta


class DiffeomorphismPathMetric(PathMetric):
    """The landmark-diffeomorphism (Camion–Younes) metric ``λ φ̇ᵀ(K + λI)⁻¹φ̇`` (eq. 3) as the path
    solver sees it (model Hessian only: no ``qform_hessian``)."""

    name = "diffeomorphism"

    def __init__(self, lam: float, width: float):
        self.lam, self.width = lam, width

    def prepare(self, points):
        return None

    def _solve(self, theta, vel):
        kmat, delta = _kernel(theta, theta, self.width)
        k = theta.shape[1]
        a = kmat + self.lam * np.eye(k)
        w = np.linalg.solve(a, vel)  # (m, K, d): (K + λI)⁻¹ φ̇ per coordinate
        return kmat, delta, w

    def qform(self, theta, vel, ctx):
        _, _, w = self._solve(theta, vel)
        return self.lam * np.einsum("mai,mai->m", vel, w)

    def qform_grad(self, theta, vel, ctx):
        """``Q = λ vᵀ A⁻¹ v``: ``∂Q/∂v = 2λ A⁻¹ v``; ``∂Q/∂φ_a = −λ wᵀ (∂K/∂φ_a) w
        = 2λ Σ_b (w_a·w_b) k_ab Δ_ab / s²`` (Δ_ab = φ_a − φ_b, Gaussian k)."""
        kmat, delta, w = self._solve(theta, vel)
        q = self.lam * np.einsum("mai,mai->m", vel, w)
        ww = np.einsum("mai,mbi->mab", w, w) * kmat
        d_theta = 2 * self.lam * np.einsum("mab,mabi->mai", ww, delta) / self.width**2
        return q, d_theta, 2 * self.lam * w

    def tensors(self, theta, ctx):
        kmat, _, _ = self._solve(theta, np.zeros_like(theta))
        k, d = theta.shape[1:]
        inv = np.linalg.inv(kmat + self.lam * np.eye(k))
        return self.lam * np.einsum("mab,ij->maibj", inv, np.eye(d)).reshape(len(theta), k * d, k * d)

    def lower_bound(self, u, v):
        # along any path K(φ) ≼ K·I (kernel entries ≤ 1), so g ≽ λ/(λ + K) · I
        return float(np.sqrt(self.lam / (self.lam + len(u))) * np.linalg.norm(v - u))

    def settings(self):
        return {"lam": self.lam, "kernel_width": self.width}


def diffeomorphism_quadratic_form(theta, velocity, *, lam: float = 10.0, kernel_width: float = 1.0) -> float:
    """``λ φ̇ᵀ (K(φ) + λI)⁻¹ φ̇``: the reduced Camion–Younes energy density for landmarks ``theta``."""
    theta = as_shape(theta, name="theta")
    vel = as_shape(velocity, name="velocity")
    if vel.shape != theta.shape:
        raise ValueError(f"velocity must have the shape of theta {theta.shape}; got {vel.shape}")
    m = DiffeomorphismPathMetric(check_positive(lam, name="lam"), check_positive(kernel_width, name="kernel_width"))
    return float(m.qform(theta[None], vel[None], None)[0])


def landmark_diffeomorphism(u, v, *, lam: float = 10.0, kernel_width: float = 1.0, n_steps: int = 16,
                            tol: float = 1e-6, max_iter: int = 500, window: int = 5, init=None,
                            warn: bool = True) -> GeodesicResult:
    """Geodesic landmark matching (Camion & Younes), reduced to landmark trajectories (module doc).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Source and target landmarks in correspondence.
    lam : float
        λ of eq. (3) (the paper uses λ = 10).
    kernel_width : float
        Width ``s`` of the Gaussian kernel ``exp(−|r|²/(2s²))``.
    n_steps, tol, max_iter, window, init, warn
        As in :func:`shapelib.geodesic`.

    Returns
    -------
    GeodesicResult
        ``length`` is the distance ∫ √(λ φ̇ᵀ(K + λI)⁻¹φ̇) dt of the computed path; ``path`` the
        landmark trajectories; ``lower_bound`` = √(λ/(λ + K))‖v − u‖.
    """
    u, v = as_shape_pair(u, v)
    check_pose(np.stack([u, v]), metric="diffeomorphism")  # the kernel sees where the landmarks are
    width = check_positive(kernel_width, name="kernel_width")
    model = DiffeomorphismPathMetric(check_positive(lam, name="lam"), width)
    return minimise_path(model, u, v, n_steps=n_steps, tol=tol, max_iter=max_iter, window=window, init=init,
                         warn=warn, length_scale=width, stacklevel=3)


def diffeomorphism_warp(points, result: GeodesicResult, *, lam: float | None = None,
                        kernel_width: float | None = None, substeps: int = 4) -> np.ndarray:
    """Carry ``points`` (M, d) along the flow ``ẋ = f_t(x)`` of a computed landmark diffeomorphism.

    On each segment of the path the landmark velocities are constant; the field is
    ``f(x) = Σ_a k(x − φ_a) w_a`` with ``w = (K + λI)⁻¹ φ̇``, integrated with ``substeps``
    midpoint (RK2) steps per segment, the landmarks moving linearly within the segment.

    Returns
    -------
    ndarray, shape (n_steps + 1, M, d)
        The points at every path time (the intermediate warps of Fig. 9).
    """
    lam = result.log["lam"] if lam is None else lam
    width = result.log["kernel_width"] if kernel_width is None else kernel_width
    x = as_shape(points, name="points").copy()
    path = result.path
    n = len(path) - 1
    model = DiffeomorphismPathMetric(lam, width)

    def field(pts, phi, vel):
        _, _, w = model._solve(phi[None], vel[None])
        kx, _ = _kernel(pts, phi, width)
        return kx @ w[0]

    out = [x.copy()]
    h = 1.0 / (n * substeps)
    for t in range(n):
        vel = n * (path[t + 1] - path[t])
        for s in range(substeps):
            tau0 = s / substeps
            phi0 = path[t] + tau0 * (path[t + 1] - path[t])
            phim = path[t] + (tau0 + 0.5 / substeps) * (path[t + 1] - path[t])
            k1 = field(x, phi0, vel)
            x = x + h * field(x + 0.5 * h * k1, phim, vel)
        out.append(x.copy())
    return np.stack(out)
