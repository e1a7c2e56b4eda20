r"""Certified distance brackets: ``lower ≤ d(u, v) ≤ upper`` to a relative accuracy ``rtol``.

A geodesic distance (eqs. 8–12) is only as accurate as the time discretisation of the path
(``n_steps``), which is ~1e-4 relative for the corpus callosum at σ² = 0.5 — so driving the
path energy to 1e-9 (the Newton-decrement certificate of :func:`shapelib.geodesic`)
buys nothing for a distance. What a distance needs is a certified interval:

* **lower**: the closed-form bound of the metric (:func:`lower_bound`). Both metrics are
  pull-backs of flat L² (α-order, eq. 22: :math:`\theta \mapsto p`; Fisher–Rao, eq. 6:
  :math:`\theta \mapsto 2\sqrt{p}` on the sphere of radius 2), so no path is shorter than the
  chord :math:`\|p_u - p_v\|` (:func:`shapelib.l2_distance`) or the great circle
  :math:`2 \arccos \int \sqrt{p_u p_v}\, dx` (:func:`shapelib.fisher_rao_lower_bound`).
* **upper**: the length of an actual path from ``u`` to ``v``
  (:func:`shapelib.path_length`), which no geodesic can beat.

.. math::

    \text{lower} \le d(u, v) \le \text{upper}, \qquad
    \frac{\text{upper}}{\text{lower}} - 1 \le \text{rtol}.

:func:`distance_bracket` starts from the bound and the straight line and refines the path only
until ``upper / lower − 1 ≤ rtol``: a few Levenberg–Marquardt iterations at a small
``n_steps``, stopped as soon as ``√E ≤ lower · (1 + rtol)`` (``length ≤ √E`` by
Cauchy–Schwarz), then, if the iterations at that ``n_steps`` stop paying, ``n_steps`` doubled
with the current path as the start (the same piecewise-linear curve, so the gap never grows).
When doubling no longer shrinks the gap enough to reach ``rtol`` — the geodesic itself is
longer than the chord, which happens at small σ² (``notebooks/alpha_discretisation.py``) — it
stops and reports the gap honestly (``stopped_by="stalled"``).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._validate import as_pair_batch, as_shape_pair, check_positive, check_positive_int, check_sigma2
from .geodesic import _check_entries, check_entry, fisher_rao_lower_bound
from .batched import batched_geodesics, check_backend
from .minimise import minimise_path
from .path_metric import METRICS, path_metric
from .result import BracketStopReason, GeodesicWarning
from ..geometry.gmm import l2_distance
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING
from ..geometry.scale import SIGMA_RATIO_MIN

__all__ = ["DistanceBracket", "distance_bracket", "distance_brackets", "JAX_LEVEL_ITER", "JAX_LEVEL_WINDOW", "extrapolate_doublings", "lower_bound", "refine_path"]

#: Hessian of the Levenberg–Marquardt steps per metric when ``hessian=None``. Measured on the CC
#: pairs at σ² = 0.5 (2026-11-23, load ~20, so as ratios): α exact 32 iterations for 21 pairs,
#: model 45 and ~5 % slower; Fisher–Rao exact 9 iterations for 7 pairs, model 14 but 1.5–1.9×
#: faster in all (a model-Hessian iteration is ~4× cheaper: metric tensors at the segment
#: midpoints instead of Hessians of the quadratic form at every Gauss–Legendre node).
DEFAULT_HESSIAN = {"alpha": "exact", "fisher_rao": "model"}
#: Fisher–Rao quadrature step (in σ) of a bracket with ``rtol ≥ BRACKET_SPACING_RTOL`` when
#: ``grid_spacing`` is not given. Against a 0.25σ grid, the bound and the straight-line length of
#: the 21 corpus callosum pairs differ by at most 3e-8 (σ² = 0.1, 0.5) and 3.2e-7 (σ² = 1.5)
#: relative at 0.5σ, far inside any such rtol, with half the nodes of the library's 0.35σ: the
#: Fisher–Rao brackets at σ² = 0.5 run 2.1× faster (4.0 → 8.4 pairs/s), same iterations.
BRACKET_SPACING = 0.5
BRACKET_SPACING_RTOL = 1e-5
#: ``backend="jax"``: L-BFGS iterations per level per ``level_iter`` (an L-BFGS iteration is one
#: gradient, far cheaper and weaker than a Levenberg–Marquardt step)
JAX_LEVEL_ITER = 100
#: ``backend="jax"``: iterations over which a level's energy decrease is measured
JAX_LEVEL_WINDOW = 10


@dataclass
class DistanceBracket:
    r"""A certified bracket ``lower ≤ d(u, v) ≤ upper`` on a geodesic distance.

    ``lower`` is the closed-form bound of the metric, ``upper`` the length of an actual path under
    the metric of eq. (6) or (22) of [1]_, so

    .. math::

        \text{lower} \le d(u, v) \le \text{upper} \le \sqrt{E_n}, \qquad
        \text{gap} = \frac{\text{upper}}{\text{lower}} - 1

    (``rel_gap``), :math:`E_n` the path energy of eq. (8).

    Attributes
    ----------
    lower : float
        Closed-form bound (α: ``‖p_u − p_v‖``; Fisher–Rao: ``2 arccos ∫ √(p_u p_v)``).
    upper : float
        Length of the computed path (an upper bound on the geodesic distance).
    rel_gap : float
        ``upper / lower − 1`` (0.0 if ``u == v``; ``inf`` if the densities coincide but the
        landmarks do not, e.g. relabelled landmarks).
    energy : float
        Path energy (eq. 8) of the computed path (``≥ upper²``, ≈ ``upper²``).
    path : ndarray, shape (n_steps + 1, K, d)
        The computed path.
    metric : str
        The metric's name.
    sigma2 : float
        σ² of eq. (5).
    n_steps : int
        The ``n_steps`` it ended with.
    n_iter : int
        Levenberg–Marquardt iterations, summed over the refinements.
    converged : bool
        ``rel_gap ≤ rtol``.
    stopped_by : str
        A :class:`~shapelib.BracketStopReason` value (also :attr:`stop_reason`):
        ``"rtol"``, ``"stalled"`` (the gap stopped shrinking; reported as it is),
        ``"trivial"`` (``u == v``) or ``"max_n_steps"``.
    seconds : float
        Wall-clock time of the computation.
    log : dict
        ``levels``: per ``n_steps`` level, ``{"n_steps", "n_iter", "upper", "rel_gap",
        "stopped_by", "seconds"}``; ``rtol``; the options used.
    stop_reason : BracketStopReason
        ``stopped_by`` as an enum (property).

    See Also
    --------
    shapelib.distance_bracket : What returns it.
    shapelib.GeodesicResult : A geodesic solved to its own tolerance.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> b = sl.distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=1e-2)
    >>> b.converged, b.stop_reason, bool(b.lower <= b.upper <= (1 + 1e-2) * b.lower)
    (True, <BracketStopReason.RTOL: 'rtol'>, True)
    """

    lower: float
    upper: float
    rel_gap: float
    energy: float
    path: np.ndarray
    metric: str
    sigma2: float
    n_steps: int
    n_iter: int
    converged: bool
    stopped_by: str
    seconds: float
    log: dict = field(default_factory=dict, repr=False)

    @property
    def value(self) -> float:
        """The distance reported: :attr:`upper`, as :func:`shapelib.distance` with ``rtol`` returns it."""
        return self.upper

    @property
    def stop_reason(self) -> BracketStopReason:
        """Why the refinement stopped (:class:`~shapelib.BracketStopReason`)."""
        return BracketStopReason(self.stopped_by)

    def summary(self) -> str:
        """One line: the interval, its relative width and why it stopped."""
        return (f"{self.metric} (σ² = {self.sigma2:g}): {self.lower:.6g} ≤ d ≤ {self.upper:.6g} "
                f"(gap {self.rel_gap:.2e}, {self.stopped_by}, n_steps {self.n_steps}, {self.n_iter} iterations)")


def _check_metric(metric):
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}; got {metric!r}")
    return metric


def lower_bound(u, v, *, metric: str, sigma2, grid_spacing: float = DEFAULT_SPACING,
                grid_margin: float = DEFAULT_MARGIN) -> float:
    r"""Closed-form lower bound on the geodesic distance (no solver).

    Both metrics are pull-backs of flat L² [1]_, so

    .. math::

        d_\alpha(u, v) \ge \|p_u - p_v\|_{L^2}, \qquad
        d_{FR}(u, v) \ge 2 \arccos \int \sqrt{p_u\, p_v}\, dx.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence.
    metric : {"alpha", "fisher_rao"}
        α-order (eq. 22): the L² chord ``‖p_u − p_v‖`` (:func:`shapelib.l2_distance`, exact).
        Fisher–Rao (eq. 6): the great circle ``2 arccos ∫ √(p_u p_v)``
        (:func:`shapelib.fisher_rao_lower_bound`, by quadrature).
    sigma2 : float
        σ² of eq. (5).
    grid_spacing, grid_margin : float
        Fisher–Rao quadrature (:mod:`shapelib.geometry.quadrature`); ignored for α.

    Returns
    -------
    float
        The bound.

    Raises
    ------
    ValueError
        For an unknown ``metric``, shapes that do not match, or a non-positive option.

    See Also
    --------
    shapelib.distance_bracket : The bound with an upper bound to match.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.solver.bracket import lower_bound
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> lower_bound(u, v, metric="alpha", sigma2=0.5) == sl.l2_distance(u, v, sigma2=0.5)
    True
    """
    _check_metric(metric)
    if metric == "alpha":
        return l2_distance(u, v, sigma2=sigma2)
    return fisher_rao_lower_bound(u, v, sigma2=sigma2, grid_spacing=grid_spacing, grid_margin=grid_margin)


def refine_path(path) -> np.ndarray:
    r"""The same piecewise-linear curve with a point inserted in every segment.

    ``(2n + 1, K, d)`` from ``(n + 1, K, d)``: the new points are the segment midpoints,

    .. math::

        \theta'_{2t} = \theta_t, \qquad \theta'_{2t+1} = \tfrac12 (\theta_t + \theta_{t+1}).

    Its length and energy (eq. 8 of [1]_) equal the input's (up to the time quadrature), so a solve
    at ``2n`` warm-started from it never starts above the solve at ``n``.

    Parameters
    ----------
    path : array_like, shape (n + 1, K, d)
        A path, n ≥ 1.

    Returns
    -------
    ndarray, shape (2n + 1, K, d)
        The refined path.

    Raises
    ------
    ValueError
        For a path that is not ``(n + 1, K, d)`` with n ≥ 1.

    See Also
    --------
    shapelib.distance_bracket : Doubles ``n_steps`` with it.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.bracket import refine_path
    >>> path = np.array([[[0.0, 0.0]], [[1.0, 0.0]]])
    >>> refine_path(path)[:, 0, 0]
    array([0. , 0.5, 1. ])
    """
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 3 or len(path) < 2:
        raise ValueError(f"path must have shape (n + 1, K, d) with n >= 1; got {path.shape}")
    fine = np.empty((2 * len(path) - 1,) + path.shape[1:])
    fine[0::2], fine[1::2] = path, 0.5 * (path[:-1] + path[1:])
    return fine


def extrapolate_doublings(gaps):
    r"""``(limit, order)`` of ``g(n) = g∞ + C n^−p`` from the last three gaps at doubling ``n_steps``.

    Each of the last three values of ``gaps`` is at twice the ``n_steps`` of the one before:
    Richardson extrapolation with the order fitted, which is Aitken's Δ² limit,

    .. math::

        2^p = \frac{d_1}{d_2}, \qquad g_\infty = g_3 - \frac{d_2^2}{d_1 - d_2},
        \qquad d_1 = g_1 - g_2, \quad d_2 = g_2 - g_3.

    Used by :func:`~shapelib.distance_bracket` to stop a bracket whose gap converges
    above ``rtol`` (the discretisation of eq. 8 of [1]_ is then not what keeps the bracket open), and
    by ``notebooks/alpha_discretisation.py``.

    Parameters
    ----------
    gaps : sequence of float
        Relative gaps, one per level.

    Returns
    -------
    limit : float or None
        :math:`g_\infty`; ``None`` unless the last three are finite and decrease with
        :math:`0 < d_2 < d_1` — the case where the extrapolation means something.
    order : float or None
        :math:`p`.

    See Also
    --------
    shapelib.distance_bracket : Its user.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    Gaps :math:`0.01 + n^{-2}` at n = 1, 2, 4:

    >>> from shapelib.solver.bracket import extrapolate_doublings
    >>> limit, order = extrapolate_doublings([1.01, 0.26, 0.0725])
    >>> round(limit, 6), round(order, 6)
    (0.01, 2.0)
    """
    if len(gaps) < 3 or not all(np.isfinite(gaps[-3:])):
        return None, None
    g1, g2, g3 = gaps[-3:]
    d1, d2 = g1 - g2, g2 - g3
    if not (d1 > 0 and d2 > 0 and d2 < d1):
        return None, None
    return g3 - d2 * d2 / (d1 - d2), float(np.log2(d1 / d2))


def _check_levels(*, rtol, n_steps, max_n_steps, level_iter, level_tol, min_shrink, grid_spacing):
    """The refinement options of :func:`distance_bracket` and :func:`distance_brackets`, checked:
    ``(rtol, n_steps, max_n_steps, level_iter, level_tol, min_shrink, grid_spacing)`` with the
    defaults filled in (``level_tol = rtol / 10``; the grid step from ``rtol``)."""
    rtol = check_positive(rtol, name="rtol")
    n = check_positive_int(n_steps, name="n_steps")
    max_n = check_positive_int(max_n_steps, name="max_n_steps")
    if max_n < n:
        raise ValueError(f"max_n_steps must be >= n_steps; got max_n_steps={max_n_steps!r}, n_steps={n_steps!r}")
    level_iter = check_positive_int(level_iter, name="level_iter")
    level_tol = rtol / 10 if level_tol is None else check_positive(level_tol, name="level_tol")
    if not 0.0 <= float(min_shrink) < 1.0:
        raise ValueError(f"min_shrink must lie in [0, 1); got {min_shrink!r}")
    if grid_spacing is None:
        grid_spacing = BRACKET_SPACING if rtol >= BRACKET_SPACING_RTOL else DEFAULT_SPACING
    return rtol, n, max_n, level_iter, level_tol, float(min_shrink), grid_spacing


def _level_stop(levels, prev_gap, *, rtol, min_shrink, max_n):
    """Why the refinement stops after the last of ``levels``, or None to double ``n_steps``."""
    gap, n = levels[-1]["rel_gap"], levels[-1]["n_steps"]
    if gap <= rtol:
        return "rtol"
    if prev_gap is not None and not gap < (1.0 - min_shrink) * prev_gap:
        return "stalled"
    limit, _ = extrapolate_doublings([lv["rel_gap"] for lv in levels])
    if limit is not None and limit > rtol:
        return "stalled"  # the gaps converge geometrically to a limit above rtol
    if 2 * n > max_n:
        return "max_n_steps"
    return None


def _warn_bracket(metric, stopped_by, gap, rtol, n, n_iter, lower, upper, ratio, *, stacklevel):
    warnings.warn(
        f"{metric} distance bracket stopped ({stopped_by}) at relative gap {gap:.2e} > rtol {rtol:.1e} "
        f"(n_steps {n}, {n_iter} iterations): the distance is certified only to lie in "
        f"[{lower:.6g}, {upper:.6g}]" + (
            "; raise max_n_steps to refine further" if stopped_by == "max_n_steps" else
            f"; sigma is {ratio:.3g} landmark spacings, so the Gaussians of different landmarks do not "
            f"interact and the gradient that would shorten the path underflows: bring the shapes to a "
            f"scale that fits sigma2 (shapelib.to_centroid_size)" if ratio < SIGMA_RATIO_MIN else
            "; the gap no longer shrinks with n_steps, so the geodesic is itself longer than the "
            "closed-form bound (typical at small sigma2)"),
        GeodesicWarning, stacklevel=stacklevel)


def distance_bracket(u, v, *, metric: str, sigma2, rtol: float = 1e-3, n_steps: int = 8,
                     max_n_steps: int = 64, level_iter: int = 3, level_tol: float | None = None,
                     min_shrink: float = 0.25, grid_spacing: float | None = None,
                     grid_margin: float = DEFAULT_MARGIN, hessian: str | None = None,
                     warn: bool = True, backend: str = "cpu", device: str | None = None) -> DistanceBracket:
    r"""Certified bracket ``lower ≤ d(u, v) ≤ upper`` with ``upper / lower − 1 ≤ rtol`` if reachable.

    ``lower`` is the metric's closed-form bound and ``upper`` the length of an actual path, refined
    (Levenberg–Marquardt on the path energy of eq. 8 of [1]_, ``n_steps`` doubled while needed)
    only until

    .. math::

        \text{lower} \le d(u, v) \le \text{upper}, \qquad
        \frac{\text{upper}}{\text{lower}} - 1 \le \text{rtol},

    with :math:`d` the geodesic distance under the α-order (eq. 22) or Fisher–Rao (eq. 6) metric.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence (eq. 9), d = 2 or 3.
    metric : {"alpha", "fisher_rao"}
        α-order entropy metric (eq. 22) or Fisher–Rao metric (eq. 6).
    sigma2 : float
        σ² of eq. (5).
    rtol : float
        Target relative width ``upper / lower − 1``.
    n_steps : int
        Time steps of the first level; doubled while needed, up to ``max_n_steps``.
    max_n_steps : int
        Largest ``n_steps``; the bracket stops ``"max_n_steps"`` there.
    level_iter : int
        Most Levenberg–Marquardt iterations per level.
    level_tol : float, optional
        A level ends (and ``n_steps`` is doubled) when the energy fell by less than
        ``level_tol · E`` in the last two iterations. Default ``rtol / 10``: the gap moved by
        less than ``rtol / 20``.
    min_shrink : float
        After a doubling, the gap must have shrunk by this fraction, else ``stopped_by =
        "stalled"`` (the discretisation is no longer what keeps ``upper`` above ``lower``).
        Also ``"stalled"`` when, after three levels, the Aitken Δ² extrapolation of the gaps
        to ``n_steps → ∞`` lies above ``rtol``: the geodesic is longer than the bound by more
        than ``rtol``, and no ``n_steps`` will close the bracket.
    grid_spacing : float, optional
        Fisher–Rao quadrature step in units of σ (:mod:`shapelib.geometry.quadrature`). Default
        ``BRACKET_SPACING`` (0.5) when ``rtol ≥ 1e-5`` — its quadrature error, ≤ 3.2e-7
        relative on the corpus callosum pairs, is far below such a tolerance — else the library's
        0.35 (:data:`shapelib.geometry.quadrature.DEFAULT_SPACING`).
    grid_margin : float
        Fisher–Rao quadrature margin (:mod:`shapelib.geometry.quadrature`).
    hessian : {"exact", "model"}, optional
        Hessian of the Levenberg–Marquardt steps (:func:`shapelib.geodesic`); default
        the cheaper per metric for brackets (``DEFAULT_HESSIAN``: exact for α, the model
        Hessian for Fisher–Rao).
    warn : bool
        Emit a :class:`shapelib.GeodesicWarning` when ``rtol`` was not reached, with the
        gap reached.
    backend : {"cpu", "jax"}
        ``"jax"``: each level minimises the same discrete energy by L-BFGS on a JAX device
        (:mod:`shapelib.solver.batched`), up to :data:`JAX_LEVEL_ITER` ``· level_iter`` iterations, a
        level ending when the energy fell by less than ``level_tol · E`` over
        :data:`JAX_LEVEL_WINDOW` iterations; ``hessian`` is not used. ``lower`` and ``upper`` are
        certified as on the CPU. For many pairs at once: :func:`distance_brackets`.
    device : {None, "cpu", "gpu"}
        With ``backend="jax"`` (:func:`shapelib.geodesic`).

    Returns
    -------
    DistanceBracket
        ``lower``, ``upper``, ``rel_gap``, ``converged``, ``stop_reason`` and the path.

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite, a landmark dimension other than 2 or 3,
        an unknown ``metric`` or ``hessian``, a non-positive option, or σ too small for the
        Fisher–Rao quadrature.

    Warns
    -----
    GeodesicWarning
        When ``rtol`` was not reached (``warn=True``).
    ScaleWarning
        When σ does not fit the landmarks' spacing.
    PoseWarning
        When the shapes are not aligned.

    See Also
    --------
    shapelib.geodesic : A geodesic solved to a tolerance on its energy.
    shapelib.distance : Every distance through one entry point (``rtol=`` gives this bracket's upper end).

    Notes
    -----
    At σ² = 0.5 on the corpus callosum pairs of Table I (centroid size 20) every pair reaches
    1e-3 with a few iterations; at σ² = 0.1 most pairs stop ``"stalled"`` at a gap of a few
    1e-3, because the α geodesic is measurably longer than the L² chord there
    (``docs/guide/solver.md``). The 1e-9 Newton-decrement certificate of a local minimum remains
    available through :func:`shapelib.geodesic` (``tol=``).

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> b = sl.distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=1e-3)
    >>> b.converged, round(b.lower, 4), bool(b.rel_gap <= 1e-3)
    (True, 0.0463, True)
    """
    t0 = time.perf_counter()
    _check_metric(metric)
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    ratio = check_entry(u, v, s2, metric=metric, stacklevel=3)
    rtol, n, max_n, level_iter, level_tol, min_shrink, grid_spacing = _check_levels(
        rtol=rtol, n_steps=n_steps, max_n_steps=max_n_steps, level_iter=level_iter, level_tol=level_tol,
        min_shrink=min_shrink, grid_spacing=grid_spacing)
    if hessian is None:
        hessian = DEFAULT_HESSIAN[metric]
    if hessian not in ("exact", "model"):
        raise ValueError(f"hessian must be 'exact' or 'model'; got {hessian!r}")
    backend, device = check_backend(backend, device)
    model = path_metric(metric, s2, grid_spacing=grid_spacing, grid_margin=grid_margin)
    options = {"rtol": rtol, "n_steps": n, "max_n_steps": max_n, "level_iter": level_iter,
               "level_tol": level_tol, "min_shrink": min_shrink, "hessian": hessian, "sigma_ratio": ratio,
               **model.settings()}
    if backend == "jax":
        options.update(hessian=None, backend="jax")
        return _jax_brackets(u[None], v[None], [ratio], model=model, s2=s2, rtol=rtol, n=n, max_n=max_n,
                             level_iter=level_iter, level_tol=level_tol, min_shrink=min_shrink,
                             options=options, device=device, batch_size=None, warn=warn, t0=t0)[0]

    if np.array_equal(u, v):
        path = np.stack([u] * (n + 1))
        return DistanceBracket(lower=0.0, upper=0.0, rel_gap=0.0, energy=0.0, path=path, metric=metric, sigma2=s2,
                               n_steps=n, n_iter=0, converged=True, stopped_by="trivial",
                               seconds=time.perf_counter() - t0, log={"levels": [], **options})
    lower = float(model.lower_bound(u, v))
    target = (lower * (1.0 + rtol)) ** 2
    levels, path, n_iter, prev_gap = [], None, 0, None
    while True:
        tl = time.perf_counter()
        r = minimise_path(model, u, v, n_steps=n, tol=level_tol, max_iter=level_iter, window=2, init=path,
                          warn=False, length_scale=np.sqrt(s2), sigma2=s2, hessian=hessian, target_energy=target,
                          lower_bound=lower)
        n_iter += r.n_iter
        upper, energy, path = r.length, r.energy, r.path
        gap = upper / lower - 1.0 if lower > 0 else np.inf
        levels.append({"n_steps": n, "n_iter": r.n_iter, "upper": upper, "rel_gap": gap,
                       "stopped_by": r.log["stopped_by"], "seconds": time.perf_counter() - tl})
        stopped_by = _level_stop(levels, prev_gap, rtol=rtol, min_shrink=min_shrink, max_n=max_n)
        if stopped_by is not None:
            break
        prev_gap = gap
        path = refine_path(r.path)  # warm start
        n *= 2
    converged = stopped_by == "rtol"
    if not converged and warn:
        _warn_bracket(metric, stopped_by, gap, rtol, n, n_iter, lower, upper, ratio, stacklevel=3)
    return DistanceBracket(lower=lower, upper=float(upper), rel_gap=float(gap), energy=float(energy), path=path,
                           metric=metric, sigma2=s2, n_steps=n, n_iter=n_iter, converged=converged,
                           stopped_by=stopped_by, seconds=time.perf_counter() - t0,
                           log={"levels": levels, **options})


def _jax_brackets(us, vs, ratios, *, model, s2, rtol, n, max_n, level_iter, level_tol, min_shrink, options,
                  device, batch_size, warn, t0):
    """:func:`distance_bracket`'s levels for many validated pairs at once, each level one batched
    L-BFGS solve on the device (:func:`shapelib.solver.batched.batched_geodesics`)."""
    metric = model.name
    b = len(us)
    out = [None] * b
    lowers = np.zeros(b)
    for i in range(b):
        if np.array_equal(us[i], vs[i]):
            out[i] = DistanceBracket(lower=0.0, upper=0.0, rel_gap=0.0, energy=0.0, path=np.stack([us[i]] * (n + 1)),
                                     metric=metric, sigma2=s2, n_steps=n, n_iter=0, converged=True,
                                     stopped_by="trivial", seconds=time.perf_counter() - t0,
                                     log={"levels": [], **options, "sigma_ratio": ratios[i]})
        else:
            lowers[i] = float(model.lower_bound(us[i], vs[i]))
    targets = (lowers * (1.0 + rtol)) ** 2
    active = [i for i in range(b) if out[i] is None]
    levels = {i: [] for i in active}
    prev_gap = dict.fromkeys(active)
    n_iter = dict.fromkeys(active, 0)
    paths = {}
    cur = n
    while active:
        tl = time.perf_counter()
        res = batched_geodesics(us[active], vs[active], metric=metric, sigma2=s2, n_steps=cur, tol=level_tol,
                                max_iter=level_iter * JAX_LEVEL_ITER, window=JAX_LEVEL_WINDOW,
                                init=np.stack([paths[i] for i in active]) if paths else None,
                                grid_spacing=model.spacing if metric == "fisher_rao" else DEFAULT_SPACING,
                                grid_margin=model.margin if metric == "fisher_rao" else DEFAULT_MARGIN,
                                target_energy=targets[active], lower_bounds=lowers[active], device=device,
                                batch_size=batch_size, warn=False)
        share = (time.perf_counter() - tl) / len(active)
        still = []
        for r, i in zip(res, active):
            n_iter[i] += r.n_iter
            gap = r.length / lowers[i] - 1.0 if lowers[i] > 0 else np.inf
            levels[i].append({"n_steps": cur, "n_iter": r.n_iter, "upper": r.length, "rel_gap": gap,
                              "stopped_by": r.log["stopped_by"], "seconds": share})
            stop = _level_stop(levels[i], prev_gap[i], rtol=rtol, min_shrink=min_shrink, max_n=max_n)
            if stop is None:
                prev_gap[i] = gap
                paths[i] = refine_path(r.path)
                still.append(i)
                continue
            out[i] = DistanceBracket(lower=float(lowers[i]), upper=float(r.length), rel_gap=float(gap),
                                     energy=float(r.energy), path=r.path, metric=metric, sigma2=s2, n_steps=cur,
                                     n_iter=n_iter[i], converged=stop == "rtol", stopped_by=stop,
                                     seconds=sum(lv["seconds"] for lv in levels[i]),
                                     log={"levels": levels[i], **options, "sigma_ratio": ratios[i],
                                          "device": r.log["device"]})
        active, cur = still, cur * 2
    if warn:
        failed = [x for x in out if not x.converged]
        if len(failed) == 1 and b == 1:
            x = failed[0]
            _warn_bracket(metric, x.stopped_by, x.rel_gap, rtol, x.n_steps, x.n_iter, x.lower, x.upper,
                          x.log["sigma_ratio"], stacklevel=4)
        elif failed:
            warnings.warn(f"{metric} distance brackets: {len(failed)} of {b} pairs stopped above rtol {rtol:.1e} "
                          f"(first: {failed[0].summary()})", GeodesicWarning, stacklevel=3)
    return out


def distance_brackets(us, vs, *, metric: str, sigma2, rtol: float = 1e-3, n_steps: int = 8,
                      max_n_steps: int = 64, level_iter: int = 3, level_tol: float | None = None,
                      min_shrink: float = 0.25, grid_spacing: float | None = None,
                      grid_margin: float = DEFAULT_MARGIN, hessian: str | None = None, backend: str = "jax",
                      device: str | None = None, batch_size: int | None = None, warn: bool = True) -> list:
    """Certified brackets of many pairs ``(us[i], vs[i])``: :func:`distance_bracket` for each, with
    ``backend="jax"`` every level of all pairs solved as one batch on the device.

    Parameters
    ----------
    us, vs : array_like, shape (B, K, d)
        Pairs of shapes of one size (group pairs by ``K`` and ``d`` before calling).
    metric, sigma2, rtol, n_steps, max_n_steps, level_iter, level_tol, min_shrink, grid_spacing, grid_margin
        As in :func:`distance_bracket`.
    hessian : {"exact", "model"}, optional
        As in :func:`distance_bracket`; ``backend="cpu"`` only (L-BFGS needs none).
    backend : {"jax", "cpu"}
        ``"jax"`` (default): batched on a JAX device; ``"cpu"``: :func:`distance_bracket` pair by pair.
    device : {None, "cpu", "gpu"}
        JAX device (:func:`shapelib.geodesic`).
    batch_size : int, optional
        Pairs per device call (default: from the device's memory,
        :func:`shapelib.solver.batched.batched_geodesics`).
    warn : bool
        One :class:`~shapelib.solver.result.GeodesicWarning` for the pairs that stopped above ``rtol``.

    Returns
    -------
    list of DistanceBracket
        In the order of the pairs; each certified as :func:`distance_bracket`'s.

    See Also
    --------
    distance_bracket : One pair, with the same options.
    shapelib.solver.geodesic.geodesics : Geodesics of many pairs at one resolution.

    Notes
    -----
    Each bracket encloses the geodesic distance of [1]_ between ``us[i]`` and ``vs[i]``, as
    :func:`distance_bracket`'s; with ``backend="jax"`` the paths of every level are minimised together by
    L-BFGS [2]_ in JAX [3]_.

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
    >>> from shapelib import distance_brackets
    >>> u = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.5]])
    >>> vs = np.stack([u + [[0.3, -0.2], [0.0, 0.1], [-0.2, 0.0]], u * 1.1])
    >>> out = distance_brackets(np.stack([u, u]), vs, metric="alpha", sigma2=0.5, device="cpu")
    >>> [bool(b.lower <= b.upper) for b in out]
    [True, True]
    """
    t0 = time.perf_counter()
    _check_metric(metric)
    us, vs = as_pair_batch(us, vs)
    backend, device = check_backend(backend, device)
    common = dict(metric=metric, sigma2=sigma2, rtol=rtol, n_steps=n_steps, max_n_steps=max_n_steps,
                  level_iter=level_iter, level_tol=level_tol, min_shrink=min_shrink, grid_spacing=grid_spacing,
                  grid_margin=grid_margin)
    if backend == "cpu":
        return [distance_bracket(u, v, warn=warn, hessian=hessian, **common) for u, v in zip(us, vs)]
    s2 = check_sigma2(sigma2)
    us, vs, ratios = _check_entries(us, vs, s2, metric=metric, stacklevel=3)
    rtol, n, max_n, level_iter, level_tol, min_shrink, grid_spacing = _check_levels(
        rtol=rtol, n_steps=n_steps, max_n_steps=max_n_steps, level_iter=level_iter, level_tol=level_tol,
        min_shrink=min_shrink, grid_spacing=grid_spacing)
    model = path_metric(metric, s2, grid_spacing=grid_spacing, grid_margin=grid_margin)
    options = {"rtol": rtol, "n_steps": n, "max_n_steps": max_n, "level_iter": level_iter, "level_tol": level_tol,
               "min_shrink": min_shrink, "hessian": None, "backend": "jax", **model.settings()}
    return _jax_brackets(us, vs, ratios, model=model,
                         s2=s2, rtol=rtol, n=n, max_n=max_n, level_iter=level_iter, level_tol=level_tol,
                         min_shrink=min_shrink, options=options, device=device, batch_size=batch_size,
                         warn=warn, t0=t0)
