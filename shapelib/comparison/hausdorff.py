r"""Hausdorff distance of two landmark sets (Table I's comparison, paper ref. [41]).

.. math::

    H(u, v) = \max\big(h(u, v),\, h(v, u)\big), \qquad h(u, v) = \max_a \min_b |u_a - v_b|:

the landmarks' correspondence is not used.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

from .._validate import as_shape_pair
from ..geometry.procrustes import check_pose

__all__ = ["hausdorff_distance"]


def hausdorff_distance(u, v) -> float:
    r"""Symmetrised Hausdorff distance between two landmark sets (correspondence not used).

    .. math::

        H(u, v) = \max\Big(\max_a \min_b |u_a - v_b|,\ \max_b \min_a |u_a - v_b|\Big)

    one of the comparison distances of Table I of [1]_ [2]_.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Landmark sets (same shape).

    Returns
    -------
    float
        ``max(max_a min_b |u_a − v_b|, max_b min_a |u_a − v_b|)``. It depends on the pose of
        the shapes: :class:`~shapelib.PoseWarning` if they are not aligned.

    Raises
    ------
    ValueError
        For shapes that do not match or are not finite.

    Warns
    -----
    PoseWarning
        When the shapes are not aligned.

    See Also
    --------
    scipy.spatial.distance.directed_hausdorff : The directed distance for point sets of any size.
    shapelib.distance : Every distance through one entry point.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] D. P. Huttenlocher, G. A. Klanderman and W. J. Rucklidge, "Comparing images using the Hausdorff
       distance", *IEEE Transactions on Pattern Analysis and Machine Intelligence* 15(9), 850–863, 1993.

    Examples
    --------
    A unit square and the same square enlarged by 20 % about its centre: every corner moves by
    0.2 · √2 / 2.

    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = 1.2 * (u - 0.5) + 0.5
    >>> round(sl.hausdorff_distance(u, v), 6)
    0.141421
    """
    u, v = as_shape_pair(u, v)
    check_pose(np.stack([u, v]), metric="hausdorff")
    d = cdist(u, v)
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))
