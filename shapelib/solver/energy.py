r"""The discrete path energy (eq. 8 on piecewise-linear paths), its gradient and Hessian, and
the length of a path — for any :class:`~shapelib.PathMetric`.

On each of the ``n`` segments the landmarks move at constant velocity and the energy is
integrated in time with a 3-point Gauss–Legendre rule:

.. math::

    E_n = \sum_{t=0}^{n-1} \frac{1}{n} \sum_{k=1}^{3} w_k\, V_t^\top g(\theta_t + \tau_k \Delta_t)\, V_t,
    \qquad \Delta_t = \theta_{t+1} - \theta_t, \quad V_t = n \Delta_t.

The Hessian over the interior points is block tridiagonal: ``(diag, upper)`` with blocks
``H[t, t]`` (n-1, q, q) and ``H[t, t+1]`` (n-2, q, q), q = K d.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .path_metric import GL3_NODES, GL3_WEIGHTS, GL5_NODES, GL5_WEIGHTS

__all__ = ["segment_nodes", "path_energy", "path_hessian_weights", "exact_path_hessian", "metric_length"]


def segment_nodes(path, nodes):
    r"""Positions at the quadrature nodes of every segment and the segments' velocities.

    .. math::

        \theta_{t,k} = \theta_t + \tau_k (\theta_{t+1} - \theta_t), \qquad V_t = n (\theta_{t+1} - \theta_t),

    the points where the integrand of eq. (8) of [1]_ is evaluated.

    Parameters
    ----------
    path : ndarray, shape (n + 1, K, d)
        The path.
    nodes : ndarray, shape (q,)
        Quadrature nodes :math:`\tau_k` in [0, 1].

    Returns
    -------
    theta : ndarray, shape (n, q, K, d)
        Positions.
    velocity : ndarray, shape (n, K, d)
        Velocities.

    See Also
    --------
    shapelib.solver.path_metric.gauss_legendre01 : The nodes.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.energy import segment_nodes
    >>> path = np.array([[[0.0, 0.0]], [[1.0, 0.0]], [[1.0, 2.0]]])
    >>> theta, vel = segment_nodes(path, np.array([0.5]))
    >>> theta[:, 0, 0], vel[:, 0]
    (array([[0.5, 0. ],
           [1. , 1. ]]), array([[2., 0.],
           [0., 4.]]))
    """
    n = len(path) - 1
    seg = np.diff(path, axis=0)
    return path[:-1, None] + nodes[None, :, None, None] * seg[:, None], n * seg


def path_energy(model, path, *, gradient=True, hessian=None):
    r"""Energy of the piecewise-linear path, its gradient (interior points) and a Hessian.

    The discrete energy of eq. (8) of [1]_ (module docstring),

    .. math::

        E_n = \sum_{t} \frac{1}{n} \sum_{k} w_k\, Q(\theta_t + \tau_k \Delta_t,\ V_t),
        \qquad Q(\theta, v) = v^\top g(\theta)\, v,

    with its gradient with respect to the interior points (the ends are fixed; no Christoffel
    symbols are needed, cf. eqs. 10–11).

    Parameters
    ----------
    model : PathMetric
        The metric.
    path : ndarray, shape (n + 1, K, d)
        The path.
    gradient : bool, default True
        Also return the gradient (else only the energy).
    hessian : {None, "model", "exact"}
        ``"model"``: the metric-weighted time Laplacian (Gauss–Newton-like); ``"exact"``: needs
        ``model.has_exact_hessian``.

    Returns
    -------
    energy : float
        :math:`E_n`.
    grad : ndarray, shape (n - 1, K, d) or None
        Gradient at the interior points.
    blocks : tuple or None
        ``(diag, upper)``: blocks ``H[t, t]`` (n-1, q, q) and ``H[t, t+1]`` (n-2, q, q), q = K d.

    Raises
    ------
    ValueError
        For an unknown ``hessian``.

    See Also
    --------
    shapelib.geodesic : Minimises it.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    A single landmark under the α-order metric: the energy of a straight path is
    :math:`|\Delta|^2 g`, with :math:`g = 1 / (2\sigma^2 (4\pi\sigma^2))`.

    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.solver.energy import path_energy
    >>> path = np.array([[[0.0, 0.0]], [[0.5, 0.0]], [[1.0, 0.0]]])
    >>> e, grad, _ = path_energy(sl.path_metric("alpha", 0.5), path)
    >>> bool(np.isclose(e, 1.0 / (2 * 0.5 * 4 * np.pi * 0.5))), bool(np.allclose(grad, 0.0))
    (True, True)
    """
    n = len(path) - 1
    k, d = path.shape[1:]
    nq = len(GL3_NODES)
    ctx = model.prepare(path)
    node_hessian, blocks = None, None
    if hessian == "exact" and gradient and model.has_path_pass:  # α: one compiled pass
        q, dq_t, dq_v, blocks = model.path_grad_hessian(path, ctx)
    else:
        theta, vel = segment_nodes(path, GL3_NODES)
        flat_t = theta.reshape(-1, k, d)
        flat_v = np.repeat(vel, nq, axis=0)
        if not gradient:
            q = model.qform(flat_t, flat_v, ctx).reshape(n, nq)
            return float(np.sum(q * GL3_WEIGHTS) / n), None, None
        if hessian == "exact":  # one call, which may share work between the two
            q, dq_t, dq_v, node_hessian = model.qform_grad_hessian(flat_t, flat_v, ctx)
        else:
            q, dq_t, dq_v = model.qform_grad(flat_t, flat_v, ctx)
    energy = float(np.sum(q.reshape(n, nq) * GL3_WEIGHTS) / n)
    w = GL3_WEIGHTS[None, :, None, None]
    tau = GL3_NODES[None, :, None, None]
    dq_t = dq_t.reshape(n, nq, k, d) * w
    dq_v = dq_v.reshape(n, nq, k, d) * w
    # θ_t enters segment t through the position (weight 1 − τ) and the velocity (−n);
    # θ_{t+1} through the position (τ) and the velocity (+n)
    g_left = (np.sum((1 - tau) * dq_t, axis=1) - n * np.sum(dq_v, axis=1)) / n
    g_right = (np.sum(tau * dq_t, axis=1) + n * np.sum(dq_v, axis=1)) / n
    grad = g_left[1:] + g_right[:-1]
    if hessian == "model":
        gbar = model.tensors(path[:-1] + 0.5 * np.diff(path, axis=0), ctx)
        blocks = (2 * n * (gbar[:-1] + gbar[1:]), -2 * n * gbar[1:-1])
    elif hessian == "exact":
        if blocks is None:
            blocks = exact_path_hessian(model, flat_t, flat_v, ctx, n, node_hessian)
    elif hessian is not None:
        raise ValueError(f"unknown hessian {hessian!r}")
    return energy, grad, blocks


@lru_cache(maxsize=64)
def path_hessian_weights(n):
    r"""Weights of the node Hessians in the segment blocks of the exact path Hessian.

    ``coef[x, k] = (k_a, k_b, k_bᵀ, k_c)·w_k/n``: the weights of
    :math:`(Q_{\theta\theta}, Q_{\theta v}, Q_{\theta v}^\top, Q_{vv})` at Gauss–Legendre node
    :math:`k` in the segment blocks x = (t, t), (t, t+1), (t+1, t+1). On segment t,

    .. math::

        \frac{\partial}{\partial \theta_t} = (1 - \tau)\, \partial_\theta - n\, \partial_v, \qquad
        \frac{\partial}{\partial \theta_{t+1}} = \tau\, \partial_\theta + n\, \partial_v,

    the chain rule through the discrete energy of eq. (8) of [1]_.

    Parameters
    ----------
    n : int
        Number of segments.

    Returns
    -------
    ndarray, shape (3, 3, 4)
        Read-only weights (cached per ``n``).

    See Also
    --------
    shapelib.solver.energy.exact_path_hessian : Their use.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.solver.energy import path_hessian_weights
    >>> path_hessian_weights(4).shape
    (3, 3, 4)
    """
    tau, w = GL3_NODES, GL3_WEIGHTS / n
    coef = np.stack([
        np.stack([(1 - tau) ** 2, -(1 - tau) * n, -(1 - tau) * n, np.full_like(tau, n * n)], axis=1),
        np.stack([(1 - tau) * tau, (1 - tau) * n, -tau * n, np.full_like(tau, -n * n)], axis=1),
        np.stack([tau**2, tau * n, tau * n, np.full_like(tau, n * n)], axis=1),
    ]) * w[None, :, None]
    coef.setflags(write=False)
    return coef


def exact_path_hessian(model, theta, vel, ctx, n, node_hessian=None):
    r"""Exact Hessian of the piecewise-linear path energy from the Hessian of ``Q = vᵀg(θ)v``.

    The segment blocks of the energy of eq. (8) of [1]_ are combined with the weights of
    :func:`~shapelib.solver.energy.path_hessian_weights`,

    .. math::

        H_{t,t} = \sum_k c_k^{(t,t)} \cdot (Q_{\theta\theta}, Q_{\theta v}, Q_{\theta v}^\top, Q_{vv})_k,

    summed over the two segments that meet at each interior point (models with a compiled
    ``path_grad_hessian`` do the same in one pass).

    Parameters
    ----------
    model : PathMetric
        The metric (with ``has_exact_hessian``).
    theta, vel : ndarray, shape (n · 3, K, d)
        Positions and velocities at the segments' Gauss–Legendre nodes
        (:func:`~shapelib.solver.energy.segment_nodes`, flattened).
    ctx : object
        ``model.prepare(path)``.
    n : int
        Number of segments.
    node_hessian : tuple, optional
        ``model.qform_hessian(theta, vel, ctx)`` if already computed.

    Returns
    -------
    diag : ndarray, shape (n - 1, q, q)
        Blocks ``H[t, t]``.
    upper : ndarray, shape (n - 2, q, q)
        Blocks ``H[t, t+1]``.

    See Also
    --------
    shapelib.solver.energy.path_energy : Its usual caller (``hessian="exact"``).

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.solver.energy import exact_path_hessian, segment_nodes
    >>> from shapelib.solver.path_metric import GL3_NODES
    >>> path = np.array([[[0.0, 0.0]], [[0.4, 0.1]], [[0.7, 0.0]], [[1.0, 0.0]]])
    >>> theta, vel = segment_nodes(path, GL3_NODES)
    >>> model = sl.path_metric("alpha", 0.5)
    >>> diag, upper = exact_path_hessian(model, theta.reshape(-1, 1, 2), np.repeat(vel, 3, axis=0), None, 3)
    >>> diag.shape, upper.shape
    ((2, 2, 2), (1, 2, 2))
    """
    if node_hessian is None:
        node_hessian = model.qform_hessian(theta, vel, ctx)
    a, b, c = (x.reshape(n, len(GL3_NODES), *x.shape[1:]) for x in node_hessian)
    bt = b.transpose(0, 1, 3, 2)
    coef = path_hessian_weights(n)
    h00, h01, h11 = (np.einsum("k,tkij->tij", cx[:, 0], a) + np.einsum("k,tkij->tij", cx[:, 1], b)
                     + np.einsum("k,tkij->tij", cx[:, 2], bt) + np.einsum("k,tkij->tij", cx[:, 3], c) for cx in coef)
    return h11[:-1] + h00[1:], h01[1:-1]



def metric_length(model, path):
    r"""Riemannian length of the piecewise-linear path, 5-point Gauss–Legendre on each segment.

    .. math::

        L = \int_0^1 \sqrt{\dot\theta^\top g(\theta)\, \dot\theta}\, dt
        \approx \sum_t \frac{1}{n} \sum_{k=1}^{5} w_k \sqrt{Q(\theta_t + \tau_k \Delta_t,\ V_t)},

    the length whose square eq. (8) of [1]_ integrates; an upper bound on the geodesic distance
    between the ends.

    Parameters
    ----------
    model : PathMetric
        The metric.
    path : ndarray, shape (n + 1, K, d)
        The path.

    Returns
    -------
    float
        :math:`L`.

    See Also
    --------
    shapelib.path_length : The checked entry point.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.solver.energy import metric_length
    >>> path = np.array([[[0.0, 0.0]], [[1.0, 0.0]]])
    >>> bool(np.isclose(metric_length(sl.path_metric("alpha", 0.5), path), 1 / np.sqrt(2 * 0.5 * 4 * np.pi * 0.5)))
    True
    """
    n = len(path) - 1
    k, d = path.shape[1:]
    theta, vel = segment_nodes(path, GL5_NODES)
    q = model.qform(theta.reshape(-1, k, d), np.repeat(vel, len(GL5_NODES), axis=0), model.prepare(path))
    return float(np.sum(np.sqrt(np.maximum(q, 0.0)).reshape(n, -1) * GL5_WEIGHTS) / n)
