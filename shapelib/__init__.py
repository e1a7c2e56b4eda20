"""shapelib: information geometry for landmark shape analysis (Peter & Rangarajan).

Shapes are ``(K, d)`` float arrays of landmarks in correspondence; collections are ``(N, K, d)``.

Each module's docstring derives what it computes. Which function computes which equation of
the paper, and which module derives it: "The paper's equations in the code" in the API reference
of the documentation (``make docs``; ``api/reference/equations.html``).
"""

from ._validate import InputError
from .solver.bracket import DistanceBracket, distance_bracket
from .comparison.diffeomorphism import diffeomorphism_warp, landmark_diffeomorphism
from .distances import MetricInfo, distance, metric_info, pair_record, register_metric
from .solver.geodesic import GeodesicResult, GeodesicWarning, fisher_rao_lower_bound, geodesic, path_length
from .solver.logexp import exp_map, log_map, tangent_space
from .solver.path_metric import AlphaPathMetric, FisherRaoPathMetric, PathMetric, path_metric
from .solver.result import BracketStopReason, StopReason
from .geometry.gmm import gmm_density, l2_distance
from .geometry.bound_matrices import alpha_bound_matrix, bound_matrix_sweep, fisher_rao_bound_matrix
from .geometry.metrics import alpha_metric, alpha_quadratic_form, fisher_rao_metric, fisher_rao_quadratic_form
from .geometry.procrustes import (
    PoseWarning,
    centroid_size,
    generalized_procrustes,
    pose_align,
    preshape,
    procrustes_align,
    procrustes_distance,
)
from .geometry.scale import ScaleWarning, landmark_spacing, sigma_ratio, to_centroid_size
from .geometry.scale import Sigma2Estimate, estimate_sigma2
from .comparison.hausdorff import hausdorff_distance
from .comparison.splines import tps_bending_energy, wendland_bending_energy
from .comparison.warp import extrinsic_warp

from ._version import __version__  # noqa: F401  (the package version)

#: modules above the mathematics, imported on first use (``shapelib.io.read_landmarks(...)`` works
#: after ``import shapelib``, which itself imports neither pandas' IO nor Dask nor zarr)
_LAZY_SUBMODULES = ("io", "pairwise", "population", "statistics", "datasets", "study", "plotting", "cli")
#: earlier names of submodules, still served on first use
_ALIASES = {"stats": "statistics", "report": "study.report"}
#: public functions of those modules, served from the package namespace on first use
_LAZY_FUNCTIONS = {"pairwise_distances": "pairwise", "frechet_mean": "population", "tangent_pca": "population",
                   "geodesic_regression": "population", "mean_difference_test": "population",
                   "TangentPCA": "statistics.tangent_pca"}


def __getattr__(name):
    if name in _LAZY_SUBMODULES or name in _ALIASES:
        import importlib

        return importlib.import_module(f".{_ALIASES.get(name, name)}", __name__)
    if name in _LAZY_FUNCTIONS:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY_FUNCTIONS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY_SUBMODULES) | set(_LAZY_FUNCTIONS))

__all__ = [
    "MetricInfo",
    "metric_info",
    "register_metric",
    "AlphaPathMetric",
    "BracketStopReason",
    "FisherRaoPathMetric",
    "PathMetric",
    "path_metric",
    "StopReason",
    "alpha_metric",
    "alpha_quadratic_form",
    "alpha_bound_matrix",  # shapelib.geometry.bound_matrices
    "fisher_rao_bound_matrix",
    "bound_matrix_sweep",
    "estimate_sigma2",  # shapelib.geometry.scale
    "Sigma2Estimate",
    "centroid_size",
    "diffeomorphism_warp",
    "distance",
    "distance_bracket",
    "DistanceBracket",
    "exp_map",
    "extrinsic_warp",
    "fisher_rao_lower_bound",
    "fisher_rao_metric",
    "fisher_rao_quadratic_form",
    "frechet_mean",
    "generalized_procrustes",
    "geodesic",
    "geodesic_regression",
    "GeodesicResult",
    "GeodesicWarning",
    "gmm_density",
    "hausdorff_distance",
    "landmark_spacing",
    "l2_distance",
    "log_map",
    "landmark_diffeomorphism",
    "mean_difference_test",
    "pair_record",
    "pairwise_distances",
    "path_length",
    "InputError",
    "PoseWarning",
    "pose_align",
    "preshape",
    "procrustes_align",
    "procrustes_distance",
    "ScaleWarning",
    "sigma_ratio",
    "tangent_pca",
    "tangent_space",
    "TangentPCA",
    "to_centroid_size",
    "tps_bending_energy",
    "wendland_bending_energy",
]
