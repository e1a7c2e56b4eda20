"""Population statistics.

Distance-based (on a distance matrix from :func:`shapelib.pairwise_distances`):
:func:`permanova`, :func:`knn_loo_accuracy`, :func:`classical_mds`, :func:`mantel_test`,
:func:`gower_centered` (:mod:`shapelib.statistics.distance_based`).
"""

from .distance_based import *  # noqa: F401,F403
from .distance_based import __all__ as _distance_based_all

__all__ = [*_distance_based_all]
