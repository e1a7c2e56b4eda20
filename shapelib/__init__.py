"""shapelib: information geometry for landmark shape analysis (Peter & Rangarajan).

Shapes are ``(K, d)`` float arrays of landmarks in correspondence; collections are ``(N, K, d)``.

Each module's docstring derives what it computes. Which function computes which equation of
the paper, and which module derives it: "The paper's equations in the code" in the API reference
of the documentation (``make docs``; ``api/reference/equations.html``).
"""

from ._validate import InputError
from .solver.bracket import DistanceBracket, distance_bracket, distance_brackets
from .solver.batched import batched_lengths
from .comparison.diffeomorphism import diffeomorphism_warp, landmark_diffeomorphism
from .distances import MetricInfo, distance, metric_info, pair_record, register_metric
from .solver.geodesic import GeodesicResult, GeodesicWarning, fisher_rao_lower_bound, geodesic, geodesics, path_length
from .solver.logexp import exp_map, log_map, tangent_space
from .solver.transport import parallel_transport
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
from .comparison.missing import MissingEstimate, estimate_missing, tps_map
from .geometry.semilandmarks import SlideResult, bending_energy_matrix, curve_sliders, slide_semilandmarks
from .pointsets import (
    RegistrationResult,
    RegistrationWarning,
    register,
    register_many,
    EMWarning,
    MixtureFit,
    fit_mixture,
    Pose,
    PoseSearchWarning,
    align,
    as_point_set,
    as_point_sets,
    bhattacharyya_affinity,
    density_distance,
    density_inner,
    hellinger_sq,
    l2_distance_sq,
)
from .pointsets.outline import outline_topology, resample_closed, trace_outline
from .pointsets.invariant import InvariantDistance, invariant_distance, invariant_distance_matrix, normalise_points
from .retrieval import BullseyeScore, bullseye, nearest_wrong, procrustes_outline_matrix
from .rerank import rerank

from ._version import __version__  # noqa: F401  (the package version)

#: modules above the mathematics, imported on first use (``shapelib.io.read_landmarks(...)`` works
#: after ``import shapelib``, which itself imports neither pandas' IO nor Dask nor zarr)
_LAZY_SUBMODULES = ("io", "pairwise", "statistics", "datasets", "study", "plotting", "cli")
#: earlier names of submodules, still served on first use
_ALIASES = {"stats": "statistics", "report": "study.report"}
#: public functions of those modules, served from the package namespace on first use
_LAZY_FUNCTIONS = {"read_point_sets": "io", "write_point_set": "io", "read_sliders": "io",
                   "pairwise_distances": "pairwise", "frechet_mean": "statistics", "tangent_pca": "statistics",
                   "geodesic_regression": "statistics", "mean_difference_test": "statistics",
                   "TangentPCA": "statistics.tangent_pca", "holm_adjust": "statistics.multiple",
                   "shape_lm": "statistics.linear_model", "ShapeLinearModel": "statistics.linear_model",
                   "procrustes_coordinates": "statistics.linear_model", "allometry": "statistics.allometry",
                   "AllometryResult": "statistics.allometry", "morphological_disparity": "statistics.disparity",
                   "DisparityResult": "statistics.disparity", "two_block_pls": "statistics.pls",
                   "PLSResult": "statistics.pls", "modularity_test": "statistics.modularity",
                   "ModularityResult": "statistics.modularity", "bilateral_symmetry": "statistics.symmetry",
                   "SymmetryResult": "statistics.symmetry", "trajectory_analysis": "statistics.trajectory",
                   "TrajectoryResult": "statistics.trajectory", "global_integration": "statistics.integration",
                   "GlobalIntegrationResult": "statistics.integration"}


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
    "slide_semilandmarks",
    "SlideResult",
    "curve_sliders",
    "read_sliders",  # shapelib.io, loaded on first use
    "bending_energy_matrix",
    "estimate_missing",
    "MissingEstimate",
    "tps_map",
    "holm_adjust",
    "shape_lm",
    "ShapeLinearModel",
    "procrustes_coordinates",
    "allometry",
    "AllometryResult",
    "morphological_disparity",
    "DisparityResult",
    "two_block_pls",
    "PLSResult",
    "modularity_test",
    "ModularityResult",
    "bilateral_symmetry",
    "SymmetryResult",
    "trajectory_analysis",
    "TrajectoryResult",
    "global_integration",
    "GlobalIntegrationResult",
    "as_point_set",  # shapelib.pointsets
    "as_point_sets",
    "density_inner",
    "l2_distance_sq",
    "hellinger_sq",
    "bhattacharyya_affinity",
    "density_distance",
    "align",
    "Pose",
    "PoseSearchWarning",
    "fit_mixture",
    "MixtureFit",
    "EMWarning",
    "register",
    "register_many",
    "RegistrationResult",
    "RegistrationWarning",
    "read_point_sets",  # shapelib.io, loaded on first use
    "write_point_set",
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
    "distance_brackets",  # many pairs at once, batched on a JAX device
    "batched_lengths",
    "DistanceBracket",
    "exp_map",
    "extrinsic_warp",
    "fisher_rao_lower_bound",
    "fisher_rao_metric",
    "fisher_rao_quadratic_form",
    "frechet_mean",
    "generalized_procrustes",
    "geodesic",
    "geodesics",
    "geodesic_regression",
    "GeodesicResult",
    "GeodesicWarning",
    "gmm_density",
    "hausdorff_distance",
    "landmark_spacing",
    "l2_distance",
    "log_map",
    "parallel_transport",
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
    "trace_outline",  # shapelib.pointsets.outline
    "resample_closed",
    "outline_topology",
    "invariant_distance",  # shapelib.pointsets.invariant
    "invariant_distance_matrix",
    "InvariantDistance",
    "normalise_points",
    "bullseye",  # shapelib.retrieval
    "BullseyeScore",
    "nearest_wrong",
    "procrustes_outline_matrix",
    "rerank",  # shapelib.rerank
]
