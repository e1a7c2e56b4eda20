r"""Spline bending energies, comparison distances of Table I that are not information metrics.

Thin-plate spline bending energy (2-D: Bookstein 1989, paper ref. [5]; 3-D: biharmonic Green's function)
    The TPS :math:`f` with :math:`f(u_a) = v_a` minimises

    .. math::

        J(f) = \int_{\mathbb{R}^d} \sum_{i,j} (\partial_i \partial_j f)^2\, dx

    (per coordinate; in 2-D :math:`\int (f_{xx}^2 + 2 f_{xy}^2 + f_{yy}^2)`). It is
    :math:`f(x) = \sum_a w_a U(|x - u_a|)` plus an affine part, with :math:`U` the fundamental
    solution of the biharmonic operator :math:`\Delta^2` in :math:`\mathbb{R}^d` (up to a positive
    constant): :math:`U(r) = r^2 \log r^2` in 2-D (Bookstein's form) and :math:`U(r) = -r` in 3-D
    (:math:`\Delta^2(-r) = 8\pi\delta` there). With the kernel matrix
    :math:`K_{ab} = U(|u_a - u_b|)`, :math:`P = [1, u]` and

    .. math::

        L = \begin{pmatrix} K & P \\ P^\top & 0 \end{pmatrix},

    let :math:`B` be the upper-left K×K block of :math:`L^{-1}` (positive semidefinite, null
    space the affine functions of :math:`u`). The bending energy is
    :math:`\operatorname{tr}(D^\top B D)` with :math:`D = v - u` the displacements (equal to
    :math:`\operatorname{tr}(v^\top B v)`, since :math:`B` annihilates affine maps).

    * 2-D (default kernel ``"r2logr2"``): for :math:`U(r) = r^2 \log r` the integral above
      equals :math:`8\pi \operatorname{tr}(D^\top B D)`; for :math:`U(r) = r^2 \log r^2`,
      :math:`16\pi \operatorname{tr}(D^\top B D)` holds with the B of that kernel. The energy is
      scale invariant: scaling ``u`` and ``v`` by ``s`` leaves it unchanged.
    * 3-D (default kernel ``"r"``, :math:`U(r) = -r`): the integral equals
      :math:`8\pi \operatorname{tr}(D^\top B D)` (checked by an independent quadrature of the
      interpolant's second derivatives in the tests). The energy scales linearly with size:
      scaling ``u`` and ``v`` by ``s`` multiplies it by ``s``.

    It is affine invariant in the target and not symmetric.

Wendland spline bending energy (Fornefett, Rohr & Stiehl 2001, paper ref. [42])
    Same construction with the compactly supported, positive-definite Wendland function

    .. math::

        \psi_{3,1}(r) = (1 - r)_+^4 (4r + 1)

    scaled to support radius :math:`a`: :math:`K_{ab} = \psi(|u_a - u_b| / a)`. With
    ``affine=True`` the affine part is free (side conditions :math:`P^\top w = 0`), exactly as for
    the TPS; with ``affine=False`` the energy is the native-space norm
    :math:`\operatorname{tr}(D^\top K^{-1} D)` of the displacement interpolant, which is *not*
    affine invariant.
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
    r"""Thin-plate spline radial function ``U(r)``.

    .. math::

        U(r) = r^2 \log r^2 \quad (\text{"r2logr2"}), \qquad
        U(r) = r^2 \log r \quad (\text{"r2logr"}), \qquad
        U(r) = -r \quad (\text{"r"}),

    the fundamental solution of the biharmonic operator in 2-D (the first two, Bookstein's form
    first [1]_) and 3-D (the last), up to a positive constant; 0 at r = 0. The TPS is a
    comparison of Table I of [2]_.

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

    Raises
    ------
    ValueError
        For an unknown ``kernel``.

    See Also
    --------
    shapelib.comparison.splines.tps_bending_matrix : The matrix built from it.

    References
    ----------
    .. [1] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of deformations",
       *IEEE Transactions on Pattern Analysis and Machine Intelligence* 11(6), 567–585, 1989.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.comparison.splines import tps_kernel
    >>> tps_kernel(np.array([0.0, 1.0, 2.0])).round(4)
    array([0.    , 0.    , 5.5452])
    >>> tps_kernel(np.array([0.0, 2.0]), kernel="r")
    array([-0., -2.])
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


def _spline_system(kmat: np.ndarray, u: np.ndarray) -> np.ndarray:
    r"""The bordered matrix :math:`L = \begin{pmatrix} K & P \\ P^\top & 0 \end{pmatrix}`,
    :math:`P = [1\; u]`, of a spline with an affine part through the landmarks ``u`` (K, d)."""
    k = len(u)
    p = np.hstack([np.ones((k, 1)), u])
    lmat = np.zeros((k + p.shape[1], k + p.shape[1]))
    lmat[:k, :k] = kmat
    lmat[:k, k:] = p
    lmat[k:, :k] = p.T
    return lmat


def _bending_matrix(kmat: np.ndarray, u: np.ndarray, affine: bool) -> np.ndarray:
    k = len(u)
    if not affine:
        return np.linalg.inv(kmat)
    try:
        inv = np.linalg.inv(_spline_system(kmat, u))
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
    r"""Bookstein's bending-energy matrix ``B`` (upper-left K×K block of ``L⁻¹``) of the landmarks ``u``.

    .. math::

        L = \begin{pmatrix} K & P \\ P^\top & 0 \end{pmatrix}, \qquad
        K_{ab} = U(|u_a - u_b|), \quad P = [\mathbf{1}, u], \qquad
        B = (L^{-1})_{1:K,\ 1:K}

    [1]_; the bending energy of a displacement :math:`D` is :math:`\operatorname{tr}(D^\top B D)`
    (Table I of [2]_).

    Parameters
    ----------
    u : array_like, shape (K, d)
        Landmarks (K >= d + 1, distinct, not all on one hyperplane).
    kernel : {"r2logr2", "r2logr", "r"}, optional
        Radial function (see :func:`~shapelib.comparison.splines.tps_kernel`). Default: the
        thin-plate kernel of the dimension, ``"r2logr2"`` for d = 2 and ``"r"`` (``U(r) = −r``)
        for d = 3; other dimensions need an explicit kernel.

    Returns
    -------
    numpy.ndarray, shape (K, K)
        Symmetric positive semidefinite; annihilates affine functions of ``u``.

    Raises
    ------
    ValueError
        Too few landmarks for an affine part, coincident landmarks (an
        :class:`~shapelib.InputError` naming them), degenerate (collinear, coplanar) landmarks, or
        no default kernel for the dimension.

    See Also
    --------
    shapelib.tps_bending_energy : The energy of a map.

    References
    ----------
    .. [1] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of deformations",
       *IEEE Transactions on Pattern Analysis and Machine Intelligence* 11(6), 567–585, 1989.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.comparison.splines import tps_bending_matrix
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> b = tps_bending_matrix(u)
    >>> bool(np.allclose(b @ np.c_[np.ones(4), u], 0.0))  # affine maps cost nothing
    True
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
    r"""Thin-plate spline bending energy ``tr(Dᵀ B D)`` of the map taking ``u`` onto ``v`` (see module doc).

    With Bookstein's bending-energy matrix :math:`B` of the source landmarks [1]_ and the
    displacements :math:`D = v - u`,

    .. math::

        E_{\mathrm{TPS}}(u \to v) = \operatorname{tr}(D^\top B D)
        = \frac{1}{16\pi} \int_{\mathbb{R}^2} \sum_{i,j} (\partial_i \partial_j f)^2\, dx
        \quad (\text{2-D, } U = r^2 \log r^2),

    the smoothness term :math:`\|Lf\|^2` of the spline matching model of eq. (1) of [2]_ with the
    thin-plate operator, and a comparison measure of its Table I (not a metric: not symmetric).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Source and target landmarks, d = 2 or 3 with the default kernel (K >= d + 1,
        distinct, not all on one line in 2-D or one plane in 3-D).
    kernel : {"r2logr2", "r2logr", "r"}, optional
        Radial function (see :func:`~shapelib.comparison.splines.tps_kernel`). Default:
        ``"r2logr2"`` for d = 2 (scale invariant energy) and ``"r"`` (``U(r) = −r``) for d = 3
        (energy linear in size); other dimensions need an explicit kernel.

    Returns
    -------
    float
        The bending energy; ``∫ Σ_ij (∂_i∂_j f)²`` of the interpolant is ``16π`` times it
        for ``"r2logr2"`` (2-D) and ``8π`` times it for ``"r2logr"`` (2-D) and ``"r"`` (3-D).

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite, or what
        :func:`~shapelib.comparison.splines.tps_bending_matrix` raises.

    See Also
    --------
    shapelib.wendland_bending_energy : The compactly supported counterpart.
    shapelib.distance : Every distance through one entry point (``metric="tps"``).

    References
    ----------
    .. [1] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of deformations",
       *IEEE Transactions on Pattern Analysis and Machine Intelligence* 11(6), 567–585, 1989.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    An affine map bends nothing; moving one corner does.

    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> bool(abs(sl.tps_bending_energy(u, 2.0 * u @ np.array([[1.0, 0.3], [0.0, 1.0]]) + 1.0)) < 1e-12)
    True
    >>> v = np.array([[0.0, 0.0], [1.2, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> round(sl.tps_bending_energy(u, v), 6)
    0.007213
    """
    u, v = as_shape_pair(u, v, dims=None)  # any d with an explicit kernel
    b = tps_bending_matrix(u, kernel=kernel)
    dsp = v - u
    return float(np.einsum("ai,ab,bi->", dsp, b, dsp))


def wendland_psi31(r) -> np.ndarray:
    r"""Wendland's ψ₃,₁: C², positive definite in up to 3 dimensions, compactly supported.

    .. math::

        \psi_{3,1}(r) = (1 - r)_+^4\, (4r + 1)

    [1]_; the basis of the Wendland spline of Table I of [2]_.

    Parameters
    ----------
    r : array_like
        Distances in units of the support radius (>= 0).

    Returns
    -------
    numpy.ndarray
        :math:`\psi_{3,1}(r)`, 0 for :math:`r \ge 1`.

    See Also
    --------
    shapelib.wendland_bending_energy : The bending energy built on it.

    References
    ----------
    .. [1] H. Wendland, "Piecewise polynomial, positive definite and compactly supported radial functions
       of minimal degree", *Advances in Computational Mathematics* 4, 389–396, 1995.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.comparison.splines import wendland_psi31
    >>> wendland_psi31([0.0, 0.5, 1.0, 2.0])
    array([1.    , 0.1875, 0.    , 0.    ])
    """
    r = np.asarray(r, dtype=np.float64)
    return np.where(r < 1, (1 - r) ** 4 * (4 * r + 1), 0.0)


def wendland_bending_energy(u, v, *, support: float | None = None, affine: bool = True) -> float:
    r"""Wendland ψ₃,₁ spline bending energy of the map taking ``u`` onto ``v`` (see module doc).

    The construction of the TPS energy with :math:`K_{ab} = \psi_{3,1}(|u_a - u_b| / a)` [1]_:

    .. math::

        E_W(u \to v) = \operatorname{tr}(D^\top B D), \qquad D = v - u,

    with :math:`B` the upper-left block of the inverse of the bordered kernel matrix (``affine=True``)
    or :math:`B = K^{-1}` (``affine=False``): the term :math:`\|Lf\|^2` of eq. (1) of [2]_ with
    the operator whose Green's function is :math:`\psi_{3,1}`, and a comparison measure of its
    Table I (not symmetric).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Source and target landmarks.
    support : float, optional
        Support radius ``a`` of ψ(r/a); default: the diameter of ``u`` (every basis function
        reaches every landmark).
    affine : bool
        Leave the affine part free (side conditions), as for the TPS.

    Returns
    -------
    float
        The bending energy (≥ 0).

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite, too few landmarks for an affine part,
        coincident landmarks (an :class:`~shapelib.InputError`), a non-positive ``support`` or a
        zero diameter.

    Warns
    -----
    PoseWarning
        With ``affine=False``, when the shapes are not aligned (the energy then includes the
        affine part).

    See Also
    --------
    shapelib.tps_bending_energy : The thin-plate counterpart.

    References
    ----------
    .. [1] H. Wendland, "Piecewise polynomial, positive definite and compactly supported radial functions
       of minimal degree", *Advances in Computational Mathematics* 4, 389–396, 1995.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = np.array([[0.0, 0.0], [1.2, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> round(sl.wendland_bending_energy(u, v), 6)
    0.010597
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
