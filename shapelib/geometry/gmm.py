r"""The shape representation: an equal-weight isotropic Gaussian mixture (paper eq. 5).

A landmark shape :math:`\theta = (\phi_1, \dots, \phi_K)`, :math:`\phi_a \in \mathbb{R}^d`, is
the density

.. math::

    p(x \mid \theta) = \frac{1}{K} \sum_{a=1}^{K} \mathcal{N}(x; \phi_a, \sigma^2 I)
    \qquad \text{(eq. 5)}

with σ² a free parameter. This module holds the density itself and the closed-form
Gaussian overlaps it implies:

.. math::

    G(\Delta) = \int \mathcal{N}(x; a, \sigma^2 I)\, \mathcal{N}(x; b, \sigma^2 I)\, dx
    = (4\pi\sigma^2)^{-d/2} \exp\!\left(-\frac{|\Delta|^2}{4\sigma^2}\right),
    \qquad \Delta = a - b,

which give the L² inner product of two mixtures,
:math:`\langle p_u, p_v \rangle = K^{-2} \sum_{ab} G(u_a - v_b)`, and hence the L² distance
:math:`\|p_u - p_v\|` in closed form. Because the α-order metric (eq. 22) is the pull-back of
the flat L² metric on densities, :math:`\|p_u - p_v\|` is a lower bound on the α-order geodesic
distance.

Near shapes. :math:`\|p_u - p_v\|^2 = \langle p_u, p_u\rangle + \langle p_v, p_v\rangle - 2\langle p_u, p_v\rangle`
loses the digits the three terms share: shapes of one population are close (at the study's scale
and σ the squared distance is typically 10⁻³ and down to 10⁻⁸ of :math:`\langle p_u, p_u\rangle`),
so the difference keeps only ~13 and down to ~8 correct digits. Each landmark pair's four overlaps
form a mixed second difference of :math:`g(x) = \exp(-|x|^2/4\sigma^2)`: with
:math:`r = u_a - u_b`, :math:`\delta = v - u`,

.. math::

    g(r) - g(r - \delta_b) - g(r + \delta_a) + g(r + \delta_a - \delta_b)
    = g(r)\, \operatorname{expm1}(\alpha)\, \operatorname{expm1}(\beta)
      - g(v_a - v_b)\, \operatorname{expm1}\!\left(-\frac{\delta_a \cdot \delta_b}{2\sigma^2}\right),

    \alpha = -\frac{2 r \cdot \delta_a + |\delta_a|^2}{4\sigma^2}, \qquad
    \beta = \frac{2 r \cdot \delta_b - |\delta_b|^2}{4\sigma^2},

whose terms are :math:`O(|\delta|^2)` themselves (``_l2_sq_near``); :func:`l2_distance` uses it when the
plain difference has lost more than three digits (:data:`L2_NEAR`) and the landmarks moved by at
most √2 σ (beyond that the two terms grow like :math:`\exp(|\delta|^2/2\sigma^2)` and cancel each
other instead).
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


def gmm_log_density(x, theta, *, sigma2) -> np.ndarray:
    r"""Log of the GMM shape density of eq. (5), computed stably (log-sum-exp).

    The logarithm of the shape density of [1]_, without leaving log space:

    .. math::

        \log p(x \mid \theta) = \operatorname{logsumexp}_a
        \left(-\frac{|x - \phi_a|^2}{2\sigma^2}\right) - \frac{d}{2}\log(2\pi\sigma^2) - \log K
        \qquad \text{(log of eq. 5)}

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
        :math:`\log p(x_m \mid \theta)`; finite far from every landmark, where
        :func:`gmm_density` underflows to 0.

    Raises
    ------
    ValueError
        If ``x`` and ``theta`` differ in dimension, contain non-finite values, or ``sigma2`` is not
        a positive number.

    See Also
    --------
    gmm_density : The density itself.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.gmm import gmm_log_density
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0]])
    >>> bool(np.isfinite(gmm_log_density([[100.0, 100.0]], theta, sigma2=0.01)[0]))
    True
    >>> float(np.round(gmm_log_density([[0.5, 0.0]], theta, sigma2=0.5)[0], 4))
    -1.3947
    """
    x, theta = _point_sets(x, theta, ("x", "theta"))
    s2 = check_sigma2(sigma2)
    k, d = theta.shape
    log_n = -_sqdist(x, theta) / (2 * s2) - 0.5 * d * np.log(2 * np.pi * s2)
    return logsumexp(log_n, axis=1) - np.log(k)


def gmm_density(x, theta, *, sigma2) -> np.ndarray:
    r"""The GMM shape density of eq. (5).

    A shape of K landmarks is the equal-weight mixture of K isotropic Gaussians centred on its
    landmarks [1]_:

    .. math::

        p(x \mid \theta) = \frac{1}{K} \sum_{a=1}^{K} \frac{1}{(2\pi\sigma^2)^{d/2}}
        \exp\!\left(-\frac{|x - \phi_a|^2}{2\sigma^2}\right) \qquad \text{(eq. 5)}

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
        :math:`p(x_m \mid \theta)` at each point.

    Raises
    ------
    ValueError
        If ``x`` and ``theta`` differ in dimension, contain non-finite values, or ``sigma2`` is not
        a positive number.

    See Also
    --------
    shapelib.geometry.gmm.gmm_log_density : Its logarithm, stable far from the landmarks.
    shapelib.l2_distance : Closed-form L² distance between two such densities.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    One landmark: the density at its centre is :math:`1/(2\pi\sigma^2)` in the plane.

    >>> import numpy as np
    >>> import shapelib as sl
    >>> p = sl.gmm_density([[0.0, 0.0]], [[0.0, 0.0]], sigma2=0.5)
    >>> bool(np.isclose(p[0], 1 / (2 * np.pi * 0.5)))
    True
    >>> theta = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> sl.gmm_density([[0.0, 0.0], [5.0, 5.0]], theta, sigma2=0.5).round(4)
    array([0.1842, 0.    ])
    """
    return np.exp(gmm_log_density(x, theta, sigma2=sigma2))


def gaussian_overlap(a, b, *, sigma2) -> np.ndarray:
    r"""Matrix of overlaps of two sets of isotropic Gaussians of variance σ².

    .. math::

        G_{ij} = \int \mathcal{N}(x; a_i, \sigma^2 I)\, \mathcal{N}(x; b_j, \sigma^2 I)\, dx
        = (4\pi\sigma^2)^{-d/2} \exp\!\left(-\frac{|a_i - b_j|^2}{4\sigma^2}\right)

    the building block of every closed-form L² quantity of the mixtures of eq. (5) and of the
    α-order metric (eq. 22) [1]_.

    Parameters
    ----------
    a : array_like, shape (M, d)
        Centres of the first Gaussians.
    b : array_like, shape (N, d)
        Centres of the second Gaussians (any number, same dimension).
    sigma2 : float
        σ² > 0 of eq. (5).

    Returns
    -------
    ndarray, shape (M, N)
        The overlaps :math:`G_{ij}`.

    Raises
    ------
    ValueError
        If ``a`` and ``b`` differ in dimension, contain non-finite values, or ``sigma2`` is not
        positive.

    See Also
    --------
    shapelib.geometry.gmm.l2_inner : The mean of these overlaps over landmark pairs.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.gmm import gaussian_overlap
    >>> g = gaussian_overlap([[0.0, 0.0]], [[0.0, 0.0], [1.0, 0.0]], sigma2=0.5)
    >>> g.shape
    (1, 2)
    >>> bool(np.isclose(g[0, 0], 1 / (4 * np.pi * 0.5)))
    True
    """
    a, b = _point_sets(a, b, ("a", "b"))
    return overlap_matrix(a, b, check_sigma2(sigma2))


def overlap_matrix(a: np.ndarray, b: np.ndarray, s2: float) -> np.ndarray:
    """:func:`gaussian_overlap` on checked float arrays ``a`` (M, d), ``b`` (K, d) and σ² (no
    checks: for inner loops, e.g. the point-set objectives of :mod:`shapelib.pointsets.density`)."""
    return np.exp(-_sqdist(a, b) / (4 * s2)) / (4 * np.pi * s2) ** (a.shape[1] / 2)


def l2_inner(u, v, *, sigma2) -> float:
    r"""Closed-form L² inner product of the GMM densities (eq. 5) of two shapes.

    .. math::

        \langle p_u, p_v \rangle = \int p(x \mid u)\, p(x \mid v)\, dx
        = \frac{1}{K_u K_v} \sum_{a, b} G(u_a - v_b)

    with :math:`G` the Gaussian overlap (:func:`gaussian_overlap`) [1]_.

    Parameters
    ----------
    u : array_like, shape (K_u, d)
        Landmarks of the first shape.
    v : array_like, shape (K_v, d)
        Landmarks of the second shape (any number, same dimension).
    sigma2 : float
        σ² > 0 of eq. (5).

    Returns
    -------
    float
        The inner product (positive).

    Raises
    ------
    ValueError
        If the shapes differ in dimension, contain non-finite values, or ``sigma2`` is not
        positive.

    See Also
    --------
    shapelib.l2_distance : The distance these inner products give.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.gmm import l2_inner
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0]])
    >>> round(l2_inner(u, u, sigma2=0.5), 4)
    0.1278
    """
    return float(gaussian_overlap(u, v, sigma2=sigma2).mean())


def l2_distance(u, v, *, sigma2) -> float:
    r"""Closed-form L² distance between the GMM densities (eq. 5) of two shapes.

    .. math::

        \|p_u - p_v\| = \left(\langle p_u, p_u\rangle + \langle p_v, p_v\rangle
        - 2\langle p_u, p_v\rangle\right)^{1/2}

    This is the lower bound certified by :func:`shapelib.geodesic` for the α-order metric: the
    α-order metric of eq. (22) is the pull-back of the L² metric,
    :math:`\dot\theta^\top g^\alpha \dot\theta = \int (\partial_t p)^2 dx`, so every path from ``u``
    to ``v`` is at least this long [1]_. For near shapes the difference is computed without
    cancellation (module docstring), so it keeps its relative accuracy.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence.
    sigma2 : float
        σ² > 0 of eq. (5).

    Returns
    -------
    float
        :math:`\|p_u - p_v\| \ge 0`.

    Raises
    ------
    ValueError
        If the shapes differ in shape, contain non-finite values, or ``sigma2`` is not positive.

    See Also
    --------
    shapelib.alpha_metric : The metric whose geodesic distance this bounds from below.
    shapelib.alpha_bound_matrix : The same bound for every pair of a population.
    shapelib.gmm_density : The densities compared.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> v = u + [[0.0, 0.0], [0.1, 0.0], [0.0, 0.0]]
    >>> sl.l2_distance(u, u, sigma2=0.5)
    0.0
    >>> round(sl.l2_distance(u, v, sigma2=0.5), 5)
    0.01328
    """
    u, v = as_shape_pair(u, v)
    s2 = check_sigma2(sigma2)
    uu, vv = l2_inner(u, u, sigma2=s2), l2_inner(v, v, sigma2=s2)
    sq = uu + vv - 2 * l2_inner(u, v, sigma2=s2)
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
