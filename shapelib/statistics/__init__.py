"""Population statistics.

Distance-based (on a distance matrix from :func:`shapelib.pairwise_distances`):
:func:`permanova`, :func:`knn_loo_accuracy`, :func:`classical_mds`, :func:`mantel_test`,
:func:`gower_centered` (:mod:`shapelib.statistics.distance_based`).

Intrinsic (shapes out, under the α-order or Fisher–Rao metric, on the log and exp maps of
:mod:`shapelib.solver.logexp`): :func:`frechet_mean` (:mod:`~shapelib.statistics.frechet`),
:func:`tangent_pca` and :class:`TangentPCA` (:mod:`~shapelib.statistics.tangent_pca`),
:func:`geodesic_regression` (:mod:`~shapelib.statistics.regression`), :func:`mean_difference_test`
(:mod:`~shapelib.statistics.group`). Their log
maps run on any executor (:mod:`~shapelib.statistics.population_logs`), or where ``n_jobs`` /
``client`` / ``scheduler`` say, as for :func:`shapelib.pairwise_distances`: ``shapelib.frechet_mean``
is this :func:`frechet_mean`.

Across a sweep of distance matrices (one per σ²), with a family-wise test over the sweep:
:func:`permanova_sweep`, :func:`knn_sweep` (:mod:`shapelib.statistics.sweep`).
"""

from .distance_based import *  # noqa: F401,F403
from .distance_based import __all__ as _distance_based_all
from .frechet import FrechetMeanResult, frechet_mean, procrustes_mean
from .group import MeanDifferenceResult, mean_difference_test
from .regression import GeodesicRegressionResult, geodesic_regression
from .sweep import *  # noqa: F401,F403
from .sweep import __all__ as _sweep_all
from .tangent_pca import TangentPCA, TangentPCAResult, tangent_pca

__all__ = [*_distance_based_all, "FrechetMeanResult", "frechet_mean", "procrustes_mean", "TangentPCA",
           "TangentPCAResult", "tangent_pca", "GeodesicRegressionResult", "geodesic_regression", "MeanDifferenceResult",
           "mean_difference_test", *_sweep_all]
