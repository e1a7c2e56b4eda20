"""Spline bending energies, comparison distances of Table I that are not information metrics.

Thin-plate spline bending energy (2-D: Bookstein 1989, paper ref. [5]; 3-D: biharmonic Green's function)
    The TPS ``f`` with ``f(u_a) = v_a`` minimises ``∫ Σ_ij (∂_i∂_j f)²`` over ``R^d`` (per
    coordinate; in 2-D ``∫ (f_xx² + 2 f_xy² + f_yy²)``). It is ``f(x) = Σ_a w_a U(|x − u_a|)`` plus
    an affine part, with ``U`` the fundamental solution of the biharmonic operator ``Δ²`` in
    ``R^d`` (up to a positive constant): ``U(r) = r² log r²`` in 2-D (Bookstein's form) and
    ``U(r) = −r`` in 3-D (``Δ²(−r) = 8π δ`` there).
    With the kernel matrix ``K_ab = U(|u_a − u_b|)``, ``P = [1, u]`` and
    ``L = [[K, P], [Pᵀ, 0]]``, let ``B`` be the upper-left K×K block of ``L⁻¹`` (positive
    semidefinite, null space the affine functions of ``u``). The bending energy is
    ``tr(Dᵀ B D)`` with ``D = v − u`` the displacements (equal to ``tr(vᵀ B v)``, since ``B``
    annihilates affine maps).

    * 2-D (default kernel ``"r2logr2"``): for ``U(r) = r² log r`` the integral above equals
      ``8π tr(DᵀBD)``; for ``U(r) = r² log r²`` ``16π tr(DᵀBD)`` holds with the B of that
      kernel. The energy is scale invariant: scaling ``u`` and ``v`` by ``s`` leaves it unchanged.
    * 3-D (default kernel ``"r"``, ``U(r) = −r``): the integral equals ``8π tr(DᵀBD)``
      (checked by an independent quadrature of the interpolant's second derivatives in the
      tests). The energy scales linearly with size: scaling ``u`` and ``v`` by ``s``
      multiplies it by ``s``.

    It is affine invariant in the target and not symmetric.

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

from .._validate import InputError, as_shape, as_shape_pair, check_positive, literal
from ..geometry.procrustes import check_pose

__all__ = [
    "tps_kernel",
    "tps_bending_matrix",
    "tps_bending_energy",
    "wendland_psi31",
    "wendland_bending_energy",
]


#: Radial functions accepted by :func:`tps_kernel` (``kernel=``).
_TPS_KERNELS = ("r2logr2", "r2logr", "r")

#: Default TPS kernel per dimension (``kernel=None``): the biharmonic fundamental solution.
_DEFAULT_KERNEL = {2: "r2logr2", 3: "r"}


def tps_kernel(r: np.ndarray, *, kernel: str = "r2logr2") -> np.ndarray:
    """Thin-plate spline radial function ``U(r)``.

    Parameters
    ----------
    r : array_like
        Distances (>= 0).
    kernel : {"r2logr2", "r2logr", "r"}
        ``"r2logr2"``: ``r² log r²`` (2-D, Bookstein's form; 0 at r = 0); ``"r2logr"``:
        ``r² log r`` (2-D; 0 at r = 0); ``"r"``: ``−r`` (3-D).

    Returns
    -------
    numpy.ndarray
        ``U(r)``, float64, same shape as ``r``.
    """
    if kernel not in _TPS_KERNELS:
        raise ValueError(f"kernel must be one of {', '.join(repr(k) for k in _TPS_KERNELS)}; got {kernel!r}")
    r = np.asarray(r, dtype=np.float64)
    if kernel == "r":
        return -r
    out = np.zeros_like(r)
    pos = r > 0
    out[pos] = r[pos] ** 2 * np.log(r[pos] ** (2 if kernel == "r2logr2" else 1))
    return out


def _default_kernel(kernel, d: int) -> str:
    if kernel is not None:
        return kernel
    try:
        return _DEFAULT_KERNEL[d]
    except KeyError:
        raise ValueError(
            f"no default thin-plate kernel for {d}-D landmarks (defaults: 'r2logr2' in 2-D, 'r' in 3-D); "
            f"pass kernel= one of {', '.join(repr(k) for k in _TPS_KERNELS)}"
        ) from None


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
        raise ValueError("the landmarks are degenerate (collinear in 2-D, coplanar in 3-D, or coincident): "
                         "the spline system is singular") from None
    return inv[:k, :k]


def _check_distinct(u, name="u"):
    d = cdist(u, u)
    np.fill_diagonal(d, np.inf)
    if d.min() == 0:
        i, j = np.argwhere(d == 0)[0]
        raise InputError(f"{literal(name)} has coincident landmarks {i} and {j}: a spline cannot interpolate them",
                         {"landmarks": (int(i), int(j))})


def tps_bending_matrix(u, *, kernel: str | None = None) -> np.ndarray:
    """Bookstein's bending-energy matrix ``B`` (upper-left K×K block of ``L⁻¹``) of the landmarks ``u``.

    Parameters
    ----------
    u : array_like, shape (K, d)
        Landmarks (K >= d + 1, distinct, not all on one hyperplane).
    kernel : {"r2logr2", "r2logr", "r"}, optional
        Radial function (see :func:`tps_kernel`). Default: the thin-plate kernel of the
        dimension, ``"r2logr2"`` for d = 2 and ``"r"`` (``U(r) = −r``) for d = 3; other
        dimensions need an explicit kernel.

    Returns
    -------
    numpy.ndarray, shape (K, K)
        Symmetric positive semidefinite; annihilates affine functions of ``u``.
    """
    u = as_shape(u, name="u", dims=None)  # any d with an explicit kernel
    kernel = _default_kernel(kernel, u.shape[1])
    _check_affine_count(u)
    _check_distinct(u)
    return _bending_matrix(tps_kernel(cdist(u, u), kernel=kernel), u, True)


def _check_affine_count(u):
    k, d = u.shape
    if k < d + 1:
        raise ValueError(f"an affine part in {d} dimensions needs at least {d + 1} landmarks; got shape {u.shape}")


def tps_bending_energy(u, v, *, kernel: str | None = None) -> float:
    """Thin-plate spline bending energy ``tr(Dᵀ B D)`` of the map taking ``u`` onto ``v`` (see module doc).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Source and target landmarks, d = 2 or 3 with the default kernel (K >= d + 1,
        distinct, not all on one line in 2-D or one plane in 3-D).
    kernel : {"r2logr2", "r2logr", "r"}, optional
        Radial function (see :func:`tps_kernel`). Default: ``"r2logr2"`` for d = 2 (scale
        invariant energy) and ``"r"`` (``U(r) = −r``) for d = 3 (energy linear in size);
        other dimensions need an explicit kernel.

    Returns
    -------
    float
        The bending energy; ``∫ Σ_ij (∂_i∂_j f)²`` of the interpolant is ``16π`` times it
        for ``"r2logr2"`` (2-D) and ``8π`` times it for ``"r2logr"`` (2-D) and ``"r"`` (3-D).
    """
    u, v = as_shape_pair(u, v, dims=None)  # any d with an explicit kernel
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
    if not affine:  # the energy then includes the affine part, so it depends on pose
        check_pose(np.stack([u, v]), metric="wendland (affine=False)")
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
