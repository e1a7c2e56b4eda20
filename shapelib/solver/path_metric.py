r"""The metric a path solver needs: a quadratic form on landmark velocities, with its derivatives,
metric tensors and a closed-form lower bound on distances.

.. math::

    Q(\theta, v) = v^\top g(\theta)\, v

:class:`PathMetric` is the protocol every metric of the path solver implements — the α-order
(eq. 22, :class:`AlphaPathMetric`) and Fisher–Rao (eq. 6, :class:`FisherRaoPathMetric`) information
metrics and the landmark-diffeomorphism baseline (:mod:`shapelib.comparison.diffeomorphism`). The
solver (:func:`shapelib.solver.minimise.minimise_path`), the certified bracket and the intrinsic
statistics use metrics only through it.
"""

from __future__ import annotations

import numpy as np

from .._validate import check_positive
from ..geometry import _kernels
from ..geometry.gmm import l2_distance
from ..geometry.metrics import (
    alpha_qform_hessian,
    alpha_tensor_batch,
    fr_qform_compiled,
    fr_qform_grad_compiled,
    fr_qform_grad_hessian_compiled,
    fr_qform_hessian_compiled,
    fr_tensor_batch,
    psi_coef,
)
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING, make_grid

__all__ = ["PathMetric", "AlphaPathMetric", "FisherRaoPathMetric", "path_metric", "METRICS",
           "GL3_NODES", "GL3_WEIGHTS", "GL5_NODES", "GL5_WEIGHTS", "gauss_legendre01"]

#: the information metrics of the paper with a path solver
METRICS = ("alpha", "fisher_rao")


def gauss_legendre01(q: int):
    r"""Nodes and weights of the ``q``-point Gauss–Legendre rule on [0, 1].

    .. math::

        \int_0^1 f(\tau)\, d\tau \approx \sum_{k=1}^{q} w_k f(\tau_k),

    exact for polynomials of degree :math:`2q - 1`: the time integral of the path energy (eq. 8 of
    [1]_) on each segment uses ``q = 3``, the reported length ``q = 5``.

    Parameters
    ----------
    q : int
        Number of nodes.

    Returns
    -------
    nodes : ndarray, shape (q,)
        :math:`\tau_k \in (0, 1)`.
    weights : ndarray, shape (q,)
        :math:`w_k`, summing to 1.

    See Also
    --------
    numpy.polynomial.legendre.leggauss : The rule on [−1, 1].

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.solver.path_metric import gauss_legendre01
    >>> tau, w = gauss_legendre01(3)
    >>> round(float(w.sum()), 12), round(float(w @ tau ** 5), 12)
    (1.0, 0.166666666667)
    """
    x, w = np.polynomial.legendre.leggauss(q)
    return 0.5 * (x + 1.0), 0.5 * w


#: 3-point Gauss–Legendre rule on [0, 1]: the path energy's time integral on each segment
GL3_NODES, GL3_WEIGHTS = gauss_legendre01(3)
#: 5-point rule: the reported length
GL5_NODES, GL5_WEIGHTS = gauss_legendre01(5)


class PathMetric:
    r"""A Riemannian metric on landmark configurations, as the path solver uses it.

    The solver minimises the path energy of eq. (8) of [1]_ through the quadratic form
    :math:`Q(\theta, v) = v^\top g(\theta) v` and its derivatives; the closed-form lower bound
    certifies the distance. Batched over nodes: ``theta`` and ``vel`` are ``(m, K, d)`` arrays of
    positions and velocities. ``ctx`` is whatever :meth:`prepare` returns for the points of a path
    (the Fisher–Rao quadrature grid; ``None`` for closed-form metrics) and is passed back unchanged.

    Required: :attr:`name`, :meth:`prepare`, :meth:`qform`, :meth:`qform_grad`, :meth:`tensors`,
    :meth:`lower_bound`, :meth:`settings`. Exact Newton steps need :meth:`qform_hessian`
    (declare it with ``has_exact_hessian = True``); :meth:`qform_grad_hessian` and
    :meth:`path_grad_hessian` are optional faster routes to the same numbers.

    Attributes
    ----------
    name : str
        Short name used in results and messages.
    has_exact_hessian : bool
        Whether :meth:`qform_hessian` is implemented (exact Newton steps and the certificate).
    has_path_pass : bool
        Whether :meth:`path_grad_hessian` is implemented (one pass over the whole path).

    See Also
    --------
    shapelib.AlphaPathMetric, shapelib.FisherRaoPathMetric
    shapelib.path_metric : The metric of a name.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    Every path metric answers the same questions:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> metric = sl.path_metric("alpha", 0.5)
    >>> theta = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
    >>> vel = np.array([[[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]]])
    >>> q = metric.qform(theta, vel, metric.prepare(theta))
    >>> bool(np.isclose(q[0], sl.alpha_quadratic_form(theta[0], vel[0], sigma2=0.5)))
    True
    """

    #: short name used in results and messages
    name: str = "path metric"
    #: whether :meth:`qform_hessian` is implemented (exact Newton steps and the certificate)
    has_exact_hessian: bool = False
    #: whether :meth:`path_grad_hessian` is implemented (one pass over the whole path)
    has_path_pass: bool = False

    def prepare(self, points):
        """Context for a path through ``points`` (n, K, d); ``None`` by default."""
        return None

    def qform(self, theta, vel, ctx):  # pragma: no cover - interface
        """``Q = vᵀ g(θ) v`` at every node, shape (m,)."""
        raise NotImplementedError

    def qform_grad(self, theta, vel, ctx):  # pragma: no cover - interface
        """``(Q, ∂Q/∂θ, ∂Q/∂v)``, shapes (m,), (m, K, d), (m, K, d)."""
        raise NotImplementedError

    def tensors(self, theta, ctx):  # pragma: no cover - interface
        """Metric tensors ``g(θ)`` at every node, shape (m, K d, K d)."""
        raise NotImplementedError

    def qform_hessian(self, theta, vel, ctx):  # pragma: no cover - interface
        """Second derivatives ``(Q_θθ, Q_θv, Q_vv)``, each (m, K d, K d)."""
        raise NotImplementedError

    def qform_grad_hessian(self, theta, vel, ctx):
        """``qform_grad`` and ``qform_hessian`` together (override to share work)."""
        return (*self.qform_grad(theta, vel, ctx), self.qform_hessian(theta, vel, ctx))

    def lower_bound(self, u, v) -> float:  # pragma: no cover - interface
        """A closed-form lower bound on the geodesic distance between ``u`` and ``v``."""
        raise NotImplementedError

    def settings(self) -> dict:
        """The metric's options, recorded in a result's log."""
        return {}


class AlphaPathMetric(PathMetric):
    r"""The α-order entropy metric (eq. 22) as the path solver sees it.

    Closed form, compiled kernels (``shapelib.geometry._kernels``), exact Hessian in one compiled
    pass over the path; lower bound :math:`\|p_u - p_v\|` (:func:`shapelib.l2_distance`) [1]_:

    .. math::

        Q(\theta, v) = v^\top g^\alpha(\theta)\, v = \int (\partial_t p)^2\, dx, \qquad
        d_\alpha(u, v) \ge \|p_u - p_v\|_{L^2}.

    Parameters
    ----------
    s2 : float
        σ² > 0 of eq. (5) (not checked: :func:`shapelib.path_metric` is the checked door).

    Attributes
    ----------
    s2 : float
        σ².
    name : str
        ``"alpha"``.

    See Also
    --------
    shapelib.alpha_metric : The tensor of eq. (22).
    shapelib.PathMetric : The protocol.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> metric = sl.AlphaPathMetric(0.5)
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> bool(np.isclose(metric.lower_bound(u, u + 0.1), sl.l2_distance(u, u + 0.1, sigma2=0.5)))
    True
    """

    name = "alpha"
    has_exact_hessian = True
    has_path_pass = True

    def __init__(self, s2: float):
        self.s2 = s2

    def prepare(self, points):
        return None

    def qform_grad(self, theta, vel, ctx):
        return _kernels.alpha_qform_grad(np.ascontiguousarray(theta), np.ascontiguousarray(vel), self.s2)

    def qform(self, theta, vel, ctx):
        return _kernels.alpha_qform(np.ascontiguousarray(theta), np.ascontiguousarray(vel), self.s2)

    def tensors(self, theta, ctx):
        return alpha_tensor_batch(theta, self.s2)

    def qform_hessian(self, theta, vel, ctx):
        return alpha_qform_hessian(theta, vel, self.s2)

    def path_grad_hessian(self, path, ctx):
        """``qform_grad`` at the segments' Gauss–Legendre nodes and the exact path Hessian
        (:func:`shapelib.solver.energy.path_energy`), in one compiled pass
        (``shapelib.geometry._kernels.alpha_path_grad_hessian``).
        """
        n = len(path) - 1
        q = path[0].size
        tau, w = GL3_NODES, GL3_WEIGHTS
        tw = np.stack([w * (1 - tau) ** 2 / n, w * (1 - tau) * tau / n, w * tau**2 / n, w * (1 - tau), w * tau, w * n])
        qf, d_theta, d_vel, diag, upper = _kernels.alpha_path_grad_hessian(
            np.ascontiguousarray(path), self.s2, tau, tw, np.array([1.0, -1.0, 1.0]))
        return qf, d_theta, d_vel, (diag.reshape(-1, q, q), upper.reshape(-1, q, q))

    def lower_bound(self, u, v):
        return l2_distance(u, v, sigma2=self.s2)

    def settings(self):
        return {}


class FisherRaoPathMetric(PathMetric):
    r"""The Fisher–Rao metric (eq. 6) as the path solver sees it.

    Integrals by quadrature on one grid covering the path (:mod:`shapelib.geometry.quadrature`),
    exact Hessian by the same quadrature; the lower bound is the great circle of
    :math:`\psi = 2\sqrt{p}` on the sphere of radius 2 [1]_:

    .. math::

        Q(\theta, v) = \int \frac{(\partial_t p)^2}{p}\, dx, \qquad
        d_{FR}(u, v) \ge 2 \arccos \int \sqrt{p_u\, p_v}\, dx.

    Parameters
    ----------
    s2 : float
        σ² > 0 of eq. (5).
    spacing : float
        Quadrature step in units of σ.
    margin : float
        Quadrature margin in units of σ.

    Attributes
    ----------
    s2, spacing, margin : float
        The parameters.
    name : str
        ``"fisher_rao"``.

    See Also
    --------
    shapelib.fisher_rao_metric : The tensor of eq. (6).
    shapelib.fisher_rao_lower_bound : The checked bound.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> metric = sl.path_metric("fisher_rao", 0.5)
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> metric.settings()
    {'grid_spacing': 0.35, 'grid_margin': 6.0}
    >>> round(metric.lower_bound(u, u), 12)
    0.0
    """

    name = "fisher_rao"
    has_exact_hessian = True

    def __init__(self, s2: float, spacing: float, margin: float):
        self.s2, self.spacing, self.margin = s2, spacing, margin

    def prepare(self, points):
        """One quadrature grid covering every shape the path passes through."""
        return make_grid(points, sigma2=self.s2, grid_spacing=self.spacing, grid_margin=self.margin)

    def qform_grad(self, theta, vel, grid):
        return fr_qform_grad_compiled(theta, vel, self.s2, grid)

    def qform(self, theta, vel, grid):
        return fr_qform_compiled(theta, vel, self.s2, grid)

    def tensors(self, theta, grid):
        return fr_tensor_batch(theta, self.s2, grid)

    def qform_hessian(self, theta, vel, grid):
        return fr_qform_hessian_compiled(theta, vel, self.s2, grid)

    def qform_grad_hessian(self, theta, vel, grid):
        return fr_qform_grad_hessian_compiled(theta, vel, self.s2, grid)

    def lower_bound(self, u, v):
        grid = self.prepare(np.stack([u, v]))
        pu, _ = psi_coef(u, self.s2, grid)
        pv, _ = psi_coef(v, self.s2, grid)
        c = np.sqrt(grid.integrate((pu - pv) ** 2))
        # great circle on the sphere of radius 2: 4 arcsin(c/4) = 2 arccos ∫√(p_u p_v)
        return float(4.0 * np.arcsin(min(c / 4.0, 1.0)))

    def settings(self):
        return {"grid_spacing": self.spacing, "grid_margin": self.margin}


def path_metric(metric: str, sigma2: float, *, grid_spacing: float = DEFAULT_SPACING,
                grid_margin: float = DEFAULT_MARGIN) -> PathMetric:
    r"""The :class:`~shapelib.PathMetric` of an information metric by name.

    ``"alpha"``: the α-order entropy metric of eq. (22); ``"fisher_rao"``: the Fisher–Rao metric
    of eq. (6) [1]_, integrated on a grid of step ``grid_spacing · σ`` and margin
    ``grid_margin · σ``:

    .. math::

        g^\alpha_{ij} = \int \partial_i p\, \partial_j p\, dx, \qquad
        g^{FR}_{ij} = \int \frac{\partial_i p\, \partial_j p}{p}\, dx.

    Parameters
    ----------
    metric : {"alpha", "fisher_rao"}
        The metric.
    sigma2 : float
        σ² > 0 of eq. (5) (checked by the caller).
    grid_spacing : float, default 0.35
        Fisher–Rao quadrature step in units of σ.
    grid_margin : float, default 6.0
        Fisher–Rao quadrature margin in units of σ.

    Returns
    -------
    PathMetric
        :class:`~shapelib.AlphaPathMetric` or
        :class:`~shapelib.FisherRaoPathMetric`.

    Raises
    ------
    ValueError
        For an unknown ``metric`` or a non-positive grid option.

    See Also
    --------
    shapelib.geodesic : Geodesics under these metrics.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import shapelib as sl
    >>> sl.path_metric("alpha", 0.5).name, sl.path_metric("fisher_rao", 0.5).name
    ('alpha', 'fisher_rao')
    """
    if metric == "alpha":
        return AlphaPathMetric(sigma2)
    if metric == "fisher_rao":
        return FisherRaoPathMetric(sigma2, check_positive(grid_spacing, name="grid_spacing"),
                                   check_positive(grid_margin, name="grid_margin"))
    raise ValueError(f"metric must be one of {METRICS}; got {metric!r}")
