"""The study's notebooks: their parameters, the raw data each reads and the values each must record.

:data:`NOTEBOOKS` is the table :mod:`shapelib.study.runner` (``python run_all.py``) runs; adding a
notebook to the study is adding its entry here (see CONTRIBUTING.md).
"""

from __future__ import annotations

__all__ = ["NOTEBOOKS", "CC_FILES", "MPEG7_GIFS", "registered"]

CC_FILES = ["cdfhc/cdfhc_data2D_CC.mat"]


def registered(prefix: str, suffix: str) -> list[str]:
    """Registry paths (:func:`shapelib.datasets.registry`) under ``prefix`` ending in ``suffix``."""
    from ..datasets import registry

    return sorted(p for p in registry() if p.startswith(prefix) and p.endswith(suffix))


MPEG7_GIFS = registered("mpeg7/", ".gif")

#: name -> full parameters, quick parameters (CI), raw data files used (their checksums key the cache).
#: ``expects`` maps a value-key prefix to how many values a quick run records under it (a full run,
#: or one with parameters changed, at least as many), ``figures`` how many PNG files it saves at
#: least: the runner checks both after every run (:func:`shapelib.study.runner.check_outputs`), so
#: that the report never silently loses a column and the documentation a figure.
#: ``"cores": "all"``: the notebook starts a worker per core and runs alone (:class:`_Cores`);
#: ``"store": True``: it gets a ``store_dir`` for resumable zarr stores (:func:`run_one`).
NOTEBOOKS: dict[str, dict] = {
    "fig07_fish_deformations": {
        "params": {}, "quick": {"max_iter": 3},
        "data": ["cdfhc/cdfhc_data2D_fish.mat", "cdfhc/cdfhc_data2D_beijing.mat", "tps-rpm/save_fish_def_2_1.mat"],
        "figures": 3, "expects": {"fig08/": 6, "fig09/": 3},
    },
    "fig10_corpus_callosum": {"params": {}, "quick": {}, "data": CC_FILES, "figures": 1, "expects": {"fig10/": 2}},
    "fig01_gmm_representation": {"params": {}, "quick": {"resolution": 80}, "data": ["mpeg7/fish-1.gif"] + CC_FILES,
                                 "figures": 1, "expects": {"fig01/": 6}},
    "fig02_intrinsic_extrinsic": {"params": {}, "quick": {}, "data": ["mpeg7/fish-1.gif"], "figures": 1,
                                  "expects": {"fig02/": 3}},
    "fig04_line_bending": {"params": {}, "quick": {"n_steps": 6, "max_iter": 20}, "data": [],
                           "figures": 2, "expects": {"fig04/": 6, "fig05/": 1}},
    "fig06_square_rotation": {"params": {}, "quick": {"n_steps": 8, "max_iter": 20}, "data": [],
                              "figures": 1, "expects": {"fig06/": 8}},
    "sec3e_extrinsic_warp": {"params": {}, "quick": {"n_steps": 4, "max_iter": 5, "grid_size": 48},
                             "data": ["mpeg7/fish-1.gif"], "figures": 1, "expects": {"sec3e/": 3}},
    "pointset_registration": {
        "params": {}, "quick": {"levels": "fish_def_2,fish_outlier_3,fish_occlusion_3,fish_rot_4"},
        "data": [f"tps-rpm/save_{shape}_{kind}_{level}_{sample}.mat" for shape in ("fish", "chinese")
                 for kind, top in (("def", 5), ("noise", 6), ("outlier", 5), ("occlusion", 6), ("rot", 6))
                 for level in range(1, top + 1) for sample in range(1, 11)],
        "figures": 2, "expects": {"registration/summary/": 20},
    },
    "alpha_discretisation": {
        "params": {}, "quick": {"n_pairs": 2, "n_steps_list": [2, 4, 8], "max_iter": 20},
        "data": CC_FILES, "figures": 1, "expects": {"alpha_discretisation/": 13},
    },
    "tutorial_own_data": {
        "cores": "all",
        "params": {},
        "quick": {"per_class": 2, "n_landmarks": 16, "n_steps": 4, "n_jobs": 1,
                  "metrics": ["procrustes", "alpha", "fisher_rao_bound"]},
        "data": [f"mpeg7/{c}-{i}.gif" for c in ("fish", "Heart", "Bone") for i in (1, 2, 3)],
        "figures": 3, "expects": {"tutorial/": 23},
    },
    "table1_pairwise": {
        "cores": "all",
        # full run: α and Fisher–Rao distances through the certified bracket (rtol 1e-3, well
        # inside print precision): 105 s instead of 13 min on 2 cores, ratio medians and CVs within
        # 0.1 % of the converged geodesics' (measured 2026-11-23); quick keeps 3 fixed iterations
        # (Fisher–Rao: one, on a coarse quadrature grid; it was 3/4 of the test suite's notebook time)
        "params": {"n_steps": 8, "max_iter": 200, "fisher_rao_max_iter": 200, "tol": 1e-6, "geodesic_rtol": 1e-3},
        "quick": {"n_steps": 2, "max_iter": 3, "fisher_rao_max_iter": 1, "fisher_rao_grid_spacing": 0.7,
                  "diffeomorphism_max_iter": 3, "geodesic_rtol": None},
        "data": CC_FILES,
        "figures": 1, "expects": {f"table1/{c}/": 21 for c in (
            "procrustes", "hausdorff", "tps", "wendland", "diffeomorphism", "alpha_s2_0.1", "alpha_s2_0.5", "alpha_s2_1.5",
            "fisher_rao_s2_0.1", "fisher_rao_s2_0.5", "fisher_rao_s2_1.5")} | {"fig11/": 28, "speed/": 2, "constant/table1/": 7},
    },
    "intrinsic_statistics": {
        "cores": "all",
        "params": {},
        "quick": {"n_shapes": 16, "n_subset": 6, "permutations": 19, "fisher_rao_n_steps": 2,
                  "fisher_rao_grid_spacing": 1.0, "geodesic_steps": 4, "wings_min_genus": 25, "n_jobs": 1},
        "data": ["adhd200/ADHD-200.Rdata", "adhd200/clinical_info.csv"],
        "figures": 10,
        "expects": {"intrinsic/adhd/alpha/": 11, "intrinsic/adhd/procrustes/": 6, "intrinsic/adhd/subset/": 3,
                    "intrinsic/adhd/fisher_rao/": 7, "intrinsic/adhd/pca/": 25, "intrinsic/adhd/regression/": 8,
                    "intrinsic/wings/": 10},
    },
    # MPEG-7 bull's-eye retrieval (beyond the paper). Default: 20 of the 70 classes (400 shapes);
    # the standard test on all 1,400 shapes: ``python run_all.py --only mpeg7_retrieval -p full=True``
    # (resumable through the zarr stores; the engine prints its cost estimate before each matrix)
    "mpeg7_retrieval": {
        "params": {}, "store": True, "cores": "all",
        "quick": {"classes": ["Bone", "apple", "deer", "fork"], "per_class": 8, "n_points": 64, "n_jobs": 1},
        "data": MPEG7_GIFS,
        "figures": 6, "expects": {"mpeg7/outline/": 3, "mpeg7/bullseye/": 3, "mpeg7/sweep/": 8, "mpeg7/seconds/": 3,
                    "mpeg7/worst_class_score": 1, "mpeg7/n_shapes": 1},
    },
    "adhd200_population": {
        "params": {"rtol": 1e-3}, "store": True, "cores": "all",
        "quick": {"n_shapes": 40, "n_subset": 8, "geodesic_n_steps": 2, "geodesic_max_iter": 1, "permutations": 199,
                  "sweep_points": 3, "sweep_permutations": 99, "mosquito_per_genus": 8},
        "data": ["adhd200/ADHD-200.Rdata", "adhd200/clinical_info.csv"],
        "figures": 2,
        "expects": {"adhd200/permanova/": 108, "adhd200/knn/": 36, "adhd200/mantel/": 62, "adhd200/mds/": 14,
                    "adhd200/bracket/": 6, "adhd200/correspondence/": 4, "adhd200/scale/": 4,
                    "sigma/adhd200/": 27, "sigma/mosquito/": 23},
    },
}
