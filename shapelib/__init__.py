"""shapelib: information geometry for landmark shape analysis (Peter & Rangarajan).

Shapes are ``(K, d)`` float arrays of landmarks in correspondence; collections are ``(N, K, d)``.

Each module's docstring derives what it computes. Which function computes which equation of
the paper, and which module derives it: "The paper's equations in the code" in the API reference
of the documentation (``make docs``; ``api/reference/equations.html``).
"""

import lazy_loader as _lazy

from ._validate import InputError
from ._version import __version__  # noqa: F401  (the package version)

#: every public name, imported from its module on first use (``lazy_loader``, Scientific Python's
#: SPEC 1): ``import shapelib`` loads none of the compiled kernels, SciPy, IO, Dask or zarr, so that a
#: notebook kernel, a Dask worker or a command that needs one part of the package pays for that part
#: only. ``shapelib.register`` (or ``from shapelib import register``) imports its module then.
_PUBLIC = {
    "solver.bracket": ["DistanceBracket", "distance_bracket", "distance_brackets"],
    "solver.batched": ["batched_lengths"],
    "solver.geodesic": ["GeodesicResult", "GeodesicWarning", "fisher_rao_lower_bound", "geodesic", "geodesics",
                        "path_length"],
    "solver.logexp": ["exp_map", "log_map", "tangent_space"],
    "solver.transport": ["parallel_transport"],
    "solver.path_metric": ["AlphaPathMetric", "FisherRaoPathMetric", "PathMetric", "path_metric"],
    "solver.result": ["BracketStopReason", "StopReason"],
    "distances": ["MetricInfo", "distance", "metric_info", "pair_record", "register_metric"],
    "geometry.gmm": ["gmm_density", "l2_distance"],
    "geometry.bound_matrices": ["alpha_bound_matrix", "bound_matrix_sweep", "fisher_rao_bound_matrix"],
    "geometry.metrics": ["alpha_metric", "alpha_quadratic_form", "fisher_rao_metric", "fisher_rao_quadratic_form"],
    "geometry.procrustes": ["PoseWarning", "centroid_size", "generalized_procrustes", "pose_align", "preshape",
                            "procrustes_align", "procrustes_distance"],
    "geometry.scale": ["ScaleWarning", "landmark_spacing", "sigma_ratio", "to_centroid_size", "Sigma2Estimate",
                       "estimate_sigma2"],
    "geometry.semilandmarks": ["SlideResult", "bending_energy_matrix", "curve_sliders", "slide_semilandmarks"],
    "comparison.diffeomorphism": ["diffeomorphism_warp", "landmark_diffeomorphism"],
    "comparison.hausdorff": ["hausdorff_distance"],
    "comparison.splines": ["tps_bending_energy", "wendland_bending_energy"],
    "comparison.warp": ["extrinsic_warp"],
    "comparison.missing": ["MissingEstimate", "estimate_missing", "tps_map"],
    "pointsets": ["RegistrationResult", "RegistrationWarning", "register", "register_many", "EMWarning", "MixtureFit",
                  "fit_mixture", "Pose", "PoseSearchWarning", "align", "as_point_set", "as_point_sets",
                  "bhattacharyya_affinity", "density_distance", "density_inner", "hellinger_sq", "l2_distance_sq"],
    "pointsets.outline": ["outline_topology", "resample_closed", "trace_outline"],
    "pointsets.invariant": ["InvariantDistance", "invariant_distance", "invariant_distance_matrix", "normalise_points"],
    "retrieval": ["BullseyeScore", "bullseye", "nearest_wrong", "procrustes_outline_matrix"],
    "rerank": ["rerank"],
    "io": ["read_point_sets", "write_point_set", "read_sliders"],
    "pairwise": ["pairwise_distances"],
    "statistics": ["frechet_mean", "tangent_pca", "geodesic_regression", "mean_difference_test"],
    "statistics.tangent_pca": ["TangentPCA"],
    "statistics.multiple": ["holm_adjust"],
    "statistics.linear_model": ["shape_lm", "ShapeLinearModel", "procrustes_coordinates"],
    "statistics.allometry": ["allometry", "AllometryResult"],
    "statistics.disparity": ["morphological_disparity", "DisparityResult"],
    "statistics.pls": ["two_block_pls", "PLSResult"],
    "statistics.modularity": ["modularity_test", "ModularityResult"],
    "statistics.symmetry": ["bilateral_symmetry", "SymmetryResult"],
    "statistics.trajectory": ["trajectory_analysis", "TrajectoryResult"],
    "statistics.integration": ["global_integration", "GlobalIntegrationResult"],
}
#: the subpackages and modules, also imported on first use (``shapelib.io.read_landmarks(...)`` works
#: after ``import shapelib``)
_SUBMODULES = ["geometry", "solver", "comparison", "pointsets", "distances", "retrieval", "io", "pairwise", "statistics",
               "datasets", "study", "plotting", "cli"]  # (``shapelib.rerank`` is the function of the module rerank)
#: earlier names of submodules, still served on first use
_ALIASES = {"stats": "statistics", "report": "study.report"}

_lazy_getattr, _lazy_dir, _lazy_names = _lazy.attach(__name__, submodules=_SUBMODULES, submod_attrs=_PUBLIC)


def __getattr__(name):
    if name in _ALIASES:
        import importlib

        return importlib.import_module(f".{_ALIASES[name]}", __name__)
    if name not in _lazy_names:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return _lazy_getattr(name)


def __dir__():
    return sorted(set(_lazy_dir()) | {"InputError", "__version__"})


#: the package's public names: its door's own and the table's
__all__ = ["InputError", *(name for names in _PUBLIC.values() for name in names)]
