r"""Extrinsic deformation (paper §III-E, eqs. 23–26): warp the ambient space along a geodesic.

Along a geodesic θ(t) the points x(t) of the ambient space move with a flow (u, v) that keeps
their likelihood under the GMM (eq. 23) constant (eq. 24),

.. math::

    \frac{d \log L}{dt} = \nabla_\theta \log p(x \mid \theta) \cdot \dot\theta
    + \nabla_x \log p(x \mid \theta) \cdot (u, v) = 0, \qquad \text{(eq. 24)}

regularised by the thin-plate (Laplacian) energy (eq. 25); the flow minimises

.. math::

    E(u, v) = \int \lambda \left[(\nabla^2 u)^2 + (\nabla^2 v)^2\right]
    + \left(\frac{d \log L}{dt}\right)^2 dx. \qquad \text{(eq. 26)}

With responsibilities :math:`w_a(x) = N_a(x) / (K p(x))`:
:math:`\nabla_x \log p = -\sum_a w_a (x - \phi_a)/\sigma^2` and
:math:`\nabla_{\phi_a} \log p = w_a (x - \phi_a)/\sigma^2`. We discretise E on a regular grid
(5-point Laplacian with reflecting borders), solve the sparse normal equations for each segment
of the geodesic (landmark velocities constant on a segment, shape at its midpoint) and move the
points by the interpolated flow. As the paper notes, the result is not guaranteed to be a
diffeomorphism.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import RegularGridInterpolator
from scipy.sparse.linalg import spsolve

from .._validate import as_shape, check_positive
from ..solver.geodesic import GeodesicResult

__all__ = ["likelihood_flow", "extrinsic_warp"]


def _axes(points, size, margin):
    lo, hi = points.min(0) - margin, points.max(0) + margin
    return [np.linspace(lo[i], hi[i], size) for i in range(2)]


def _laplacian(nx, ny, hx, hy):
    def d2(n, h):  # second difference with reflecting (Neumann) ends: constants have zero Laplacian
        main = -2 * np.ones(n)
        main[[0, -1]] = -1
        return sp.diags([np.ones(n - 1), main, np.ones(n - 1)], [-1, 0, 1]) / h**2

    return sp.kron(d2(nx, hx), sp.identity(ny)) + sp.kron(sp.identity(nx), d2(ny, hy))


def likelihood_flow(theta, velocity, *, sigma2, axes, lam: float):
    r"""The flow (u, v) of eq. (26) on a grid for a shape moving with given landmark velocities.

    Minimises, over the grid values of the flow, the discretised energy of [1]_

    .. math::

        E(u, v) = \sum_{\text{nodes}} \lambda \left[(\nabla^2 u)^2 + (\nabla^2 v)^2\right]
        + \left(\nabla_\theta \log p \cdot \dot\theta + \nabla_x \log p \cdot (u, v)\right)^2
        \qquad \text{(eqs. 24–26)}

    by its sparse normal equations (5-point Laplacian with reflecting borders).

    Parameters
    ----------
    theta : ndarray, shape (K, 2)
        The shape.
    velocity : ndarray, shape (K, 2)
        Its landmark velocities.
    sigma2 : float
        σ² of eq. (5).
    axes : sequence of two ndarray
        Grid coordinates along x and y (regular).
    lam : float, keyword-only
        λ of eq. (26).

    Returns
    -------
    ndarray, shape (nx, ny, 2)
        The flow (u, v) at the grid nodes.

    See Also
    --------
    shapelib.extrinsic_warp : Moves points with it along a geodesic.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    A translation of every landmark carries the ambient space with it:

    >>> import numpy as np
    >>> from shapelib.comparison.warp import likelihood_flow
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> axes = [np.linspace(-1.0, 2.0, 12)] * 2
    >>> flow = likelihood_flow(u, np.tile([1.0, 0.0], (4, 1)), sigma2=0.5, axes=axes, lam=1e-3)
    >>> flow.shape, bool(np.allclose(flow[6, 6], [1.0, 0.0]))
    ((12, 12, 2), True)
    """
    xx, yy = np.meshgrid(axes[0], axes[1], indexing="ij")
    nodes = np.column_stack([xx.ravel(), yy.ravel()])
    r = nodes[:, None, :] - theta[None]  # (N, K, 2)
    logn = -np.einsum("nki,nki->nk", r, r) / (2 * sigma2)
    logn -= logn.max(axis=1, keepdims=True)
    w = np.exp(logn)
    w /= w.sum(axis=1, keepdims=True)  # responsibilities N_a / (K p)
    a = -np.einsum("nk,nki->ni", w, r) / sigma2  # ∇_x log p
    b = np.einsum("nk,nki,ki->n", w, r, velocity) / sigma2  # ∇_θ log p · θ̇
    nx, ny = len(axes[0]), len(axes[1])
    lap = _laplacian(nx, ny, axes[0][1] - axes[0][0], axes[1][1] - axes[1][0])
    reg = lam * (lap.T @ lap)
    data = sp.bmat([[sp.diags(a[:, 0] ** 2), sp.diags(a[:, 0] * a[:, 1])],
                    [sp.diags(a[:, 0] * a[:, 1]), sp.diags(a[:, 1] ** 2)]])
    system = (sp.block_diag([reg, reg]) + data).tocsc()
    rhs = -np.concatenate([a[:, 0] * b, a[:, 1] * b])
    f = spsolve(system, rhs)
    return np.stack([f[: nx * ny].reshape(nx, ny), f[nx * ny:].reshape(nx, ny)], axis=-1)


def extrinsic_warp(points, geodesic_result: GeodesicResult, *, lam: float = 1e-3, grid_size: int = 64,
                   margin: float | None = None) -> np.ndarray:
    r"""Move ``points`` along the likelihood-preserving flow of a geodesic (§III-E, eqs. 23–26).

    On each segment of the geodesic the flow :math:`(u, v)` minimising eq. (26) of [1]_,

    .. math::

        E(u, v) = \int \lambda \left[(\nabla^2 u)^2 + (\nabla^2 v)^2\right]
        + \left(\frac{d \log L}{dt}\right)^2 dx,

    is solved on a grid around the shapes and the points are moved by it (midpoint rule in time).

    Parameters
    ----------
    points : array_like, shape (M, 2)
        Ambient (extrinsic) points, e.g. a dense outline around the landmarks.
    geodesic_result : GeodesicResult
        From :func:`shapelib.geodesic` (uses its path and σ²).
    lam : float
        λ of eq. (26), weight of the thin-plate regulariser.
    grid_size : int
        Grid points per axis for the flow.
    margin : float, optional
        Grid margin around the path and the points (default 4σ).

    Returns
    -------
    ndarray, shape (n_steps + 1, M, 2)
        The points at every time of the path.

    Raises
    ------
    ValueError
        For points or a path not in 2-D, a non-positive ``lam``, or a result without σ² (not a GMM
        geodesic).

    See Also
    --------
    shapelib.geodesic : The geodesic that drives it.
    shapelib.diffeomorphism_warp : The landmark-diffeomorphism counterpart (Fig. 9).

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> r = sl.geodesic(u, v, sigma2=0.5, n_steps=4)
    >>> sl.extrinsic_warp([[0.5, 0.5], [0.5, -0.2]], r, grid_size=24).shape
    (5, 2, 2)
    """
    x = as_shape(points, name="points").copy()
    if x.shape[1] != 2 or geodesic_result.path.shape[2] != 2:
        raise ValueError(f"extrinsic_warp works in 2-D; got points {x.shape} and path {geodesic_result.path.shape}")
    lam = check_positive(lam, name="lam")
    s2 = geodesic_result.sigma2
    if s2 is None:
        raise ValueError("extrinsic_warp needs a GMM geodesic (alpha or fisher_rao) with sigma2")
    path = geodesic_result.path
    n = len(path) - 1
    margin = 4 * np.sqrt(s2) if margin is None else margin
    out = [x.copy()]
    for t in range(n):
        axes = _axes(np.vstack([path[t], path[t + 1], x]), int(grid_size), margin)
        flow = likelihood_flow(0.5 * (path[t] + path[t + 1]), n * (path[t + 1] - path[t]), sigma2=s2, axes=axes, lam=lam)
        interp = [RegularGridInterpolator(axes, flow[..., i]) for i in range(2)]
        mid = x + 0.5 / n * np.column_stack([f(x) for f in interp])  # midpoint rule in time
        mid = np.clip(mid, [axes[0][0], axes[1][0]], [axes[0][-1], axes[1][-1]])
        x = x + (1.0 / n) * np.column_stack([f(mid) for f in interp])
        out.append(x.copy())
    return np.stack(out)
