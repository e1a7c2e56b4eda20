"""Population statistics.

Distance-based (on a distance matrix from :func:`shapelib.pairwise_distances`):
:func:`permanova`, :func:`knn_loo_accuracy`, :func:`classical_mds`, :func:`mantel_test`,
:func:`gower_centered` (:mod:`shapelib.statistics.distance_based`).

Across a sweep of distance matrices (one per σ²), with a family-wise test over the sweep:
:func:`permanova_sweep`, :func:`knn_sweep` (:mod:`shapelib.statistics.sweep`).
"""

from .distance_based import *  # noqa: F401,F403
from .distance_based import __all__ as _distance_based_all
from .sweep import *  # noqa: F401,F403
from .sweep import __all__ as _sweep_all

__all__ = [*_distance_based_all, *_sweep_all]
