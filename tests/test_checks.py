"""What shapelib checks for the user (docs/guide/checks.md): the layout of shape arrays on every
entry point, the pose of the shapes for pose-dependent metrics, σ against the landmarks' scale
for every σ² metric, and honest convergence words. CLI cases: tests/test_cli_checks.py."""

import warnings

import numpy as np
import pytest

import shapelib as sl
from shapelib.distances import METRICS

SIGMA2_METRICS = ("alpha", "fisher_rao", "alpha_bound", "fisher_rao_bound")


def outline(k, rng, *, size=200.0, noise=0.03):
    """A closed outline of ``k`` landmarks (an ellipse with noise), in pixel-like units."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    base = np.stack([1.6 * np.cos(t), np.sin(t)], axis=1)
    return size * (base + noise * rng.normal(size=base.shape))


def population(n, k, rng, **kw):
    """``n`` specimens of one outline, each moved by a random rotation and translation (raw data)."""
    out = []
    for _ in range(n):
        a = rng.uniform(0, 2 * np.pi)
        r = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        out.append(outline(k, rng, **kw) @ r.T + rng.uniform(300, 600, size=2))
    return np.stack(out)


# ---------------------------------------------------------------------------------------------
# Layout: (N, K, d) with d in {2, 3} on every entry point that takes shapes
# ---------------------------------------------------------------------------------------------


@pytest.fixture
def nkd(rng):
    return population(12, 8, rng)


LAYOUT_ENTRY_POINTS = {
    "pairwise_distances": lambda x: sl.pairwise_distances(x, metric="procrustes", n_jobs=1, progress=False),
    "generalized_procrustes": lambda x: sl.generalized_procrustes(x),
    "to_centroid_size": lambda x: sl.to_centroid_size(x),
    "landmark_spacing": lambda x: sl.landmark_spacing(x),
    "sigma_ratio": lambda x: sl.sigma_ratio(x, 0.5),
    "check_scale": lambda x: sl.geometry.scale.check_scale(x, 0.5),
}


@pytest.mark.parametrize("entry", sorted(LAYOUT_ENTRY_POINTS))
def test_a_geomorph_pkn_array_is_refused_with_the_conversion(nkd, entry):
    pkn = sl.io.to_pkn(nkd)  # (8, 2, 12): read as 8 shapes of 2 landmarks in 12 dimensions
    with pytest.raises(ValueError, match=r"12 dimensions.*p x k x n.*shapelib\.io\.from_pkn"):
        LAYOUT_ENTRY_POINTS[entry](pkn)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.ScaleWarning)  # pixel units against sigma2 = 0.5
        LAYOUT_ENTRY_POINTS[entry](nkd)  # the right layout passes


def test_an_input_error_names_its_fix_in_the_callers_words_and_survives_pickling(nkd):
    """One message, two vocabularies: the library's keyword or another caller's option, never
    a rewrite of the text; the facts and the message cross process boundaries (Dask) intact."""
    import pickle

    with pytest.raises(sl.InputError) as info:
        sl.pose_align(sl.io.to_pkn(nkd))
    exc = info.value
    assert isinstance(exc, ValueError) and "{pkn}" in exc.template
    assert "convert it with shapelib.io.from_pkn" in str(exc)
    other = exc.phrase({"pkn": "read it with --pkn"})
    assert "read it with --pkn" in other and "from_pkn" not in other
    assert other.replace("read it with --pkn", "convert it with shapelib.io.from_pkn") == str(exc)
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is sl.InputError and str(back) == str(exc) and back.facts == exc.facts
    with pytest.raises(sl.InputError) as info:
        sl.distance(nkd[0], nkd[1], metric="fisher_rao_bound")
    assert info.value.facts == {"metric": "fisher_rao_bound", "parameters": ("sigma2",)}
    assert str(info.value).endswith("needs sigma2=...")
    errors = [info.value]
    bad = nkd[0].copy()
    bad[3, 1] = np.nan
    with pytest.raises(sl.InputError, match="first at landmark 3, coordinate 1") as info:
        sl.procrustes_distance(bad, nkd[1])
    assert info.value.facts == {"landmarks": (3,)}
    errors.append(info.value)
    for exc in errors:  # facts survive the round trip too
        back = pickle.loads(pickle.dumps(exc))
        assert str(back) == str(exc) and back.facts == exc.facts and back.facts


def test_a_metric_option_named_like_a_remedy_is_named_as_an_option():
    """Only sigma2 has a wording of its own: a registered metric's required ``scale`` is asked
    for as ``scale=...``, not as the tps reader's ``scale=True``."""
    from shapelib.distances import _REGISTRY, check_metric_params, register_metric

    def scaled(u, v, *, scale):
        return scale * float(np.abs(np.asarray(u) - np.asarray(v)).max())

    register_metric("scaled_test_metric", scaled)
    try:
        with pytest.raises(sl.InputError) as info:
            check_metric_params("scaled_test_metric", {})
        assert str(info.value).endswith("needs scale=...") and "scale=True" not in str(info.value)
        assert info.value.phrase({"scale": "--scale"}).endswith("needs scale=...")
    finally:
        del _REGISTRY["scaled_test_metric"]


@pytest.mark.parametrize("entry", sorted(LAYOUT_ENTRY_POINTS))
def test_an_n_d_k_array_is_refused_with_the_conversion(nkd, entry):
    ndk = nkd.transpose(0, 2, 1)  # (12, 2, 8): read as 12 shapes of 2 landmarks in 8 dimensions
    with pytest.raises(ValueError, match=r"8 dimensions.*\(N, d, K\).*swapaxes"):
        LAYOUT_ENTRY_POINTS[entry](ndk)


@pytest.mark.parametrize("entry", ["procrustes_distance", "procrustes_align", "centroid_size", "preshape"])
def test_procrustes_functions_refuse_a_transposed_shape(nkd, entry):
    u, v = nkd[0].T, nkd[1].T  # (2, 8): 2 landmarks in 8 dimensions
    f = getattr(sl, entry)
    with pytest.raises(ValueError, match=r"8 dimensions.*\(K, d\).*transposed"):
        f(u, v) if entry.startswith("procrustes") else f(u)


@pytest.mark.parametrize("metric", sorted(METRICS))
def test_every_metric_refuses_a_transposed_pair(nkd, metric):
    params = {"sigma2": 0.5} if metric in SIGMA2_METRICS else {}
    u, v = nkd[0].T, nkd[1].T
    with pytest.raises(ValueError, match=r"8 dimensions.*\(K, d\)"):
        sl.distance(u, v, metric=metric, **params)
    with pytest.raises(ValueError, match=r"8 dimensions.*\(K, d\)"):
        sl.pair_record(u, v, metric=metric, **params)


# ---------------------------------------------------------------------------------------------
# Pose: the pose-dependent metrics say so when the shapes are not aligned
# ---------------------------------------------------------------------------------------------

#: metric -> options for a quick evaluation on 8-landmark shapes at centroid size 20
POSE_CASES = {
    "alpha_bound": {"sigma2": 25.0},
    "fisher_rao_bound": {"sigma2": 25.0},
    "alpha": {"sigma2": 25.0, "n_steps": 4},
    "fisher_rao": {"sigma2": 25.0, "n_steps": 2, "max_iter": 1, "warn": False},
    "diffeomorphism": {"n_steps": 4, "kernel_width": 5.0},
    "hausdorff": {},
    "wendland": {"affine": False},
}
#: pose-invariant metrics (and options): no warning, the same value for a rotated, moved copy
INVARIANT_CASES = {"procrustes": {}, "tps": {}, "wendland": {"affine": True}}


def rotation(angle_deg):
    a = np.deg2rad(angle_deg)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


@pytest.fixture
def aligned_set(rng):
    """Twelve 8-landmark outlines, aligned (generalised Procrustes), centroid size 20; sigma2 = 25
    puts sigma at about one landmark spacing."""
    return sl.to_centroid_size(population(12, 8, rng, size=1.0, noise=0.05))


@pytest.mark.parametrize("metric", sorted(POSE_CASES))
def test_a_rotated_copy_warns_for_every_pose_dependent_metric(aligned_set, metric):
    u = aligned_set[0]
    v = aligned_set[1] @ rotation(30).T + [3.0, -2.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.PoseWarning)
        before = sl.distance(u, aligned_set[1], metric=metric, **POSE_CASES[metric])  # aligned: silent
    with pytest.warns(sl.PoseWarning, match=rf"{metric}.* depends on the pose.*not aligned.*procrustes_align"):
        after = sl.distance(u, v, metric=metric, **POSE_CASES[metric])
    assert after != pytest.approx(before, rel=1e-3)  # the metric does depend on the pose
    assert sl.pose_align(np.stack([u, v]))[1].max() > 0.1


@pytest.mark.parametrize("metric", sorted(INVARIANT_CASES))
def test_pose_invariant_metrics_neither_warn_nor_change(aligned_set, metric):
    u, v = aligned_set[0], aligned_set[1]
    moved = v @ rotation(30).T + [3.0, -2.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.PoseWarning)
        before = sl.distance(u, v, metric=metric, **INVARIANT_CASES[metric])
        after = sl.distance(u, moved, metric=metric, **INVARIANT_CASES[metric])
    assert after == pytest.approx(before, rel=1e-9)


def test_pairs_from_one_aligned_set_pass_though_not_aligned_to_each_other(aligned_set):
    """Generalised Procrustes aligns each shape to the mean, not to every other shape: that
    leftover is of second order in the shape difference and must not warn."""
    from shapelib.geometry.procrustes import pose_change

    assert max(pose_change(a, b)[0] for a in aligned_set for b in aligned_set) > 1e-6  # not exactly aligned
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.PoseWarning)
        for i in range(len(aligned_set)):
            for j in range(i + 1, len(aligned_set)):
                sl.distance(aligned_set[i], aligned_set[j], metric="alpha_bound", sigma2=25.0)


def test_the_pairwise_engine_warns_once_for_an_unaligned_set(rng, aligned_set):
    raw = aligned_set @ rotation(20).T
    raw[3] = raw[3] @ rotation(40).T + 5.0  # one specimen out of pose
    with pytest.warns(sl.PoseWarning, match=r"not aligned.*shapes\[3\] by 1\d\d %.*pose_align") as rec:
        sl.pairwise_distances(raw, metric="alpha_bound", sigma2=25.0, n_jobs=1, progress=False)
    assert sum(issubclass(w.category, sl.PoseWarning) for w in rec) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.PoseWarning)
        sl.pairwise_distances(sl.pose_align(raw)[0], metric="alpha_bound", sigma2=25.0, n_jobs=1, progress=False)
        sl.pairwise_distances(raw, metric="procrustes", n_jobs=1, progress=False)  # pose-invariant: silent


def test_pose_align_removes_pose_and_keeps_sizes(rng, aligned_set):
    sizes = rng.uniform(10, 30, size=len(aligned_set))
    x = aligned_set * (sizes / 20.0)[:, None, None]
    raw = np.stack([s @ rotation(a).T + t for s, a, t in zip(x, rng.uniform(0, 360, len(x)),
                                                               rng.normal(0, 50, (len(x), 2)))])
    a1, moved = sl.pose_align(raw)
    assert moved.max() > 0.1
    assert np.allclose([sl.centroid_size(s) for s in a1], sizes)
    assert sl.pose_align(a1)[1].max() < 1e-9  # aligned shapes stay put
    # the pose-dependent distances of the aligned raw shapes are those of the aligned set
    d_raw = sl.pairwise_distances(a1, metric="alpha_bound", sigma2=25.0, n_jobs=1, progress=False)
    d_ref = sl.pairwise_distances(sl.pose_align(x)[0], metric="alpha_bound", sigma2=25.0, n_jobs=1, progress=False)
    np.testing.assert_allclose(d_raw, d_ref, rtol=1e-7, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Scale: every sigma2 metric checks sigma against the landmarks; a degenerate Fisher-Rao
# quadrature is a ValueError before any work, never a ZeroDivisionError
# ---------------------------------------------------------------------------------------------


@pytest.fixture
def pixels(rng):
    """Raw pixel coordinates (landmark spacing ~100 px), in one pose."""
    x = population(6, 8, rng)
    return sl.pose_align(x)[0]


@pytest.mark.parametrize("metric", ["alpha_bound", "fisher_rao_bound"])
def test_the_bounds_warn_about_scale_like_the_geodesics(pixels, metric):
    sigma2 = 400.0 if metric == "fisher_rao_bound" else 0.5  # sigma 0.11 spacings (below 0.059: an error)
    with pytest.warns(sl.ScaleWarning, match=r"times the mean nearest-landmark spacing"):
        sl.distance(pixels[0], pixels[1], metric=metric, sigma2=sigma2)
    with pytest.warns(sl.ScaleWarning) as rec:
        sl.pairwise_distances(pixels, metric=metric, sigma2=sigma2, n_jobs=1, progress=False)
    assert sum(issubclass(w.category, sl.ScaleWarning) for w in rec) == 1  # once for the set, not per pair


@pytest.mark.parametrize("entry", ["geodesic", "bracket", "bound", "distance", "pairwise"])
def test_a_degenerate_fisher_rao_quadrature_is_a_value_error_before_any_work(pixels, entry, tmp_path):
    from shapelib.solver.bracket import distance_bracket

    u, v = pixels[0], pixels[1]
    store = tmp_path / "fr.zarr"
    calls = {
        "geodesic": lambda: sl.geodesic(u, v, metric="fisher_rao", sigma2=0.5, n_steps=2, max_iter=2),
        "bracket": lambda: distance_bracket(u, v, metric="fisher_rao", sigma2=0.5),
        "bound": lambda: sl.fisher_rao_lower_bound(u, v, sigma2=0.5),
        "distance": lambda: sl.distance(u, v, metric="fisher_rao", sigma2=0.5, n_steps=2),
        "pairwise": lambda: sl.pairwise_distances(pixels, metric="fisher_rao", sigma2=0.5, n_steps=2, store=store,
                                                  n_jobs=1, progress=False),
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.ScaleWarning)
        with pytest.raises(ValueError, match=r"sigma2 = 0.5 is too small.*below 0.059.*Use sigma2 >= \d"):
            calls[entry]()
    assert not store.exists()  # refused before any work


def test_far_apart_shapes_give_a_fisher_rao_value_not_a_division_by_zero(aligned_set):
    """The density underflows far from every landmark (here: where the other shape lies); those
    quadrature nodes add nothing instead of dividing by zero."""
    u, v = aligned_set[0], aligned_set[1] + [120.0, 0.0]  # 60 sigma apart
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.PoseWarning)
        r = sl.geodesic(u, v, metric="fisher_rao", sigma2=4.0, n_steps=4, max_iter=5, warn=False)
        bound = sl.fisher_rao_lower_bound(u, v, sigma2=4.0)
    assert np.isfinite(r.length) and np.isfinite(r.energy)
    assert bound == pytest.approx(np.pi, abs=1e-6)  # disjoint densities: the great circle's quarter turn
    assert r.length >= bound


# ---------------------------------------------------------------------------------------------
# Convergence words: "bracket wider than rtol" (certified, how wide) apart from "solver failed"
# ---------------------------------------------------------------------------------------------


def test_a_bracket_wider_than_rtol_is_said_as_such_with_its_width(aligned_set):
    x = aligned_set[:5]
    with pytest.warns(sl.GeodesicWarning, match=r"10 of 10 alpha pairs: the certified bracket is wider than "
                                                 r"rtol = 1e-09 \(relative gap median [\d.e+-]+ %, max [\d.e+-]+ %\).*"
                                                 r"not a solver failure"):
        res = sl.pairwise_distances(x, metric="alpha", sigma2=25.0, rtol=1e-9, max_n_steps=8, n_jobs=1,
                                    progress=False, return_result=True)
    frame = res.to_frame()
    assert set(frame["status"]) == {"bracket wider than rtol"}
    np.testing.assert_allclose(frame["rel_gap"], frame["upper"] / frame["lower"] - 1, rtol=1e-12)
    assert (frame["rel_gap"] > 1e-9).all() and (frame["lower"] <= frame["value"]).all()
    # the same pairs to a tolerance they reach: converged, and inside the wider brackets
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.GeodesicWarning)
        ok = sl.pairwise_distances(x, metric="alpha", sigma2=25.0, rtol=0.5, n_jobs=1, progress=False,
                                   return_result=True)
    assert set(ok.to_frame()["status"]) == {"converged"}


def test_a_solver_that_stopped_early_is_a_solver_failure(aligned_set):
    with pytest.warns(sl.GeodesicWarning, match=r"alpha pairs: solver failed.*upper bound"):
        res = sl.pairwise_distances(aligned_set[:4], metric="alpha", sigma2=25.0, n_steps=8, max_iter=1, n_jobs=1,
                                    progress=False, return_result=True)
    frame = res.to_frame()
    assert set(frame["status"]) == {"solver failed"} and not frame["converged"].any()
    assert set(sl.pairwise_distances(aligned_set[:4], metric="procrustes", n_jobs=1, progress=False,
                                     return_result=True).to_frame()["status"]) == {"converged"}


# ---------------------------------------------------------------------------------------------
# Cost up front: pairs x timed seconds per pair / workers, before the run
# ---------------------------------------------------------------------------------------------


def test_the_engine_states_its_estimate_before_a_long_run(aligned_set, monkeypatch, caplog):
    import logging

    from shapelib.pairwise import _driver  # where the engine reads LONG_RUN_SECONDS

    x = aligned_set[:6]
    res = sl.pairwise_distances(x, metric="alpha_bound", sigma2=25.0, n_jobs=1, progress=False, return_result=True)
    spp = res.log["seconds_per_pair_estimate"]
    assert res.log["estimated_seconds"] == pytest.approx(15 * spp, rel=1e-12)  # 15 pairs, one worker
    monkeypatch.setattr(_driver, "LONG_RUN_SECONDS", 0.0)  # every run counts as long
    with caplog.at_level(logging.INFO, logger="shapelib.pairwise"):
        res = sl.pairwise_distances(x, metric="alpha_bound", sigma2=25.0, n_jobs=1, progress=False,
                                    return_result=True)
    [record] = [r for r in caplog.records if r.name == "shapelib.pairwise"]
    assert record.levelno == logging.INFO
    assert record.getMessage().startswith("alpha_bound: 15 pairs × ") and "s per pair (timed) ÷ 1 worker ≈ " in \
        record.getMessage()
