"""Scale: how σ of the GMM representation (eq. 5) compares with the landmarks.

σ² is a length² in the units of the landmark coordinates, so the same ``sigma2`` means very
different things for shapes in pixels and shapes at unit size. The paper's σ² = 0.1, 0.5, 1.5
for the corpus callosum fit shapes of centroid size 20 (:data:`PAPER_CENTROID_SIZE`; Table I),
where σ is 1.1–4.5 times the mean nearest-landmark spacing: neighbouring Gaussians overlap and
the mixture outlines the contour (Fig. 1). Far below the spacing each landmark is an isolated
Gaussian (the metric is flat, the contour invisible, and quantities underflow); far above the
shape's extent the whole shape is one blob.

* :func:`landmark_spacing` — mean distance from a landmark to its nearest neighbour;
* :func:`sigma_ratio` — σ in units of that spacing (≈ 1–5 is the paper's regime);
* :func:`to_centroid_size` — bring shapes to the study's scale;
* :func:`check_scale` — warn when σ does not fit the landmarks;
* :func:`estimate_sigma2` — σ² from the data: the landmarks' own scatter around the mean shape
  (:mod:`shapelib.geometry.sigma2`), the library's one σ² advice (``shapelib info``, the CLI's
  ``--sigma2 auto``, the advice of :class:`ScaleWarning`).

:func:`shapelib.solver.geodesic.geodesic` and :func:`shapelib.solver.bracket.distance_bracket` check the
ratio at entry (:func:`check_scale`) and warn with a :class:`ScaleWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .._validate import as_shape, as_shapes, check_positive, check_sigma2
from .procrustes import generalized_procrustes, preshape
from .sigma2 import predictive_sigma2, scatter_sigma2

__all__ = ["landmark_spacing", "sigma_ratio", "to_centroid_size", "ScaleWarning", "PAPER_CENTROID_SIZE",
           "SIGMA_RATIO_MIN", "check_scale", "FISHER_RAO_RATIO_MIN", "check_fisher_rao_scale", "estimate_sigma2",
           "Sigma2Estimate", "SIGMA2_METHODS"]

#: Centroid size at which Table I's distances appear to have been computed (see table1_pairwise).
PAPER_CENTROID_SIZE = 20.0

#: Below this σ / spacing, neighbouring Gaussians overlap by less than e^{-1/(4·0.2²)} ≈ 2e-3.
SIGMA_RATIO_MIN = 0.2


class ScaleWarning(UserWarning):
    r"""σ does not fit the scale of the landmarks (see :mod:`shapelib.geometry.scale`).

    σ² of eq. (5) [1]_ is a squared length in the landmarks' units. The geodesics, brackets and
    bounds warn with this category when σ is below ``SIGMA_RATIO_MIN`` (0.2) times the mean
    nearest-landmark spacing,

    .. math::

        \frac{\sigma}{\bar h} < 0.2, \qquad \bar h = \frac{1}{K} \sum_a \min_{b \ne a} |x_a - x_b|,

    (the Gaussians of neighbouring landmarks do not overlap) or above the shapes' extent (each
    shape is one blob); the message says what :func:`shapelib.estimate_sigma2` gives for the shapes.

    See Also
    --------
    shapelib.sigma_ratio : The ratio of σ to the spacing.
    shapelib.to_centroid_size : Bring shapes to the study's scale.
    shapelib.estimate_sigma2 : The σ² the data suggest.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import shapelib as sl
    >>> t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    >>> u = 300.0 * np.c_[np.cos(t), np.sin(t)]  # pixel units: σ² = 0.5 is far too small
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = sl.distance(u, 1.1 * u, metric="alpha_bound", sigma2=0.5)
    >>> any(issubclass(w.category, sl.ScaleWarning) for w in caught)
    True

    Attributes
    ----------
    facts : dict
        What the message says, for callers that word it their own way (the command line names its
        options): ``kind`` (``"small"``: σ below ``SIGMA_RATIO_MIN`` spacings; ``"large"``: σ above
        the shapes' extent), ``sigma2``, ``ratio`` (σ / spacing), ``spacing`` and ``estimate``
        (:func:`shapelib.estimate_sigma2`'s σ² for the shapes, or None).
    """

    def __init__(self, message, facts=None):
        super().__init__(message)
        self.facts = dict(facts or {})


def _as_collection(shapes) -> np.ndarray:
    arr = np.asarray(shapes, dtype=np.float64) if not isinstance(shapes, (list, tuple)) else shapes
    if np.ndim(arr) == 2:
        return as_shape(arr, name="shapes")[None]
    return as_shapes(shapes, name="shapes")


def landmark_spacing(shapes) -> float:
    r"""Mean distance from each landmark to its nearest other landmark of the same shape.

    .. math::

        \bar h = \frac{1}{N K} \sum_{i=1}^{N} \sum_{a=1}^{K} \min_{b \ne a} |x_{ia} - x_{ib}|

    the length σ of eq. (5) [1]_ is compared with (:func:`shapelib.sigma_ratio`).

    Parameters
    ----------
    shapes : array_like, shape (K, d) or (N, K, d)
        One shape or a population.

    Returns
    -------
    float
        The mean over landmarks and shapes; ``0.0`` only if landmarks coincide pairwise.

    Raises
    ------
    ValueError
        For fewer than two landmarks (no spacing to measure), or non-finite input.

    See Also
    --------
    shapelib.sigma_ratio : The ratio of σ to this spacing.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import shapelib as sl
    >>> sl.landmark_spacing([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 2.0]])
    1.0
    """
    x = _as_collection(shapes)
    if x.shape[1] < 2:
        raise ValueError(f"shapes need at least 2 landmarks to measure their spacing; got shape {x.shape}")
    return float(np.mean([cKDTree(s).query(s, k=2)[0][:, 1] for s in x]))


def sigma_ratio(shapes, *, sigma2) -> float:
    r"""σ in units of the mean nearest-landmark spacing.

    .. math::

        r = \frac{\sqrt{\sigma^2}}{\bar h}

    with :math:`\bar h` of :func:`shapelib.landmark_spacing`. The paper's corpus callosum settings
    [1]_ (centroid size 20, σ² = 0.1, 0.5, 1.5) give 1.1, 2.6 and 4.5; below ``SIGMA_RATIO_MIN``
    (0.2) the Gaussians of neighbouring landmarks no longer overlap.

    Parameters
    ----------
    shapes : array_like, shape (K, d) or (N, K, d)
        One shape or a population.
    sigma2 : float
        σ² > 0 of eq. (5).

    Returns
    -------
    float
        :math:`r`; ``inf`` if all landmarks coincide pairwise.

    Raises
    ------
    ValueError
        For a non-positive ``sigma2``, fewer than two landmarks or non-finite input.

    See Also
    --------
    shapelib.landmark_spacing : The spacing.
    shapelib.ScaleWarning : The warning this ratio decides.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import shapelib as sl
    >>> sl.sigma_ratio([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 2.0]], sigma2=0.25)
    0.5
    """
    s = np.sqrt(check_sigma2(sigma2))
    spacing = landmark_spacing(shapes)
    return float(s / spacing) if spacing > 0 else float("inf")


def to_centroid_size(shapes, size: float = PAPER_CENTROID_SIZE) -> np.ndarray:
    r"""Shapes at the study's scale: aligned (rotations only), centred, each at centroid size ``size``.

    Generalised Procrustes alignment without scaling, then every shape scaled to

    .. math::

        S(x_i) = \|x_i - \bar x_i\|_F = \text{size},

    the centroid size 20 at which the σ² values of Table I of [1]_ fit the corpus callosum shapes.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d) or (K, d)
        A single shape is only centred and scaled.
    size : float, default 20.0
        Centroid size (Frobenius norm of the centred landmarks) of every output shape.

    Returns
    -------
    ndarray
        Same shape as the input.

    Raises
    ------
    ValueError
        For a non-positive ``size``, fewer than two landmarks, a shape of zero size, or
        non-finite input.

    See Also
    --------
    shapelib.generalized_procrustes : The alignment.
    shapelib.centroid_size : The size measure.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> shapes = rng.standard_normal((4, 10, 2)) * [3.0, 1.0]
    >>> out = sl.to_centroid_size(shapes)
    >>> out.shape, [round(sl.centroid_size(s), 9) for s in out]
    ((4, 10, 2), [20.0, 20.0, 20.0, 20.0])
    """
    size = check_positive(size, name="size")
    if np.ndim(shapes) == 2:
        return preshape(as_shape(shapes, name="shapes", min_landmarks=2)) * size
    aligned, _ = generalized_procrustes(shapes, scaling=False)
    return aligned * size


def check_scale(shapes, sigma2: float, *, stacklevel: int = 3) -> float:
    r"""Warn (:class:`~shapelib.ScaleWarning`) when σ does not fit the landmarks' scale.

    Warns when

    .. math::

        \frac{\sigma}{\bar h} < 0.2 \qquad \text{or} \qquad
        \sigma > \max_i \operatorname{extent}(x_i),

    :math:`\bar h` the mean nearest-landmark spacing: below, the Gaussians of neighbouring landmarks
    of eq. (5) [1]_ do not overlap (the metric is nearly flat and lengths and gradients underflow);
    above, every shape is one blob (0.2 is ``SIGMA_RATIO_MIN``).

    Parameters
    ----------
    shapes : array_like, shape (K, d) or (N, K, d)
        The shapes a computation is asked of.
    sigma2 : float
        σ² > 0 of eq. (5).
    stacklevel : int, default 3
        Counted from this function, as :func:`warnings.warn` counts it (3: the caller of its caller).

    Returns
    -------
    float
        :math:`\sigma / \bar h` (``inf`` for single landmarks or coincident ones).

    Raises
    ------
    ValueError
        For a non-positive ``sigma2`` or non-finite input.

    Warns
    -----
    ScaleWarning
        When σ does not fit; the message says what to change and what
        :func:`shapelib.estimate_sigma2` gives.

    See Also
    --------
    shapelib.sigma_ratio : The ratio alone.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import warnings
    >>> from shapelib.geometry.scale import check_scale
    >>> square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("error")
    ...     check_scale(square, 0.25)
    0.5
    """
    x = _as_collection(shapes)
    sigma2 = check_sigma2(sigma2)
    sigma = float(np.sqrt(sigma2))
    if x.shape[1] < 2:
        return float("inf")
    spacing = landmark_spacing(x)
    ratio = sigma / spacing if spacing > 0 else float("inf")
    extent = float(np.max(np.ptp(x, axis=1)))
    small, large = ratio < SIGMA_RATIO_MIN, extent > 0 and sigma > extent
    if not (small or large):
        return ratio
    est = _estimate_or_none(x)
    facts = {"kind": "small" if small else "large", "sigma2": sigma2, "ratio": ratio, "spacing": spacing,
             "estimate": None if est is None else est.sigma2}
    if small and est is not None and abs(sigma2 / est.sigma2 - 1.0) <= OWN_ESTIMATE_RTOL:
        # σ² is the shapes' own scatter (estimate_sigma2): no other scale of the shapes fits it
        # better (σ / spacing does not change with the scale); the estimate's summary says what it means
        return ratio
    fix = ("Bring the shapes to a scale that fits sigma2, e.g. shapelib.to_centroid_size(shapes) "
           "(the study's centroid size 20, where the paper's sigma2 = 0.1-1.5 give sigma = 1.1-4.5 "
           "spacings), or estimate sigma2 from the data")
    if small:
        warnings.warn(ScaleWarning(
            f"sigma = {sigma:.3g} (sigma2 = {sigma2:.3g}) is {ratio:.3g} times the mean nearest-landmark "
            f"spacing {spacing:.3g}: the Gaussians of neighbouring landmarks do not overlap, so the "
            f"metric sees isolated points, not a shape, and energies and gradients underflow. {fix}"
            f"{_advice(est, spacing)}", facts),
            stacklevel=stacklevel)
    else:
        warnings.warn(ScaleWarning(
            f"sigma = {sigma:.3g} (sigma2 = {sigma2:.3g}) exceeds the largest extent of the shapes "
            f"({extent:.3g}): each shape is a single blob and distances between shapes nearly vanish. "
            f"{fix}{_advice(est, spacing)}", facts),
            stacklevel=stacklevel)
    return ratio


#: Below this σ / spacing the Gaussians of neighbouring landmarks do not overlap even in float64:
#: midway between landmarks one spacing ``h`` apart each is ``exp(−h²/(8σ²))`` of its peak, below
#: machine epsilon (2.2e-16) for σ < h / √(8 ln(1/ε)) ≈ 0.059 h. The Fisher–Rao quantities divide
#: by √p, which then vanishes between the landmarks: their quadrature has nothing to resolve.
FISHER_RAO_RATIO_MIN = float(1.0 / np.sqrt(8.0 * np.log(1.0 / np.finfo(np.float64).eps)))


def check_fisher_rao_scale(shapes, *, sigma2, metric: str = "fisher_rao", ratio: float | None = None) -> None:
    r"""Raise ``ValueError`` before any work when σ is too small for the Fisher–Rao quadrature.

    The Fisher–Rao metric (eq. 6 of [1]_) and its bound divide by :math:`\sqrt{p}`; when

    .. math::

        \frac{\sigma}{\bar h} < \frac{1}{\sqrt{8 \ln(1/\varepsilon)}} \approx 0.059

    (:math:`\varepsilon` the float64 machine epsilon, :math:`\bar h` the mean nearest-landmark
    spacing), the Gaussians of neighbouring landmarks do not overlap even in double precision: the
    density underflows between them and the quadrature has nothing to resolve.

    Parameters
    ----------
    shapes : array_like, shape (K, d) or (N, K, d)
        The shapes.
    sigma2 : float
        σ² > 0 of eq. (5).
    metric : str, default "fisher_rao"
        The metric's name, for the message.
    ratio : float, optional
        σ / spacing if already known (:func:`~shapelib.geometry.scale.check_scale` returns it).

    Returns
    -------
    None

    Raises
    ------
    ValueError
        When σ is below the threshold; the message gives the smallest σ² that works.

    See Also
    --------
    shapelib.fisher_rao_metric : The metric that needs it.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.geometry.scale import check_fisher_rao_scale
    >>> square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    >>> check_fisher_rao_scale(square, sigma2=0.25) is None
    True
    >>> try:
    ...     check_fisher_rao_scale(square, sigma2=1e-4)
    ... except ValueError as exc:
    ...     print(str(exc)[:40])
    fisher_rao: sigma2 = 0.0001 is too small
    """
    sigma2 = check_sigma2(sigma2)
    if ratio is None:
        x = _as_collection(shapes)
        if x.shape[1] < 2:
            return
        spacing = landmark_spacing(x)
        ratio = np.sqrt(sigma2) / spacing if spacing > 0 else float("inf")
    if ratio < FISHER_RAO_RATIO_MIN:
        spacing = np.sqrt(sigma2) / ratio
        raise ValueError(
            f"{metric}: sigma2 = {sigma2:.3g} is too small for these landmarks: sigma = {np.sqrt(sigma2):.3g} is "
            f"{ratio:.3g} times their mean nearest-landmark spacing {spacing:.3g}, below {FISHER_RAO_RATIO_MIN:.2g}, "
            f"where the Gaussians of neighbouring landmarks do not overlap even in double precision and the "
            f"Fisher-Rao quadrature has nothing to resolve (it divides by the density, which vanishes between "
            f"them). Use sigma2 >= {(FISHER_RAO_RATIO_MIN * spacing) ** 2:.3g} (sigma at one spacing: "
            f"{spacing ** 2:.3g}), or bring the shapes to a scale that fits sigma2 (shapelib.to_centroid_size)")


#: a σ² within this relative distance of :func:`estimate_sigma2`'s value for the same shapes is
#: taken as that estimate (printed to 6 digits by ``--sigma2 auto``): :func:`check_scale` does not
#: advise rescaling shapes that are already at the scale their σ² was estimated for
OWN_ESTIMATE_RTOL = 1e-3


def _estimate_or_none(x):
    if len(x) < 2:
        return None
    try:
        return estimate_sigma2(x)
    except ValueError:
        return None


def _advice(est, spacing) -> str:
    """The tail of a :class:`ScaleWarning`: what :func:`estimate_sigma2` gives for these shapes."""
    if est is None:
        return "."
    text = (f": shapelib.estimate_sigma2(shapes) gives sigma2 = {est.sigma2:.3g} here (the landmarks' scatter "
            f"around their mean, sigma = {est.sigma_over_spacing:.2g} spacings)")
    if est.sigma_over_spacing < SIGMA_RATIO_MIN:
        text += (f"; that is below {SIGMA_RATIO_MIN:g} spacings too: the landmarks vary less than they are apart. "
                 f"At such sigma the closed-form bounds (alpha_bound, fisher_rao_bound) are still exact and compare the "
                 f"shapes landmark by landmark, while geodesics are straight lines (paths bend from sigma2 = "
                 f"{(SIGMA_RATIO_MIN * spacing) ** 2:.3g})")
    return text + "."


# ---------------------------------------------------------------------------------------------
# σ² from the data
# ---------------------------------------------------------------------------------------------

#: the estimators of :func:`estimate_sigma2` (see :mod:`shapelib.geometry.sigma2`)
SIGMA2_METHODS = ("scatter", "predictive")


@dataclass(frozen=True)
class Sigma2Estimate:
    r"""σ² of eq. (5) estimated from a population (:func:`shapelib.estimate_sigma2`).

    For ``"scatter"`` the estimate and its standard error are

    .. math::

        \hat\sigma^2 = \frac{1}{\mathrm{df}} \sum_{i,a} |x_{ia} - \bar x_a|^2, \qquad
        \operatorname{se}(\hat\sigma^2) = \hat\sigma^2 \sqrt{2/\mathrm{df}}

    (:mod:`shapelib.geometry.sigma2`); the paper [1]_ fixes σ² by hand.

    Attributes
    ----------
    sigma2 : float
        The estimate, in squared units of the landmark coordinates.
    method : {"scatter", "predictive"}
        The estimator.
    standard_error : float or None
        Its sampling standard error (``"scatter"``: :math:`\hat\sigma^2 \sqrt{2/\mathrm{df}}`;
        ``None`` for ``"predictive"``).
    spacing : float
        Mean nearest-landmark spacing of the shapes (:func:`shapelib.landmark_spacing`).
    n_shapes, n_landmarks, dim : int
        The population's size.
    landmark_range : tuple of float or None
        ``"scatter"``: the smallest and largest σ of a single landmark, over σ — how unequal
        the landmarks' variability is (eq. 5 gives all of them one σ).
    pose_share : float
        Share of the scatter of the shapes as given that is pose (position, orientation): the
        estimate is computed after superimposing them rigidly, but the distances see the shapes
        as given, so a large share means: align them first.
    sigma : float
        :math:`\sqrt{\hat\sigma^2}` (property).
    sigma_over_spacing : float
        σ in units of ``spacing`` (property).

    See Also
    --------
    shapelib.estimate_sigma2 : What returns it.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(1)
    >>> t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    >>> shapes = 3.0 * np.c_[np.cos(t), np.sin(t)] + 0.5 * rng.standard_normal((20, 12, 2))
    >>> est = sl.estimate_sigma2(shapes)
    >>> est.method, est.n_shapes, round(est.sigma, 2)
    ('scatter', 20, 0.45)
    >>> print(est.summary().splitlines()[0][:30])
    sigma2 = 0.204 ± 0.014 (landma
    """

    sigma2: float
    method: str
    standard_error: float | None
    spacing: float
    n_shapes: int
    n_landmarks: int
    dim: int
    landmark_range: tuple | None
    pose_share: float

    @property
    def sigma(self) -> float:
        return float(np.sqrt(self.sigma2))

    @property
    def sigma_over_spacing(self) -> float:
        return self.sigma / self.spacing if self.spacing > 0 else float("inf")

    def summary(self) -> str:
        what = {"scatter": "landmark scatter: the maximum-likelihood variance of each landmark around the "
                           "mean shape, per coordinate",
                "predictive": "held-out prediction: half the variance at which one shape's mixture best "
                              "predicts another's landmarks"}[self.method]
        se = f" ± {self.standard_error:.2g}" if self.standard_error is not None else ""
        lines = [f"sigma2 = {self.sigma2:.4g}{se} ({what}; {self.n_shapes} shapes x {self.n_landmarks} landmarks "
                 f"in {self.dim}-D)",
                 f"sigma = {self.sigma:.4g} = {self.sigma_over_spacing:.3g} x the mean nearest-landmark spacing "
                 f"{self.spacing:.4g}"]
        if self.landmark_range is not None:
            lo, hi = self.landmark_range
            lines.append(f"single landmarks vary from {lo:.2g} to {hi:.2g} times this sigma (eq. 5 gives all one sigma)")
        if self.sigma_over_spacing < SIGMA_RATIO_MIN:
            lines.append(f"the Gaussians of neighbouring landmarks barely overlap at this sigma (below "
                         f"{SIGMA_RATIO_MIN:g} spacings): the closed-form bounds are fine; geodesics are nearly "
                         f"straight and the solvers warn")
        if self.pose_share > 0.1:
            lines.append(f"{self.pose_share:.0%} of this scatter is pose (position, orientation): align the shapes "
                         f"first (shapelib.to_centroid_size, `shapelib align`) and estimate again")
        return "\n".join(lines)


def estimate_sigma2(shapes, *, method: str = "scatter") -> Sigma2Estimate:
    r"""σ² of the GMM shape (eq. 5) from a population of shapes (:mod:`shapelib.geometry.sigma2`).

    ``"scatter"`` (default): the maximum-likelihood σ² of the landmarks around the mean shape, each
    landmark a noisy observation of its mixture component (shapes superimposed rigidly first):

    .. math::

        \hat\sigma^2 = \frac{\sum_{i,a} |x_{ia} - \bar x_a|^2}{(N - 1) K d - N d(d + 1)/2}.

    With it, the overlap of two shapes' Gaussians at corresponding landmarks is the density of the
    difference of two corresponding landmarks under the model: displacements of the size the
    population shows count as typical. ``"predictive"``: half the σ² at which one shape's mixture
    best predicts another's landmarks (no correspondence used; low once neighbouring Gaussians
    overlap). The paper [1]_ fixes σ² by hand and names estimating it from the data as its next step.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        The shapes the distances will be computed on — aligned, at that scale (σ² is in squared
        coordinate units); N ≥ 2.
    method : {"scatter", "predictive"}, default "scatter"
        The estimator.

    Returns
    -------
    Sigma2Estimate
        ``.sigma2``; ``.summary()`` says what the number means and warns when the shapes are not
        aligned or σ is below the landmark spacing's regime.

    Raises
    ------
    ValueError
        For an unknown ``method``, fewer than two shapes, too few landmarks to estimate anything
        beyond the pose, or identical shapes.

    See Also
    --------
    shapelib.Sigma2Estimate : The result.
    shapelib.geometry.sigma2.scatter_sigma2 : The scatter estimator itself.
    shapelib.bound_matrix_sweep : Distances over a range of σ².

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    Noisy copies of a circle with landmark noise σ = 0.5:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(1)
    >>> t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    >>> shapes = 3.0 * np.c_[np.cos(t), np.sin(t)] + 0.5 * rng.standard_normal((20, 12, 2))
    >>> est = sl.estimate_sigma2(shapes)
    >>> round(est.sigma2, 2), round(est.standard_error, 3)
    (0.2, 0.014)
    """
    if method not in SIGMA2_METHODS:
        raise ValueError(f"method must be one of {SIGMA2_METHODS}; got {method!r}")
    x = as_shapes(shapes, name="shapes", min_shapes=2)
    n, k, d = x.shape
    s2, se, per_landmark = scatter_sigma2(x)
    share = float(max(0.0, 1.0 - s2 / scatter_sigma2(x, superimpose=False)[0]))
    spacing = landmark_spacing(x) if k >= 2 else 0.0
    if method == "predictive":
        return Sigma2Estimate(predictive_sigma2(x), method, None, spacing, n, k, d, None, share)
    spread = np.sqrt(per_landmark / s2)
    return Sigma2Estimate(s2, method, se, spacing, n, k, d, (float(spread.min()), float(spread.max())), share)
