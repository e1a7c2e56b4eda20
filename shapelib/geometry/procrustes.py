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
"""

from __future__ import annotations

import warnings

import numpy as np

from .._validate import as_shape, as_shape_pair, as_shapes

__all__ = [
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
    return float(np.linalg.norm(center(x)))


def preshape(x) -> np.ndarray:
    """Centre and scale to unit centroid size; raises ``ValueError`` if all landmarks coincide."""
    c = center(x)
    size = np.linalg.norm(c)
    if size == 0 or not np.isfinite(size):
        raise ValueError(f"configuration of shape {c.shape} has zero centroid size (all landmarks coincide)")
    return c / size


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
