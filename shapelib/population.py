"""Intrinsic statistics of a population on the engine: ``n_jobs=``, ``client=``, ``scheduler=``.

The statistics of :mod:`shapelib.statistics` take these keywords themselves (where the log maps
run: :mod:`shapelib.statistics._run`, on :func:`shapelib._executor.engine_executor`); this module
serves the same functions under its older name: ``shapelib.population.frechet_mean`` *is*
:func:`shapelib.statistics.frechet_mean` (and ``shapelib.frechet_mean``), likewise
:func:`~shapelib.statistics.tangent_pca`, :func:`~shapelib.statistics.geodesic_regression` and
:func:`~shapelib.statistics.mean_difference_test`.
"""

from __future__ import annotations

from .statistics import frechet_mean, geodesic_regression, mean_difference_test, tangent_pca
from .statistics._run import MEAN_ROUNDS, projected_seconds

__all__ = ["frechet_mean", "tangent_pca", "geodesic_regression", "mean_difference_test", "projected_seconds",
           "MEAN_ROUNDS"]
