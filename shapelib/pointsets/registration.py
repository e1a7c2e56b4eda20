"""Registration of point sets by the information geometry: pose over every rotation, then a
deformation that is a geodesic of the α-order (or Fisher–Rao) metric.

Both sets are mixtures of eq. (5), one component per point. ``register(source, target)``:

1. **Pose.** Centre each set and scale it to unit RMS radius (the source keeps the target's scale
   for ``transform="rigid"``), then :func:`shapelib.align`: the density distance
   (α: closed-form L²; Fisher–Rao: Hellinger) minimised over every rotation (a global search, not
   one local start), the similarity group for ``"nonrigid"``.
2. **σ², outliers, correspondences by EM** with the posed source ``u`` as the means of a mixture
   that explains the target ``y`` together with a uniform component of weight ``w``
   (Coherent Point Drift's model, Myronenko & Song 2010, with the uniform density ``1/V`` over
   the target's bounding box of volume V in place of CPD's ``1/m``): posteriors

       P_ij = exp(−|y_j − θ_i|²/2σ²) / (Σ_k exp(−|y_j − θ_k|²/2σ²) + (2πσ²)^{d/2} w/(1−w) · n/V),

   ``σ² = Σ_ij P_ij |y_j − θ_i|² / (d Σ_ij P_ij)`` and, with ``w="auto"``, ``w = 1 − Σ_ij P_ij / m``.
   Non-rigid, ``w`` is estimated with the means held at the pose and then held fixed: with both
   free, σ² → 0 and w → 1 (a deformation that explains a few target points exactly and calls the
   rest outliers) has an unbounded likelihood.
3. **Non-rigid: the metric as the deformation's kernel.** The means move to
   ``θ = u + G W``, where ``G = g(u)/g_aa`` is the α-order metric tensor of eq. (22) of the posed
   source mixture at the geometry's σ_g², divided by its diagonal:

       G_ab = exp(−|u_a − u_b|²/4σ_g²) [I − (u_a − u_b)(u_a − u_b)ᵀ/(2σ_g²)]

   (the Gram matrix ``⟨∂_a p, ∂_b p⟩_{L²}`` of the mixture's tangent functions; for Fisher–Rao
   the Fisher information matrix by quadrature). The M-step minimises
   ``Σ_ij P_ij |y_j − θ_i|²/2σ² + (λ/2) Wᵀ G W`` — a linear solve,
   ``(diag(P1) G + λσ² I) W = P y − diag(P1) u``. ``Wᵀ G W = (θ − u)ᵀ G⁻¹ (θ − u)`` is the
   squared length of the displacement in the metric's dual: a displacement that moves
   neighbouring points together costs little, one that tears them apart costs much. (The metric
   itself, ``(θ − u)ᵀ G (θ − u)``, ranks them the other way — two overlapping components moving
   apart leave the density almost unchanged — so it does not keep a shape together.)
4. **The deformation is a geodesic.** The path from ``u`` to the fitted ``θ`` (points in
   correspondence) is the α-order (or Fisher–Rao) geodesic (:func:`shapelib.geodesic`) at the
   target's leave-one-out σ² (the spacing of its points, the scale of the paper's geodesics),
   computed on first use of ``result.path``. Other points are moved by the fit's kernel,
   ``x ↦ x + Σ_b G(x, u_b) W_b`` (exact at the source points), or, in 2-D on request, carried
   along the geodesic by the paper's extrinsic warp (§III-E, :func:`shapelib.extrinsic_warp`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .._validate import check_nonnegative_int, check_positive, check_positive_int, check_sigma2
from ..geometry.metrics import alpha_metric, fisher_rao_metric
from ..solver.linalg import one_blas_thread
from .checks import as_point_set, check_same_dimension
from .density import DENSITY_METRICS
from .em import fit_mixture
from .pose import Pose, align

__all__ = ["register", "RegistrationResult", "RegistrationWarning", "REGISTRATION_TRANSFORMS"]

REGISTRATION_TRANSFORMS = ("rigid", "similarity", "affine", "nonrigid")
#: the last σ² of the pose search before a non-rigid fit, in units of the target's squared RMS radius
NONRIGID_POSE_SIGMA2 = 0.025
#: non-rigid: the pose search's best few distinct poses are each followed by SCREEN_ITER EM
#: iterations and the one with the smallest negative log-posterior is carried on (a deformed
#: shape can overlap the target best in a wrong pose; the deformation it then needs costs more)
N_CANDIDATES = 3
#: the pose group searched before a non-rigid fit
NONRIGID_POSE = "affine"
SCREEN_ITER = 150
#: EM iterations of the outlier weight at the pose (``w="auto"``, non-rigid)
W_ITER = 50
#: the largest outlier weight ``w="auto"`` estimates
W_MAX = 0.9
#: EM's σ² stays above this fraction of the target's leave-one-out σ²: an exact fit of some points
#: at σ² → 0 has an unbounded likelihood, which would otherwise decide between candidate poses
SIGMA2_FLOOR = 1e-4
#: the deformation kernels: the metric in the mixture's weight coordinates, or on its means
KERNELS = ("weights", "means")


class RegistrationWarning(RuntimeWarning):
    """The registration's EM stopped before meeting its tolerance.

    A :class:`RuntimeWarning`: :func:`register` still returns its last estimate, with
    ``converged`` false and ``stop_reason`` ``"max_iter"``.

    Parameters
    ----------
    *args : str
        The message, as for any warning (:func:`warnings.warn` passes its text when given this
        category).

    See Also
    --------
    register : What warns (``warn=False`` silences it).

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import shapelib as sl
    >>> x = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.5, 1.5], [-0.5, 0.8]])
    >>> c, s = np.cos(0.7), np.sin(0.7)
    >>> y = 1.5 * x @ np.array([[c, -s], [s, c]]).T + [3.0, 1.0]
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     res = sl.register(x, y, transform="similarity", max_iter=1)
    >>> res.converged, any(issubclass(w.category, sl.RegistrationWarning) for w in caught)
    (False, True)
    """


def _rms(x):
    return float(np.sqrt(np.mean(np.sum(x * x, axis=1))))


def _sq(x, y):
    """Squared distances (n, m) by the expansion |x|² + |y|² − 2 x·y (clipped at 0)."""
    out = np.einsum("id,id->i", x, x)[:, None] + np.einsum("jd,jd->j", y, y)[None, :] - 2.0 * (x @ y.T)
    return np.maximum(out, 0.0, out=out)


def _volume(y):
    """Volume of the target's bounding box: the support of the uniform (outlier) component."""
    return float(np.prod(np.maximum(np.ptp(y, axis=0), 1e-12)))


def _posteriors(theta, y, s2, w):
    """P (n, m), the uniform component's constant included; and Σ_ij P_ij |y_j − θ_i|²."""
    n, d = theta.shape
    m = _volume(y)
    sq = _sq(theta, y)
    e = np.exp(-sq / (2 * s2))
    c = (2 * np.pi * s2) ** (d / 2) * w / (1 - w) * n / m if w > 0 else 0.0
    den = e.sum(axis=0) + c
    den[den == 0] = np.finfo(float).tiny
    p = e / den
    return p, float(np.sum(p * sq))


def alpha_kernel(a, b, sigma2):
    """Blocks ``G(a_i, b_j) = exp(−|Δ|²/4σ²)[I − ΔΔᵀ/2σ²]`` (Δ = a_i − b_j) as an (n d, m d) matrix:
    the α-order metric of eq. (22) divided by its diagonal block (for ``a = b``, ``alpha_metric / g_aa``)."""
    n, d = a.shape
    delta = a[:, None, :] - b[None, :, :]
    e = np.exp(-np.einsum("ijk,ijk->ij", delta, delta) / (4 * sigma2))
    blocks = e[:, :, None, None] * (np.eye(d) - delta[:, :, :, None] * delta[:, :, None, :] / (2 * sigma2))
    return blocks.transpose(0, 2, 1, 3).reshape(n * d, len(b) * d)


def overlap_kernel(a, b, sigma2):
    """``⟨N_a, N_b⟩_{L²} / ⟨N_a, N_a⟩_{L²} = exp(−|a_i − b_j|²/4σ²)`` (n, m): the α-order metric of
    the mixture in its weight coordinates (``∂p/∂π_a = N_a``), divided by its diagonal."""
    return np.exp(-_sq(a, b) / (4 * sigma2))


def _fr_weight_metric(u, s2):
    """Fisher information of the mixture of eq. (5) in its weight coordinates,
    ``g_ab = ∫ N_a N_b / p dx`` (quadrature on the grid of ``shapelib.geometry.quadrature``)."""
    from ..geometry.metrics import psi_coef
    from ..geometry.quadrature import make_grid

    grid = make_grid(u, sigma2=s2)
    psi, coef = psi_coef(u, s2, grid)  # coef = N_a / (K σ² √p)
    f = coef * (len(u) * s2)  # N_a / √p
    return grid.weight * (f.T @ f)


def _kernel(u, s2g, metric, kernel):
    """The deformation kernel at the posed source ``u`` (normalised units), divided by its mean
    diagonal: (n, n) for the weight-coordinate kernels (the same for every coordinate), (n d, n d)
    for the metric on the means."""
    if kernel == "weights":
        if metric == "alpha":
            return overlap_kernel(u, u, s2g)
        g = _fr_weight_metric(u, s2g)
    else:
        g = alpha_metric(u, sigma2=s2g) if metric == "alpha" else fisher_rao_metric(u, sigma2=s2g)
    return g / np.mean(np.diag(g))


@dataclass
class RegistrationResult:
    """What :func:`register` returns.

    Attributes
    ----------
    points : ndarray, shape (n, d)
        The source points moved onto the target (in the target's coordinates).
    correspondence : ndarray of int, shape (n,)
        For each source point the index of its target point (largest posterior), −1 where the
        point explains less than half a target point (``Σ_j P_ij < 0.5``: a missing part).
    pose : Pose
        The rigid (similarity, affine) part, from the source's coordinates to the target's.
    objective : float
        The density bound between the moved source and the target (α: ``‖p − q‖``, Fisher–Rao:
        ``2 arccos ∫√(pq)``) at ``sigma2_objective``: the given σ², or the target's leave-one-out σ²
        (:func:`shapelib.fit_mixture`).
    sigma2 : float
        The final σ² of the EM (in the target's units); ``w``: the final outlier weight.
    converged, stop_reason, n_iter
        EM: ``"tolerance"`` (converged), ``"max_iter"`` (not).
    transform, metric : str

    See Also
    --------
    register : The registration.
    shapelib.pointsets.pose.Pose : Its rigid (similarity, affine) part.

    Notes
    -----
    The deformation is a geodesic of the metric of [1]_; ``sigma2``, ``w`` and ``probabilities`` are those of
    Coherent Point Drift's mixture model [2]_, estimated by EM.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] A. Myronenko and X. Song, "Point set registration: coherent point drift", *IEEE Transactions on
       Pattern Analysis and Machine Intelligence* 32(12), 2262–2275, 2010.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> x = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.5, 1.5], [-0.5, 0.8]])
    >>> c, s = np.cos(0.7), np.sin(0.7)
    >>> y = 1.5 * x @ np.array([[c, -s], [s, c]]).T + [3.0, 1.0]
    >>> res = sl.register(x, y[::-1], transform="similarity")
    >>> bool(np.abs(res.points - y).max() < 1e-3), res.correspondence.tolist(), res.converged
    (True, [4, 3, 2, 1, 0], True)
    >>> round(res.pose.scale, 3)
    1.5
    """

    points: np.ndarray
    correspondence: np.ndarray
    pose: Pose
    objective: float
    sigma2: float
    w: float
    converged: bool
    stop_reason: str
    n_iter: int
    transform: str
    metric: str
    sigma2_metric: float | None
    sigma2_objective: float = None
    _source: np.ndarray = field(repr=False, default=None)
    _target: np.ndarray = field(repr=False, default=None)
    _u: np.ndarray = field(repr=False, default=None)
    _coef: np.ndarray = field(repr=False, default=None)
    _p: np.ndarray = field(repr=False, default=None)
    _frame: tuple = field(repr=False, default=None)
    _n_steps: int = field(repr=False, default=16)
    _kernel: str = field(repr=False, default="weights")
    _geodesic: object = field(repr=False, default=None)

    @property
    def probabilities(self) -> np.ndarray:
        """Soft correspondences ``P`` (n, m): ``P_ij`` the posterior that target point j came
        from source point i (columns sum to ``1 −`` the outlier posterior)."""
        return self._p.copy()

    @property
    def rigid_points(self) -> np.ndarray:
        """The source moved by the pose alone."""
        return self.pose(self._source)

    @property
    def geodesic(self):
        """The geodesic (:class:`shapelib.GeodesicResult`) from the posed source to ``points`` at
        ``sigma2_objective``, in the target's units (non-rigid only; computed on first use with the
        ``n_steps`` of :func:`register`: α, seconds for 50 points; Fisher–Rao, about a minute for
        30)."""
        if self.transform != "nonrigid":
            return None
        if self._geodesic is None:
            from ..solver.geodesic import geodesic

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", category=UserWarning)
                self._geodesic = geodesic(self.rigid_points, self.points, metric=self.metric,
                                          sigma2=self.sigma2_objective, n_steps=self._n_steps, warn=False)
        return self._geodesic

    @property
    def path(self) -> np.ndarray:
        """The deformation path ``(n_steps + 1, n, d)``: the geodesic from the posed source to
        ``points`` (non-rigid), or the straight line of the pose from the source (others)."""
        if self.transform == "nonrigid":
            return self.geodesic.path
        t = np.linspace(0.0, 1.0, self._n_steps + 1)[:, None, None]
        return (1 - t) * self._source + t * self.points

    def warp(self, x, *, method: str = "kernel", lam: float | None = None, grid_size: int = 64) -> np.ndarray:
        """Move new points ``x`` (k, d), given in the source's coordinates, as the source was moved.

        ``method="kernel"`` (default): the pose, then ``x ↦ x + Σ_b G(x, u_b) W_b`` with the kernel
        of the fit (α only): it reproduces ``points`` at the source points exactly.
        ``method="extrinsic"`` (2-D): the pose, then the paper's likelihood-preserving flow along the
        deformation's geodesic (§III-E, :func:`shapelib.extrinsic_warp`, ``lam`` (default
        ``1e-3 ×`` the target's squared RMS radius) and ``grid_size`` passed on). It solves one
        sparse system per path step on a ``grid_size²`` grid (tens of seconds for 16 steps) and
        carries the source points only approximately to ``points``: the flow keeps each point's
        likelihood, not its identity.
        """
        x = as_point_set(x, name="x", min_points=1)
        if x.shape[1] != self.points.shape[1]:
            raise ValueError(f"x must have d = {self.points.shape[1]} coordinates per point; got {x.shape[1]}")
        z = self.pose(x)
        if self.transform != "nonrigid":
            return z
        d = x.shape[1]
        if method == "extrinsic":
            if d != 2:
                raise ValueError("the extrinsic warp (§III-E) is implemented in 2-D; use method='kernel' in 3-D")
            from ..comparison.warp import extrinsic_warp

            lam = 1e-3 * self._frame[1] ** 2 if lam is None else lam
            return extrinsic_warp(z, self.geodesic, lam=lam, grid_size=grid_size)[-1]
        if method != "kernel":
            raise ValueError(f"method must be 'extrinsic' or 'kernel'; got {method!r}")
        if self.metric != "alpha":
            raise ValueError("method='kernel' needs the closed-form alpha kernel; register with metric='alpha'")
        mean, size = self._frame
        zn = (z - mean) / size
        s2g = self.sigma2_metric / size ** 2
        if self._kernel == "weights":
            return (zn + overlap_kernel(zn, self._u, s2g) @ self._coef) * size + mean
        return (zn + (alpha_kernel(zn, self._u, s2g) @ self._coef.ravel()).reshape(-1, d)) * size + mean

    def summary(self) -> str:
        """A few lines: the pose, the fit, the correspondences and convergence."""
        n = len(self.points)
        matched = int(np.sum(self.correspondence >= 0))
        return (f"{self.transform} registration ({self.metric}) of {n} points onto {len(self._target)}\n"
                f"{self.pose.summary()}\n"
                f"EM: sigma2 = {self.sigma2:.4g}, outlier weight w = {self.w:.3g}, {self.n_iter} iterations, "
                f"{'converged' if self.converged else 'NOT converged'} ({self.stop_reason})\n"
                f"bound between moved source and target {self.objective:.6g}; {matched} of {n} source points matched")


def register(source, target, *, transform: str = "nonrigid", metric: str = "alpha", sigma2=None, w=0.0,
             reflection: bool = False, lam: float = 2.0, sigma2_metric: float = 1.0, kernel: str = "weights", n_angles: int = 36,
             max_iter: int = 150, tol: float = 1e-5, n_steps: int = 16, warn: bool = True) -> RegistrationResult:
    """Register the point set ``source`` onto ``target`` by the information geometry.

    The pose (rigid, similarity or affine) minimises a density distance over every rotation;
    σ², the outlier weight and the correspondences come from EM; a non-rigid deformation moves the
    source mixture's means ``θ = u + G W`` with ``G`` the α-order (or Fisher–Rao) metric tensor of
    the posed source mixture, and is the geodesic of that metric from ``u`` to ``θ`` (the module
    docstring has the equations). The sets may have different sizes, need no correspondence, and
    the target may hold outliers and miss parts of the source.

    Parameters
    ----------
    source, target : array_like, shapes (n, d) and (m, d)
        Point sets, d = 2 or 3.
    transform : {"rigid", "similarity", "affine", "nonrigid"}
        ``"nonrigid"``: a similarity pose, then the deformation.
    metric : {"alpha", "fisher_rao"}
        The density distance of the pose search and the metric of the deformation.
    sigma2 : float, optional
        σ² of the mixtures, in the target's units: fixed if given, estimated by EM if None.
    w : float or "auto"
        Weight of the uniform (outlier) component in ``[0, 1)``; ``"auto"``: estimated by EM.
    reflection : bool
        Also search mirror images of the source.
    lam : float
        λ, the weight of the deformation's squared dual-metric length (non-rigid).
    sigma2_metric : float
        σ_g² of the metric that regularises and carries the deformation, in units of the target's
        squared RMS radius (default 1: the metric sees the whole shape).
    n_angles : int
        2-D start angles of the pose search (:func:`shapelib.align`).
    max_iter : int
        EM iterations.
    tol : float
        EM stops when σ² changes by less than ``tol`` (relative) between iterations.
    n_steps : int
        Time steps of the deformation path.
    warn : bool
        Warn (:class:`RegistrationWarning`) when EM stops without converging.

    Returns
    -------
    RegistrationResult
        ``points``, ``correspondence``, ``probabilities``, ``warp(x)``, ``pose``, ``path``,
        ``objective``, ``sigma2``, ``w``, ``converged``, ``stop_reason``, ``summary()``.

    See Also
    --------
    shapelib.pointsets.pose.align : The pose search of step 1.
    shapelib.pointsets.em.fit_mixture : σ² of one point set by maximum likelihood.
    shapelib.solver.geodesic.geodesic : Geodesics between landmark shapes.

    Notes
    -----
    The deformation is a geodesic of the α-order (or Fisher–Rao) metric of [1]_; σ², outliers and
    correspondences follow Coherent Point Drift's mixture model [2]_, estimated by EM [3]_; the point
    sets of Chui and Rangarajan's TPS-RPM [4]_ are its benchmark.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] A. Myronenko and X. Song, "Point set registration: coherent point drift", *IEEE Transactions on
       Pattern Analysis and Machine Intelligence* 32(12), 2262–2275, 2010.
    .. [3] A. P. Dempster, N. M. Laird and D. B. Rubin, "Maximum likelihood from incomplete data via the EM
       algorithm", *Journal of the Royal Statistical Society, Series B* 39(1), 1–38, 1977.
    .. [4] H. Chui and A. Rangarajan, "A new point matching algorithm for non-rigid registration",
       *Computer Vision and Image Understanding* 89(2–3), 114–141, 2003.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> t = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    >>> fish = np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])
    >>> bent = fish + np.column_stack([0.05 * np.sin(2 * fish[:, 1]), 0.25 * fish[:, 0] ** 2])
    >>> c, s = np.cos(2.4), np.sin(2.4)
    >>> target = (bent @ np.array([[c, -s], [s, c]]).T)[::-1]  # turned by 137.5 degrees, reordered
    >>> res = sl.register(fish, target)
    >>> bool(np.abs(res.points - target[::-1]).max() < 1e-3)
    True
    >>> bool(np.all(res.correspondence == np.arange(50)[::-1]))
    True
    """
    x = as_point_set(source, name="source")
    y = as_point_set(target, name="target")
    check_same_dimension(x, y)
    if transform not in REGISTRATION_TRANSFORMS:
        raise ValueError(f"transform must be one of {REGISTRATION_TRANSFORMS}; got {transform!r}")
    if metric not in DENSITY_METRICS:
        raise ValueError(f"metric must be one of {DENSITY_METRICS}; got {metric!r}")
    fixed_s2 = None if sigma2 is None else check_sigma2(sigma2)
    auto_w = isinstance(w, str)
    if auto_w and w != "auto":
        raise ValueError(f"w must be a number in [0, 1) or 'auto'; got {w!r}")
    w0 = 0.1 if auto_w else float(w)
    if not 0.0 <= w0 < 1.0:
        raise ValueError(f"w must be in [0, 1) or 'auto'; got {w!r}")
    lam = check_positive(lam, name="lam")
    s2g = check_positive(sigma2_metric, name="sigma2_metric")
    max_iter = check_positive_int(max_iter, name="max_iter")
    n_steps = check_positive_int(n_steps, name="n_steps")
    check_nonnegative_int(n_angles, name="n_angles")
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}; got {kernel!r}")
    tol = check_positive(tol, name="tol")
    with one_blas_thread():
        return _register(x, y, transform, metric, fixed_s2, w0, auto_w, reflection, lam, s2g, kernel, n_angles,
                         max_iter, tol, n_steps, warn)


@dataclass
class _EMState:
    u: np.ndarray
    g: np.ndarray | None
    coef: np.ndarray
    s2: float
    w: float
    it: int = 0
    ok: bool = False
    why: str = "max_iter"

    @property
    def theta(self):
        if self.g is None:
            return self.u
        if len(self.g) == len(self.u):
            return self.u + self.g @ self.coef
        return self.u + (self.g @ self.coef.ravel()).reshape(self.u.shape)


def _em(st, yn, *, lam, fixed_s2, auto_w, max_iter, tol, s2_floor=1e-12):
    """Continue the EM of the module docstring for up to ``max_iter`` more iterations."""
    u, g = st.u, st.g
    n, d = u.shape
    if g is None and fixed_s2 is not None and not auto_w:
        st.ok, st.why = True, "tolerance"  # nothing to estimate: pose and σ² given
        return st
    for _ in range(max_iter):
        st.it += 1
        p, _ = _posteriors(st.theta, yn, st.s2, st.w)
        p1 = p.sum(axis=1)
        np_ = float(p1.sum())
        if g is not None:
            if len(g) == n:  # one kernel for every coordinate: an (n, n) solve with d right-hand sides
                st.coef = np.linalg.solve(p1[:, None] * g + lam * st.s2 * np.eye(n), p @ yn - p1[:, None] * u)
            else:
                a = p1.repeat(d)[:, None] * g + lam * st.s2 * np.eye(n * d)
                st.coef = np.linalg.solve(a, (p @ yn - p1[:, None] * u).ravel()).reshape(n, d)
        s2_old, w_old = st.s2, st.w
        if fixed_s2 is None:
            st.s2 = max(float(np.sum(p * _sq(st.theta, yn))) / (np_ * d), s2_floor)
        if auto_w:
            st.w = float(np.clip(1.0 - np_ / len(yn), 1e-6, W_MAX))
        if abs(st.s2 - s2_old) <= tol * s2_old and abs(st.w - w_old) <= tol:
            st.ok, st.why = True, "tolerance"
            break
    return st


def _neg_log_posterior(st, yn, lam):
    """``−Σ_j log[(1 − w)(1/n) Σ_i N(y_j; θ_i, σ²I) + w/m] + (λ/2) tr(Wᵀ G W)``: the objective EM
    decreases, comparable between starts."""
    n, d = st.u.shape
    m = len(yn)
    logn = -_sq(st.theta, yn) / (2 * st.s2) - 0.5 * d * np.log(2 * np.pi * st.s2)
    from scipy.special import logsumexp

    mix = logsumexp(logn, axis=0) + np.log((1 - st.w) / n)
    ll = np.logaddexp(mix, np.log(st.w / _volume(yn))) if st.w > 0 else mix
    prior = 0.0
    if st.g is not None:
        c = st.coef.reshape(n, -1)
        gc = st.g @ c if len(st.g) == n else (st.g @ c.ravel()).reshape(c.shape)
        prior = 0.5 * lam * float(np.sum(c * gc))
    return float(-ll.sum() + prior)


def _register(x, y, transform, metric, fixed_s2, w, auto_w, reflection, lam, s2g, kernel, n_angles, max_iter, tol,
              n_steps, warn, n_candidates=N_CANDIDATES):
    d = x.shape[1]
    my, sy = y.mean(axis=0), _rms(y - y.mean(axis=0))
    mx = x.mean(axis=0)
    sx = sy if transform == "rigid" else _rms(x - mx)
    xn, yn = (x - mx) / sx, (y - my) / sy
    # pose: σ² of the search's last level from the target's own spread (leave-one-out), or the given one
    s2_pose = fixed_s2 / sy ** 2 if fixed_s2 is not None else fit_mixture(yn, warn=False).sigma2
    s2_eval = s2_pose  # the σ² at which the objective is reported
    if transform == "nonrigid":  # the pose need not resolve what the deformation will fit
        s2_pose = max(s2_pose, NONRIGID_POSE_SIGMA2)
    pose_t = NONRIGID_POSE if transform == "nonrigid" else transform
    pn = align(xn, yn, sigma2=s2_pose, transform=pose_t, metric=metric, reflection=reflection,
               n_angles=max(n_angles, 1), warn=warn)
    poses = [(pn.matrix, pn.translation)]
    if transform == "nonrigid":  # the distinct poses of the search, each followed by a short EM
        poses += [(a, t) for _, a, t in pn.candidates[:n_candidates]]
        poses.append((np.eye(d), np.zeros(d)))  # and the pose as given (centred, scaled), as CPD starts

    def start(a, t):
        u = xn @ a.T + t
        s2 = fixed_s2 / sy ** 2 if fixed_s2 is not None else float(np.mean(_sq(u, yn)) / d)
        w_start = w
        if auto_w and transform == "nonrigid":
            # w from the pose alone (EM on σ² ≥ the target's leave-one-out σ² and w, the means held):
            # a deformation free to choose which target points to explain would call inliers outliers
            rigid = _em(_EMState(u=u, g=None, coef=None, s2=s2, w=w), yn, lam=lam, fixed_s2=fixed_s2, auto_w=True,
                        max_iter=W_ITER, tol=tol, s2_floor=s2_eval)
            w_start = rigid.w
        g = _kernel(u, s2g, metric, kernel) if transform == "nonrigid" else None
        return _EMState(u=u, g=g, coef=np.zeros((len(u), d)), s2=s2, w=w_start)

    opts = dict(lam=lam, fixed_s2=fixed_s2, auto_w=auto_w and transform != "nonrigid", tol=tol,
                s2_floor=SIGMA2_FLOOR * s2_eval)
    if len(poses) > 1:
        trials = []
        for k, (a, t) in enumerate(poses):
            st = _em(start(a, t), yn, max_iter=min(SCREEN_ITER, max_iter), **opts)
            trials.append((_neg_log_posterior(st, yn, lam), k, st))
        _, k, st = min(trials, key=lambda c: c[0])
        chosen = poses[k]
    else:
        st, chosen = start(*poses[0]), poses[0]
    if not st.ok:
        st = _em(st, yn, max_iter=max_iter - st.it, **opts)
    theta, coef, s2, w, it, ok, why, u = st.theta, st.coef, st.s2, st.w, st.it, st.ok, st.why, st.u
    p, _ = _posteriors(theta, yn, s2, w)
    if warn and not ok:
        warnings.warn(f"register: EM stopped after {max_iter} iterations without converging (sigma2 = "
                      f"{s2 * sy ** 2:.3g}); raise max_iter or loosen tol", RegistrationWarning, stacklevel=3)
    p1 = p.sum(axis=1)
    corr = np.where(p1 >= 0.5, np.argmax(p, axis=1), -1)
    from .density import _hellinger_sq, _l2_sq

    if metric == "alpha":
        obj = float(np.sqrt(max(_l2_sq(theta, yn, s2_eval, grad=False)[0], 0.0)) / sy ** (d / 2))
    else:
        h2 = _hellinger_sq(theta, yn, s2_eval, grad=False)[0]
        obj = float(4.0 * np.arcsin(min(np.sqrt(max(h2, 0.0)) / 2, 1.0)))
    # the pose in the input units: x -> A (x − m_x)/s_x · s_y + t̃ s_y + m_y
    a = chosen[0] * (sy / sx)
    t = my + sy * chosen[1] - a @ mx
    pose = Pose(matrix=a, translation=t, points=x @ a.T + t, value=pn.value, objective=pn.objective,
                converged=pn.converged, stop_reason=pn.stop_reason, transform=pn.transform, metric=metric,
                sigma2=s2_pose * sy ** 2, n_starts=pn.n_starts, n_iter=pn.n_iter)
    return RegistrationResult(points=theta * sy + my, correspondence=corr, pose=pose, objective=obj,
                              sigma2=s2 * sy ** 2, w=float(w), converged=ok, stop_reason=why, n_iter=it,
                              transform=transform, metric=metric,
                              sigma2_metric=(s2g * sy ** 2) if transform == "nonrigid" else None,
                              sigma2_objective=s2_eval * sy ** 2,
                              _source=x, _target=y, _u=u, _coef=coef, _p=p, _frame=(my, sy), _n_steps=n_steps,
                              _kernel=kernel)
