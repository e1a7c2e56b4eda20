"""Comparison distances of Table I that are not information metrics: Hausdorff and spline bending energies.

Hausdorff (paper ref. [41])
    ``H(u, v) = max(h(u, v), h(v, u))``, ``h(u, v) = max_a min_b |u_a − v_b|``.

Thin-plate spline bending energy (Bookstein 1989, paper ref. [5])
    The TPS ``f`` with ``f(u_a) = v_a`` minimises ``∫ (f_xx² + 2 f_xy² + f_yy²)`` (per coordinate).
    With the kernel matrix ``K_ab = U(|u_a − u_b|)``, ``P = [1, u]`` and
    ``L = [[K, P], [Pᵀ, 0]]``, let ``B`` be the upper-left K×K block of ``L⁻¹``. The bending
    energy is ``tr(Dᵀ B D)`` with ``D = v − u`` the displacements (equal to ``tr(vᵀ B v)``,
    since ``B`` annihilates affine maps). For ``U(r) = r² log r`` the integral above equals
    ``8π tr(DᵀBD)``; for ``U(r) = r² log r²`` (the default, Bookstein's form) ``16π tr(DᵀBD)``
    holds with the B of that kernel. It is affine invariant in the target and not symmetric.

Wendland spline bending energy (Fornefett, Rohr & Stiehl 2001, paper ref. [42])
    Same construction with the compactly supported, positive-definite Wendland function
    ``ψ₃,₁(r) = (1 − r)₊⁴ (4r + 1)`` scaled to support radius ``a``: ``K_ab = ψ(|u_a − u_b| / a)``.
    With ``affine=True`` the affine part is free (side conditions ``Pᵀ w = 0``), exactly as for
    the TPS; with ``affine=False`` the energy is the native-space norm ``tr(Dᵀ K⁻¹ D)`` of the
    displacement interpolant, which is *not* affine invariant.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

from ._validate import as_shape, as_shape_pair, check_positive

__all__ = [
    "hausdorff_distance",
    "tps_kernel",
    "tps_bending_matrix",
    "tps_bending_energy",
    "wendland_psi31",
    "wendland_bending_energy",
]


def hausdorff_distance(u, v) -> float:
    """Symmetrised Hausdorff distance between two landmark sets (correspondence not used)."""
    u, v = as_shape_pair(u, v)
    d = cdist(u, v)
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


def tps_kernel(r: np.ndarray, *, kernel: str = "r2logr2") -> np.ndarray:
    """TPS radial function: ``r² log r²`` (``"r2logr2"``) or ``r² log r`` (``"r2logr"``), 0 at r = 0."""
    if kernel not in ("r2logr2", "r2logr"):
        raise ValueError(f"kernel must be 'r2logr2' or 'r2logr'; got {kernel!r}")
    r = np.asarray(r, dtype=np.float64)
    out = np.zeros_like(r)
    pos = r > 0
    out[pos] = r[pos] ** 2 * np.log(r[pos] ** (2 if kernel == "r2logr2" else 1))
    return out


def _bending_matrix(kmat: np.ndarray, u: np.ndarray, affine: bool) -> np.ndarray:
    k = len(u)
    if not affine:
        return np.linalg.inv(kmat)
    p = np.hstack([np.ones((k, 1)), u])
    lmat = np.zeros((k + p.shape[1], k + p.shape[1]))
    lmat[:k, :k] = kmat
    lmat[:k, k:] = p
    lmat[k:, :k] = p.T
    try:
        inv = np.linalg.inv(lmat)
    except np.linalg.LinAlgError:
        raise ValueError("the landmarks are degenerate (collinear or coincident): the spline system is singular") from None
    return inv[:k, :k]


def _check_distinct(u, name="u"):
    d = cdist(u, u)
    np.fill_diagonal(d, np.inf)
    if d.min() == 0:
        i, j = np.argwhere(d == 0)[0]
        raise ValueError(f"{name} has coincident landmarks {i} and {j}: a spline cannot interpolate them")


def tps_bending_matrix(u, *, kernel: str = "r2logr2") -> np.ndarray:
    """Bookstein's bending-energy matrix ``B`` (upper-left K×K block of ``L⁻¹``) of the landmarks ``u``."""
    u = as_shape(u, name="u")
    _check_affine_count(u)
    _check_distinct(u)
    return _bending_matrix(tps_kernel(cdist(u, u), kernel=kernel), u, True)


def _check_affine_count(u):
    k, d = u.shape
    if k < d + 1:
        raise ValueError(f"an affine part in {d} dimensions needs at least {d + 1} landmarks; got shape {u.shape}")


def tps_bending_energy(u, v, *, kernel: str = "r2logr2") -> float:
    """Thin-plate spline bending energy ``tr(Dᵀ B D)`` of the map taking ``u`` onto ``v`` (see module doc).

    Parameters
    ----------
    u, v : array_like, shape (K, 2)
        Source and target landmarks (K >= 3, not collinear).
    kernel : {"r2logr2", "r2logr"}
    """
    u, v = as_shape_pair(u, v)
    b = tps_bending_matrix(u, kernel=kernel)
    dsp = v - u
    return float(np.einsum("ai,ab,bi->", dsp, b, dsp))


def wendland_psi31(r) -> np.ndarray:
    """Wendland's ψ₃,₁(r) = (1 − r)₊⁴ (4r + 1): C², positive definite in up to 3 dimensions."""
    r = np.asarray(r, dtype=np.float64)
    return np.where(r < 1, (1 - r) ** 4 * (4 * r + 1), 0.0)


def wendland_bending_energy(u, v, *, support: float | None = None, affine: bool = True) -> float:
    """Wendland ψ₃,₁ spline bending energy of the map taking ``u`` onto ``v`` (see module doc).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
    support : float, optional
        Support radius ``a`` of ψ(r/a); default: the diameter of ``u`` (every basis function
        reaches every landmark).
    affine : bool
        Leave the affine part free (side conditions), as for the TPS.
    """
    u, v = as_shape_pair(u, v)
    if affine:
        _check_affine_count(u)
    _check_distinct(u)
    dist = cdist(u, u)
    a = float(dist.max()) if support is None else check_positive(support, name="support")
    if a == 0:
        raise ValueError("support radius is zero (a single landmark); pass support=...")
    b = _bending_matrix(wendland_psi31(dist / a), u, affine)
    dsp = v - u
    return float(np.einsum("ai,ab,bi->", dsp, b, dsp))
