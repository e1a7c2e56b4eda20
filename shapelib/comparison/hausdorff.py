"""Hausdorff distance of two landmark sets (Table I's comparison, paper ref. [41]).

``H(u, v) = max(h(u, v), h(v, u))`` with ``h(u, v) = max_a min_b |u_a − v_b|``: the landmarks'
correspondence is not used.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

from .._validate import as_shape_pair
from ..geometry.procrustes import check_pose

__all__ = ["hausdorff_distance"]


def hausdorff_distance(u, v) -> float:
    """Symmetrised Hausdorff distance between two landmark sets (correspondence not used).

    Parameters
    ----------
    u, v : array_like, shape (K, d)

    Returns
    -------
    float
        ``max(max_a min_b |u_a − v_b|, max_b min_a |u_a − v_b|)``. It depends on the pose of
        the shapes: :class:`~shapelib.geometry.procrustes.PoseWarning` if they are not aligned.
    """
    u, v = as_shape_pair(u, v)
    check_pose(np.stack([u, v]), metric="hausdorff")
    d = cdist(u, v)
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))
