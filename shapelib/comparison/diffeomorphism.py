r"""Landmark diffeomorphisms (Camion & Younes 2001, "Geodesic interpolating splines"; paper ref. [8], eq. 3).

The paper's comparison metric minimises, over landmark trajectories :math:`\phi_a(t)` and
velocity fields :math:`f_t`,

.. math::

    E(\{\phi, f\}) = \sum_{a=1}^{K} \int_0^1 |\dot\phi_a - f_t(\phi_a)|^2\, dt
    + \lambda \int_0^1 \|L f_t\|^2\, dt \qquad \text{(eq. 3)}

For fixed trajectories the optimal field is the smoothing spline
:math:`f_t(x) = \sum_a k(x - \phi_a)\, w_a` with :math:`w = (K(\phi) + \lambda I)^{-1} \dot\phi`
(per coordinate), where :math:`k` is the Green's function of :math:`L^*L` and
:math:`K_{ab} = k(\phi_a - \phi_b)`. Substituting it, the energy becomes

.. math::

    \int_0^1 \lambda\, \dot\phi^\top (K(\phi) + \lambda I)^{-1} \dot\phi\, dt,

a Riemannian metric on landmark configurations: the same boundary-value problem as the GMM
geodesics, solved by the same path minimiser (:func:`shapelib.solver.minimise.minimise_path`). The
kernel must be positive definite; we use the Gaussian :math:`k(r) = \exp(-|r|^2 / (2 s^2))` (with
a thin-plate kernel and a free affine part, affine motions cost nothing and an optimised path
collapses the shape). Since :math:`K \preceq K_{\max} I` with :math:`K_{\max} \le` the number of
landmarks, the metric is at least :math:`\lambda/(\lambda + K_{\max})` times the Euclidean one:
:math:`d(u, v) \ge \sqrt{\lambda/(\lambda + K_{\max})}\, \|v - u\|`.

Intermediate warps of any point set (Fig. 9) follow the flow :math:`\dot x = f_t(x)`
(:func:`diffeomorphism_warp`).
"""

from __future__ import annotations

import numpy as np

from .._validate import as_shape, as_shape_pair, check_positive, check_positive_int
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
    solver sees it (model Hessian only: no ``qform_hessian``).
    """

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


def _path_metric(lam, kernel_width) -> DiffeomorphismPathMetric:
    """The path metric of λ = ``lam`` and kernel width ``kernel_width``, both checked (finite, > 0)."""
    return DiffeomorphismPathMetric(check_positive(lam, name="lam"), check_positive(kernel_width, name="kernel_width"))


def diffeomorphism_quadratic_form(theta, velocity, *, lam: float = 10.0, kernel_width: float = 1.0) -> float:
    r"""The reduced Camion–Younes energy density of landmarks ``theta`` moving with ``velocity``.

    Eq. (3) of [1]_ with the optimal smoothing-spline field substituted [2]_:

    .. math::

        Q(\phi, \dot\phi) = \lambda\, \dot\phi^\top (K(\phi) + \lambda I)^{-1} \dot\phi,
        \qquad K_{ab} = \exp\!\left(-\frac{|\phi_a - \phi_b|^2}{2 s^2}\right),

    applied per coordinate.

    Parameters
    ----------
    theta : array_like, shape (K, d)
        Landmarks :math:`\phi`.
    velocity : array_like, shape (K, d)
        Their velocities :math:`\dot\phi`.
    lam : float, default 10.0
        λ of eq. (3).
    kernel_width : float, default 1.0
        Width :math:`s` of the Gaussian kernel.

    Returns
    -------
    float
        :math:`Q \ge 0`.

    Raises
    ------
    ValueError
        If ``velocity`` does not have the shape of ``theta``, an array is not finite, or ``lam`` or
        ``kernel_width`` is not positive.

    See Also
    --------
    shapelib.landmark_diffeomorphism : Geodesics of this metric.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] V. Camion and L. Younes, "Geodesic interpolating splines", *Energy Minimization Methods in
       Computer Vision and Pattern Recognition* (EMMCVPR), LNCS 2134, 513–527, 2001.

    Examples
    --------
    Far-apart landmarks do not interact: :math:`Q = \frac{\lambda}{1 + \lambda} |\dot\phi|^2`.

    >>> import numpy as np
    >>> from shapelib.comparison.diffeomorphism import diffeomorphism_quadratic_form
    >>> theta = np.array([[0.0, 0.0], [100.0, 0.0]])
    >>> q = diffeomorphism_quadratic_form(theta, [[1.0, 0.0], [0.0, 1.0]], lam=10.0)
    >>> bool(np.isclose(q, 10.0 / 11.0 * 2.0))
    True
    """
    theta = as_shape(theta, name="theta")
    vel = as_shape(velocity, name="velocity")
    if vel.shape != theta.shape:
        raise ValueError(f"velocity must have the shape of theta {theta.shape}; got {vel.shape}")
    m = _path_metric(lam, kernel_width)
    return float(m.qform(theta[None], vel[None], None)[0])


def landmark_diffeomorphism(u, v, *, lam: float = 10.0, kernel_width: float = 1.0, n_steps: int = 16,
                            tol: float = 1e-6, max_iter: int = 500, window: int = 5, init=None,
                            warn: bool = True) -> GeodesicResult:
    r"""Geodesic landmark matching (Camion & Younes), reduced to landmark trajectories (module doc).

    Minimises eq. (3) of [1]_ over landmark trajectories from ``u`` to ``v``, the velocity field
    eliminated [2]_:

    .. math::

        d(u, v)^2 = \min_{\phi(0) = u,\ \phi(1) = v} \int_0^1 \lambda\, \dot\phi^\top
        (K(\phi) + \lambda I)^{-1} \dot\phi\, dt,

    by the path solver of the information metrics (model Hessian). Table I's comparison column;
    the paper uses λ = 10.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Source and target landmarks in correspondence.
    lam : float
        λ of eq. (3) (the paper uses λ = 10).
    kernel_width : float
        Width ``s`` of the Gaussian kernel ``exp(−|r|²/(2s²))``.
    n_steps : int
        Time steps of the path.
    tol : float
        Convergence tolerance (as :func:`shapelib.geodesic`).
    max_iter : int
        Maximum Levenberg–Marquardt iterations.
    window : int
        Iterations over which the energy decrease is measured.
    init : array_like, shape (n_steps + 1, K, d), optional
        Initial path (default: the straight line).
    warn : bool
        Emit a :class:`~shapelib.GeodesicWarning` when it stops before converging.

    Returns
    -------
    GeodesicResult
        ``length`` is the distance ∫ √(λ φ̇ᵀ(K + λI)⁻¹φ̇) dt of the computed path; ``path`` the
        landmark trajectories; ``lower_bound`` = √(λ/(λ + K))‖v − u‖.

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite, or a non-positive option.

    Warns
    -----
    PoseWarning
        When the shapes are not aligned (the kernel sees where the landmarks are).
    GeodesicWarning
        When the solver stops before converging (``warn=True``).

    See Also
    --------
    shapelib.diffeomorphism_warp : Carry any point set along the flow (Fig. 9).
    shapelib.geodesic : The information-metric geodesics through the same solver.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] V. Camion and L. Younes, "Geodesic interpolating splines", *Energy Minimization Methods in
       Computer Vision and Pattern Recognition* (EMMCVPR), LNCS 2134, 513–527, 2001.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> r = sl.landmark_diffeomorphism(u, v, n_steps=4)
    >>> r.converged, round(r.length, 3), bool(r.lower_bound <= r.length)
    (True, 0.329, True)
    """
    u, v = as_shape_pair(u, v)
    check_pose(np.stack([u, v]), metric="diffeomorphism")  # the kernel sees where the landmarks are
    model = _path_metric(lam, kernel_width)
    return minimise_path(model, u, v, n_steps=n_steps, tol=tol, max_iter=max_iter, window=window, init=init,
                         warn=warn, length_scale=model.width, stacklevel=3)


def diffeomorphism_warp(points, result: GeodesicResult, *, lam: float | None = None,
                        kernel_width: float | None = None, substeps: int = 4) -> np.ndarray:
    r"""Carry ``points`` along the flow ``ẋ = f_t(x)`` of a computed landmark diffeomorphism.

    On each segment of the path the landmark velocities are constant; the field of eq. (3) of [1]_
    is the smoothing spline [2]_

    .. math::

        f_t(x) = \sum_{a=1}^{K} k(x - \phi_a)\, w_a, \qquad w = (K(\phi) + \lambda I)^{-1} \dot\phi,

    integrated with ``substeps`` midpoint (RK2) steps per segment, the landmarks moving linearly
    within the segment.

    Parameters
    ----------
    points : array_like, shape (M, d)
        Points to carry (e.g. a dense outline).
    result : GeodesicResult
        From :func:`shapelib.landmark_diffeomorphism`.
    lam : float, optional
        λ of eq. (3); default the one ``result`` was computed with.
    kernel_width : float, optional
        Kernel width; default the one ``result`` was computed with.
    substeps : int, default 4
        RK2 steps per path segment.

    Returns
    -------
    ndarray, shape (n_steps + 1, M, d)
        The points at every path time (the intermediate warps of Fig. 9).

    Raises
    ------
    ValueError
        If ``points`` is not a finite ``(M, d)`` array, or ``lam`` or ``kernel_width`` is not a positive number.

    See Also
    --------
    shapelib.landmark_diffeomorphism : The trajectories that drive the flow.
    shapelib.extrinsic_warp : The information metrics' counterpart (§III-E).

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] V. Camion and L. Younes, "Geodesic interpolating splines", *Energy Minimization Methods in
       Computer Vision and Pattern Recognition* (EMMCVPR), LNCS 2134, 513–527, 2001.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> r = sl.landmark_diffeomorphism(u, v, n_steps=4)
    >>> sl.diffeomorphism_warp([[0.5, 0.5], [0.2, 0.8]], r).shape
    (5, 2, 2)
    """
    lam = result.log["lam"] if lam is None else lam
    width = result.log["kernel_width"] if kernel_width is None else kernel_width
    x = as_shape(points, name="points").copy()
    substeps = check_positive_int(substeps, name="substeps")
    path = result.path
    n = len(path) - 1
    model = _path_metric(lam, width)

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
