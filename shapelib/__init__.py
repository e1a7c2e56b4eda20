"""shapelib: information geometry for landmark shape analysis (Peter & Rangarajan).

Shapes are ``(K, d)`` float arrays of landmarks in correspondence; collections are ``(N, K, d)``.

Where each equation lives:

* eq. (5), the GMM shape density, and closed-form L² quantities: :mod:`shapelib.gmm`
* eq. (6) Fisher–Rao and eq. (22) α-order metrics: :mod:`shapelib.metrics`
  (quadrature rules: :mod:`shapelib.quadrature`)
* eqs. (8)–(12), geodesics and their certified lengths: :mod:`shapelib.geodesic`;
  certified distance brackets ``lower ≤ d ≤ upper`` to a relative width: :mod:`shapelib.bracket`
* σ against the landmarks' scale: :mod:`shapelib.scale`
* comparison distances: :mod:`shapelib.procrustes`, :mod:`shapelib.splines`,
  :mod:`shapelib.diffeomorphism` (eq. 3, Camion–Younes, through the same path solver)
* §III-E, eqs. 23–26, extrinsic warp of ambient points: :mod:`shapelib.warp`
* one entry point for all distances: :mod:`shapelib.distances`
"""

from .bracket import DistanceBracket, distance_bracket
from .diffeomorphism import diffeomorphism_warp, landmark_diffeomorphism
from .distances import distance, pair_record, pairwise_distances
from .geodesic import GeodesicResult, GeodesicWarning, fisher_rao_lower_bound, geodesic, path_length
from .gmm import gmm_density, l2_distance
from .metrics import alpha_metric, alpha_quadratic_form, fisher_rao_metric, fisher_rao_quadratic_form
from .procrustes import (
    centroid_size,
    generalized_procrustes,
    preshape,
    procrustes_align,
    procrustes_distance,
)
from .scale import ScaleWarning, landmark_spacing, sigma_ratio, to_centroid_size
from .splines import hausdorff_distance, tps_bending_energy, wendland_bending_energy
from .warp import extrinsic_warp

__version__ = "0.1.0"

#: modules above the mathematics, imported on first use (``shapelib.io.read_landmarks(...)`` works
#: after ``import shapelib``, which itself imports neither pandas' IO nor Dask nor zarr)
_LAZY_SUBMODULES = ("io", "pairwise", "stats", "datasets", "study", "report", "plotting", "cli")


def __getattr__(name):
    if name in _LAZY_SUBMODULES:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY_SUBMODULES))

__all__ = [
    "alpha_metric",
    "alpha_quadratic_form",
    "centroid_size",
    "diffeomorphism_warp",
    "distance",
    "distance_bracket",
    "DistanceBracket",
    "extrinsic_warp",
    "fisher_rao_lower_bound",
    "fisher_rao_metric",
    "fisher_rao_quadratic_form",
    "generalized_procrustes",
    "geodesic",
    "GeodesicResult",
    "GeodesicWarning",
    "gmm_density",
    "hausdorff_distance",
    "landmark_spacing",
    "l2_distance",
    "landmark_diffeomorphism",
    "pair_record",
    "pairwise_distances",
    "path_length",
    "preshape",
    "procrustes_align",
    "procrustes_distance",
    "ScaleWarning",
    "sigma_ratio",
    "to_centroid_size",
    "tps_bending_energy",
    "wendland_bending_energy",
]
