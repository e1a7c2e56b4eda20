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

Near shapes. ``‖p_u − p_v‖² = ⟨p_u, p_u⟩ + ⟨p_v, p_v⟩ − 2⟨p_u, p_v⟩`` loses the digits the three
terms share: shapes of one population are close (at the study's scale and σ the squared
distance is typically 10⁻³ and down to 10⁻⁸ of ``⟨p_u, p_u⟩``), so the difference keeps only
~13 and down to ~8 correct digits. Each landmark pair's four overlaps form a mixed second
difference of ``g(x) = exp(−|x|²/4σ²)``: with ``r = u_a − u_b``, ``δ = v − u``, ::

    g(r) − g(r − δ_b) − g(r + δ_a) + g(r + δ_a − δ_b)
        = g(r) expm1(α) expm1(β) − g(v_a − v_b) expm1(−δ_a·δ_b / 2σ²),
    α = −(2 r·δ_a + |δ_a|²) / 4σ²,  β = (2 r·δ_b − |δ_b|²) / 4σ²,

whose terms are ``O(|δ|²)`` themselves (:func:`_l2_sq_near`); :func:`l2_distance` uses it when the
plain difference has lost more than three digits (:data:`L2_NEAR`) and the landmarks moved by at
most √2 σ (beyond that the two terms grow like ``exp(|δ|²/2σ²)`` and cancel each other instead).
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
    "L2_NEAR",
]

#: :func:`l2_distance` recomputes ``‖p_u − p_v‖²`` without cancellation (:func:`_l2_sq_near`) when
#: the plain difference is below this fraction of ``‖p_u‖² + ‖p_v‖²`` (so the plain formula is
#: kept only where it has lost fewer than three of its ~16 digits: relative error ≲ 1e-13)
L2_NEAR = 1e-3
#: ... and every landmark moved by at most √(NEAR_DISPLACEMENT) σ (see the module docstring)
NEAR_DISPLACEMENT = 2.0


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
    uu, vv = l2_inner(u, u, s2), l2_inner(v, v, s2)
    sq = uu + vv - 2 * l2_inner(u, v, s2)
    if sq <= L2_NEAR * (uu + vv) and _small_displacement(u[None], v[None], s2)[0]:
        sq = float(_l2_sq_near(u[None], v[None], s2)[0])
    return float(np.sqrt(max(sq, 0.0)))


def _small_displacement(u, v, s2) -> np.ndarray:
    """``(P,)`` bool: every landmark of ``v[p]`` within √(:data:`NEAR_DISPLACEMENT`) σ of ``u[p]``'s."""
    dv = v - u
    return np.einsum("pkd,pkd->pk", dv, dv).max(axis=1) <= NEAR_DISPLACEMENT * s2


def _l2_sq_near(u, v, s2, *, chunk: int = 1 << 15) -> np.ndarray:
    """``‖p_u − p_v‖²`` for pairs of shapes ``u[p]``, ``v[p]`` (``(P, K, d)`` each), without cancellation.

    The mixed-second-difference form of the module docstring: every term is O(|v − u|²), so the
    result keeps its relative accuracy however close the shapes are (landmark displacements up to
    √2 σ; :func:`_small_displacement`). Returns ``(P,)``.
    """
    p, k, d = u.shape
    out = np.empty(p)
    c = 0.25 / s2
    step = max(1, chunk // (k * k))
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        for s in range(0, p, step):
            uu, dd = u[s:s + step], v[s:s + step] - u[s:s + step]
            shape = (len(uu), k, k)
            r2, v2, alpha, beta = (np.zeros(shape) for _ in range(4))
            for i in range(d):  # one coordinate at a time: differences taken directly, never expanded
                ri = uu[:, :, None, i] - uu[:, None, :, i]  # r_ab = u_a − u_b
                da, db = dd[:, :, None, i], dd[:, None, :, i]
                r2 += ri * ri
                alpha -= (2 * ri + da) * da
                beta += (2 * ri - db) * db
                ri += da - db  # v_a − v_b
                v2 += ri * ri
            q = np.matmul(dd, dd.transpose(0, 2, 1))  # δ_a·δ_b
            # g(r) is 0 wherever expm1 would overflow (|r| ≫ σ): clip so 0·inf never happens
            t1 = np.exp(-c * r2) * np.expm1(np.minimum(c * alpha, 700.0)) * np.expm1(np.minimum(c * beta, 700.0))
            t2 = np.exp(-c * v2) * np.expm1(-2 * c * q)
            out[s:s + step] = (t1 - t2).sum(axis=(1, 2))
    return out * (4 * np.pi * s2) ** (-d / 2) / k ** 2
