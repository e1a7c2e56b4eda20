"""Pose search between point sets: every rotation captured, then refined by the analytic gradient.

The pose ``x ↦ A x + t`` of a source point set that best explains a target minimises a density
distance between the moved source's mixture and the target's (``shapelib.pointsets.density``):

    min_{A, t}  D²(A x + t, y) / ‖p_y‖²       (α: D² = ‖p_{Ax+t} − p_y‖², closed form)
    min_{A, t}  H²(A x + t, y)                (Fisher–Rao: squared Hellinger distance, quadrature)

with ``A = R`` (rigid), ``s R`` (similarity) or any ``A`` (affine). Neither needs correspondences
or equal sizes. The objective has a local minimum for nearly every coarse orientation of an
elongated shape, so one local start captures only rotations of up to about 90°. The search is
global in rotation:

1. both sets are centred and scaled by the target's RMS radius (σ² with them);
2. every start is scored at a coarse σ² (σ ≈ 0.3–0.6 of the radius, where the landscape is
   smooth): in 2-D ``n_angles`` rotations evenly spaced over 360°, in 3-D the four proper
   rotations taking the source's principal axes to the target's and the 60 rotations of the
   icosahedral group (no orientation farther than 44.5° from one of them); with ``reflection=True``
   each start also mirrored;
3. the best ``n_starts`` starts (in 2-D: local minima of the score over the circle of angles)
   are refined by L-BFGS with the analytic gradient at the coarse σ²;
4. those within ``SELECT_RTOL`` of the best refined objective there are followed while σ² is
   lowered by factors of 4 down to the requested σ², and the smallest objective at the requested
   σ² wins. (Choosing among all starts at a small σ² fails for deformed shapes: a wrong pose can
   overlap more of the target's points than the right one.)
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from .._validate import check_positive_int, check_sigma2
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING
from ..solver.linalg import one_blas_thread
from ._transforms import TRANSFORMS, Model
from .checks import as_point_set, check_same_dimension
from .density import DENSITY_METRICS, _hellinger_sq, _inner_grad, _l2_sq

__all__ = ["align", "Pose", "PoseSearchWarning", "COARSE_SIGMA2"]

#: the coarsest σ² of the search, in units of the target's squared RMS radius
COARSE_SIGMA2 = 0.1
#: starts whose refined objective at the coarsest σ² is within this fraction of the best are
#: followed down to the requested σ² (the others are dropped: at a small σ² a wrong pose of a
#: deformed shape can overlap the target better than the right one)
SELECT_RTOL = 0.05


class PoseSearchWarning(RuntimeWarning):
    """The local refinement of the best pose stopped before converging.

    A :class:`RuntimeWarning`: :func:`align` still returns the best pose found, with ``converged``
    false and ``stop_reason`` ``"max_iter"``.

    Parameters
    ----------
    *args : str
        The message, as for any warning (:func:`warnings.warn` passes its text when given this
        category).

    See Also
    --------
    align : What warns (``warn=False`` silences it; a larger ``max_iter`` lets it converge).

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from shapelib.pointsets import align, PoseSearchWarning
    >>> x = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.5, 1.5], [-0.5, 0.8]])
    >>> c, s = np.cos(0.7), np.sin(0.7)
    >>> y = 1.5 * x @ np.array([[c, -s], [s, c]]).T + [3.0, 1.0]
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     pose = align(x, y, sigma2=0.01, max_iter=1)
    >>> pose.converged, any(issubclass(w.category, PoseSearchWarning) for w in caught)
    (False, True)
    """


@dataclass
class Pose:
    """A pose ``x ↦ A x + t`` found by :func:`align`.

    Attributes
    ----------
    matrix : ndarray, shape (d, d)
        ``A`` (``s R`` for a similarity, ``R`` for a rigid motion; ``R`` may be a mirror when
        reflections were allowed).
    translation : ndarray, shape (d,)
        ``t``.
    rotation : ndarray, shape (d, d)
        The orthogonal factor of ``A`` (polar decomposition).
    scale : float
        ``|det A|^{1/d}``.
    reflection : bool
        ``det A < 0``.
    points : ndarray, shape (n, d)
        The source moved: ``A x + t``.
    value : float
        The density bound at ``sigma2`` after the move: ``‖p_{Ax+t} − p_y‖`` (α) or
        ``2 arccos ∫√(p_{Ax+t} p_y)`` (Fisher–Rao).
    objective : float
        The normalised objective minimised (module docstring).
    converged, stop_reason
        Whether the refinement of the winning start met its tolerance, and why it stopped
        (``"gradient"``, ``"objective_change"``, ``"no_decrease"``: converged; ``"max_iter"``: not).
    candidates : list of (float, ndarray, ndarray)
        Every refined start at the coarsest σ² as ``(objective, A, t)``, best first: the distinct
        poses the search found (:func:`shapelib.register` follows several of them).

    See Also
    --------
    align : The search that finds it.
    shapelib.pointsets.registration.RegistrationResult : A registration, whose ``pose`` this is.

    Notes
    -----
    The pose minimises a density distance between the mixtures of eq. (5) of [1]_ (module docstring).

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    A similarity found by :func:`align`, then used to move other points:

    >>> import numpy as np
    >>> from shapelib.pointsets import align
    >>> x = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.5, 1.5], [-0.5, 0.8]])
    >>> c, s = np.cos(0.7), np.sin(0.7)
    >>> y = 1.5 * x @ np.array([[c, -s], [s, c]]).T + [3.0, 1.0]
    >>> pose = align(x, y, sigma2=0.01, transform="similarity")
    >>> round(pose.scale, 3), round(pose.angle, 2), pose.reflection, pose.converged
    (1.5, 40.11, False, True)
    >>> bool(np.allclose(pose(x), y, atol=1e-4))
    True
    """

    matrix: np.ndarray
    translation: np.ndarray
    points: np.ndarray
    value: float
    objective: float
    converged: bool
    stop_reason: str
    transform: str
    metric: str
    sigma2: float
    n_starts: int
    n_iter: int
    candidates: list = field(default_factory=list, repr=False)

    @property
    def rotation(self) -> np.ndarray:
        u, _, vt = np.linalg.svd(self.matrix)
        return u @ vt

    @property
    def scale(self) -> float:
        return float(abs(np.linalg.det(self.matrix)) ** (1.0 / len(self.matrix)))

    @property
    def reflection(self) -> bool:
        return bool(np.linalg.det(self.matrix) < 0)

    @property
    def angle(self) -> float | None:
        """The rotation angle in degrees (2-D), or None (3-D)."""
        if len(self.matrix) != 2:
            return None
        r = self.rotation
        return float(np.degrees(np.arctan2(r[1, 0], r[0, 0])))

    def __call__(self, x) -> np.ndarray:
        """Move points ``x`` (k, d) by the pose."""
        x = np.asarray(x, dtype=np.float64)
        return x @ self.matrix.T + self.translation

    def summary(self) -> str:
        """A few lines: transform, the pose, the bound and convergence."""
        ang = f", angle {self.angle:.2f} deg" if self.angle is not None else ""
        return (f"{self.transform} pose ({self.metric}, sigma2 = {self.sigma2:.4g}): scale {self.scale:.4g}{ang}"
                f"{', mirrored' if self.reflection else ''}, translation {np.array2string(self.translation, precision=4)}\n"
                f"bound after the move {self.value:.6g}; {self.n_starts} starts refined, {self.n_iter} iterations; "
                f"{'converged' if self.converged else 'NOT converged'} ({self.stop_reason})")


def _rms(x):
    return float(np.sqrt(np.mean(np.sum(x * x, axis=1))))


def _stop(res, start) -> tuple[bool, str]:
    """``(converged, stop_reason)`` of an L-BFGS-B run ``res`` from the point ``start``.

    A run whose line search found no decrease stops with status 2 in SciPy before 1.17; from 1.17
    the same run ends with status 0 and "relative reduction of f" without having moved. Both are
    ``"no_decrease"`` here (a point no step lowers at machine precision: converged), told apart from a
    real relative-reduction stop by the point itself: it is still ``start``."""
    if res.status == 1:
        return False, "max_iter"
    if res.status == 0 and "GRAD" in str(res.message).upper():
        return True, "gradient"
    if res.status == 0 and not np.array_equal(res.x, start):
        return True, "objective_change"
    return True, "no_decrease"


class _Problem:
    """The normalised objective for one (x, y, σ², metric)."""

    def __init__(self, x, y, s2, metric, spacing, margin):
        self.x, self.y, self.s2, self.metric = x, y, s2, metric
        self.spacing, self.margin = spacing, margin
        if metric == "alpha":
            self.yy = float(_inner_grad(y, y, s2, grad=False)[0])  # ⟨p_y, p_y⟩

    def points_value(self, z, grad=True):
        if self.metric == "alpha":
            v, g = _l2_sq(z, self.y, self.s2, grad=grad, yy=self.yy)
            return v / self.yy, (None if g is None else g / self.yy)
        return _hellinger_sq(z, self.y, self.s2, grad=grad, spacing=self.spacing, margin=self.margin)

    def fun(self, p, model):
        a, t, _ = model.matrix(p)
        z = self.x @ a.T + t
        v, g = self.points_value(z)
        return float(v), model.chain(p, self.x, g)


def _starts(x, y, d, n_angles, reflection):
    """Start matrices B (rotations, possibly mirrored)."""
    mirrors = [np.eye(d)] + ([np.diag([-1.0] + [1.0] * (d - 1))] if reflection else [])
    out = []
    if d == 2:
        for k, m in enumerate(mirrors):
            for a in np.arange(n_angles) * 2 * np.pi / n_angles:
                c, s = np.cos(a), np.sin(a)
                out.append((k, np.array([[c, -s], [s, c]]) @ m))
        return out
    from scipy.spatial.transform import Rotation

    _, ex = np.linalg.eigh(x.T @ x)
    _, ey = np.linalg.eigh(y.T @ y)
    group = Rotation.create_group("I").as_matrix()
    for k, m in enumerate(mirrors):
        for f in ([1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]):
            r = ey @ np.diag(f) @ ex.T
            if np.linalg.det(r) * np.linalg.det(m) < 0:
                r = ey @ np.diag(f) @ np.diag([1, 1, -1]) @ ex.T
            out.append((k, r @ m @ m))  # principal axes onto principal axes (already mirrored if m is)
        for g in group:
            out.append((k, g @ m))
    return out


def align(source, target, *, sigma2, transform: str = "rigid", metric: str = "alpha", reflection: bool = False,
          n_angles: int = 36, n_starts: int = 6, max_iter: int = 200, grid_spacing: float = DEFAULT_SPACING,
          grid_margin: float = DEFAULT_MARGIN, warn: bool = True) -> Pose:
    """Pose of ``source`` that best explains ``target`` by a density distance, over every rotation.

    Minimises ``‖p_{Ax+t} − p_y‖² / ‖p_y‖²`` (α, closed form) or the squared Hellinger distance
    ``∫(√p_{Ax+t} − √p_y)²`` (Fisher–Rao, quadrature) over ``A`` (rotation, similarity or affine
    map) and ``t``, with a global search over rotations followed by L-BFGS on the analytic
    gradient while σ² is lowered to ``sigma2`` (the module docstring has the steps). The two sets
    may have different numbers of points and need no correspondence.

    Parameters
    ----------
    source, target : array_like, shapes (n, d) and (m, d)
        Point sets, d = 2 or 3.
    sigma2 : float
        σ² of both mixtures at the end of the search, in the units of the points.
    transform : {"rigid", "similarity", "affine"}
        The group searched.
    metric : {"alpha", "fisher_rao"}
        α bound (L² distance, closed form) or Fisher–Rao bound (Hellinger, quadrature).
    reflection : bool
        Also search mirror images of the source.
    n_angles : int
        2-D: start angles, evenly spaced (default every 10°). 3-D uses 64 fixed starts.
    n_starts : int
        How many of the best starts are refined.
    max_iter : int
        L-BFGS iterations per start and σ² level.
    grid_spacing, grid_margin : float
        Fisher–Rao quadrature (:func:`shapelib.hellinger_sq`).
    warn : bool
        Warn (:class:`PoseSearchWarning`) when the winning refinement did not converge.

    Returns
    -------
    Pose
        ``matrix``, ``translation``, ``points`` (the moved source), ``value`` (the bound at
        ``sigma2``), ``converged``, ``stop_reason``, ``summary()``; call it to move other points.

    See Also
    --------
    shapelib.pointsets.density.density_distance : The density distances it minimises.
    shapelib.pointsets.registration.register : Pose, then a non-rigid deformation.
    shapelib.pointsets.invariant.invariant_distance : Distances modulo the similarity group.

    Notes
    -----
    The α objective is the L² distance between the mixtures of eq. (5) of [1]_, the density-matching criterion
    also used by rigid point-set registration with Gaussian mixtures [2]_.

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
    >>> from shapelib.pointsets import align
    >>> t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    >>> x = np.column_stack([2 * np.cos(t) + 0.5 * np.cos(2 * t), np.sin(t)])  # a pear: no symmetry but a mirror
    >>> c, s = np.cos(2.5), np.sin(2.5)
    >>> y = x @ np.array([[c, -s], [s, c]]).T + [1.0, -2.0]
    >>> pose = align(x, y[::-1], sigma2=0.01)  # the target's points in another order
    >>> bool(np.allclose(pose.points, y, atol=1e-6)), round(pose.angle, 3)
    (True, 143.239)
    """
    x = as_point_set(source, name="source")
    y = as_point_set(target, name="target")
    check_same_dimension(x, y)
    s2 = check_sigma2(sigma2)
    if transform not in TRANSFORMS:
        raise ValueError(f"transform must be one of {TRANSFORMS}; got {transform!r}")
    if metric not in DENSITY_METRICS:
        raise ValueError(f"metric must be one of {DENSITY_METRICS}; got {metric!r}")
    n_angles = check_positive_int(n_angles, name="n_angles")
    n_starts = check_positive_int(n_starts, name="n_starts")
    max_iter = check_positive_int(max_iter, name="max_iter")
    d = x.shape[1]
    cx, cy = x.mean(axis=0), y.mean(axis=0)
    size = _rms(y - cy)
    xn, yn = (x - cx) / size, (y - cy) / size
    scale0 = size / max(_rms(x - cx), 1e-300) if transform != "rigid" else 1.0
    with one_blas_thread():  # small dense problems: a second BLAS thread only adds hand-off costs
        return _search(x, y, xn, yn, cx, cy, size, scale0, s2, transform, metric, reflection, n_angles, n_starts,
                       max_iter, grid_spacing, grid_margin, warn)


def _search(x, y, xn, yn, cx, cy, size, scale0, s2, transform, metric, reflection, n_angles, n_starts, max_iter,
            grid_spacing, grid_margin, warn):
    d = x.shape[1]
    s2n = s2 / size ** 2
    levels = [s2n]
    while levels[0] < COARSE_SIGMA2:
        levels.insert(0, levels[0] * 4)
    problems = [_Problem(xn, yn, lv, metric, grid_spacing, grid_margin) for lv in levels]
    starts = _starts(xn * scale0, yn, d, n_angles, reflection)
    models = [Model(transform, d, b, scale0) for _, b in starts]
    scores = np.array([problems[0].fun(m.start(), m)[0] for m in models])
    chosen = _choose(scores, starts, d, n_starts)
    # every chosen start refined at the coarsest σ²; those within SELECT_RTOL of the best there
    # (the shape's overall layout decides) are followed down to σ², where the best wins
    n_iter, coarse = 0, []
    for i in chosen:
        m = models[i]
        res = minimize(problems[0].fun, m.start(), args=(m,), jac=True, method="L-BFGS-B",
                       options={"maxiter": max_iter, "ftol": 1e-15, "gtol": 1e-11})
        n_iter += int(res.nit)
        coarse.append((float(res.fun), i, res))
    coarse.sort(key=lambda c: c[0])
    candidates = []
    for fval, i, res in coarse:
        a, tn, _ = models[i].matrix(res.x)
        candidates.append((fval, a, cy - a @ cx + size * tn))
    top = coarse[0][0]
    best = None
    for fval, i, res in coarse:
        if fval > top + SELECT_RTOL * max(top, 1e-300) + 1e-12:
            continue
        m, p = models[i], res.x
        start = m.start()
        for prob in problems[1:]:
            start = p
            res = minimize(prob.fun, p, args=(m,), jac=True, method="L-BFGS-B",
                           options={"maxiter": max_iter, "ftol": 1e-15, "gtol": 1e-11})
            p = res.x
            n_iter += int(res.nit)
        ok, why = _stop(res, start)
        cand = (float(res.fun), i, p, ok, why)
        if best is None or cand[0] < best[0]:
            best = cand
    fval, i, p, ok, why = best
    m = models[i]
    a, tn, _ = m.matrix(p)
    # back to the input units: y = A x + t with t = c_y − A c_x + size · t̃
    t = cy - a @ cx + size * tn
    points = x @ a.T + t
    prob = problems[-1]
    raw = prob.points_value(xn @ a.T + tn, grad=False)[0]
    if metric == "alpha":
        value = float(np.sqrt(max(raw * prob.yy, 0.0)) / size ** (d / 2))  # ‖p‖² scales as size^-d
    else:
        value = float(4.0 * np.arcsin(min(np.sqrt(max(raw, 0.0)) / 2.0, 1.0)))
    if warn and not ok:
        warnings.warn(f"align: the refinement of the best start stopped after {max_iter} iterations without "
                      f"converging ({why}); raise max_iter", PoseSearchWarning, stacklevel=3)
    return Pose(matrix=a, translation=t, points=points, value=value, objective=fval, converged=ok, stop_reason=why,
                transform=transform, metric=metric, sigma2=s2, n_starts=len(chosen), n_iter=n_iter,
                candidates=candidates)


def _choose(scores, starts, d, n_starts):
    """Indices of the starts to refine: in 2-D the local minima of the score over each circle of
    angles (per mirror), best first; in 3-D the best scores."""
    order = list(np.argsort(scores))
    if d != 2:
        return order[:n_starts]
    groups = np.array([k for k, _ in starts])
    keep = []
    for k in np.unique(groups):
        idx = np.flatnonzero(groups == k)
        s = scores[idx]
        loc = (s <= np.roll(s, 1)) & (s <= np.roll(s, -1))
        keep.extend(idx[loc])
    keep.sort(key=lambda i: scores[i])
    return keep[:n_starts] or order[:1]
