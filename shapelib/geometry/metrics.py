r"""Riemannian metrics on the GMM shape parameters: α-order entropy (closed form) and Fisher–Rao.

Parameters are ordered as in eq. (9): :math:`\theta = (\phi_1^1, \phi_1^2, \phi_2^1, \dots)`,
i.e. the ``(K, d)`` landmark array flattened row by row. With
:math:`N_a(x) = \mathcal{N}(x; \phi_a, \sigma^2 I)` and :math:`r_a = x - \phi_a`, the density
(eq. 5) has :math:`\partial p / \partial \phi_a = N_a r_a / (K \sigma^2)`.

α-order entropy metric, α = 2 (eq. 22)
    With :math:`\Delta = \phi_a - \phi_b` and the overlap :math:`G(\Delta)` of
    :mod:`shapelib.geometry.gmm`, the (a, b) block of

    .. math::

        g^\alpha_{ij} = \int \frac{\partial p}{\partial \theta_i}
        \frac{\partial p}{\partial \theta_j}\, dx \qquad \text{(eq. 22)}

    is

    .. math::

        g^\alpha_{ab} = \frac{G(\Delta)}{K^2 \sigma^4}
        \left[\frac{\sigma^2}{2} I - \frac{\Delta \Delta^\top}{4}\right],

    so the diagonal blocks are :math:`I / (2 K^2 \sigma^2 (4\pi\sigma^2)^{d/2})` and, as the paper
    notes, the off-diagonal entries *within* a landmark vanish. Since
    :math:`\dot\theta^\top g^\alpha \dot\theta = \int (\partial_t p)^2 dx`, the metric is the flat
    L² metric pulled back to the parameters.

Fisher–Rao metric (eq. 6)
    .. math::

        g_{ij} = \int \frac{1}{p} \frac{\partial p}{\partial \theta_i}
        \frac{\partial p}{\partial \theta_j}\, dx
        = \int \frac{\partial \psi}{\partial \theta_i} \frac{\partial \psi}{\partial \theta_j}\, dx,
        \qquad \psi = 2\sqrt{p} \qquad \text{(eq. 6)}

    the pull-back of the L² metric by :math:`\theta \mapsto 2\sqrt{p}`, which maps into the
    sphere of radius 2. It has no closed form; it is integrated on a grid
    (:mod:`shapelib.geometry.quadrature`). Bounds used in the tests:
    :math:`g \preceq I/(K\sigma^2)` (the complete-data information) and :math:`g = I/\sigma^2`
    exactly when K = 1.

The α formulas below (quadratic form, gradient, second derivatives) are written once here, in
numpy; the geodesic solver runs compiled versions of the same sums (``shapelib.geometry._kernels``,
numba), which ``tests/test_kernels.py`` checks against these to ~1e-12.
"""

from __future__ import annotations

import numpy as np

from . import _kernels
from .._validate import as_shape, check_sigma2
from .quadrature import DEFAULT_MARGIN, DEFAULT_SPACING, Grid, make_grid

__all__ = [
    "alpha_metric",
    "alpha_quadratic_form",
    "fisher_rao_metric",
    "fisher_rao_quadratic_form",
]


# ---------------------------------------------------------------------------------------------
# α-order entropy metric (eq. 22), closed form
# ---------------------------------------------------------------------------------------------


def _alpha_overlaps(theta: np.ndarray, s2: float):
    """``c_ab = G(Δ_ab)/K²`` (the Gaussian overlap of :mod:`shapelib.geometry.gmm` over K²), (m, K, K),
    and the coordinate differences ``Δ_ab,i = φ_a,i − φ_b,i`` as a list of d (m, K, K) arrays,
    for a batch of shapes (m, K, d); one coordinate at a time (no (m, K, K, d) temporaries)."""
    m, k, d = theta.shape
    delta = [theta[:, :, None, i] - theta[:, None, :, i] for i in range(d)]
    c = np.exp(-sum(x * x for x in delta) / (4 * s2)) / (4 * np.pi * s2) ** (d / 2) / (k * k)
    return c, delta


def _alpha_metric_blocks(c, delta, s2: float) -> np.ndarray:
    """The α metric (eq. 22) from :func:`_alpha_overlaps`, in the (m, K, d, K, d) layout:
    ``g_ab = c_ab [I/(2σ²) − Δ_ab Δ_abᵀ/(4σ⁴)]``."""
    d = len(delta)
    m, k, _ = c.shape
    out = np.empty((m, k, d, k, d))
    for i in range(d):
        for j in range(i, d):
            out[:, :, i, :, j] = c * (float(i == j) / (2 * s2) - delta[i] * delta[j] / (4 * s2 * s2))
            if j > i:
                out[:, :, j, :, i] = out[:, :, i, :, j]
    return out


def alpha_metric(theta, *, sigma2) -> np.ndarray:
    r"""The α-order (α = 2) entropy metric tensor of eq. (22), in closed form.

    The Havrda–Charvát entropy with α = 2 turns the φ-entropy metric of Burbea and Rao (eq. 19) into
    the correlation of the density's partial derivatives [1]_ [2]_:

    .. math::

        g^\alpha_{ij}(\theta) = \int_{\mathbb{R}^d} \frac{\partial p(x \mid \theta)}{\partial \theta_i}
        \frac{\partial p(x \mid \theta)}{\partial \theta_j}\, dx \qquad \text{(eq. 22)}

    For the mixture of eq. (5) each (a, b) block of landmarks is, with
    :math:`\Delta = \phi_a - \phi_b` and :math:`G` the Gaussian overlap,

    .. math::

        g^\alpha_{ab} = \frac{G(\Delta)}{K^2}
        \left[\frac{I}{2\sigma^2} - \frac{\Delta\Delta^\top}{4\sigma^4}\right],
        \qquad G(\Delta) = (4\pi\sigma^2)^{-d/2} e^{-|\Delta|^2/4\sigma^2}.

    Parameters
    ----------
    theta : array_like, shape (K, d)
        Landmarks (GMM means).
    sigma2 : float
        σ² > 0 of eq. (5).

    Returns
    -------
    ndarray, shape (K d, K d)
        :math:`g^\alpha`, parameters ordered as in eq. (9) (the landmarks flattened row by row).
        Symmetric positive semi-definite.

    Raises
    ------
    ValueError
        If ``theta`` is not a finite ``(K, d)`` array or ``sigma2`` is not positive.

    See Also
    --------
    shapelib.alpha_quadratic_form : :math:`\dot\theta^\top g^\alpha \dot\theta` without the matrix.
    shapelib.fisher_rao_metric : The Fisher–Rao metric of eq. (6).
    shapelib.geodesic : Geodesics under this metric.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] J. Burbea and C. R. Rao, "Entropy differential metric, distance and divergence measures in
       probability spaces: a unified approach", *Journal of Multivariate Analysis* 12(4), 575–596, 1982.

    Examples
    --------
    For one landmark the tensor is :math:`I / (2\sigma^2 (4\pi\sigma^2)^{d/2})`:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> g = sl.alpha_metric([[0.0, 0.0]], sigma2=0.5)
    >>> bool(np.allclose(g, np.eye(2) / (2 * 0.5 * 4 * np.pi * 0.5)))
    True
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> g = sl.alpha_metric(theta, sigma2=0.5)
    >>> g.shape, bool(np.allclose(g, g.T)), bool(np.linalg.eigvalsh(g).min() > -1e-12)
    ((6, 6), True, True)
    """
    theta = as_shape(theta, name="theta")
    return alpha_tensor_batch(theta[None], check_sigma2(sigma2))[0]


def _alpha_pairs(theta: np.ndarray, vel: np.ndarray, s2: float):
    """Pair quantities of the α quadratic form, each (m, K, K): ``c_ab`` and ``Δ_ab`` of
    :func:`_alpha_overlaps`, ``V_a·V_b``, ``Δ_ab·V_a`` and ``Δ_ab·V_b``."""
    c, delta = _alpha_overlaps(theta, s2)
    dva = sum(x * vel[:, :, None, i] for i, x in enumerate(delta))
    dvb = sum(x * vel[:, None, :, i] for i, x in enumerate(delta))
    return c, delta, vel @ vel.transpose(0, 2, 1), dva, dvb


def _alpha_qform(theta: np.ndarray, vel: np.ndarray, s2: float) -> np.ndarray:
    """Batched ``vᵀ g_α(θ) v`` for ``theta, vel`` of shape (m, K, d); O(m K²) memory.

    ``Q = Σ_ab c_ab [V_a·V_b/(2σ²) − (Δ_ab·V_a)(Δ_ab·V_b)/(4σ⁴)]`` (the block formula above).
    """
    c, _, vv, dva, dvb = _alpha_pairs(theta, vel, s2)
    return np.einsum("mab,mab->m", c, vv / (2 * s2) - dva * dvb / (4 * s2 * s2))


def alpha_quadratic_form(theta, velocity, *, sigma2) -> float:
    r"""The α-order metric's quadratic form :math:`\dot\theta^\top g^\alpha(\theta)\, \dot\theta`, without the matrix.

    The integrand of the path energy (eq. 8) under the metric of eq. (22) [1]_: for a shape ``theta``
    moving with landmark velocities ``velocity``,

    .. math::

        \dot\theta^\top g^\alpha(\theta)\, \dot\theta = \int (\partial_t p)^2\, dx
        = \sum_{a,b} \frac{G(\Delta_{ab})}{K^2}
        \left[\frac{V_a \cdot V_b}{2\sigma^2}
        - \frac{(\Delta_{ab} \cdot V_a)(\Delta_{ab} \cdot V_b)}{4\sigma^4}\right],

    with :math:`\Delta_{ab} = \phi_a - \phi_b`; O(K²) memory, the ``(Kd, Kd)`` matrix never formed.

    Parameters
    ----------
    theta : array_like, shape (K, d)
        Landmarks (GMM means).
    velocity : array_like, shape (K, d)
        Landmark velocities :math:`\dot\theta`, in the layout of ``theta``.
    sigma2 : float
        σ² > 0 of eq. (5).

    Returns
    -------
    float
        The quadratic form, ≥ 0.

    Raises
    ------
    ValueError
        If ``velocity`` does not have the shape of ``theta``, an array is not finite, or ``sigma2``
        is not positive.

    See Also
    --------
    shapelib.alpha_metric : The tensor itself.
    shapelib.fisher_rao_quadratic_form : The same under the Fisher–Rao metric.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    It equals :math:`v^\top g^\alpha v` with the matrix of :func:`shapelib.alpha_metric`:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> v = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    >>> q = sl.alpha_quadratic_form(theta, v, sigma2=0.5)
    >>> bool(np.isclose(q, v.ravel() @ sl.alpha_metric(theta, sigma2=0.5) @ v.ravel()))
    True
    """
    theta = as_shape(theta, name="theta")
    vel = as_shape(velocity, name="velocity")
    if vel.shape != theta.shape:
        raise ValueError(f"velocity must have the shape of theta {theta.shape}; got {vel.shape}")
    return float(_kernels.alpha_qform(theta[None], vel[None], check_sigma2(sigma2))[0])


# ---------------------------------------------------------------------------------------------
# Fisher–Rao metric (eq. 6), by quadrature
# ---------------------------------------------------------------------------------------------


def psi_coef(theta: np.ndarray, s2: float, grid: Grid):
    r"""The Fisher–Rao integrands' building blocks at the grid nodes: ψ = 2√p and the coefficients of ∂ψ/∂φ.

    With :math:`N_a(x) = \mathcal{N}(x; \phi_a, \sigma^2 I)` and :math:`r_{ma} = x_m - \phi_a`,

    .. math::

        \psi(x_m) = 2\sqrt{p(x_m)}, \qquad
        \frac{\partial \psi}{\partial \phi_a}(x_m) = c_{ma}\, r_{ma}, \qquad
        c_{ma} = \frac{N_a(x_m)}{K \sigma^2 \sqrt{p(x_m)}},

    the integrand of eq. (6) of [1]_ in its stable form :math:`\int \partial_i\psi\, \partial_j\psi`.
    On a tensor grid the Gaussians factorise over coordinates, so only :math:`\sum_i n_i K`
    exponentials are needed instead of :math:`M K` (each factor scaled by its largest value per
    node coordinate, so it lies in (0, 1]); the products, ψ and ``coef`` are one compiled pass over
    the nodes (``shapelib.geometry._kernels.psi_coef_grid``). Nodes where the product underflows
    (far from every landmark) are recomputed in log space.

    Parameters
    ----------
    theta : ndarray, shape (K, d)
        Landmarks (not checked).
    s2 : float
        σ² of eq. (5).
    grid : Grid
        The quadrature grid (:func:`~shapelib.geometry.quadrature.make_grid`).

    Returns
    -------
    psi : ndarray, shape (M,)
        :math:`\psi` at the nodes.
    coef : ndarray, shape (M, K)
        :math:`c_{ma}`.

    See Also
    --------
    shapelib.fisher_rao_metric : The Gram matrix of these derivatives.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    :math:`\int \psi^2 = 4 \int p = 4`:

    >>> import numpy as np
    >>> from shapelib.geometry.metrics import psi_coef
    >>> from shapelib.geometry.quadrature import make_grid
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> grid = make_grid(theta, sigma2=0.5)
    >>> psi, coef = psi_coef(theta, 0.5, grid)
    >>> coef.shape, round(float(grid.integrate(psi ** 2)), 6)
    ((1681, 3), 4.0)
    """
    k, d = theta.shape
    if len(grid.axes) != d:
        return _psi_coef_nodes(theta, s2, grid.nodes)
    factors = []
    top = np.zeros((1,) * d)
    for i, ax in enumerate(grid.axes):
        expo = -((ax[:, None] - theta[None, :, i]) ** 2) / (2 * s2)  # (n_i, K)
        shift = expo.max(axis=1)
        factors.append(np.exp(expo - shift[:, None]))
        shape = [1] * d
        shape[i] = len(ax)
        top = top + shift.reshape(shape)
    log_norm = -0.5 * d * np.log(2 * np.pi * s2)
    # the products over axes, ψ and coef in one compiled pass (shapelib.geometry._kernels.psi_coef_grid)
    sizes = np.array([len(ax) for ax in grid.axes], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    psi, coef, far = _kernels.psi_coef_grid(np.concatenate(factors), offsets, sizes, top.reshape(-1), log_norm, s2)
    if np.any(far):
        psi[far], coef[far] = _psi_coef_nodes(theta, s2, grid.nodes[far])
    return psi, coef


def _psi_coef_nodes(theta: np.ndarray, s2: float, nodes: np.ndarray):
    """``ψ = 2√p`` at the nodes (M,) and ``coef_ma = N_a(x_m) / (K σ² √p(x_m))`` (M, K), log-space stable.

    ``∂ψ/∂φ_a (x_m) = coef_ma r_ma`` with ``r_ma = x_m − φ_a``.
    """
    k, d = theta.shape
    expo = np.zeros((len(nodes), k))
    for i in range(d):  # −|x − φ|² / (2σ²), one coordinate at a time
        expo -= np.subtract.outer(nodes[:, i], theta[:, i]) ** 2
    expo *= 0.5 / s2
    # one exponential pass: e = N_a / N_max with N_max the largest component at each node;
    # ratios below e^-60 are set to e^-60·(tiny): exp of huge negative numbers is slow and
    # they are negligible next to the leading component (which is 1)
    top = expo.max(axis=1)
    expo -= top[:, None]
    np.maximum(expo, -60.0, out=expo)
    e = np.exp(expo)
    total = e.sum(axis=1)
    log_norm = -0.5 * d * np.log(2 * np.pi * s2)
    log_p = np.log(total) + top + log_norm - np.log(k)  # log p(x_m)
    psi = 2.0 * np.exp(0.5 * log_p)
    # coef = N_a / (K σ² √p) = e · exp(top + log_norm − ½ log p) / (K σ²)
    coef = e * (np.exp(top + log_norm - 0.5 * log_p) / (k * s2))[:, None]
    return psi, coef


def _r_weighted(w: np.ndarray, nodes: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``Σ_m w_ma r_ma`` for ``r_ma = x_m − φ_a`` without forming r: (K, d)."""
    return w.T @ nodes - w.sum(axis=0)[:, None] * theta


def _fr_gram(theta: np.ndarray, s2: float, grid: Grid) -> np.ndarray:
    """``Σ_m ∂ψ/∂θ_i ∂ψ/∂θ_j`` over the nodes, (K d, K d), with ``∂ψ/∂φ_a = coef_a r_a``.

    Built one coordinate pair at a time from contiguous (M, K) factors (d² products of
    (K, M)·(M, K)) rather than from an (M, K, d) Jacobian.
    """
    k, d = theta.shape
    nodes = grid.nodes
    _, coef = psi_coef(theta, s2, grid)
    jac = [coef * (nodes[:, i, None] - theta[None, :, i]) for i in range(d)]  # ∂ψ/∂φ_{a,i}
    out = np.empty((k, d, k, d))
    for i in range(d):
        for j in range(i, d):
            block = jac[i].T @ jac[j]
            out[:, i, :, j] = block
            if j > i:
                out[:, j, :, i] = block.T
    return out.reshape(k * d, k * d)


def fisher_rao_metric(theta, *, sigma2, grid_spacing: float = DEFAULT_SPACING, grid_margin: float = DEFAULT_MARGIN) -> np.ndarray:
    r"""The Fisher–Rao metric tensor of eq. (6) for the GMM of eq. (5), by quadrature.

    The Fisher information of the landmark coordinates, a Riemannian metric on the shapes [1]_ [2]_:

    .. math::

        g_{ij}(\theta) = \int p(x \mid \theta)\, \frac{\partial \log p(x \mid \theta)}{\partial \theta_i}
        \frac{\partial \log p(x \mid \theta)}{\partial \theta_j}\, dx
        = \int \frac{\partial \psi}{\partial \theta_i} \frac{\partial \psi}{\partial \theta_j}\, dx,
        \qquad \psi = 2\sqrt{p} \qquad \text{(eq. 6)}

    It has no closed form for a mixture: the right-hand form (numerically stable in the tails) is
    integrated by the trapezoid rule on a grid of step ``grid_spacing·σ`` reaching ``grid_margin·σ`` beyond the
    landmarks (see :mod:`shapelib.geometry.quadrature` for its accuracy).

    Parameters
    ----------
    theta : array_like, shape (K, d)
        Landmarks (GMM means).
    sigma2 : float
        σ² > 0 of eq. (5).
    grid_spacing : float, default 0.35
        Grid step in units of σ.
    grid_margin : float, default 6.0
        Grid margin beyond the landmarks, in units of σ.

    Returns
    -------
    ndarray, shape (K d, K d)
        Symmetric positive semi-definite, parameters ordered as in eq. (9); :math:`I/\sigma^2` for
        K = 1, and :math:`\preceq I/(K\sigma^2)` in general.

    Raises
    ------
    ValueError
        If ``theta`` is not a finite ``(K, d)`` array, ``sigma2``, ``spacing`` or ``margin`` is not
        positive, or the grid would exceed
        ``shapelib.geometry.quadrature.MAX_ENTRIES`` nodes × landmarks.

    See Also
    --------
    shapelib.fisher_rao_quadratic_form : :math:`\dot\theta^\top g\, \dot\theta` without the matrix.
    shapelib.alpha_metric : The closed-form α-order metric of eq. (22).
    shapelib.geometry.quadrature.make_grid : The integration grid.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] S. Amari and H. Nagaoka, *Methods of Information Geometry*, American Mathematical Society and
       Oxford University Press, 2000.

    Examples
    --------
    One landmark: the Fisher information of a Gaussian mean, :math:`I/\sigma^2`.

    >>> import numpy as np
    >>> import shapelib as sl
    >>> g = sl.fisher_rao_metric([[0.0, 0.0]], sigma2=0.5)
    >>> bool(np.allclose(g, np.eye(2) / 0.5, rtol=1e-6))
    True
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> g = sl.fisher_rao_metric(theta, sigma2=0.5)
    >>> g.shape, bool(np.all(np.linalg.eigvalsh(np.eye(6) / (3 * 0.5) - g) > -1e-9))
    ((6, 6), True)
    """
    theta = as_shape(theta, name="theta")
    s2 = check_sigma2(sigma2)
    grid = make_grid(theta, sigma2=s2, grid_spacing=grid_spacing, grid_margin=grid_margin)
    g = grid.weight * _fr_gram(theta, s2, grid)
    return 0.5 * (g + g.T)


def _fr_psidot(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid):
    """``ψ`` and ``coef`` of :func:`psi_coef`, ``rv_ma = r_ma·V_a`` (M, K) and
    ``ψ̇ = Σ_a coef_a (r_a·V_a)`` (M,) for one shape ``theta`` (K, d) moving with ``vel``."""
    psi, coef = psi_coef(theta, s2, grid)
    rv = grid.nodes @ vel.T - np.einsum("ki,ki->k", theta, vel)[None, :]
    return psi, coef, rv, np.einsum("mk,mk->m", coef, rv)


def _fr_qform(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid) -> np.ndarray:
    """Batched ``vᵀ g_FR(θ) v = ∫ ṗ²/p`` for ``theta, vel`` of shape (m, K, d) on a common grid."""
    return np.array([grid.integrate(_fr_psidot(t, w, s2, grid)[3] ** 2) for t, w in zip(theta, vel)])


def fisher_rao_quadratic_form(theta, velocity, *, sigma2, grid_spacing: float = DEFAULT_SPACING,
                              grid_margin: float = DEFAULT_MARGIN) -> float:
    r"""The Fisher–Rao quadratic form :math:`\dot\theta^\top g(\theta)\, \dot\theta`, by quadrature, no matrix.

    The integrand of the path energy (eq. 8) under the metric of eq. (6) [1]_:

    .. math::

        \dot\theta^\top g(\theta)\, \dot\theta = \int \frac{(\partial_t p)^2}{p}\, dx
        = \int (\partial_t \psi)^2\, dx, \qquad \psi = 2\sqrt{p},

    integrated on the grid of :func:`shapelib.fisher_rao_metric`.

    Parameters
    ----------
    theta : array_like, shape (K, d)
        Landmarks (GMM means).
    velocity : array_like, shape (K, d)
        Landmark velocities :math:`\dot\theta`, in the layout of ``theta``.
    sigma2 : float
        σ² > 0 of eq. (5).
    grid_spacing : float, default 0.35
        Grid step in units of σ.
    grid_margin : float, default 6.0
        Grid margin beyond the landmarks, in units of σ.

    Returns
    -------
    float
        The quadratic form, ≥ 0.

    Raises
    ------
    ValueError
        If ``velocity`` does not have the shape of ``theta``, an array is not finite, a parameter
        is not positive, or the grid is too large (as :func:`shapelib.fisher_rao_metric`).

    See Also
    --------
    shapelib.fisher_rao_metric : The tensor itself.
    shapelib.alpha_quadratic_form : The same under the α-order metric.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> v = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    >>> q = sl.fisher_rao_quadratic_form(theta, v, sigma2=0.5)
    >>> bool(np.isclose(q, v.ravel() @ sl.fisher_rao_metric(theta, sigma2=0.5) @ v.ravel()))
    True
    """
    theta = as_shape(theta, name="theta")
    vel = as_shape(velocity, name="velocity")
    if vel.shape != theta.shape:
        raise ValueError(f"velocity must have the shape of theta {theta.shape}; got {vel.shape}")
    s2 = check_sigma2(sigma2)
    grid = make_grid(theta, sigma2=s2, grid_spacing=grid_spacing, grid_margin=grid_margin)
    return float(_fr_qform(theta[None], vel[None], s2, grid)[0])


# ---------------------------------------------------------------------------------------------
# Quadratic forms with their gradients (what the geodesic solver needs), batched over points
# ---------------------------------------------------------------------------------------------


def _alpha_qform_grad(theta: np.ndarray, vel: np.ndarray, s2: float):
    """``Q = vᵀ g_α(θ) v`` and its gradients ``∂Q/∂θ`` and ``∂Q/∂v``, batched over (m, K, d).

    ``Q = Σ_ab (G_ab/K²) B_ab`` with ``B_ab = V_a·V_b/(2σ²) − (Δ·V_a)(Δ·V_b)/(4σ⁴)``,
    ``Δ = φ_a − φ_b``. Since the summand is even in Δ and symmetric in (a, b),
    ``∂Q/∂φ_a = 2 Σ_b (G_ab/K²) [−Δ B_ab/(2σ²) − (V_a (Δ·V_b) + V_b (Δ·V_a))/(4σ⁴)]`` and
    ``∂Q/∂V_a = 2 (g_α v)_a``.
    """
    c, _, vv, dva, dvb = _alpha_pairs(theta, vel, s2)
    s4 = 4 * s2 * s2
    cb = c * (vv / (2 * s2) - dva * dvb / s4)
    q = cb.sum(axis=(1, 2))
    cdva, cdvb = c * dva, c * dvb
    # Σ_b w_ab Δ_ab = φ_a Σ_b w_ab − (w φ)_a for any pair weights w
    rsum = lambda w: theta * w.sum(axis=2)[..., None] - w @ theta  # noqa: E731
    d_theta = 2 * (-rsum(cb) / (2 * s2) - (cdvb.sum(axis=2)[..., None] * vel + cdva @ vel) / s4)
    # (g v)_a = Σ_b c_ab [V_b/(2σ²) − Δ_ab (Δ_ab·V_b)/(4σ⁴)]
    gv = (c @ vel) / (2 * s2) - rsum(cdvb) / s4
    return q, d_theta, 2 * gv


def alpha_qform_hessian(theta: np.ndarray, vel: np.ndarray, s2: float):
    r"""Second derivatives of the α quadratic form ``Q = vᵀ g_α(θ) v``: ``(Q_θθ, Q_θv, Q_vv)``.

    :math:`Q = \sum_{ab} f(\Delta_{ab}, V_a, V_b)` over ordered pairs (eq. 22 of [1]_ in closed form),
    with :math:`f = c(\Delta) h`,

    .. math::

        c = \frac{e^{-|\Delta|^2/4\sigma^2}}{(4\pi\sigma^2)^{d/2} K^2}, \qquad
        h = \frac{V_a \cdot V_b}{2\sigma^2} - \frac{(\Delta \cdot V_a)(\Delta \cdot V_b)}{4\sigma^4},
        \qquad \Delta = \phi_a - \phi_b.

    Each term depends on the positions only through Δ, and the terms (a, b) and (b, a) are the same
    function, so with :math:`H_{ab} = \partial^2 f / \partial\Delta^2`,
    :math:`M_{ab} = \partial^2 f / \partial\Delta\, \partial V_b` and
    :math:`N_{ab} = \partial^2 f / \partial\Delta\, \partial V_a` (rows Δ, columns V) evaluated at
    the ordered pair (a, b):

    .. math::

        Q_{\theta\theta}[a, b] = -2 H_{ab}, \quad Q_{\theta\theta}[a, a] = 2 \sum_{b \ne a} H_{ab}, \quad
        Q_{\theta v}[a, b] = 2 M_{ab}, \quad Q_{\theta v}[a, a] = 2 \sum_{b \ne a} N_{ab}, \quad
        Q_{vv} = 2 g^\alpha,

    with :math:`\nabla_\Delta c = -c \Delta / (2\sigma^2)` and
    :math:`\nabla_\Delta h = -((\Delta \cdot V_b) V_a + (\Delta \cdot V_a) V_b) / (4\sigma^4)`.
    Computed one coordinate pair (i, j) at a time on contiguous (m, K, K) arrays. Used for exact
    Newton steps on the α path energy; checked against finite differences of the gradient.
    ``Q_θv`` has rows indexed by θ and columns by v.

    Parameters
    ----------
    theta, vel : ndarray, shape (m, K, d)
        Positions and velocities (a batch of m nodes).
    s2 : float
        σ² of eq. (5).

    Returns
    -------
    q_tt, q_tv, q_vv : ndarray, shape (m, K d, K d)
        The three second-derivative blocks.

    See Also
    --------
    shapelib.alpha_quadratic_form : :math:`Q` itself.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.metrics import alpha_qform_hessian
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> vel = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    >>> q_tt, q_tv, q_vv = alpha_qform_hessian(theta[None], vel[None], 0.5)
    >>> q_tt.shape, bool(np.allclose(q_vv[0], 2 * sl.alpha_metric(theta, sigma2=0.5)))
    ((1, 6, 6), True)
    """
    m, k, d = theta.shape
    s4 = 4 * s2 * s2
    c, delta, vv, dva, dvb = _alpha_pairs(theta, vel, s2)
    va = [vel[:, :, None, i] for i in range(d)]  # V_a,i broadcast over b
    vb = [vel[:, None, :, i] for i in range(d)]  # V_b,i broadcast over a
    idx = np.arange(k)
    c_off = c.copy()
    c_off[:, idx, idx] = 0.0  # the terms f_aa do not depend on the positions
    h = vv / (2 * s2) - dva * dvb / s4
    grad_h = [-(dvb * va[i] + dva * vb[i]) / s4 for i in range(d)]
    q_tt, q_tv = np.empty((m, k, d, k, d)), np.empty((m, k, d, k, d))

    def put(out, i, j, offdiag, diag):
        out[:, :, i, :, j] = offdiag
        out[:, idx, i, idx, j] = diag

    for i in range(d):
        for j in range(d):
            eye = float(i == j)
            # H_ij and its diagonal sum (symmetric in i, j)
            if j >= i:
                hess = c_off * (-(va[i] * vb[j] + vb[i] * va[j]) / s4 + (h / s4) * delta[i] * delta[j]
                                - eye * h / (2 * s2) - (delta[i] * grad_h[j] + grad_h[i] * delta[j]) / (2 * s2))
                put(q_tt, i, j, -2 * hess, 2 * hess.sum(axis=2))
                if j > i:
                    q_tt[:, :, j, :, i] = q_tt[:, :, i, :, j]
            # mixed: ∂²f/∂Δ_i∂V_j with the other velocity V_a (for M) or V_b (for N)
            m_ij = -c_off * (eye * dva / s4 + va[i] * delta[j] / s4
                             + delta[i] * (va[j] / (2 * s2) - dva * delta[j] / s4) / (2 * s2))
            n_ij = -c_off * (eye * dvb / s4 + vb[i] * delta[j] / s4
                             + delta[i] * (vb[j] / (2 * s2) - dvb * delta[j] / s4) / (2 * s2))
            put(q_tv, i, j, 2 * m_ij, 2 * n_ij.sum(axis=2))
    shape = (m, k * d, k * d)
    return q_tt.reshape(shape), q_tv.reshape(shape), 2 * _alpha_metric_blocks(c, delta, s2).reshape(shape)


def alpha_tensor_batch(theta: np.ndarray, s2: float) -> np.ndarray:
    r"""α metric tensors of eq. (22) for a batch of shapes.

    For each shape, the blocks :math:`g^\alpha_{ab} = c_{ab} [I/(2\sigma^2) - \Delta\Delta^\top/(4\sigma^4)]`,
    :math:`c_{ab} = G(\Delta_{ab})/K^2` (module docstring; [1]_):

    .. math::

        g^\alpha_{ij} = \int \frac{\partial p}{\partial \theta_i} \frac{\partial p}{\partial \theta_j}\, dx.

    Parameters
    ----------
    theta : ndarray, shape (m, K, d)
        The shapes (not checked).
    s2 : float
        σ² of eq. (5).

    Returns
    -------
    ndarray, shape (m, K d, K d)
        One tensor per shape.

    See Also
    --------
    shapelib.alpha_metric : One checked tensor.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.metrics import alpha_tensor_batch
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> bool(np.allclose(alpha_tensor_batch(theta[None], 0.5)[0], sl.alpha_metric(theta, sigma2=0.5)))
    True
    """
    m, k, d = theta.shape
    return _alpha_metric_blocks(*_alpha_overlaps(theta, s2), s2).reshape(m, k * d, k * d)


def _over_psi(x: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """``x / ψ``, 0 where ψ is below :data:`shapelib.geometry._kernels.PSI_FLOOR`: only far from every
    landmark, where what it multiplies (``coef`` ∝ √p) is as small, so such nodes add nothing."""
    return np.divide(x, psi, out=np.zeros_like(x), where=psi > _kernels.PSI_FLOOR)


def _fr_qform_grad(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid):
    """``Q = ∫ ṗ²/p = ∫ ψ̇²`` (ψ = 2√p) and its gradients, batched over (m, K, d), on ``grid``.

    With ``ψ̇ = Σ_a coef_a (r_a·V_a)`` (``coef_a = N_a/(Kσ²√p)``):
    ``∂Q/∂V_a = 2 ∫ ψ̇ coef_a r_a`` and
    ``∂Q/∂φ_a = 2 ∫ ψ̇ coef_a [(r_a·V_a) r_a/σ² − V_a] − 2 ∫ ψ̇² coef_a r_a / ψ``.
    """
    m = len(theta)
    q = np.empty(m)
    d_theta = np.empty_like(theta)
    d_vel = np.empty_like(theta)
    x = grid.nodes
    for i in range(m):
        th, v = theta[i], vel[i]
        psi, coef, rv, psidot = _fr_psidot(th, v, s2, grid)
        q[i] = grid.integrate(psidot**2)
        pc = psidot[:, None] * coef  # (M, K)
        d_vel[i] = 2 * grid.weight * _r_weighted(pc, x, th)
        d_theta[i] = 2 * grid.weight * (
            _r_weighted(pc * rv, x, th) / s2
            - pc.sum(axis=0)[:, None] * v
            - _r_weighted(pc * _over_psi(psidot, psi)[:, None], x, th)
        )
    return q, d_theta, d_vel


def _fr_qform_hessian(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid):
    """Second derivatives of ``Q = vᵀ g_FR(θ) v = ∫ ṗ²/p``: ``(Q_θθ, Q_θv, Q_vv)``, each (m, K d, K d).

    Written with ``s = ṗ = Σ_a V_a·∂_a p`` and ``∂_a p = N_a r_a/(Kσ²)``; every derivative of
    ``p`` of order ≥ 2 is block diagonal over landmarks, so with the responsibilities
    ``ρ_a = N_a/(K p)``, ``β = ∂p/p`` (``β_a = ρ_a r_a/σ²``), ``γ = ∂s/p``
    (``γ_a = ρ_a [r_a (r_a·V_a)/σ⁴ − V_a/σ²]``) and ``u = s/p``:

        Q_θθ = 2 ∫ p (γ − uβ)(γ − uβ)ᵀ + ∫ [2u ∂²s − u² ∂²p]   (second term block diagonal),
        Q_θv = 2 ∫ p (γ − uβ) βᵀ + 2 ∫ u ∂²p,                   Q_vv = 2 ∫ p β βᵀ = 2 g_FR,

    with ``∂²p_a = (N_a/K)(r rᵀ/σ⁴ − I/σ²)`` and ``∂²s_a = (N_a/K)[r rᵀ (r·V_a)/σ⁶ −
    (I (r·V_a) + V_a rᵀ + r V_aᵀ)/σ⁴]``. The three dense parts are one Gram matrix of the
    (M, 2 K d) array ``√p [γ − uβ, β]`` (``√p β_a = coef_a r_a`` with ``coef`` of
    :func:`psi_coef`, ``u = 2ψ̇/ψ``). Used for exact Newton steps on the Fisher–Rao path
    energy; checked against finite differences of :func:`_fr_qform_grad`. ``Q_θv`` has rows
    indexed by θ and columns by v.
    """
    m, k, d = theta.shape
    q = k * d
    x = grid.nodes
    w = grid.weight
    q_tt, q_tv, q_vv = np.empty((3, m, q, q))
    idx = np.arange(k)
    s4 = s2 * s2
    # E's columns are built in (2, d, K) order (contiguous writes), the Gram matrix is then
    # permuted to the (2, K, d) order of θ = (φ_1^1, φ_1^2, φ_2^1, …)
    perm = np.arange(2 * q).reshape(2, d, k).transpose(0, 2, 1).ravel()
    e = np.empty((len(x), 2, d, k))
    for n in range(m):
        th, v = theta[n], vel[n]
        psi, coef, rv, psidot = _fr_psidot(th, v, s2, grid)
        r = [x[:, i, None] - th[None, :, i] for i in range(d)]  # r_a (M, K) per coordinate
        u = 2 * _over_psi(psidot, psi)
        for i in range(d):
            np.multiply(coef, r[i], out=e[:, 1, i])  # √p β
            e[:, 0, i] = coef * (r[i] * rv / s2 - v[None, :, i]) - u[:, None] * e[:, 1, i]  # √p (γ − uβ)
        flat = e.reshape(len(x), 2 * q)
        gram = (2 * w) * (flat.T @ flat)
        gram = gram[np.ix_(perm, perm)]
        q_tt[n], q_tv[n], q_vv[n] = gram[:q, :q], gram[:q, q:], gram[q:, q:]
        # block-diagonal parts: moments of a = ψ̇ coef and b = (ψ̇²/ψ) coef over the grid
        a = psidot[:, None] * coef
        b = _over_psi(psidot**2, psi)[:, None] * coef
        arv = a * rv
        ar = [a * ri for ri in r]
        arv_r = [arv * ri for ri in r]
        br = [b * ri for ri in r]
        s_a, s_b, s_arv = a.sum(axis=0), b.sum(axis=0), arv.sum(axis=0)
        s_ar = [x_.sum(axis=0) for x_ in ar]
        tt = q_tt[n].reshape(k, d, k, d)
        tv = q_tv[n].reshape(k, d, k, d)
        for i in range(d):
            for j in range(i, d):
                eye = float(i == j)
                s_arr = np.einsum("mk,mk->k", ar[i], r[j])
                d2p_a = s_arr / s4 - eye * s_a / s2  # Σ_m ψ̇ coef (r rᵀ/σ⁴ − I/σ²)
                d2p_b = np.einsum("mk,mk->k", br[i], r[j]) / s4 - eye * s_b / s2
                d2s = (np.einsum("mk,mk->k", arv_r[i], r[j]) / (s4 * s2)
                       - (eye * s_arv + v[:, j] * s_ar[i] + v[:, i] * s_ar[j]) / s4)
                dtt = 2 * s2 * w * (d2s - d2p_b)
                dtv = 2 * s2 * w * d2p_a
                tt[idx, i, idx, j] += dtt
                tv[idx, i, idx, j] += dtv
                if j > i:
                    tt[idx, j, idx, i] += dtt
                    tv[idx, j, idx, i] += dtv
    return q_tt, q_tv, q_vv


# Compiled versions used by the geodesic solver (same formulas as above, fused per node and
# landmark in shapelib._kernels; tests/test_kernels.py checks them against the numpy ones).


def _compiled_layout(theta, vel):
    """``theta`` and ``vel`` as C-ordered, writable float64 arrays: the one layout the compiled kernels
    are compiled for (a transposed or read-only array would compile, and cache, another
    specialisation of each kernel on first use)."""
    return (np.require(theta, np.float64, ["C", "W"]), np.require(vel, np.float64, ["C", "W"]))


def fr_qform_compiled(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid) -> np.ndarray:
    r"""Batched Fisher–Rao quadratic form ``vᵀ g_FR(θ) v`` on a common grid, ψ̇ fused in compiled code.

    .. math::

        Q(\theta, v) = \int \frac{(\partial_t p)^2}{p}\, dx = \int \dot\psi^2\, dx, \qquad
        \dot\psi = \sum_a c_a (r_a \cdot V_a),

    the integrand of eq. (8) under the metric of eq. (6) of [1]_
    (``shapelib.geometry._kernels.fr_psidot``).

    Parameters
    ----------
    theta, vel : ndarray, shape (m, K, d)
        Positions and velocities.
    s2 : float
        σ² of eq. (5).
    grid : Grid
        A grid covering every position.

    Returns
    -------
    ndarray, shape (m,)
        :math:`Q` at every node.

    See Also
    --------
    shapelib.fisher_rao_quadratic_form : One checked value.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.metrics import fr_qform_compiled
    >>> from shapelib.geometry.quadrature import make_grid
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> vel = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    >>> q = fr_qform_compiled(theta[None], vel[None], 0.5, make_grid(theta, sigma2=0.5))
    >>> bool(np.isclose(q[0], sl.fisher_rao_quadratic_form(theta, vel, sigma2=0.5)))
    True
    """
    theta, vel = _compiled_layout(theta, vel)
    x = grid.nodes
    out = np.empty(len(theta))
    for n, (t, v) in enumerate(zip(theta, vel)):
        coef = psi_coef(t, s2, grid)[1]
        out[n] = grid.integrate(_kernels.fr_psidot(x, t, v, coef) ** 2)
    return out


def fr_qform_grad_compiled(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid):
    r"""Batched Fisher–Rao quadratic form and its gradients, fused per node and landmark.

    With :math:`\dot\psi = \sum_a c_a (r_a \cdot V_a)` (:func:`~shapelib.geometry.metrics.psi_coef`),

    .. math::

        \frac{\partial Q}{\partial V_a} = 2 \int \dot\psi\, c_a r_a, \qquad
        \frac{\partial Q}{\partial \phi_a} = 2 \int \dot\psi\, c_a \left[\frac{(r_a \cdot V_a)\, r_a}{\sigma^2}
        - V_a\right] - 2 \int \frac{\dot\psi^2 c_a r_a}{\psi},

    the gradient of the integrand of eq. (8) under the metric of eq. (6) of [1]_
    (``shapelib.geometry._kernels.fr_qform_grad``).

    Parameters
    ----------
    theta, vel : ndarray, shape (m, K, d)
        Positions and velocities.
    s2 : float
        σ² of eq. (5).
    grid : Grid
        A grid covering every position.

    Returns
    -------
    q : ndarray, shape (m,)
        :math:`Q`.
    d_theta, d_vel : ndarray, shape (m, K, d)
        :math:`\partial Q / \partial\theta` and :math:`\partial Q / \partial v`.

    See Also
    --------
    shapelib.geometry.metrics.fr_qform_compiled : :math:`Q` alone.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    :math:`\partial Q / \partial v = 2 g v`:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.metrics import fr_qform_grad_compiled
    >>> from shapelib.geometry.quadrature import make_grid
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> vel = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    >>> q, d_theta, d_vel = fr_qform_grad_compiled(theta[None], vel[None], 0.5, make_grid(theta, sigma2=0.5))
    >>> bool(np.allclose(d_vel[0].ravel(), 2 * sl.fisher_rao_metric(theta, sigma2=0.5) @ vel.ravel(), rtol=1e-6))
    True
    """
    theta, vel = _compiled_layout(theta, vel)
    m = len(theta)
    q = np.empty(m)
    d_theta = np.empty_like(theta)
    d_vel = np.empty_like(theta)
    for n in range(m):
        psi, coef = psi_coef(theta[n], s2, grid)
        q[n], d_theta[n], d_vel[n] = _kernels.fr_qform_grad(grid.nodes, grid.weight, theta[n], vel[n], s2, psi, coef)
    return q, d_theta, d_vel


def _fr_hessian_one(theta, vel, s2, grid, psi, coef, q_tt, q_tv, q_vv):
    """Second derivatives of Q for one shape into ``q_tt, q_tv, q_vv`` (each (K d, K d)), from
    :func:`shapelib.geometry._kernels.fr_hessian_parts` and one Gram product by BLAS."""
    k, d = theta.shape
    q = k * d
    w = grid.weight
    e, dtt, dtv = _kernels.fr_hessian_parts(grid.nodes, theta, vel, s2, psi, coef)
    flat = e.reshape(len(e), 2 * q)
    gram = (flat.T @ flat).reshape(2, d, k, 2, d, k)  # columns in the kernel's (2, d, K) order
    for out, (r, c) in ((q_tt, (0, 0)), (q_tv, (0, 1)), (q_vv, (1, 1))):  # to the (K, d) order of θ
        np.multiply(gram[r, :, :, c], 2 * w, out=out.reshape(k, d, k, d).transpose(1, 0, 3, 2))
    idx = np.arange(k)
    tt = q_tt.reshape(k, d, k, d)
    tv = q_tv.reshape(k, d, k, d)
    for i in range(d):
        for j in range(d):
            tt[idx, i, idx, j] += 2 * s2 * w * dtt[:, i, j]
            tv[idx, i, idx, j] += 2 * s2 * w * dtv[:, i, j]


def fr_qform_hessian_compiled(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid):
    r"""Second derivatives of the Fisher–Rao quadratic form, ``(Q_θθ, Q_θv, Q_vv)``, each (m, K d, K d).

    Written with :math:`s = \dot p`, responsibilities :math:`\rho_a = N_a/(Kp)`,
    :math:`\beta = \partial p / p`, :math:`\gamma = \partial s / p` and :math:`u = s/p`:

    .. math::

        Q_{\theta\theta} = 2 \int p (\gamma - u\beta)(\gamma - u\beta)^\top
        + \int \left[2u\, \partial^2 s - u^2 \partial^2 p\right], \qquad
        Q_{\theta v} = 2 \int p (\gamma - u\beta) \beta^\top + 2 \int u\, \partial^2 p, \qquad
        Q_{vv} = 2 g^{FR},

    the element-wise work fused (``shapelib.geometry._kernels.fr_hessian_parts``), the Gram
    product by BLAS: exact Newton steps on the path energy of eq. (8) under eq. (6) of [1]_.

    Parameters
    ----------
    theta, vel : ndarray, shape (m, K, d)
        Positions and velocities.
    s2 : float
        σ² of eq. (5).
    grid : Grid
        A grid covering every position.

    Returns
    -------
    q_tt, q_tv, q_vv : ndarray, shape (m, K d, K d)
        The three blocks (``q_tv``: rows θ, columns v).

    See Also
    --------
    shapelib.geometry.metrics.fr_qform_grad_compiled : The gradient.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.metrics import fr_qform_hessian_compiled
    >>> from shapelib.geometry.quadrature import make_grid
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> vel = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    >>> q_tt, q_tv, q_vv = fr_qform_hessian_compiled(theta[None], vel[None], 0.5, make_grid(theta, sigma2=0.5))
    >>> bool(np.allclose(q_vv[0], 2 * sl.fisher_rao_metric(theta, sigma2=0.5)))
    True
    """
    theta, vel = _compiled_layout(theta, vel)
    m, k, d = theta.shape
    q_tt, q_tv, q_vv = np.empty((3, m, k * d, k * d))
    for n in range(m):
        psi, coef = psi_coef(theta[n], s2, grid)
        _fr_hessian_one(theta[n], vel[n], s2, grid, psi, coef, q_tt[n], q_tv[n], q_vv[n])
    return q_tt, q_tv, q_vv


def fr_qform_grad_hessian_compiled(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid):
    r"""The Fisher–Rao quadratic form, its gradients and second derivatives, ψ computed once per shape.

    :func:`~shapelib.geometry.metrics.fr_qform_grad_compiled` and
    :func:`~shapelib.geometry.metrics.fr_qform_hessian_compiled` together, with one evaluation of
    ψ and ``coef`` (:func:`~shapelib.geometry.metrics.psi_coef`) per shape, for
    :math:`Q = \int \dot p^2 / p` (eq. 6 of [1]_):

    .. math::

        \left(Q,\ \frac{\partial Q}{\partial\theta},\ \frac{\partial Q}{\partial v},\
        (Q_{\theta\theta}, Q_{\theta v}, Q_{vv})\right).

    Parameters
    ----------
    theta, vel : ndarray, shape (m, K, d)
        Positions and velocities.
    s2 : float
        σ² of eq. (5).
    grid : Grid
        A grid covering every position.

    Returns
    -------
    q : ndarray, shape (m,)
        :math:`Q`.
    d_theta, d_vel : ndarray, shape (m, K, d)
        The gradients.
    hessian : tuple of ndarray
        ``(q_tt, q_tv, q_vv)``, each (m, K d, K d).

    See Also
    --------
    shapelib.geometry.metrics.fr_qform_grad_compiled, shapelib.geometry.metrics.fr_qform_hessian_compiled

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.metrics import fr_qform_compiled, fr_qform_grad_hessian_compiled
    >>> from shapelib.geometry.quadrature import make_grid
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> vel = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    >>> grid = make_grid(theta, sigma2=0.5)
    >>> q, d_theta, d_vel, (q_tt, q_tv, q_vv) = fr_qform_grad_hessian_compiled(theta[None], vel[None], 0.5, grid)
    >>> bool(np.isclose(q[0], fr_qform_compiled(theta[None], vel[None], 0.5, grid)[0])), q_tt.shape
    (True, (1, 6, 6))
    """
    theta, vel = _compiled_layout(theta, vel)
    m, k, d = theta.shape
    q = np.empty(m)
    d_theta = np.empty_like(theta)
    d_vel = np.empty_like(theta)
    q_tt, q_tv, q_vv = np.empty((3, m, k * d, k * d))
    for n in range(m):
        psi, coef = psi_coef(theta[n], s2, grid)
        q[n], d_theta[n], d_vel[n] = _kernels.fr_qform_grad(grid.nodes, grid.weight, theta[n], vel[n], s2, psi, coef)
        _fr_hessian_one(theta[n], vel[n], s2, grid, psi, coef, q_tt[n], q_tv[n], q_vv[n])
    return q, d_theta, d_vel, (q_tt, q_tv, q_vv)


def fr_tensor_batch(theta: np.ndarray, s2: float, grid: Grid) -> np.ndarray:
    r"""Fisher–Rao metric tensors of eq. (6) for a batch of shapes on a common grid.

    .. math::

        g_{ij} = \int \frac{\partial \psi}{\partial \theta_i} \frac{\partial \psi}{\partial \theta_j}\, dx
        \approx h^d \sum_m \frac{\partial \psi}{\partial \theta_i}(x_m) \frac{\partial \psi}{\partial \theta_j}(x_m),
        \qquad \psi = 2\sqrt{p}

    (eq. 6 of [1]_; the trapezoid rule of :mod:`shapelib.geometry.quadrature`).

    Parameters
    ----------
    theta : ndarray, shape (m, K, d)
        The shapes.
    s2 : float
        σ² of eq. (5).
    grid : Grid
        A grid covering every shape.

    Returns
    -------
    ndarray, shape (m, K d, K d)
        One tensor per shape.

    See Also
    --------
    shapelib.fisher_rao_metric : One checked tensor on its own grid.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.metrics import fr_tensor_batch
    >>> from shapelib.geometry.quadrature import make_grid
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> g = fr_tensor_batch(theta[None], 0.5, make_grid(theta, sigma2=0.5))
    >>> bool(np.allclose(g[0], sl.fisher_rao_metric(theta, sigma2=0.5)))
    True
    """
    return np.stack([grid.weight * _fr_gram(t, s2, grid) for t in theta])
