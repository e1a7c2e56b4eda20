r"""Geodesics between GMM shapes (paper eqs. 8–12) with certified lengths.

The paper minimises the path energy

.. math::

    s = \int_0^1 g_{ij}\, \dot\theta^i \dot\theta^j\, dt \qquad \text{(eq. 8)}

between two landmark shapes by gradient descent on the Euler–Lagrange equations (eqs. 10–12).
We minimise the same energy over **piecewise-linear paths** through ``n + 1`` points (ends
fixed): on each segment the landmarks move at constant velocity and the energy is integrated in
time with a 3-point Gauss–Legendre rule,

.. math::

    E_n = \sum_{t=0}^{n-1} \frac{1}{n} \sum_{k=1}^{3} w_k\, V_t^\top g(\theta_t + \tau_k \Delta_t)\, V_t,
    \qquad \Delta_t = \theta_{t+1} - \theta_t, \quad V_t = n \Delta_t.

This is the energy of an actual path, so
:math:`E_n \ge \text{length}^2 \ge d(u, v)^2 \ge \text{lower bound}^2`: the
optimiser cannot exploit the discretisation the way it can a midpoint rule with few steps
(which lets two landmarks cross at the one instant where the metric is evaluated). As ``n``
grows the minimum decreases to the squared geodesic distance.

Both metrics are pull-backs of the flat L² metric, which gives lower bounds:

* α-order (eq. 22): :math:`\dot\theta^\top g \dot\theta = \|\partial_t p\|^2`, so
  :math:`d(u, v) \ge \|p_u - p_v\|` (closed form);
* Fisher–Rao (eq. 6): :math:`\dot\theta^\top g \dot\theta = \|\partial_t (2\sqrt{p})\|^2` and
  :math:`2\sqrt{p}` lies on the sphere of radius 2, so
  :math:`d(u, v) \ge 2 \arccos \int \sqrt{p_u p_v}\, dx`.

The reported ``length`` (:math:`\int \sqrt{\dot\theta^\top g \dot\theta}\, dt` of the computed
path, 5-point Gauss–Legendre) is an upper bound on the geodesic distance:
``lower_bound ≤ d(u, v) ≤ length``.

Where the pieces live: the metrics as the solver sees them, :mod:`shapelib.solver.path_metric`;
the discrete energy, its gradient and Hessian, :mod:`shapelib.solver.energy`; block Cholesky,
:mod:`shapelib.solver.linalg`; the damped step, the certificate and the stop rules,
:mod:`shapelib.solver.minimise`; results and stop reasons, :mod:`shapelib.solver.result`. This module
holds the entry points.

Solver: Levenberg–Marquardt (a trust-region Newton method) on a block-tridiagonal Hessian,
factorised by block Cholesky in O(n (Kd)³):

* by default the **exact** Hessian of the path energy, assembled from the second derivatives
  of ``Q = vᵀg(θ)v`` — in closed form for α (``shapelib.geometry.metrics.alpha_qform_hessian``, run
  as one compiled pass over the path, with the gradient, by
  ``shapelib.geometry._kernels.alpha_path_grad_hessian``),
  by the same quadrature as the metric for Fisher–Rao (``shapelib.geometry.metrics.fr_qform_hessian_compiled``).
  Where it is positive definite the Newton decrement :math:`\tfrac12 g^\top H^{-1} g` estimates the energy still
  to be gained; the solver stops when it falls below ``tol · E`` (``result.stop_reason ==
  StopReason.NEWTON_DECREMENT``), which certifies a local minimum, or when the relative energy decrease
  over ``window`` iterations falls below ``tol``.
* ``hessian="model"`` (and always for landmark diffeomorphisms): the model Hessian obtained by
  freezing the metric at each segment's midpoint, ``2n [[ḡ_t, −ḡ_t], [−ḡ_t, ḡ_t]]`` per
  segment (a metric-weighted Laplacian in time), with the energy-window stop only. For
  Fisher–Rao it is cheaper per iteration but converges linearly: on the benchmark pair it
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

import warnings

import numpy as np

from .._validate import as_pair_batch, as_shape_pair, check_dimension, check_positive, check_positive_int, check_sigma2, \
    set_was_checked
from ..geometry.gmm import l2_distance
from ..geometry.procrustes import check_pose
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING
from ..geometry.scale import SIGMA_RATIO_MIN, check_fisher_rao_scale, check_scale
from .energy import metric_length
from .batched import batched_geodesics, check_backend
from .minimise import minimise_path
from .path_metric import METRICS, FisherRaoPathMetric, path_metric
from .result import GeodesicResult, GeodesicWarning, StopReason

__all__ = ["geodesic", "geodesics", "shoot", "geodesic_acceleration", "fisher_rao_lower_bound", "alpha_lower_bound", "path_length",
           "check_entry",
           "METRICS", "GeodesicResult", "GeodesicWarning", "StopReason", "minimise_path"]


def path_length(path, *, metric: str = "alpha", sigma2, grid_spacing: float = DEFAULT_SPACING,
                grid_margin: float = DEFAULT_MARGIN) -> float:
    r"""Riemannian length ``∫ √(θ̇ᵀ g θ̇) dt`` of the piecewise-linear path through ``path``.

    .. math::

        L = \sum_{t=0}^{n-1} \int_0^1 \sqrt{V_t^\top g(\theta_t + \tau \Delta_t)\, V_t}\, d\tau \cdot \frac{1}{n},
        \qquad \Delta_t = \theta_{t+1} - \theta_t, \quad V_t = n \Delta_t,

    the length of eq. (8)'s infinitesimal element [1]_ along the path, by the 5-point
    Gauss–Legendre rule on each segment; an upper bound on the geodesic distance between the ends.

    Parameters
    ----------
    path : array_like, shape (n + 1, K, d)
        The path's points, n ≥ 1.
    metric : {"alpha", "fisher_rao"}, default "alpha"
        The metric of eq. (22) or eq. (6).
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    grid_spacing : float, default 0.35
        Fisher–Rao quadrature step in units of σ.
    grid_margin : float, default 6.0
        Fisher–Rao quadrature margin in units of σ.

    Returns
    -------
    float
        The length.

    Raises
    ------
    ValueError
        For a path that is not ``(n + 1, K, d)`` with n ≥ 1 or not finite, an unknown ``metric``
        or a non-positive ``sigma2``.

    See Also
    --------
    shapelib.geodesic : The shortest such path.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    Under the α-order metric a single landmark moves in a flat space: its length is
    :math:`|\Delta| / \sqrt{2\sigma^2 (4\pi\sigma^2)}`.

    >>> import numpy as np
    >>> import shapelib as sl
    >>> path = np.array([[[0.0, 0.0]], [[0.5, 0.0]], [[1.0, 0.0]]])
    >>> L = sl.path_length(path, sigma2=0.5)
    >>> bool(np.isclose(L, 1.0 / np.sqrt(2 * 0.5 * 4 * np.pi * 0.5)))
    True
    """
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 3 or len(path) < 2:
        raise ValueError(f"path must have shape (n + 1, K, d) with n >= 1; got {path.shape}")
    if not np.all(np.isfinite(path)):
        raise ValueError("path contains non-finite values")
    return metric_length(path_metric(metric, check_sigma2(sigma2), grid_spacing=grid_spacing, grid_margin=grid_margin), path)


def fisher_rao_lower_bound(u, v, *, sigma2, grid_spacing: float = DEFAULT_SPACING,
                           grid_margin: float = DEFAULT_MARGIN) -> float:
    r"""Great-circle lower bound ``2 arccos ∫ √(p_u p_v) dx`` on the Fisher–Rao geodesic distance.

    :math:`2\sqrt{p}` lies on the sphere of radius 2 in L² and the Fisher–Rao metric (eq. 6) is the
    pull-back of L² by :math:`\theta \mapsto 2\sqrt{p}`, so no path of GMMs is shorter than the
    great circle [1]_ [2]_:

    .. math::

        d_{FR}(u, v) \ge 2 \arccos \int \sqrt{p_u\, p_v}\, dx
        = 4 \arcsin \frac{\|\sqrt{p_u} - \sqrt{p_v}\|}{2}.

    Computed stably in the right-hand form by quadrature, on a grid covering the two shapes
    (:mod:`shapelib.geometry.quadrature`): with the default grid within 5e-8 (relative) of a grid
    of step 0.2 σ and margin 9 σ on ADHD-200 pairs at σ² from 0.007 to 17. Checked at entry as
    :func:`shapelib.geodesic` is: landmark dimension, σ against the landmarks' scale
    (:class:`~shapelib.ScaleWarning`) and their pose
    (:class:`~shapelib.PoseWarning`).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence, d = 2 or 3.
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    grid_spacing : float, default 0.35
        Quadrature step in units of σ.
    grid_margin : float, default 6.0
        Quadrature margin in units of σ.

    Returns
    -------
    float
        The bound, in [0, π].

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite, a dimension other than 2 or 3, a
        non-positive option, or σ too small for the quadrature
        (:func:`~shapelib.geometry.scale.check_fisher_rao_scale`).

    Warns
    -----
    ScaleWarning
        When σ does not fit the landmarks' spacing.
    PoseWarning
        When the shapes are not aligned.

    See Also
    --------
    shapelib.fisher_rao_bound_matrix : The bound for every pair of a population.
    shapelib.geodesic : The geodesic whose length it bounds.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] S. Amari and H. Nagaoka, *Methods of Information Geometry*, American Mathematical Society and
       Oxford University Press, 2000.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> round(sl.fisher_rao_lower_bound(u, v, sigma2=0.5), 4)
    0.1829
    """
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    check_entry(u, v, s2, metric="fisher_rao", stacklevel=3, what="fisher_rao_bound")
    return FisherRaoPathMetric(s2, check_positive(grid_spacing, name="grid_spacing"),
                               check_positive(grid_margin, name="grid_margin")).lower_bound(u, v)


def alpha_lower_bound(u, v, *, sigma2) -> float:
    r"""Closed-form lower bound ``‖p_u − p_v‖`` on the α-order geodesic distance (eq. 22).

    The α-order metric is the pull-back of the flat L² metric on densities [1]_, so

    .. math::

        d_\alpha(u, v) \ge \|p_u - p_v\|_{L^2},

    the L² distance of the eq. (5) densities (:func:`shapelib.l2_distance`), checked at entry as
    :func:`shapelib.geodesic` is (landmark dimension, scale, pose).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence, d = 2 or 3.
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).

    Returns
    -------
    float
        The bound.

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite, a dimension other than 2 or 3, or a
        non-positive ``sigma2``.

    Warns
    -----
    ScaleWarning
        When σ does not fit the landmarks' spacing.
    PoseWarning
        When the shapes are not aligned.

    See Also
    --------
    shapelib.l2_distance : The same number, unchecked.
    shapelib.alpha_bound_matrix : The bound for every pair of a population.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.solver.geodesic import alpha_lower_bound
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> alpha_lower_bound(u, v, sigma2=0.5) == sl.l2_distance(u, v, sigma2=0.5)
    True
    """
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    check_entry(u, v, s2, metric="alpha", stacklevel=3, what="alpha_bound")
    return l2_distance(u, v, sigma2=s2)


# ---------------------------------------------------------------------------------------------
# Entry points
# ---------------------------------------------------------------------------------------------


def check_entry(u, v, s2, *, metric, stacklevel, what=None):
    r"""Checks shared by the geodesic, the bracket and the two bounds at entry.

    Landmark dimension 2 or 3, σ of eq. (5) [1]_ against the landmarks' scale
    (:mod:`shapelib.geometry.scale`) and their pose (:func:`shapelib.geometry.procrustes.check_pose`:
    both metrics depend on it). The α bound, which does not use σ / spacing, skips the scale
    warning where the pairwise engine has checked the whole set. The ratio returned is

    .. math::

        r = \frac{\sigma}{\bar h}, \qquad \bar h = \text{mean nearest-landmark spacing}.

    Parameters
    ----------
    u, v : ndarray, shape (K, d)
        Validated shapes.
    s2 : float
        Validated σ².
    metric : {"alpha", "fisher_rao"}, keyword-only
        The metric.
    stacklevel : int, keyword-only
        Counted from here (3: the caller of the entry point).
    what : str, optional
        A bound's name in the warnings.

    Returns
    -------
    float or None
        The ratio σ / spacing (None where the α bound skipped the scale check).

    Raises
    ------
    ValueError
        For an unknown ``metric``, a dimension other than 2 or 3, or a σ that leaves the
        Fisher–Rao quadrature nothing to resolve
        (:func:`~shapelib.geometry.scale.check_fisher_rao_scale`).

    Warns
    -----
    ScaleWarning, PoseWarning
        As :func:`~shapelib.geometry.scale.check_scale` and
        :func:`~shapelib.geometry.procrustes.check_pose`.

    See Also
    --------
    shapelib.geodesic, shapelib.distance_bracket

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.geodesic import check_entry
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> check_entry(u, u, 0.25, metric="alpha", stacklevel=3)
    0.5
    """
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}; got {metric!r}")
    check_dimension(u, name="u")
    pair = np.stack([u, v])
    check_pose(pair, metric=what or metric, stacklevel=stacklevel + 1)
    if metric == "alpha" and what is not None and set_was_checked():
        return None
    ratio = check_scale(pair, s2, stacklevel=stacklevel + 1)
    if metric == "fisher_rao":  # degenerate quadrature: an error before any work
        check_fisher_rao_scale(pair, sigma2=s2, metric=what or metric, ratio=ratio)
    return ratio


def _check_entries(us, vs, s2, *, metric, stacklevel):
    """:func:`check_entry` for each pair ``(us[i], vs[i])`` of a batch (each shape checked by
    :func:`~shapelib._validate.as_shape_pair`, named ``us[i]``, ``vs[i]``).

    Returns ``(us, vs, ratios)``: the checked shapes stacked again and each pair's σ / spacing;
    ``stacklevel`` as in :func:`check_entry` (3: the caller of the entry point).
    """
    pairs = [as_shape_pair(u, v, names=(f"us[{i}]", f"vs[{i}]")) for i, (u, v) in enumerate(zip(us, vs))]
    ratios = []
    for u, v in pairs:  # a loop, not a comprehension: on Python < 3.12 that would add a frame to stacklevel
        ratios.append(check_entry(u, v, s2, metric=metric, stacklevel=stacklevel + 1))
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs]), ratios


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


def _mark_underflow(result, ratio):
    """Mark ``result`` not converged (``stopped_by`` "underflow", ``log["reason"]``) where
    :func:`_underflow` says why; the reason, or None."""
    reason = _underflow(result, ratio)
    if reason is not None:
        result.converged = False
        result.log["stopped_by"] = StopReason.UNDERFLOW.value
        result.log["reason"] = reason
    return reason


def geodesic(u, v, *, metric: str = "alpha", sigma2, n_steps: int = 16, tol: float = 1e-6,
             max_iter: int = 500, window: int = 5, init=None, grid_spacing: float = DEFAULT_SPACING,
             grid_margin: float = DEFAULT_MARGIN, hessian: str = "exact", warn: bool = True,
             backend: str = "cpu", device: str | None = None) -> GeodesicResult:
    r"""Geodesic between two landmark shapes under the α-order or Fisher–Rao metric (eqs. 8–12).

    Minimises the path energy of eq. (8) of [1]_,

    .. math::

        s = \int_0^1 g_{ij}(\theta)\, \dot\theta^i \dot\theta^j\, dt, \qquad
        \theta(0) = u, \quad \theta(1) = v \quad \text{(eq. 9)},

    whose minimisers solve the geodesic equation :math:`g_{ki}\ddot\theta^i +
    \Gamma_{k,ij}\dot\theta^i\dot\theta^j = 0` (eq. 11), over piecewise-linear paths of ``n_steps``
    segments, by Levenberg–Marquardt steps on the exact Hessian (the paper's eq. 12 is gradient
    descent on the same energy). The metric :math:`g` is the α-order entropy metric of eq. (22) or
    the Fisher–Rao metric of eq. (6). The result certifies
    :math:`\text{lower bound} \le d(u, v) \le \text{length}` (module docstring).

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
    max_iter : int
        Maximum Levenberg–Marquardt iterations.
    window : int
        Number of iterations over which the energy decrease is measured.
    init : array_like, shape (n_steps + 1, K, d), optional
        Initial path (default: the straight line in landmark space, as in the paper's figures).
    grid_spacing, grid_margin : float
        Fisher–Rao quadrature grid step and margin in units of σ (:mod:`shapelib.geometry.quadrature`).
    hessian : {"exact", "model"}
        Newton steps on the exact Hessian of the path energy (certified stop by the Newton
        decrement), or on the model Hessian that freezes the metric at each segment's midpoint
        (cheaper per iteration for Fisher–Rao, but many more iterations, and it only stops on the
        energy window; the performance page gives the measured cost of an iteration).
    warn : bool
        Emit a :class:`GeodesicWarning` when the solver stops before converging.
    backend : {"cpu", "jax"}
        ``"cpu"``: the compiled Levenberg–Marquardt solver above. ``"jax"``: the same discrete
        energy (same path, time rule and grid) in JAX with its gradient by ``jax.grad``, minimised
        by L-BFGS on the device (:mod:`shapelib.solver.batched`; ``max_iter`` then counts L-BFGS
        iterations, ``hessian`` is not used, and the stop is the energy window: no Newton
        certificate). The bounds are certified as on the CPU. Needs ``pip install "shapelib[gpu]"``
        (CUDA 12) or ``"shapelib[jax]"`` (CPU).
    device : {None, "cpu", "gpu"}
        With ``backend="jax"``: JAX's default device (None: a GPU when JAX sees one), the CPU, or a
        GPU — refused with a one-line ``RuntimeError`` when JAX sees none (never a silent CPU fallback).

    Returns
    -------
    GeodesicResult
        ``path``, ``length``, ``energy``, ``lower_bound``, ``converged``, ``n_iter``,
        ``grad_norm`` and a ``log``. The geodesic distance lies in ``[lower_bound, length]``.

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite, a landmark dimension other than 2 or 3,
        an unknown ``metric`` or ``hessian``, a non-positive option, an ``init`` of the wrong
        shape, or σ too small for the Fisher–Rao quadrature.

    Warns
    -----
    GeodesicWarning
        When the solver stops before converging (``warn=True``).
    ScaleWarning
        When σ does not fit the landmarks' spacing.
    PoseWarning
        When the shapes are not aligned.

    See Also
    --------
    shapelib.distance_bracket : The distance to a requested relative width.
    shapelib.path_length : The length of any path.
    shapelib.extrinsic_warp : Move ambient points along the geodesic (§III-E).
    shapelib.landmark_diffeomorphism : The Camion–Younes baseline through the same solver.

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
    >>> r = sl.geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=4)
    >>> r.converged, r.path.shape
    (True, (5, 4, 2))
    >>> round(r.lower_bound, 4), round(r.length, 4)
    (0.0463, 0.0464)
    """
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    backend, device = check_backend(backend, device)
    ratio = check_entry(u, v, s2, metric=metric, stacklevel=3)
    if backend == "jax":
        if hessian not in ("exact", "model"):
            raise ValueError(f"hessian must be 'exact' or 'model'; got {hessian!r}")
        result = batched_geodesics(u[None], v[None], metric=metric, sigma2=s2, n_steps=n_steps, tol=tol,
                                   max_iter=max_iter, window=window, init=None if init is None else np.asarray(init)[None],
                                   grid_spacing=grid_spacing, grid_margin=grid_margin, device=device, warn=False)[0]
        if not result.converged and warn:
            warnings.warn(f"{metric} geodesic did not converge in {result.n_iter} L-BFGS iterations "
                          f"({result.summary()})", GeodesicWarning, stacklevel=2)
    else:
        model = path_metric(metric, s2, grid_spacing=grid_spacing, grid_margin=grid_margin)
        result = minimise_path(model, u, v, n_steps=n_steps, tol=tol, max_iter=max_iter, window=window, init=init,
                               warn=warn, length_scale=np.sqrt(s2), sigma2=s2, hessian=hessian, stacklevel=3)
    reason = _mark_underflow(result, ratio)
    if reason is not None and warn:
        warnings.warn(f"{metric} geodesic not converged: {reason}. Bring the shapes to a scale that fits "
                      f"sigma2 (shapelib.to_centroid_size) or choose a larger sigma2.",
                      GeodesicWarning, stacklevel=2)
    return result


# ---------------------------------------------------------------------------------------------
# Independent check: integrate the geodesic equation (eq. 11) from an initial velocity
# ---------------------------------------------------------------------------------------------


def geodesic_acceleration(theta, velocity, *, metric: str = "alpha", sigma2, grid=None, eps: float = 1e-6,
                          grid_spacing: float = DEFAULT_SPACING, grid_margin: float = DEFAULT_MARGIN):
    r"""``θ̈`` from the geodesic equation ``g θ̈ + Γ(θ̇, θ̇) = 0`` (eqs. 10–11).

    With :math:`Q(\theta, v) = v^\top g(\theta) v`, the Christoffel term of eq. (11) of [1]_ is

    .. math::

        \Gamma_k(v, v) = \big[\partial_\theta (g v) \cdot v\big]_k - \frac12 \frac{\partial Q}{\partial \theta_k},
        \qquad \ddot\theta = -g^{-1} \Gamma(v, v)

    (the first-kind symbols contracted twice). The gradient :math:`\partial Q / \partial\theta` is
    analytic; the directional derivative of :math:`g v = \frac12 \partial Q / \partial v` along
    :math:`v` is a central difference of that analytic gradient with step ``eps``.

    Parameters
    ----------
    theta : array_like, shape (K, d)
        Position.
    velocity : array_like, shape (K, d)
        Velocity :math:`\dot\theta`.
    metric : {"alpha", "fisher_rao"}, default "alpha"
        The metric.
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    grid : Grid, optional
        The metric's context (Fisher–Rao quadrature grid); default: prepared for ``theta``.
    eps : float, default 1e-6
        Central-difference step.
    grid_spacing, grid_margin : float
        Fisher–Rao quadrature step and margin in units of σ.

    Returns
    -------
    ndarray, shape (K, d)
        :math:`\ddot\theta`.

    Raises
    ------
    ValueError
        For an unknown ``metric`` or a non-positive ``sigma2`` or ``eps``.

    See Also
    --------
    shapelib.solver.geodesic.shoot : Integrates this acceleration.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    A single landmark under the α-order metric moves in flat space: no acceleration.

    >>> import numpy as np
    >>> from shapelib.solver.geodesic import geodesic_acceleration
    >>> acc = geodesic_acceleration([[0.0, 0.0]], [[1.0, 0.5]], sigma2=0.5)
    >>> bool(np.allclose(acc, 0.0, atol=1e-6))
    True
    """
    model = path_metric(metric, check_sigma2(sigma2), grid_spacing=grid_spacing, grid_margin=grid_margin)
    eps = check_positive(eps, name="eps")
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
    r"""Integrate the geodesic ODE (eq. 11) from ``u`` with initial velocity ``velocity``.

    Classical RK4 over :math:`t \in [0, 1]` on the first-order form of the geodesic equation of
    [1]_,

    .. math::

        \dot\theta = v, \qquad \dot v = -g(\theta)^{-1}\, \Gamma(v, v) \qquad \text{(eq. 11)}

    with the acceleration of :func:`~shapelib.solver.geodesic.geodesic_acceleration`. Only
    meaningful where the metric is well conditioned (few, well separated landmarks): the ODE needs
    :math:`g^{-1}`, which for dense contours has a condition number ~1e16. An independent check on
    the boundary-value solver :func:`shapelib.geodesic`.

    Parameters
    ----------
    u : array_like, shape (K, d)
        Start shape.
    velocity : array_like, shape (K, d)
        Initial velocity.
    metric : {"alpha", "fisher_rao"}, default "alpha"
        The metric.
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    n_steps : int, default 200
        RK4 steps.
    grid_spacing, grid_margin : float
        Fisher–Rao quadrature step and margin in units of σ.

    Returns
    -------
    ndarray, shape (n_steps + 1, K, d)
        The trajectory.

    Raises
    ------
    ValueError
        For ``u`` and ``velocity`` of different shapes or non-finite, an unknown ``metric``, a
        non-positive ``sigma2`` or an ``n_steps`` that is not a positive integer.

    See Also
    --------
    shapelib.geodesic : The boundary-value problem.
    shapelib.exp_map : The discrete exponential map.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.geodesic import shoot
    >>> path = shoot([[0.0, 0.0]], [[1.0, 0.5]], sigma2=0.5, n_steps=4)
    >>> path.shape, bool(np.allclose(path[-1], [[1.0, 0.5]]))
    ((5, 1, 2), True)
    """
    u = as_shape_pair(u, velocity, names=("u", "velocity"))[0]
    s2 = check_sigma2(sigma2)
    n_steps = check_positive_int(n_steps, name="n_steps")
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


def geodesics(us, vs, *, metric: str = "alpha", sigma2, n_steps: int = 16, tol: float = 1e-6,
              max_iter: int = 500, window: int = 5, grid_spacing: float = DEFAULT_SPACING,
              grid_margin: float = DEFAULT_MARGIN, hessian: str = "exact", warn: bool = True,
              backend: str = "jax", device: str | None = None, batch_size: int | None = None) -> list:
    """Geodesics of many pairs ``(us[i], vs[i])``: :func:`geodesic` for each, with ``backend="jax"``
    all of them minimised as one batch on the device (:func:`shapelib.solver.batched.batched_geodesics`).

    Parameters
    ----------
    us, vs : array_like, shape (B, K, d)
        Pairs of shapes of one size (group pairs by ``K`` and ``d`` before calling).
    metric, sigma2, n_steps, tol, max_iter, window, grid_spacing, grid_margin, hessian
        As in :func:`geodesic` (``hessian`` applies to ``backend="cpu"``).
    warn : bool
        ``backend="jax"``: one :class:`GeodesicWarning` for the pairs that stopped before converging.
    backend : {"jax", "cpu"}
        ``"jax"`` (default): batched on a JAX device; ``"cpu"``: :func:`geodesic` pair by pair.
    device : {None, "cpu", "gpu"}
        JAX device (:func:`geodesic`).
    batch_size : int, optional
        Pairs per device call (default: from the device's memory).

    Returns
    -------
    list of GeodesicResult
        In the order of the pairs, each checked and certified as :func:`geodesic`'s.

    See Also
    --------
    geodesic : One pair, with the same options.
    shapelib.solver.batched.batched_geodesics : The batched JAX minimisation behind ``backend="jax"``.
    shapelib.solver.bracket.distance_brackets : Certified distance brackets of many pairs.

    Notes
    -----
    Each result is the minimiser of the discretised path energy of eq. (8) of [1]_ between ``us[i]`` and
    ``vs[i]``; with ``backend="jax"`` the pairs are minimised together by L-BFGS [2]_ in JAX [3]_.

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
    >>> from shapelib import geodesics
    >>> u = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.5]])
    >>> vs = np.stack([u + [[0.3, -0.2], [0.0, 0.1], [-0.2, 0.0]], u * 1.1])
    >>> out = geodesics(np.stack([u, u]), vs, metric="alpha", sigma2=0.5, n_steps=8, device="cpu")
    >>> [bool(r.converged and r.lower_bound <= r.length) for r in out]
    [True, True]
    """
    backend, device = check_backend(backend, device)
    us, vs = as_pair_batch(us, vs)
    common = dict(metric=metric, sigma2=sigma2, n_steps=n_steps, tol=tol, max_iter=max_iter, window=window,
                  grid_spacing=grid_spacing, grid_margin=grid_margin)
    if backend == "cpu":
        return [geodesic(u, v, hessian=hessian, warn=warn, **common) for u, v in zip(us, vs)]
    s2 = check_sigma2(sigma2)
    us, vs, ratios = _check_entries(us, vs, s2, metric=metric, stacklevel=3)
    out = batched_geodesics(us, vs, device=device, batch_size=batch_size, warn=False, **{**common, "sigma2": s2})
    for result, ratio in zip(out, ratios):
        _mark_underflow(result, ratio)
    failed = [r for r in out if not r.converged]
    if failed and warn:
        warnings.warn(f"{metric} geodesics: {len(failed)} of {len(out)} pairs did not converge "
                      f"(first: {failed[0].summary()})", GeodesicWarning, stacklevel=2)
    return out
