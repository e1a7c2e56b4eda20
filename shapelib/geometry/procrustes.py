"""Procrustes analysis: ordinary and generalised alignment and the Procrustes distances.

References: Kendall (1984), Dryden & Mardia, *Statistical Shape Analysis* (paper refs. [4], [40]).

For centred configurations scaled to unit Frobenius norm (pre-shapes) ``X`` and ``Y``, let
``s`` be the singular values of ``XᵀY`` with the sign of the smallest one flipped when the
optimal orthogonal map would be a reflection (rotations only). With ``S = Σ s`` (``0 ≤ S ≤ 1``):

* Procrustes angle (Riemannian shape-space distance)  ρ = arccos S,
* full Procrustes distance                           d_F = √(1 − S²),
* partial Procrustes distance                        d_P = √(2 − 2S).

``scipy.spatial.procrustes`` returns ``d_F²`` when reflections are allowed.
Table I's Procrustes column is ρ × 100 (``notebooks/table1_pairwise.py``).

Pose
----
The information metrics (eqs. 6, 22), their bounds, the landmark diffeomorphism and the
Hausdorff distance compare shapes where they lie: rotating or moving one shape changes them.
:func:`pose_align` aligns shapes by rotations and translations only (sizes kept, so σ² keeps its
meaning) and says how far each shape moved; :func:`check_pose` warns (:class:`PoseWarning`) when
that is more than :data:`POSE_TOL` of the shapes' size.
"""

from __future__ import annotations

import warnings

import numpy as np

from .._validate import as_shape, as_shape_pair, as_shapes, set_was_checked

__all__ = [
    "PoseWarning",
    "POSE_TOL",
    "POSE_PAIR_RATIO",
    "pose_align",
    "pose_change",
    "check_pose",
    "center",
    "centroid_size",
    "preshape",
    "optimal_rotation",
    "procrustes_align",
    "procrustes_distance",
    "generalized_procrustes",
]


def center(x) -> np.ndarray:
    """Translate the landmarks ``(K, d)`` so that their centroid is at the origin."""
    x = as_shape(x, name="x")
    return x - x.mean(axis=0)


def centroid_size(x) -> float:
    """Centroid size: the Frobenius norm of the centred configuration."""
    c = center(x)
    top = float(np.abs(c).max()) if c.size else 0.0
    return top * float(np.linalg.norm(c / top)) if top > 0 and np.isfinite(top) else float(np.linalg.norm(c))


def preshape(x) -> np.ndarray:
    """Centre and scale to unit centroid size; raises ``ValueError`` if all landmarks coincide."""
    c = center(x)
    if not np.isfinite(c).all():
        raise ValueError(f"configuration of shape {c.shape} has coordinates too large to centre in double precision "
                         f"(largest {np.nanmax(np.abs(np.asarray(x, dtype=np.float64))):.3g}): rescale them")
    top = float(np.abs(c).max()) if c.size else 0.0
    if top == 0:
        raise ValueError(f"configuration of shape {c.shape} has zero centroid size (all landmarks coincide)")
    u = c / top  # scaled first: the sum of squares of coordinates near 1e200 overflows
    return u / np.linalg.norm(u)


def optimal_rotation(x, y, *, reflection: bool = False):
    """Rotation ``R`` minimising ``‖x − y R‖`` for centred ``x`` and ``y``, and the summed singular values.

    Returns
    -------
    R : ndarray, shape (d, d)
    trace : float
        ``Σ s``: the sum of singular values of ``yᵀx`` (smallest one negated when a proper
        rotation is enforced and the unconstrained optimum is a reflection).
    """
    u, s, vt = np.linalg.svd(y.T @ x)
    if not reflection and np.linalg.det(u @ vt) < 0:
        u = u.copy()
        u[:, -1] *= -1
        s = s.copy()
        s[-1] *= -1
    return u @ vt, float(s.sum())


def procrustes_align(x, y, *, scaling: bool = True, reflection: bool = False) -> np.ndarray:
    """Ordinary Procrustes analysis: superimpose ``y`` onto ``x``.

    ``y`` is translated to ``x``'s centroid, rotated (and scaled if ``scaling``) to minimise
    the sum of squared landmark distances to ``x``.

    Parameters
    ----------
    x, y : array_like, shape (K, d)
        Target and moving configurations, landmarks in correspondence.
    scaling : bool
        Also fit an isotropic scale.
    reflection : bool
        Allow an improper orthogonal map.

    Returns
    -------
    ndarray, shape (K, d)
        ``y`` aligned to ``x``.
    """
    x, y = as_shape_pair(x, y, names=("x", "y"))
    mx = x.mean(axis=0)
    xc, yc = x - mx, y - y.mean(axis=0)
    r, tr = optimal_rotation(xc, yc, reflection=reflection)
    beta = 1.0
    if scaling:
        ny = np.sum(yc**2)
        if ny == 0:
            raise ValueError("y has zero centroid size (all landmarks coincide); cannot scale it")
        beta = tr / ny
    return beta * (yc @ r) + mx


def procrustes_distance(u, v, *, kind: str = "angle") -> float:
    """Procrustes distance between two landmark configurations (rotations, no reflections).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Configurations with landmarks in correspondence, K >= 2.
    kind : {"angle", "full", "partial"}
        ``"angle"``: ρ = arccos Σs (Kendall's shape-space geodesic distance, in radians);
        ``"full"``: √(1 − (Σs)²); ``"partial"``: √(2 − 2Σs). See the module docstring.

    Returns
    -------
    float
    """
    if kind not in ("angle", "full", "partial"):
        raise ValueError(f"kind must be 'angle', 'full' or 'partial'; got {kind!r}")
    u, v = as_shape_pair(u, v, min_landmarks=2)
    _, s = optimal_rotation(preshape(u), preshape(v))
    s = min(max(s, -1.0), 1.0)
    if kind == "angle":
        return float(np.arccos(s))
    if kind == "full":
        return float(np.sqrt(max(1.0 - s * s, 0.0)))
    return float(np.sqrt(max(2.0 - 2.0 * s, 0.0)))


def generalized_procrustes(shapes, *, scaling: bool = True, tol: float = 1e-12, max_iter: int = 1000):
    """Generalised Procrustes analysis (GPA) of a collection of shapes.

    Each shape is centred and scaled to unit centroid size, then rotated (rotations only)
    to the current mean, and the mean re-estimated and normalised, until the mean stops
    changing. With ``scaling``, full GPA scale factors are fitted as well (Gower 1975;
    Dryden & Mardia §7.3), keeping the total size fixed.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
    scaling : bool
        Fit per-shape scales (full GPA) instead of leaving every shape at unit size.
    tol : float
        Convergence tolerance on the change of the mean (Frobenius norm).
    max_iter : int

    Returns
    -------
    aligned : ndarray, shape (N, K, d)
        Aligned shapes, centred; with ``scaling=False`` each has unit centroid size.
    mean : ndarray, shape (K, d)
        Their mean, with unit centroid size.
    """
    x = as_shapes(shapes, name="shapes", min_landmarks=2)
    aligned = np.stack([preshape(s) for s in x])
    mean = preshape(aligned[0])
    for it in range(max_iter):
        for i in range(len(aligned)):
            r, _ = optimal_rotation(mean, aligned[i])
            aligned[i] = aligned[i] @ r
        if scaling and len(aligned) > 1:
            # Ten Berge (1977): scales proportional to the leading eigenvector of the correlation.
            flat = aligned.reshape(len(aligned), -1)
            gram = flat @ flat.T
            norms = np.sqrt(np.diag(gram))
            corr = gram / np.outer(norms, norms)
            w, vecs = np.linalg.eigh(corr)
            phi = np.abs(vecs[:, -1])
            beta = np.sqrt(np.sum(norms**2) / norms**2) * phi
            aligned = aligned * beta[:, None, None]
        new_mean = aligned.mean(axis=0)
        new_mean /= np.linalg.norm(new_mean)
        delta = np.linalg.norm(new_mean - mean)
        mean = new_mean
        if delta < tol:
            break
    else:
        warnings.warn(f"generalized_procrustes did not converge in {max_iter} iterations", RuntimeWarning, stacklevel=2)
    return aligned, mean


# ---------------------------------------------------------------------------------------------
# Pose: are the shapes aligned?
# ---------------------------------------------------------------------------------------------

#: Shapes count as aligned when aligning them moves no shape by more than this fraction of its
#: centroid size (RMS over landmarks × √K; 1e-3 is a rotation of 0.06°).
POSE_TOL = 1e-3
#: Two shapes are not aligned when aligning them moves one by more than this fraction of the shape
#: difference that remains. Shapes taken from one aligned set stay far below it: at most 0.05 over
#: the pairs of the corpus callosum, Beijing and ADHD-200 shapes after generalised Procrustes.
POSE_PAIR_RATIO = 0.25


class PoseWarning(UserWarning):
    """A pose-dependent distance was asked of shapes that are not aligned (see :func:`check_pose`)."""


def pose_align(shapes):
    """Align shapes by rotations and translations only: generalised Procrustes without scaling,
    each shape keeping its centroid size, the whole set put back in the frame nearest the input.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)

    Returns
    -------
    aligned : ndarray, shape (N, K, d)
        The shapes after GPA rotations (Dryden & Mardia §7.3) at their own centroid sizes, with
        a common centroid; then one rotation and translation of the whole set (which changes no
        pose-dependent distance) brings it as close as possible to the input.
    moved : ndarray, shape (N,)
        ``‖shapes[i] − aligned[i]‖ / centroid_size(shapes[i])``: 0 for shapes already aligned
        (0 also for a shape whose landmarks all coincide, which has no pose).
    """
    x = as_shapes(shapes, name="shapes", min_landmarks=2)
    centred = x - x.mean(axis=1, keepdims=True)
    sizes = np.linalg.norm(centred, axis=(1, 2))
    ok = sizes > 0
    aligned = x.copy()
    moved = np.zeros(len(x))
    if ok.sum() == 0:
        return aligned, moved
    if ok.sum() == 1:
        gpa = centred[ok] / sizes[ok, None, None]
    else:
        gpa, _ = generalized_procrustes(x[ok], scaling=False)
    back = gpa * sizes[ok, None, None]
    offset = x[ok].mean(axis=(0, 1))
    r, _ = optimal_rotation((x[ok] - offset).reshape(-1, x.shape[2]), back.reshape(-1, x.shape[2]))
    aligned[ok] = back @ r + offset
    moved[ok] = np.linalg.norm(x[ok] - aligned[ok], axis=(1, 2)) / sizes[ok]
    return aligned, moved


def pose_change(u, v) -> tuple[float, float]:
    """How much of the difference between ``u`` and ``v`` is pose: ``(moved, remaining)``.

    ``moved`` is ``‖v − v'‖``, ``v'`` being ``v`` rotated and translated onto ``u``
    (:func:`procrustes_align` without scaling), and ``remaining`` is ``‖u − v'‖``, both in units of
    the mean centroid size of ``u`` and ``v`` (0, 0 if both have size 0).
    """
    u, v = as_shape_pair(u, v, min_landmarks=2)
    size = 0.5 * (centroid_size(u) + centroid_size(v))
    if size == 0:
        return 0.0, 0.0
    if np.linalg.norm(v - v.mean(axis=0)) == 0:  # a point has no rotation: only its position counts
        moved_v = v - v.mean(axis=0) + u.mean(axis=0)
    else:
        moved_v = procrustes_align(u, v, scaling=False)
    return float(np.linalg.norm(v - moved_v) / size), float(np.linalg.norm(u - moved_v) / size)


def check_pose(shapes, *, metric: str, tol: float = POSE_TOL, stacklevel: int = 3) -> float:
    """Warn (:class:`PoseWarning`) when ``metric``, which depends on the pose of the shapes, is
    asked of shapes that are not aligned; returns how far aligning would move them (a fraction
    of their size).

    Two shapes ``(2, K, d)`` (one pair) are not aligned when rotating and translating ``v`` onto
    ``u`` moves it by more than ``tol`` and by more than :data:`POSE_PAIR_RATIO` times the shape
    difference that remains (:func:`pose_change`): a good part of what the distance measures is
    then their relative pose. Two shapes taken from a larger aligned set are not aligned to each
    other exactly, but what aligning them changes is of second order in their shape difference,
    so they pass. More shapes: any shape that :func:`pose_align` moves by more than ``tol``.
    ``stacklevel`` counts from this function, as :func:`warnings.warn` does. Skipped (returns NaN)
    inside :func:`shapelib._validate.set_checked`, where the pairwise engine has checked the set.
    """
    if set_was_checked():
        return float("nan")
    x = as_shapes(shapes, name="shapes")
    if x.shape[1] < 2:
        return 0.0
    if len(x) == 2:
        moved, remaining = pose_change(x[0], x[1])
        if moved > tol and moved > POSE_PAIR_RATIO * remaining:
            warnings.warn(
                f"{metric} depends on the pose of the shapes, and u and v are not aligned: rotating and "
                f"translating v onto u moves it by {100 * moved:.3g} % of their size, against a shape "
                f"difference of {100 * remaining:.3g} % that remains, so the distance measures their relative "
                f"pose as well as their shapes. Align them first: v = shapelib.procrustes_align(u, v, "
                f"scaling=False), or shapelib.pose_align(shapes)[0] for a whole set.", PoseWarning,
                stacklevel=stacklevel)
        return moved
    _, moved = pose_align(x)
    worst = int(np.argmax(moved))
    if moved[worst] > tol:
        n_bad = int(np.sum(moved > tol))
        warnings.warn(
            f"{metric} depends on the pose of the shapes, and these are not aligned: aligning them "
            f"(rotations and translations) moves {n_bad} of {len(x)} shapes by more than {100 * tol:.2g} % of "
            f"their size, shapes[{worst}] by {100 * moved[worst]:.3g} %. Align them first: "
            f"shapelib.pose_align(shapes)[0] (sizes kept, so sigma2 keeps its meaning); the shapelib "
            f"command line does this by default.", PoseWarning, stacklevel=stacklevel)
    return float(moved[worst])
