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
* :func:`to_centroid_size` — bring shapes to the study's scale (what
  :func:`shapelib.study.paper_scale` does).

:func:`shapelib.geodesic.geodesic` and :func:`shapelib.bracket.distance_bracket` check the
ratio at entry (:func:`shapelib._validate.check_scale`) and warn with a :class:`ScaleWarning`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ._validate import as_shape, as_shapes, check_positive, check_sigma2

__all__ = ["landmark_spacing", "sigma_ratio", "to_centroid_size", "ScaleWarning", "PAPER_CENTROID_SIZE",
           "SIGMA_RATIO_MIN"]

#: Centroid size at which Table I's distances appear to have been computed (see table1_pairwise).
PAPER_CENTROID_SIZE = 20.0

#: Below this σ / spacing, neighbouring Gaussians overlap by less than e^{-1/(4·0.2²)} ≈ 2e-3.
SIGMA_RATIO_MIN = 0.2


class ScaleWarning(UserWarning):
    """σ does not fit the scale of the landmarks (see :mod:`shapelib.scale`)."""


def _as_collection(shapes) -> np.ndarray:
    arr = np.asarray(shapes, dtype=np.float64) if not isinstance(shapes, (list, tuple)) else shapes
    if np.ndim(arr) == 2:
        return as_shape(arr, name="shapes")[None]
    return as_shapes(shapes, name="shapes")


def landmark_spacing(shapes) -> float:
    """Mean distance from each landmark to its nearest other landmark of the same shape.

    Parameters
    ----------
    shapes : array_like, shape (K, d) or (N, K, d)

    Returns
    -------
    float
        The mean over landmarks and shapes; ``0.0`` only if landmarks coincide pairwise.

    Raises
    ------
    ValueError
        For fewer than two landmarks (no spacing to measure).
    """
    x = _as_collection(shapes)
    if x.shape[1] < 2:
        raise ValueError(f"shapes need at least 2 landmarks to measure their spacing; got shape {x.shape}")
    return float(np.mean([cKDTree(s).query(s, k=2)[0][:, 1] for s in x]))


def sigma_ratio(shapes, sigma2) -> float:
    """σ in units of the mean nearest-landmark spacing, ``√σ² / landmark_spacing(shapes)``.

    The paper's corpus callosum settings (centroid size 20, σ² = 0.1, 0.5, 1.5) give 1.1, 2.6
    and 4.5; below :data:`SIGMA_RATIO_MIN` the Gaussians of neighbouring landmarks no longer
    overlap. ``inf`` if all landmarks coincide pairwise.
    """
    s = np.sqrt(check_sigma2(sigma2))
    spacing = landmark_spacing(shapes)
    return float(s / spacing) if spacing > 0 else float("inf")


def to_centroid_size(shapes, size: float = PAPER_CENTROID_SIZE) -> np.ndarray:
    """Shapes at the study's scale: generalised-Procrustes aligned (rotations only), centred,
    each scaled to centroid size ``size``.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d) or (K, d)
        A single shape is only centred and scaled.
    size : float
        Centroid size (Frobenius norm of the centred landmarks) of every output shape.

    Returns
    -------
    ndarray
        Same shape as the input.
    """
    from .procrustes import generalized_procrustes, preshape

    size = check_positive(size, name="size")
    if np.ndim(shapes) == 2:
        return preshape(as_shape(shapes, name="shapes", min_landmarks=2)) * size
    aligned, _ = generalized_procrustes(shapes, scaling=False)
    return aligned * size
