"""The shape representation: an equal-weight isotropic Gaussian mixture (paper eq. 5).

A landmark shape ``θ = (φ_1, …, φ_K)``, ``φ_a ∈ R^d``, is the density

    p(x | θ) = (1/K) Σ_a N(x; φ_a, σ² I)                                   (eq. 5)

with σ² a free parameter. This module holds the density itself and the closed-form
Gaussian overlaps it implies:

    G(Δ) = ∫ N(x; a, σ²I) N(x; b, σ²I) dx = (4πσ²)^{-d/2} exp(−|Δ|² / (4σ²)),  Δ = a − b,

which give the L² inner product of two mixtures, ⟨p_u, p_v⟩ = (1/K²) Σ_ab G(u_a − v_b), and
hence the L² distance ‖p_u − p_v‖ in closed form. Because the α-order metric (eq. 22) is
the pull-back of the flat L² metric on densities, ‖p_u − p_v‖ is a lower bound on the
α-order geodesic distance.
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

from .._validate import as_shape, as_shape_pair, check_sigma2

__all__ = [
    "gmm_density",
    "gmm_log_density",
    "gaussian_overlap",
    "l2_inner",
    "l2_distance",
]


def _sqdist(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Pairwise squared distances between rows of ``x`` (M, d) and ``y`` (K, d)."""
    d = x[:, None, :] - y[None, :, :]
    return np.einsum("mkd,mkd->mk", d, d)


def _point_sets(a, b, names):
    """Two point sets of the same dimension (any numbers of points)."""
    a, b = as_shape(a, name=names[0]), as_shape(b, name=names[1])
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"{names[0]} and {names[1]} must have the same dimension; got {a.shape} and {b.shape}")
    return a, b


def gmm_log_density(x, theta, sigma2) -> np.ndarray:
    """``log p(x | θ)`` of eq. (5) at the points ``x`` (M, d), computed stably (log-sum-exp)."""
    x, theta = _point_sets(x, theta, ("x", "theta"))
    s2 = check_sigma2(sigma2)
    k, d = theta.shape
    log_n = -_sqdist(x, theta) / (2 * s2) - 0.5 * d * np.log(2 * np.pi * s2)
    return logsumexp(log_n, axis=1) - np.log(k)


def gmm_density(x, theta, sigma2) -> np.ndarray:
    """The GMM shape density of eq. (5).

    Parameters
    ----------
    x : array_like, shape (M, d)
        Points where the density is evaluated.
    theta : array_like, shape (K, d)
        Landmarks: the means of the K equally weighted components.
    sigma2 : float
        Isotropic variance σ² > 0 shared by all components.

    Returns
    -------
    ndarray, shape (M,)
        ``p(x | θ) = (1/K) Σ_a (2πσ²)^{-d/2} exp(−|x − φ_a|² / (2σ²))``.
    """
    return np.exp(gmm_log_density(x, theta, sigma2))


def gaussian_overlap(a, b, sigma2) -> np.ndarray:
    """Matrix of overlaps ``G_ij = ∫ N(x; a_i, σ²I) N(x; b_j, σ²I) dx = (4πσ²)^{-d/2} e^{−|a_i − b_j|²/(4σ²)}``."""
    a, b = _point_sets(a, b, ("a", "b"))
    s2 = check_sigma2(sigma2)
    d = a.shape[1]
    return np.exp(-_sqdist(a, b) / (4 * s2)) / (4 * np.pi * s2) ** (d / 2)


def l2_inner(u, v, sigma2) -> float:
    """Closed-form L² inner product ``∫ p(x|u) p(x|v) dx = (1/(K_u K_v)) Σ_ab G(u_a − v_b)``."""
    return float(gaussian_overlap(u, v, sigma2).mean())


def l2_distance(u, v, sigma2) -> float:
    """Closed-form L² distance ``‖p_u − p_v‖`` between the GMM densities of two shapes.

    This is the lower bound certified by :func:`shapelib.geodesic` for the α-order metric:
    the α-order metric of eq. (22) is the pull-back of the L² metric, so every path from
    ``u`` to ``v`` is at least this long.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence.
    sigma2 : float
        σ² of eq. (5).
    """
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    sq = l2_inner(u, u, s2) + l2_inner(v, v, s2) - 2 * l2_inner(u, v, s2)
    return float(np.sqrt(max(sq, 0.0)))
