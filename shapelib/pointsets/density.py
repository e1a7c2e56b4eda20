"""Density quantities between point sets of different sizes, with gradients w.r.t. the points.

A point set ``x = (x_1, …, x_n)`` is the equal-weight isotropic mixture of eq. (5),
``p_x(z) = (1/n) Σ_i N(z; x_i, σ²I)``, with one σ² shared by the sets compared. Two sets
``x`` (n points) and ``y`` (m points) need no correspondence and no equal sizes:

α bound (closed form). With the Gaussian overlap ``G(Δ) = (4πσ²)^{-d/2} exp(−|Δ|²/4σ²)``
(``shapelib.geometry.gmm.overlap_matrix``),

    ⟨p_x, p_y⟩ = (1/nm) Σ_ij G(x_i − y_j),
    D²(x, y) = ‖p_x − p_y‖² = ⟨p_x, p_x⟩ + ⟨p_y, p_y⟩ − 2⟨p_x, p_y⟩,
    ∂D²/∂x_i = −(1/(n²σ²)) Σ_k G(x_i − x_k)(x_i − x_k) + (1/(nmσ²)) Σ_j G(x_i − y_j)(x_i − y_j).

``D`` is the L² distance of the densities: the lower bound on the α-order geodesic distance
(``shapelib.geometry.gmm.l2_distance`` for sets in correspondence).

Fisher–Rao bound (quadrature). The Bhattacharyya affinity ``BC = ∫ √(p_x p_y) dz`` has no closed
form for mixtures; with ``ψ = 2√p`` it is integrated on the grid of ``shapelib.geometry.quadrature``
as the squared Hellinger distance

    H²(x, y) = ∫ (√p_x − √p_y)² dz = 2 − 2 BC,
    ∂H²/∂x_i = ½ ∫ (ψ_x − ψ_y) N_i(z) (z − x_i) / (n σ² √p_x) dz,

and the great-circle bound on the Fisher–Rao distance is ``2 arccos BC = 4 arcsin(H/2)``
(:func:`shapelib.fisher_rao_lower_bound` for sets in correspondence).
"""

from __future__ import annotations

import numpy as np

from .._validate import check_sigma2
from ..geometry.gmm import overlap_matrix
from ..geometry.metrics import psi_coef
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING, make_grid
from .checks import as_point_set, check_same_dimension

__all__ = ["density_inner", "l2_distance_sq", "hellinger_sq", "bhattacharyya_affinity", "density_distance",
           "DENSITY_METRICS"]

#: the two density distances between point sets
DENSITY_METRICS = ("alpha", "fisher_rao")


def _pair(x, y, sigma2, names=("x", "y")):
    x = as_point_set(x, name=names[0])
    y = as_point_set(y, name=names[1])
    check_same_dimension(x, y, names)
    return x, y, check_sigma2(sigma2)


# --------------------------------------------------------------------------------------------
# unchecked kernels (checked arrays in; used in the optimisers' inner loops)
# --------------------------------------------------------------------------------------------


def _inner_grad(x, y, s2, *, grad=True):
    """``⟨p_x, p_y⟩`` and its gradient w.r.t. ``x`` (n, d)."""
    g = overlap_matrix(x, y, s2)
    scale = 1.0 / (len(x) * len(y))
    val = g.sum() * scale
    if not grad:
        return val, None
    gx = (g.sum(axis=1)[:, None] * x - g @ y) * (-scale / (2 * s2))
    return val, gx


def _l2_sq(x, y, s2, *, grad=True, yy=None):
    """``D² = ‖p_x − p_y‖²`` and ``∂D²/∂x``; ``yy``: ``⟨p_y, p_y⟩`` if known."""
    xx, gxx = _inner_grad(x, x, s2, grad=grad)
    xy, gxy = _inner_grad(x, y, s2, grad=grad)
    if yy is None:
        yy = _inner_grad(y, y, s2, grad=False)[0]
    val = xx + yy - 2 * xy
    if not grad:
        return val, None
    return val, 2 * gxx - 2 * gxy  # d⟨x,x⟩/dx_i counts x_i on both sides: twice the one-sided form


def _hellinger_sq(x, y, s2, *, grad=True, grid=None, spacing=DEFAULT_SPACING, margin=DEFAULT_MARGIN):
    """``H² = ∫(√p_x − √p_y)²`` by quadrature and ``∂H²/∂x``."""
    if grid is None:
        grid = make_grid(np.vstack([x, y]), sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    px, coef = psi_coef(x, s2, grid)
    py, _ = psi_coef(y, s2, grid)
    diff = px - py
    val = 0.25 * grid.integrate(diff * diff)
    if not grad:
        return val, None
    wc = coef * diff[:, None]  # (M, n)
    gx = 0.5 * grid.weight * (wc.T @ grid.nodes - wc.sum(axis=0)[:, None] * x)
    return val, gx


# --------------------------------------------------------------------------------------------
# public
# --------------------------------------------------------------------------------------------


def density_inner(x, y, *, sigma2) -> float:
    """L² inner product of the mixtures of two point sets, ``⟨p_x, p_y⟩ = (1/nm) Σ_ij G(x_i − y_j)``.

    Parameters
    ----------
    x, y : array_like, shapes (n, d) and (m, d)
        Point sets (any sizes, no correspondence).
    sigma2 : float
        σ² shared by every component of both mixtures.

    Returns
    -------
    float

    See Also
    --------
    l2_distance_sq : The squared L² distance built from this inner product.
    shapelib.geometry.gmm.l2_inner : The same inner product for landmark shapes.

    Notes
    -----
    The closed form is the L² inner product of two Gaussian mixtures of eq. (5) of [1]_, which needs no
    correspondence and no equal sizes.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.pointsets import density_inner
    >>> x = np.array([[0.0, 0.0], [1.0, 0.0]])
    >>> round(density_inner(x, x, sigma2=0.5) * 2 * np.pi, 6)  # ‖p_x‖² = (1 + e^{-1/2}) / (4π)
    0.803265
    """
    x, y, s2 = _pair(x, y, sigma2)
    return float(_inner_grad(x, y, s2, grad=False)[0])


def l2_distance_sq(x, y, *, sigma2, grad: bool = False):
    """Squared L² distance ``D² = ‖p_x − p_y‖²`` between the mixtures of two point sets, and its gradient.

    ``D² = ⟨p_x, p_x⟩ + ⟨p_y, p_y⟩ − 2⟨p_x, p_y⟩`` with the closed-form inner products of
    :func:`density_inner`; the gradient w.r.t. the points of ``x`` is

    ``∂D²/∂x_i = −(1/(n²σ²)) Σ_k G(x_i − x_k)(x_i − x_k) + (1/(nmσ²)) Σ_j G(x_i − y_j)(x_i − y_j)``.

    Parameters
    ----------
    x, y : array_like, shapes (n, d) and (m, d)
        Point sets; the gradient is taken w.r.t. ``x``.
    sigma2 : float
        Shared σ².
    grad : bool
        Also return ``∂D²/∂x`` (n, d).

    Returns
    -------
    float, or (float, ndarray)

    See Also
    --------
    density_inner : The inner product it is built from.
    shapelib.geometry.gmm.l2_distance : The L² distance of landmark shapes in correspondence.
    density_distance : The bound itself, α or Fisher–Rao.

    Notes
    -----
    ``D`` is the L² distance of the densities, the lower bound on the α-order geodesic distance of [1]_.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.pointsets import l2_distance_sq
    >>> x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    >>> round(l2_distance_sq(x, x[::-1], sigma2=0.1), 12)  # the order of the points does not matter
    0.0
    """
    x, y, s2 = _pair(x, y, sigma2)
    val, g = _l2_sq(x, y, s2, grad=grad)
    val = max(float(val), 0.0)
    return (val, g) if grad else val


def hellinger_sq(x, y, *, sigma2, grad: bool = False, grid_spacing: float = DEFAULT_SPACING,
                 grid_margin: float = DEFAULT_MARGIN):
    """Squared Hellinger distance ``H² = ∫ (√p_x − √p_y)² dz = 2 − 2 ∫ √(p_x p_y) dz`` and its gradient.

    By the trapezoid rule on a grid of step ``grid_spacing·σ`` around both sets
    (``shapelib.geometry.quadrature``); with ``ψ = 2√p``,
    ``∂H²/∂x_i = ½ ∫ (ψ_x − ψ_y) N(z; x_i, σ²I)(z − x_i) / (n σ² √p_x) dz``.

    Parameters
    ----------
    x, y : array_like, shapes (n, d) and (m, d)
        Point sets; the gradient is taken w.r.t. ``x``.
    sigma2 : float
        Shared σ².
    grad : bool
        Also return ``∂H²/∂x`` (n, d).
    grid_spacing, grid_margin : float
        Quadrature step and margin in units of σ.

    Returns
    -------
    float, or (float, ndarray)

    See Also
    --------
    bhattacharyya_affinity : The affinity ``BC = 1 − H²/2``.
    shapelib.solver.geodesic.fisher_rao_lower_bound : The bound for landmark shapes.
    density_distance : The bound itself, α or Fisher–Rao.

    Notes
    -----
    With ``ψ = 2√p`` the densities lie on a sphere of radius 2, and ``2 arccos BC = 4 arcsin(H/2)`` is the
    great-circle lower bound on the Fisher–Rao geodesic distance of [1]_.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.pointsets import hellinger_sq
    >>> round(hellinger_sq([[0, 0], [1, 0]], [[1, 0], [0, 0]], sigma2=0.1), 12)
    0.0
    """
    x, y, s2 = _pair(x, y, sigma2)
    val, g = _hellinger_sq(x, y, s2, grad=grad, spacing=grid_spacing, margin=grid_margin)
    val = max(float(val), 0.0)
    return (val, g) if grad else val


def bhattacharyya_affinity(x, y, *, sigma2, grid_spacing: float = DEFAULT_SPACING,
                           grid_margin: float = DEFAULT_MARGIN) -> float:
    """Bhattacharyya affinity ``BC = ∫ √(p_x p_y) dz`` of the mixtures of two point sets (``1 − H²/2``).

    Parameters
    ----------
    x, y : array_like, shapes (n, d) and (m, d)
        Point sets.
    sigma2 : float
        Shared σ².
    grid_spacing, grid_margin : float
        Quadrature step and margin in units of σ (:func:`hellinger_sq`).

    Returns
    -------
    float
        In ``[0, 1]``; 1 exactly when the two mixtures are equal.

    See Also
    --------
    hellinger_sq : The squared Hellinger distance ``2 − 2 BC`` and its gradient.
    density_distance : The bound ``2 arccos BC`` for Fisher–Rao.

    Notes
    -----
    ``2 arccos BC`` is the great-circle lower bound on the Fisher–Rao geodesic distance between the mixtures
    of eq. (5) of [1]_.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.pointsets import bhattacharyya_affinity
    >>> round(bhattacharyya_affinity([[0, 0], [3, 0]], [[0, 0], [3, 0], [3, 0.5]], sigma2=0.2), 3)
    0.964
    """
    return 1.0 - 0.5 * hellinger_sq(x, y, sigma2=sigma2, grid_spacing=grid_spacing, grid_margin=grid_margin)


def density_distance(x, y, *, sigma2, metric: str = "alpha", grid_spacing: float = DEFAULT_SPACING,
                     grid_margin: float = DEFAULT_MARGIN) -> float:
    """The closed-form density bound between two point sets where they lie (no pose search).

    * ``metric="alpha"``: ``‖p_x − p_y‖`` (the α bound);
    * ``metric="fisher_rao"``: ``2 arccos ∫ √(p_x p_y) dz = 4 arcsin(H/2)`` (the Fisher–Rao bound).

    Modulo pose: :func:`shapelib.align` first.

    Parameters
    ----------
    x, y : array_like, shapes (n, d) and (m, d)
        Point sets.
    sigma2 : float
        Shared σ².
    metric : {"alpha", "fisher_rao"}
    grid_spacing, grid_margin : float
        Fisher–Rao quadrature (:func:`hellinger_sq`).

    Returns
    -------
    float

    See Also
    --------
    l2_distance_sq : The α bound squared, with its gradient.
    hellinger_sq : The Hellinger distance behind the Fisher–Rao bound.
    shapelib.pointsets.invariant.invariant_distance : The same bound modulo the similarity group.

    Notes
    -----
    The α bound is the L² distance of the two mixtures and the Fisher–Rao bound the great-circle distance ``2
    arccos BC``; both are lower bounds on the geodesic distances of [1]_.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.pointsets import density_distance
    >>> x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> y = np.vstack([x, [[0.5, 0.5]]])
    >>> density_distance(x, y, sigma2=0.05) > 0
    True
    """
    if metric not in DENSITY_METRICS:
        raise ValueError(f"metric must be one of {DENSITY_METRICS}; got {metric!r}")
    if metric == "alpha":
        return float(np.sqrt(l2_distance_sq(x, y, sigma2=sigma2)))
    h2 = hellinger_sq(x, y, sigma2=sigma2, grid_spacing=grid_spacing, grid_margin=grid_margin)
    return float(4.0 * np.arcsin(min(np.sqrt(h2) / 2.0, 1.0)))
