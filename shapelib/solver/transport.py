"""Parallel transport of a tangent vector along the geodesic between two shapes, by the pole ladder
on the discrete log and exp maps.

Why
    A deformation is a tangent vector at the shape it starts from. To apply the deformation seen
    on one shape (a specimen's growth, the difference between two group means) to another shape,
    the vector has to be moved to the other shape's tangent space without turning it: parallel
    transport along the geodesic between the two.

Pole ladder [1]_ [2]_
    With ``m`` the midpoint of the geodesic from ``a`` to ``b``, the vector ``v`` at ``a`` is carried
    to ``b`` by a reflection through ``m``:

    .. math::

        p = \\exp_a(v), \\qquad q = \\exp_m(-\\log_m p), \\qquad
        \\Pi_a^b\\, v = -\\log_b q.

    The rung is exact in a symmetric space (and so in flat space) and third-order accurate in
    general [2]_; ``n_rungs`` rungs along the geodesic's nodes make it converge. ``exp`` and
    ``log`` are the discrete maps of :mod:`shapelib.solver.logexp` (Rumpf and Wirth's discrete
    geodesic calculus [3]_), so the transport is that of the discrete geodesic.

References
----------
.. [1] M. Lorenzi and X. Pennec, "Efficient parallel transport of deformations in time series of
   images: from Schild's to pole ladder", *Journal of Mathematical Imaging and Vision* 50, 5–17, 2014.
.. [2] X. Pennec, "Parallel transport with pole ladder: a third order scheme in affine connection
   spaces which is exact in affine symmetric spaces", arXiv:1805.11436, 2018.
.. [3] M. Rumpf and B. Wirth, "Variational time discretization of geodesic calculus", *IMA Journal of
   Numerical Analysis* 35(3), 1011–1046, 2015.
"""

from __future__ import annotations

import numpy as np

from .._validate import as_shape_pair, check_positive_int
from .logexp import _check_entry, exp_map, log_map

__all__ = ["parallel_transport"]


#: rungs of the ladder and time steps of its maps: the transported vector's error falls with ``n_steps``
#: (the discrete maps' first-order error) and changes little beyond a few rungs
N_RUNGS = 4
N_STEPS = 8


def parallel_transport(base, vector, end, *, metric: str = "alpha", sigma2, n_rungs: int = N_RUNGS,
                       n_steps: int = N_STEPS, tol: float = 1e-8, max_iter: int = 500) -> np.ndarray:
    r"""Carry the tangent vector ``vector`` at ``base`` to ``end`` along the geodesic between them.

    The pole ladder of [1]_ (module docstring): along the discrete geodesic ``base = θ₀, …, θ_N = end``
    cut into ``n_rungs`` rungs ``a → b`` with midpoints ``m``, each rung maps ``v`` to

    .. math::

        \Pi_a^b\, v = -\log_b \exp_m\!\big(-\log_m \exp_a(v)\big).

    Parameters
    ----------
    base, end : array_like (K, d)
        The shapes the geodesic joins (landmarks in correspondence, d = 2 or 3).
    vector : array_like (K, d)
        A tangent vector at ``base`` (e.g. a :func:`shapelib.log_map` from ``base``).
    metric : {"alpha", "fisher_rao"}
    sigma2 : float
        σ² of eq. (5) of the paper.
    n_rungs : int
        Rungs of the ladder along the geodesic (each costs two log and two exp maps).
    n_steps : int
        Time steps of each log and exp map; the geodesic from ``base`` to ``end`` has
        ``2 ⌈n_steps/2⌉ n_rungs`` steps, so that each rung's midpoint is one of its nodes. The
        discrete maps' error is of first order in ``1/n_steps`` and dominates the ladder's: raise
        ``n_steps`` for a more accurate transport (the cost grows about linearly).
    tol, max_iter : float, int
        The log maps' path solver (:func:`shapelib.log_map`).

    Returns
    -------
    ndarray (K, d)
        The transported vector, a tangent vector at ``end``.

    Raises
    ------
    ValueError
        For shapes or a vector that do not match or are not finite, an unknown ``metric`` or a bad
        option.

    Warns
    -----
    GeodesicWarning
        When a log map's path solver or an exp map's Newton solve stops before its tolerance.

    See Also
    --------
    shapelib.log_map, shapelib.exp_map : The maps the ladder is built of.

    References
    ----------
    .. [1] M. Lorenzi and X. Pennec, "Efficient parallel transport of deformations in time series of
       images: from Schild's to pole ladder", *Journal of Mathematical Imaging and Vision* 50, 5–17, 2014.

    Examples
    --------
    The change from one square to a sheared square, carried to a rectangle and applied there:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> sheared = square + [[0.0, 0.0], [0.0, 0.0], [0.15, 0.0], [0.15, 0.0]]
    >>> rectangle = square * [1.2, 1.0]
    >>> v = sl.log_map(square, sheared, sigma2=0.3)
    >>> w = sl.parallel_transport(square, v, rectangle, sigma2=0.3)
    >>> moved = sl.exp_map(rectangle, w, sigma2=0.3)
    >>> bool(np.abs(moved - rectangle).max() < 0.3)
    True
    """
    base, vector = _check_entry(base, vector, sigma2, metric, ("base", "vector"))
    base, end = as_shape_pair(base, end, names=("base", "end"))
    n_rungs = check_positive_int(n_rungs, name="n_rungs")
    n_steps = check_positive_int(n_steps, name="n_steps")
    half = -(-n_steps // 2)
    maps = dict(metric=metric, sigma2=sigma2)
    logs = dict(maps, n_steps=n_steps, tol=tol, max_iter=max_iter)
    path = log_map(base, end, **dict(logs, n_steps=2 * half * n_rungs), return_result=True).path
    v = vector
    for i in range(n_rungs):
        a, m, b = path[2 * half * i], path[2 * half * i + half], path[2 * half * (i + 1)]
        p = exp_map(a, v, n_steps=n_steps, **maps)
        q = exp_map(m, -log_map(m, p, **logs), n_steps=n_steps, **maps)
        v = -log_map(b, q, **logs)
    return v
