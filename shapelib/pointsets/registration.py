"""Registration of point sets by the information geometry: a deformation that is a geodesic of
the α-order (or Fisher–Rao) metric, found from every rotation, with a result that says when it
probably failed.

Both sets are mixtures of eq. (5), one component per point, centred and scaled to unit RMS radius
(the source keeps the target's scale for ``transform="rigid"``). ``register(source, target)``:

1. **Rigid, similarity, affine.** :func:`shapelib.align` minimises the density distance (α:
   closed-form L²; Fisher–Rao: Hellinger) over every rotation (a global search, not one local
   start); then EM on σ² (and, with ``w="auto"``, the outlier weight ``w = 1 − Σ_ij P_ij / m``)
   with the means held at the pose.
2. **Non-rigid (the default).** EM of Coherent Point Drift's model with the metric as the
   deformation's kernel (the equations: :mod:`shapelib.pointsets._coherent_em`), started from every
   rotation of a fixed set, the best starts fitted at a few fixed outlier weights and the fit of
   least negative log-posterior, with prices on the outlier weight and on the pose's turn, kept (the search:
   :mod:`shapelib.pointsets._nonrigid`). The means
   move to ``θ = u + G W`` with ``G`` the α-order metric of the source mixture in its weight
   coordinates, ``G_ab = ⟨N_a, N_b⟩_{L²} / ⟨N_a, N_a⟩_{L²} = exp(−|u_a − u_b|²/4σ_g²)``, and the
   M-step minimises ``Σ_ij P_ij |y_j − θ_i|²/2σ² + (λ/2) tr(Wᵀ G W)``: ``Wᵀ G W`` is the squared
   length of the displacement in the metric's dual, so that a displacement that moves neighbouring
   points together costs little and one that tears them apart costs much. (The metric on the
   means, ``kernel="means"``, ranks them the other way — two overlapping components moving apart
   leave the density almost unchanged — and deforms from the pose the search finds.)
   ``reliable`` is False when another start's distinct fit explains the target nearly as well or
   better (its objective without the price on the turn), when σ is large against the target's point spacing, or when most of the source is
   unmatched. Sets of over ``MAX_POINTS`` points go through farthest-point subsets, twice (two
   subsets of each set, from different first points): ``reliable`` is also False when the two
   fits move the source points apart by more than ``SUBSET_DISAGREEMENT`` of the target's RMS
   radius on average — the data do not fix where along the shape each point belongs.
3. **The deformation is a geodesic.** The path from the posed source to the fitted ``θ`` (points
   in correspondence) is the α-order (or Fisher–Rao) geodesic (:func:`shapelib.geodesic`) at the
   target's leave-one-out σ² (the spacing of its points, the scale of the paper's geodesics),
   computed on first use of ``result.path``. Other points are moved by the fit's kernel,
   ``x ↦ x + Σ_b G(x, u_b) W_b`` (exact at the source points), or, in 2-D on request, carried
   along the geodesic by the paper's extrinsic warp (§III-E, :func:`shapelib.extrinsic_warp`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .._executor import in_dask_worker, n_cores
from .._validate import check_nonnegative, check_nonnegative_int, check_positive, check_positive_int, check_sigma2
from ..geometry.metrics import alpha_metric, fisher_rao_metric
from ..solver.linalg import one_blas_thread
from ._coherent_em import box_volume, label_array, point_spacing, posteriors, sq_dist
from . import _nonrigid
from ._nonrigid import POSE_PRIOR
from .checks import as_point_set, check_same_dimension
from .density import DENSITY_METRICS
from .em import fit_mixture
from .pose import Pose, align

__all__ = ["register", "RegistrationResult", "RegistrationWarning", "REGISTRATION_TRANSFORMS"]

REGISTRATION_TRANSFORMS = ("rigid", "similarity", "affine", "nonrigid")
#: the largest outlier weight ``w="auto"`` estimates (rigid, similarity, affine)
W_MAX = 0.9
#: EM's σ² stays above this fraction of the target's leave-one-out σ²: an exact fit of some points
#: at σ² → 0 has an unbounded likelihood, which would otherwise decide between fits
SIGMA2_FLOOR = 1e-4
#: the deformation kernels: the metric in the mixture's weight coordinates, or on its means
KERNELS = ("weights", "means")
#: non-rigid: larger sets are registered through subsets of this many points (farthest-point samples),
#: the fit carried to every source point by the kernel: memory and time stay bounded
MAX_POINTS = 800
#: the start of the warning of a result that is probably wrong (its reasons follow)
PROBABLY_WRONG = "register: the registration is probably wrong: "


class RegistrationWarning(RuntimeWarning):
    """The registration probably failed: its EM stopped before meeting its tolerance, or the result
    is not ``reliable`` (another pose explains the target about as well, a large residual, most of
    the source unmatched).

    A :class:`RuntimeWarning`: :func:`register` still returns its estimate, with ``converged``
    false and ``stop_reason`` ``"max_iter"``, or ``reliable`` false and its ``reasons``.

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


def _check_w(w) -> bool:
    """Check the outlier weight ``w``: ``"auto"`` or a number in [0, 1). Returns whether it is ``"auto"``."""
    auto_w = isinstance(w, str)
    if auto_w and w != "auto":
        raise ValueError(f"w must be a number in [0, 1) or 'auto'; got {w!r}")
    if not auto_w and not 0.0 <= float(w) < 1.0:
        raise ValueError(f"w must be in [0, 1) or 'auto'; got {w!r}")
    return auto_w


def _rms(x):
    return float(np.sqrt(np.mean(np.sum(x * x, axis=1))))


def _centroid_sq(a):
    """Each point's squared distance from the centroid of ``a``."""
    return np.sum((a - a.mean(axis=0)) ** 2, axis=1)


def _posteriors(theta, y, s2, w):
    """P (n, m) with the uniform component over the target's bounding box; and Σ_ij P_ij |y_j − θ_i|²."""
    p = posteriors(theta, y, s2, w, box_volume(y))
    return p, float(np.sum(p * sq_dist(theta, y)))


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
    return np.exp(-sq_dist(a, b) / (4 * sigma2))


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
    deformation_energy : float
        The deformation's share of the fit's negative log-posterior, ``(λ/2) tr(Wᵀ G W)`` in nats
        (non-rigid, both sets in the normalised units of the search; 0 for the other transforms):
        what the warp cost (for sets over ``MAX_POINTS`` points, of the fit on the subsets). With
        ``sigma2`` it makes the registration distance
        (:func:`shapelib.pointsets.registration_distance.registration_distance`).
    converged, stop_reason, n_iter
        EM: ``"tolerance"`` (converged), ``"max_iter"`` (not), and the EM iterations of the fit
        kept. Convergence says that EM stopped at a fixed point, not that the fixed point is the
        right one: see ``reliable``.
    reliable : bool
        False when something says that the registration probably failed (non-rigid): another pose
        explains the target about as well or better with a different fit (scores within 0.15 per
        target point, or lower, without the price on the turn: a near-symmetric shape, or a target
        that no pose explains), the fit leaves σ above
        2 target point spacings, or more than a third of the source points match no target point
        (the warp only extrapolates them). The thresholds were chosen on samples 1–5 of the
        Chui–Rangarajan benchmark (and the last also on two samples of the 3-D benchmark's surfaces).
        Sets of over ``MAX_POINTS`` points are also not reliable when a second fit, on other
        subsets, moves the source points more than ``SUBSET_DISAGREEMENT`` (0.05) of the target's
        RMS radius from the first on average.
        ``register`` then warns (:class:`RegistrationWarning`) and ``summary()`` says so.
    reasons : tuple of str
        Why ``reliable`` is False (empty when it is True).
    diagnostics : dict
        What ``reliable`` was decided from: σ in target point spacings, the share of unmatched source
        points, and every final fit of the search as ``(objective, start, w)``, best first (the
        objective: the negative log-posterior plus the price on the pose's turn); for sets
        of over ``MAX_POINTS`` points also ``subsets`` (their sizes) and ``subset_disagreement``.
    target_correspondence : ndarray of int, shape (m,)
        For each target point the index of its source point (largest posterior), −1 where the
        outlier component explains more than half of it (clutter, a part the source lacks).
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
    deformation_energy: float = 0.0
    reliable: bool = True
    reasons: tuple = ()
    diagnostics: dict = field(repr=False, default_factory=dict)
    target_correspondence: np.ndarray = field(repr=False, default=None)
    _source: np.ndarray = field(repr=False, default=None)
    _target: np.ndarray = field(repr=False, default=None)
    _u: np.ndarray = field(repr=False, default=None)
    _coef: np.ndarray = field(repr=False, default=None)
    _p: np.ndarray = field(repr=False, default=None)
    _frame: tuple = field(repr=False, default=None)
    _n_steps: int = field(repr=False, default=16)
    _kernel: str = field(repr=False, default="weights")
    _geodesic: object = field(repr=False, default=None)
    _start: tuple = field(repr=False, default=None)

    @property
    def probabilities(self) -> np.ndarray:
        """Soft correspondences ``P`` (n, m): ``P_ij`` the posterior that target point j came
        from source point i (columns sum to ``1 −`` the outlier posterior). Not kept for sets over
        ``MAX_POINTS`` points (a ValueError)."""
        if self._p is None:
            raise ValueError(f"probabilities are not kept for sets over {MAX_POINTS} points (they would take "
                             f"{len(self.points) * len(self._target) * 8 / 1e9:.1f} GB); use correspondence")
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
        if self.transform != "nonrigid":
            return self.pose(x)
        d = x.shape[1]
        if method == "extrinsic":
            if d != 2:
                raise ValueError("the extrinsic warp (§III-E) is implemented in 2-D; use method='kernel' in 3-D")
            from ..comparison.warp import extrinsic_warp

            lam = 1e-3 * self._frame[1] ** 2 if lam is None else lam
            return extrinsic_warp(self.pose(x), self.geodesic, lam=lam, grid_size=grid_size)[-1]
        if method != "kernel":
            raise ValueError(f"method must be 'extrinsic' or 'kernel'; got {method!r}")
        if self.metric != "alpha":
            raise ValueError("method='kernel' needs the closed-form alpha kernel; register with metric='alpha'")
        mean, size = self._frame
        a0, t0, mx, sx = self._start
        zn = ((x - mx) / sx) @ a0.T + t0  # the frame of the fit
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
                f"bound between moved source and target {self.objective:.6g}; {matched} of {n} source points matched, "
                f"{int(np.sum(self.target_correspondence >= 0))} of {len(self._target)} target points\n"
                + ("reliable: nothing says the registration failed" if self.reliable else
                   "NOT RELIABLE (the registration probably failed): " + "; ".join(self.reasons)))


def register(source, target, *, transform: str = "nonrigid", metric: str = "alpha", sigma2="auto", w="auto",
             reflection: bool = False, lam: float = 2.0, sigma2_metric: float = 2.0, kernel: str = "weights",
             n_angles: int = 36, max_iter: int = 150, tol: float = 1e-5, n_steps: int = 16,
             warn: bool = True, progress=None, landmarks=None, n_threads: int | None = None,
             pose_prior: float = POSE_PRIOR) -> RegistrationResult:
    """Register the point set ``source`` onto ``target`` by the information geometry.

    Rigid, similarity or affine: the pose minimises a density distance over every rotation, then
    EM estimates σ² (and the outlier weight). Non-rigid: EM starts from the source turned by every
    rotation of a fixed set, the best starts (and the source as given) are carried to convergence at
    each of a few outlier weights, and the fit of least negative log-posterior, with prices on the
    outlier weight and on the pose's rotation, is the answer (:mod:`shapelib.pointsets._nonrigid`); the source mixture's means move as ``θ = u + G W`` with
    ``G`` the α-order (or Fisher–Rao) metric of the source mixture in its weight coordinates
    (:mod:`shapelib.pointsets._coherent_em` has the equations), and the deformation is the geodesic of
    that metric from the posed source to ``θ``. σ² and the outlier weight are chosen from the data
    with no switch to set, and the deformation's weight against the data (``lam`` σ²) follows σ².
    The sets may have different sizes and need no correspondence; the target may hold outliers and
    miss parts of the source, and the source parts of the target. The result says when it probably
    failed (``reliable``, ``reasons``).

    Parameters
    ----------
    source, target : array_like, shapes (n, d) and (m, d)
        Point sets, d = 2 or 3.
    transform : {"rigid", "similarity", "affine", "nonrigid"}
        ``"nonrigid"``: a smooth deformation, whose similarity part is reported as ``pose``.
    metric : {"alpha", "fisher_rao"}
        The density distance of the pose search and the metric of the deformation.
    sigma2 : float or "auto"
        σ² of the mixtures, in the target's units: fixed if a number; ``"auto"`` (default; ``None``
        too): estimated by EM.
    w : float or "auto"
        Weight of the uniform (outlier) component in ``[0, 1)``. ``"auto"`` (default): non-rigid,
        the weight of least negative log-posterior plus ``0.3 · m · w`` (a price on each of the
        ``m`` target points given up to the outliers) among 0.01, 0.05, 0.2 and 0.5 (each fit at its
        own fixed weight); rigid, similarity and affine, estimated by EM with the pose held.
    reflection : bool
        Also search mirror images of the source.
    lam : float
        λ, the weight of the deformation's squared dual-metric length (non-rigid). On the
        Chui–Rangarajan benchmark a larger λ suited the occluded fish, but the default 2 had the
        fewest failures over all the levels, on samples 1–5 (24, against 25–28 for λ = 1, 4, 8) and
        on samples 6–10 (27, against 30–39).
    sigma2_metric : float
        σ_g² of the metric that regularises and carries the deformation, in units of the target's
        squared RMS radius (default 2: the kernel ``exp(−|Δ|²/4σ_g²)`` is CPD's Gaussian of width
        β = 2).
    n_angles : int
        2-D start angles of the pose search of the rigid transforms (:func:`shapelib.align`).
    max_iter : int
        EM iterations per fit (non-rigid: the extrapolated iterations of the acceleration included).
    tol : float
        EM stops when one iteration changes σ² by less than ``tol`` (relative).
    n_steps : int
        Time steps of the deformation path.
    warn : bool
        Warn (:class:`RegistrationWarning`) when EM stops without converging or the result is not
        ``reliable``.
    progress : callable, optional
        Called as ``progress(done, total)`` as the search advances (non-rigid: after each start's
        screening and each final fit; the other transforms: after the pose search and after EM), for a
        progress bar on long fits (``shapelib register`` draws one on a terminal).
    landmarks : array_like of int, shape (k, 2), optional
        Known correspondences, non-rigid only: rows ``(i, j)``, source point ``i`` is target point
        ``j``. Each such target point is explained by its source point alone, with posterior 1 (its
        label observed, as in the extended CPD of [5]_), in every E-step and in the objective that
        compares the search's fits; the other points are matched as usual. A few landmarks decide
        a pose that a near-symmetric shape or a partial target leaves ambiguous. Each source and
        target index at most once.
    n_threads : int, optional
        Threads of the non-rigid search: its starts, and then its final fits, run side by side (the
        compiled EM releases the GIL; the result does not depend on the number). Default: every core
        this process may use, one inside a Dask worker (where the engine runs one task per core).
    pose_prior : float
        κ, in nats per source point, of the price on the rotation of the non-rigid fit's pose:
        ``κ n (1 − cos φ)`` for a turn by φ of ``n`` source points (in general ``κ n (d − tr R)/2``
        for the orthogonal part ``R`` of the pose; with ``reflection=True`` a mirror image costs at
        least a quarter turn: in 2-D exactly one), added to each fit's negative log-posterior. Of two fits that explain the target about equally well,
        the one that turns the source less wins: a shape turned by 90°–180° and slid along its own
        outline no longer wins over a noisy or occluded target by a few nats, while a rotated target's
        right pose, which leads by 0.35 nats per point and more on the Chui–Rangarajan benchmark, still
        wins. 0: no price, the fits are compared by how well they explain the target alone
        (the registration distance, :func:`shapelib.pointsets.registration_distance.registration_distance`,
        registers with 0).

    Returns
    -------
    RegistrationResult
        ``points``, ``correspondence``, ``probabilities``, ``warp(x)``, ``pose``, ``path``,
        ``objective``, ``sigma2``, ``w``, ``converged``, ``stop_reason``, ``reliable``, ``reasons``,
        ``summary()``.

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
    .. [5] V. Golyanik, B. Taetz, G. Reis and D. Stricker, "Extended coherent point drift algorithm with
       correspondence priors and optimal subsampling", *IEEE Winter Conference on Applications of Computer
       Vision (WACV)*, 2016.

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
    if isinstance(sigma2, str) and sigma2 != "auto":
        raise ValueError(f"sigma2 must be a positive number or 'auto'; got {sigma2!r}")
    fixed_s2 = None if sigma2 is None or isinstance(sigma2, str) else check_sigma2(sigma2)
    auto_w = _check_w(w)
    w0 = 0.1 if auto_w else float(w)
    lam = check_positive(lam, name="lam")
    s2g = check_positive(sigma2_metric, name="sigma2_metric")
    max_iter = check_positive_int(max_iter, name="max_iter")
    n_steps = check_positive_int(n_steps, name="n_steps")
    check_nonnegative_int(n_angles, name="n_angles")
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}; got {kernel!r}")
    tol = check_positive(tol, name="tol")
    pose_prior = check_nonnegative(pose_prior, name="pose_prior")
    if transform == "nonrigid" and max(len(x), len(y)) > MAX_POINTS and (metric, kernel) != ("alpha", "weights"):
        raise ValueError(f"sets of over {MAX_POINTS} points are registered with metric='alpha' and kernel='weights' "
                         f"(their fit is carried to every point by the kernel); got metric={metric!r}, kernel={kernel!r}")
    if progress is not None and not callable(progress):
        raise ValueError(f"progress must be a callable progress(done, total) or None; got {progress!r}")
    tick = progress if progress is not None else (lambda done, total: None)
    pairs = _check_landmarks(landmarks, len(x), len(y), transform)
    threads = (1 if in_dask_worker() else n_cores()) if n_threads is None else check_positive_int(
        n_threads, name="n_threads")

    finished = [0]  # the work of the parts already fitted

    def fit(xs, ys, pairs_s, part=(0, 1)):
        # part (i, n): the i-th of the n fits of a large registration (run in order); progress counts all n,
        # the parts still to come as large as this one until they run, and the first warns
        i, n = part
        base = finished[0]

        def tick_p(done, total):
            tick(base + done, base + (n - i) * total)
            if done == total:  # the part's last step: the next part counts on from here
                finished[0] = base + total

        warn_p = warn and i == 0
        if transform == "nonrigid":
            return _register_nonrigid(xs, ys, metric, fixed_s2, w0, auto_w, reflection, lam, s2g, kernel, max_iter,
                                      tol, n_steps, warn_p, tick_p, pairs=pairs_s, n_threads=threads,
                                      pose_prior=pose_prior)
        return _register(xs, ys, transform, metric, fixed_s2, w0, auto_w, reflection, lam, s2g, kernel, n_angles,
                         max_iter, tol, n_steps, warn_p, tick_p)

    with one_blas_thread():
        if max(len(x), len(y)) > MAX_POINTS:
            return _register_large(x, y, fit, pairs, warn=warn)
        return fit(x, y, pairs)


def _check_landmarks(landmarks, n, m, transform):
    """``landmarks`` of :func:`register` as an int array (k, 2), or None."""
    if landmarks is None:
        return None
    if transform != "nonrigid":
        raise ValueError(f"landmarks: known correspondences are used by transform='nonrigid'; got "
                         f"transform={transform!r}")
    arr = np.asarray(landmarks)
    if arr.size == 0:
        return None
    if arr.ndim != 2 or arr.shape[1] != 2 or not (np.issubdtype(arr.dtype, np.integer)
                                                   or np.all(np.mod(arr, 1) == 0)):
        raise ValueError(f"landmarks: expected rows (source index, target index) of integers, shape (k, 2); got "
                         f"shape {arr.shape} of {arr.dtype}")
    arr = arr.astype(np.int64)
    for col, size, name in ((0, n, "source"), (1, m, "target")):
        bad = np.flatnonzero((arr[:, col] < 0) | (arr[:, col] >= size))
        if bad.size:
            raise ValueError(f"landmarks: row {bad[0]} names {name} point {arr[bad[0], col]}, outside 0..{size - 1}")
        vals, counts = np.unique(arr[:, col], return_counts=True)
        if np.any(counts > 1):
            raise ValueError(f"landmarks: {name} point {vals[np.argmax(counts > 1)]} is named in more than one row")
    return arr


@dataclass
class _EMState:
    u: np.ndarray
    g: None
    coef: None
    s2: float
    w: float
    it: int = 0
    ok: bool = False
    why: str = "max_iter"

    @property
    def theta(self):
        return self.u


def _em(st, yn, *, lam, fixed_s2, auto_w, max_iter, tol, s2_floor=1e-12):
    """EM on σ² (and w) with the means held at the pose (the rigid transforms)."""
    n, d = st.u.shape
    if fixed_s2 is not None and not auto_w:
        st.ok, st.why = True, "tolerance"  # nothing to estimate: pose and σ² given
        return st
    for _ in range(max_iter):
        st.it += 1
        p, sse = _posteriors(st.u, yn, st.s2, st.w)
        np_ = float(p.sum())
        s2_old, w_old = st.s2, st.w
        if fixed_s2 is None:
            st.s2 = max(sse / (np_ * d), s2_floor)
        if auto_w:
            st.w = float(np.clip(1.0 - np_ / len(yn), 1e-6, W_MAX))
        if abs(st.s2 - s2_old) <= tol * s2_old and abs(st.w - w_old) <= tol:
            st.ok, st.why = True, "tolerance"
            break
    return st


def _objective_at(theta, yn, s2_eval, metric, sy):
    """The density bound between the moved source and the target at ``s2_eval`` (in the target's units)."""
    from .density import _hellinger_sq, _l2_sq

    d = yn.shape[1]
    if metric == "alpha":
        return float(np.sqrt(max(_l2_sq(theta, yn, s2_eval, grad=False)[0], 0.0)) / sy ** (d / 2))
    h2 = _hellinger_sq(theta, yn, s2_eval, grad=False)[0]
    return float(4.0 * np.arcsin(min(np.sqrt(max(h2, 0.0)) / 2, 1.0)))


def _frames(x, y, transform):
    my, sy = y.mean(axis=0), _rms(y - y.mean(axis=0))
    mx = x.mean(axis=0)
    sx = sy if transform == "rigid" else _rms(x - mx)
    return (x - mx) / sx, (y - my) / sy, mx, sx, my, sy


def _register(x, y, transform, metric, fixed_s2, w, auto_w, reflection, lam, s2g, kernel, n_angles, max_iter, tol,
              n_steps, warn, tick):
    """Rigid, similarity or affine: the pose search, then EM on σ² (and w) with the means held."""
    xn, yn, mx, sx, my, sy = _frames(x, y, transform)
    # pose: σ² of the search's last level from the target's own spread (leave-one-out), or the given one
    s2_pose = fixed_s2 / sy ** 2 if fixed_s2 is not None else fit_mixture(yn, warn=False).sigma2
    pn = align(xn, yn, sigma2=s2_pose, transform=transform, metric=metric, reflection=reflection,
               n_angles=max(n_angles, 1), warn=warn)
    tick(1, 2)
    u = xn @ pn.matrix.T + pn.translation
    s2 = fixed_s2 / sy ** 2 if fixed_s2 is not None else float(np.mean(sq_dist(u, yn)) / x.shape[1])
    st = _em(_EMState(u=u, g=None, coef=None, s2=s2, w=w), yn, lam=lam, fixed_s2=fixed_s2, auto_w=auto_w,
             tol=tol, s2_floor=SIGMA2_FLOOR * s2_pose, max_iter=max_iter)
    tick(2, 2)
    if warn and not st.ok:
        warnings.warn(f"register: EM stopped after {max_iter} iterations without converging (sigma2 = "
                      f"{st.s2 * sy ** 2:.3g}); raise max_iter or loosen tol", RegistrationWarning, stacklevel=4)
    a = pn.matrix * (sy / sx)  # the pose in the input units: x -> A (x − m_x)/s_x · s_y + t̃ s_y + m_y
    t = my + sy * pn.translation - a @ mx
    # the bound at the pose in the input units, as Pose documents it (the search's is in the normalised frame:
    # the α distance ‖p − q‖ of d-dimensional densities scales as size^(−d/2); Fisher–Rao's has no units)
    value = pn.value / sy ** (x.shape[1] / 2) if metric == "alpha" else pn.value
    pose = Pose(matrix=a, translation=t, points=x @ a.T + t, value=value, objective=pn.objective,
                converged=pn.converged, stop_reason=pn.stop_reason, transform=pn.transform, metric=metric,
                sigma2=s2_pose * sy ** 2, n_starts=pn.n_starts, n_iter=pn.n_iter)
    p, _ = _posteriors(st.theta, yn, st.s2, st.w)
    return _result(x, y, st.theta, p, pose, yn, my, sy, s2_pose, st, transform, metric, None, kernel, n_steps,
                   reasons=[], diagnostics={})


def deformation_energy(st, lam):
    """``(λ/2) tr(Wᵀ G W)`` of a non-rigid fit ``st`` (:class:`~shapelib.pointsets._coherent_em.EMState`):
    the deformation's term of the negative log-posterior ``F`` (:mod:`~shapelib.pointsets._coherent_em`)."""
    return 0.5 * lam * st.kernel.energy(st.coef)


def _in_range(st):
    """The fit's coefficients for :meth:`RegistrationResult.warp`: ``W`` without its part along the
    kernel's dropped eigenvectors (:meth:`~shapelib.pointsets._coherent_em.Kernel.in_range`), so that
    the warp reproduces the fitted points; a fit without a kernel (rigid EM) keeps its own."""
    kernel = getattr(st, "kernel", None)
    return st.coef if kernel is None else kernel.in_range(st.coef)


def _result(x, y, theta, p, pose, yn, my, sy, s2_eval, st, transform, metric, s2g, kernel, n_steps, *, reasons,
            diagnostics, start=None, energy=0.0):
    p1 = p.sum(axis=1)
    corr = np.where(p1 >= 0.5, np.argmax(p, axis=1), -1)
    outlier = 1.0 - p.sum(axis=0)
    tcorr = np.where(outlier < 0.5, np.argmax(p, axis=0), -1)
    return RegistrationResult(points=theta * sy + my, correspondence=corr, pose=pose,
                              objective=_objective_at(theta, yn, s2_eval, metric, sy),
                              sigma2=st.s2 * sy ** 2, w=float(st.w), converged=st.ok, stop_reason=st.why,
                              n_iter=st.it, transform=transform, metric=metric,
                              sigma2_metric=None if s2g is None else s2g * sy ** 2,
                              sigma2_objective=s2_eval * sy ** 2, deformation_energy=float(energy),
                              reliable=not reasons, reasons=tuple(reasons),
                              diagnostics=diagnostics, target_correspondence=tcorr,
                              _source=x, _target=y, _u=st.u, _coef=_in_range(st), _p=p, _frame=(my, sy),
                              _n_steps=n_steps, _kernel=kernel, _start=start)


def _nonrigid_frame(x, y, fixed_s2, target_s2=None):
    """The normalised sets of the non-rigid search and the σ² they need: ``(xn, yn, mx, sx, my, sy)``,
    the fixed σ² in normalised units (or None) and ``s2_eval`` (the given σ² or the target's
    leave-one-out σ²: the objective's, and the scale of EM's σ² floor; ``target_s2`` if it is known)."""
    frame = _frames(x, y, "nonrigid")
    sy, yn = frame[5], frame[1]
    fs2 = None if fixed_s2 is None else fixed_s2 / sy ** 2
    if fs2 is not None:
        s2_eval = fs2
    else:
        s2_eval = fit_mixture(yn, warn=False).sigma2 if target_s2 is None else target_s2
    return frame, fs2, s2_eval


def _register_nonrigid(x, y, metric, fixed_s2, w, auto_w, reflection, lam, s2g, kernel, max_iter, tol, n_steps,
                       warn, tick, *, pose_prior, pairs=None, n_threads=1):
    """Non-rigid: the search of :mod:`shapelib.pointsets._nonrigid` over starts and outlier weights."""
    frame, fs2, s2_eval = _nonrigid_frame(x, y, fixed_s2)
    xn, yn = frame[:2]
    # the search runs with the α-order metric's weight kernel (a smooth Gaussian kernel that carries a
    # rotation, a scale and a bend coherently); another metric or kernel deforms from the pose it finds
    search_kernel = _nonrigid.with_kernel(lambda u: _kernel(u, s2g, "alpha", "weights"), invariant=True)
    em_opts = dict(lam=lam, fixed_s2=fs2, max_iter=max_iter, tol=tol, s2_floor=SIGMA2_FLOOR * s2_eval)
    volume = box_volume(yn)
    labels = label_array(pairs, len(yn))
    fits, rots, _ = _nonrigid.fit_all(xn, yn, kernel_of=search_kernel, w=None if auto_w else w,
                                      reflection=reflection, progress=tick, volume=volume, labels=labels,
                                      n_threads=n_threads, pose_prior=pose_prior, **em_opts)
    return _nonrigid_result(x, y, frame, s2_eval, fits, rots, metric=metric, reflection=reflection, s2g=s2g,
                            kernel=kernel, em_opts=em_opts, n_steps=n_steps, warn=warn, stacklevel=5,
                            volume=volume, labels=labels, pose_prior=pose_prior)


def _nonrigid_result(x, y, frame, s2_eval, fits, rots, *, metric, reflection, s2g, kernel, em_opts, n_steps, warn,
                     stacklevel, pose_prior, volume=None, labels=None):
    """The :class:`RegistrationResult` of the search's ``fits`` (best first, as
    :func:`shapelib.pointsets._nonrigid.fit_all` gives them): the reliability reasons, the pose (the
    fit's similarity part), the refit with another metric or kernel, the warnings. :func:`register` and
    :func:`shapelib.register_many` (``backend="jax"``) both build their results here."""
    xn, yn, mx, sx, my, sy = frame
    max_iter = em_opts["max_iter"]
    spacing2 = _spacing2(yn)
    volume = box_volume(yn) if volume is None else volume
    f0, k, st = fits[0]
    start = (rots[k], np.zeros(x.shape[1]))  # x -> u = ((x − m_x)/s_x) A0ᵀ + t0, the fit's frame
    reasons, diagnostics = _nonrigid.assess(fits, yn, spacing2=spacing2, volume=volume, labels=labels, xn=xn,
                                            pose_prior=pose_prior, reflection=reflection)
    # the similarity part of the deformation, as the pose (the posed source: the geodesic's start)
    a, t = _similarity_part(xn, st.theta, reflection)
    if (metric, kernel) != ("alpha", "weights"):
        st = _nonrigid.refit(xn @ a.T + t, yn, st.w, _nonrigid.with_kernel(
            lambda u: _kernel(u, s2g, metric, kernel), invariant=False), volume=volume, labels=labels, **em_opts)
        f0, start = None, (a, t)
        reasons = reasons + _nonrigid.assess([(0.0, 0, st)], yn, spacing2=spacing2, volume=volume,
                                             labels=labels)[0]
        a, t = _similarity_part(xn, st.theta, reflection)
    theta = st.theta
    diagnostics.update(objective=f0, candidates=[(f, int(kk), float(s.w)) for f, kk, s in fits])
    p = posteriors(theta, yn, st.s2, st.w, volume, labels)
    a_in = a * (sy / sx)
    t_in = my + sy * t - a_in @ mx
    pose = Pose(matrix=a_in, translation=t_in, points=x @ a_in.T + t_in, value=float("nan"), objective=f0,
                converged=st.ok, stop_reason=st.why, transform="similarity", metric=metric,
                sigma2=st.s2 * sy ** 2, n_starts=len(rots), n_iter=st.it)
    if warn and not st.ok:
        warnings.warn(f"register: EM stopped after {max_iter} iterations without converging (sigma2 = "
                      f"{st.s2 * sy ** 2:.3g}); raise max_iter or loosen tol", RegistrationWarning,
                      stacklevel=stacklevel)
    if warn and reasons:
        warnings.warn(PROBABLY_WRONG + "; ".join(reasons), RegistrationWarning, stacklevel=stacklevel)
    return _result(x, y, theta, p, pose, yn, my, sy, s2_eval, st, "nonrigid", metric, s2g, kernel, n_steps,
                   reasons=reasons, diagnostics=diagnostics, start=(*start, mx, sx),
                   energy=deformation_energy(st, em_opts["lam"]))


#: source points warped at a time in a large registration (bounds the kernel block's memory)
WARP_BLOCK = 4096
#: a large registration is not reliable when its second fit, on other subsets, moves the source points
#: farther than this from the first's on average, in units of the target's RMS radius (the failure line of
#: the registration benchmarks). Measured on the two record cases of ``benchmarks/bench_registration_large.py``
#: that nothing else flags: 2-D, 10⁴ points, three subset pairs 0.014–0.016 apart (errors 0.010–0.021); 3-D
#: with three landmarks, 0.053–0.063 apart (errors 0.044–0.069)
SUBSET_DISAGREEMENT = 0.05


def farthest_points(a, k, *, first=None):
    """Indices of ``k`` points of ``a`` spread over it: farthest-point sampling from the point nearest
    the centroid (deterministic), or from point ``first``."""
    idx = np.empty(k, dtype=np.intp)
    idx[0] = int(np.argmin(_centroid_sq(a))) if first is None else first
    dist = np.sum((a - a[idx[0]]) ** 2, axis=1)
    for i in range(1, k):
        idx[i] = int(np.argmax(dist))
        dist = np.minimum(dist, np.sum((a - a[idx[i]]) ** 2, axis=1))
    return np.sort(idx)


def _subsets(x, y, pairs, first_x=None, first_y=None):
    """Farthest-point subsets of ``MAX_POINTS`` (less the landmarks) of each set, from the given first
    points (default: nearest the centroid), the landmarks joined to them and their rows renumbered into
    them: ``(ix, iy, sub_pairs)``."""
    k = 0 if pairs is None else len(pairs)
    ix = farthest_points(x, min(len(x), MAX_POINTS - k), first=first_x)
    iy = farthest_points(y, min(len(y), MAX_POINTS - k), first=first_y)
    if not k:
        return ix, iy, None
    ix, iy = np.union1d(ix, pairs[:, 0]), np.union1d(iy, pairs[:, 1])
    return ix, iy, np.column_stack([np.searchsorted(ix, pairs[:, 0]), np.searchsorted(iy, pairs[:, 1])])


def _register_large(x, y, fit, pairs=None, *, warn=True):
    """Sets over ``MAX_POINTS``: ``fit(xs, ys, pairs, part)`` (the registration of two sets, the
    ``part[0]``-th of ``part[1]``) on farthest-point subsets of ``MAX_POINTS``, its warp (the kernel's,
    or the pose of a rigid transform) applied to every source point in blocks, correspondences by
    nearest neighbours within 3σ plus a point spacing. A second fit on other subsets (farthest points
    from the points farthest from the centroids) checks the first: where they move the source points
    apart by more than ``SUBSET_DISAGREEMENT`` of the target's RMS radius, the result is not reliable.
    Memory is O((n + m) · MAX_POINTS) whatever the sizes."""
    from dataclasses import replace

    from scipy.spatial import cKDTree

    k = 0 if pairs is None else len(pairs)
    if k > MAX_POINTS // 2:
        raise ValueError(f"landmarks: at most {MAX_POINTS // 2} known correspondences for sets over {MAX_POINTS} "
                         f"points; got {k}")
    ix, iy, sub_pairs = _subsets(x, y, pairs)
    sub = fit(x[ix], y[iy], sub_pairs, (0, 2))
    points = _warp_blocks(sub, x)
    far = [int(np.argmax(_centroid_sq(a))) for a in (x, y)]
    jx, jy, other_pairs = _subsets(x, y, pairs, *far)
    other = fit(x[jx], y[jy], other_pairs, (1, 2))
    radius = _rms(y - y.mean(axis=0))
    apart = float(np.mean(np.linalg.norm(points - _warp_blocks(other, x), axis=1))) / max(radius, 1e-300)
    reasons = list(sub.reasons)
    if apart > SUBSET_DISAGREEMENT:
        why = (f"a fit on other subsets of the points moves them {apart:.3f} of the target's radius away on average: "
               f"the data do not fix where along the shape each point belongs")
        reasons.append(why)
        if warn:
            warnings.warn(PROBABLY_WRONG + why, RegistrationWarning, stacklevel=3)
    reach = 3.0 * np.sqrt(sub.sigma2) + np.sqrt(_spacing2(y))
    dist, near = cKDTree(y).query(points)
    corr = np.where(dist <= reach, near, -1)
    dist_t, near_t = cKDTree(points).query(y)
    tcorr = np.where(dist_t <= reach, near_t, -1)
    if k:  # the known correspondences as given
        corr[pairs[:, 0]], tcorr[pairs[:, 1]] = pairs[:, 1], pairs[:, 0]
    diagnostics = dict(sub.diagnostics, subsets=(len(ix), len(iy)), subset_disagreement=apart)
    return replace(sub, points=points, correspondence=corr, target_correspondence=tcorr, diagnostics=diagnostics,
                   reliable=not reasons, reasons=tuple(reasons), _source=x, _target=y, _p=None, _geodesic=None)


def _warp_blocks(res, x):
    """``res.warp`` applied to the points ``x`` in blocks of ``WARP_BLOCK``."""
    return np.concatenate([res.warp(x[i:i + WARP_BLOCK]) for i in range(0, len(x), WARP_BLOCK)])


def _similarity_part(x, theta, reflection):
    """The similarity ``x ↦ a x + t`` of least squares onto the fitted points ``theta`` (ordinary
    Procrustes with scale, :func:`~shapelib.geometry.procrustes.optimal_rotation`)."""
    from ..geometry.procrustes import optimal_rotation

    mx, mt = x.mean(axis=0), theta.mean(axis=0)
    xc = x - mx
    r, trace = optimal_rotation(theta - mt, xc, reflection=reflection)  # theta − mt ≈ xc r
    a = trace / max(float(np.sum(xc * xc)), 1e-300) * r.T
    return a, mt - a @ mx


def _spacing2(yn):
    """The squared median nearest-neighbour distance of the target: its point spacing."""
    return float(max(point_spacing(yn), 1e-12) ** 2)
