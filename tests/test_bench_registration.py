"""The registration benchmarks' bookkeeping: summaries of a hand-made record, the 3-D cases' ground truth."""

import importlib.util
import sys

import numpy as np
import pytest

from tests.conftest import ROOT, import_or_missing


def _load(name):
    sys.path.insert(0, str(ROOT))
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _cell(errors, times, exceptions=None, reliable=None, converged=None):
    n = len(errors)
    c = {"samples": list(range(1, n + 1)), "errors": list(errors), "times": list(times),
         "exceptions": list(exceptions or [None] * n)}
    if reliable is not None:
        c["reliable"] = list(reliable)
    if converged is not None:
        c["converged"] = list(converged)
    return c


def test_summarise_counts_failures_flags_and_ranges_of_a_hand_made_record():
    bench = _load("bench_registration")
    # shapelib: samples 1-5 good (0.01), 6-10 bad (0.1); flagged unreliable on samples 5, 6, 7, 8
    sl_err = [0.01] * 5 + [0.1] * 5
    sl_rel = [True] * 4 + [False] * 4 + [True] * 2
    # EM stopped at max_iter on samples 1 (good) and 9 (bad, not flagged unreliable)
    sl_conv = [False] + [True] * 7 + [False, True]
    levels = {
        "fish_def_1": {"shapelib": _cell(sl_err, [1.0] * 10, reliable=sl_rel, converged=sl_conv),
                       "cpd": _cell([0.02] * 10, [0.1] * 10, exceptions=[None] * 9 + ["LinAlgError"])},
        "chinese_rot_1": {"shapelib": _cell([0.0] * 10, [3.0] * 10, reliable=[True] * 10, converged=[True] * 10),
                          "cpd": _cell([0.2] * 10, [0.3] * 10)},
    }
    s = bench.summarise(levels, list(range(1, 11)), methods=("shapelib", "cpd"))
    assert list(s) == ["1-5", "6-10", "1-10"]
    whole, first, second = s["1-10"], s["1-5"], s["6-10"]
    # the raised registration counts as a failure though its error is small
    assert whole["methods"]["cpd"]["failures"] == 1 + 10 and whole["methods"]["cpd"]["raised"] == 1
    assert first["methods"]["shapelib"]["failures"] == 0 and second["methods"]["shapelib"]["failures"] == 5
    assert whole["methods"]["shapelib"]["median_time_s"] == pytest.approx(2.0)
    assert whole["shapelib_time_over_cpd"] == pytest.approx(2.0 / 0.2)
    # level means: fish 0.055 (shapelib) vs 0.02, chinese 0 vs 0.2
    assert whole["shapelib_le_every_peer"] == 1 and whole["shapelib_above_best_peer_plus_0.01"] == ["fish_def_1"]
    assert first["shapelib_le_every_peer"] == 2 and first["shapelib_above_best_peer_plus_0.01"] == []
    # of the 5 errors > 0.05, samples 6-8 are flagged; of the 15 below 0.02, sample 5 is flagged
    flag = whole["reliable_flag"]
    assert flag["errors_above_0.05"] == 5 and flag["catch_rate"] == pytest.approx(3 / 5)
    assert flag["errors_below_0.02"] == 15 and flag["false_alarm_rate"] == pytest.approx(1 / 15)
    # any warning: not reliable or EM not converged (sample 9 caught too, sample 1 a second false alarm)
    warn = whole["any_warning"]
    assert warn["catch_rate"] == pytest.approx(4 / 5) and warn["false_alarm_rate"] == pytest.approx(2 / 15)
    assert "any_warning" not in bench.summarise({"fish_def_1": {"shapelib": _cell(sl_err, [1.0] * 10, reliable=sl_rel),
                                                                "cpd": _cell([0.02] * 10, [0.1] * 10)}},
                                                list(range(1, 11)), methods=("shapelib", "cpd"))["1-10"]
    fam = whole["families"]["fish_def"]
    assert fam["best_peer"] == "cpd" and fam["mean_error"]["shapelib"] == pytest.approx(0.055)
    assert set(whole["families"]) == {"fish_def", "chinese_rot"}
    # only the range that ran when not all ten did
    assert list(bench.summarise(levels, [1, 2, 3], methods=("shapelib", "cpd"))) == ["1-3"]
    # the 3-D benchmark's split: the samples a threshold was tuned on, the rest, all
    split = bench.summarise(levels, [1, 2, 3, 4, 5], methods=("shapelib", "cpd"), tuned=(1, 2))
    assert list(split) == ["1-2", "3-5", "1-5"]
    assert split["1-2"]["methods"]["shapelib"]["registrations"] == 2 * len(levels)
    assert split["3-5"]["methods"]["shapelib"]["registrations"] == 3 * len(levels)
    assert bench.parse_samples("6-10") == [6, 7, 8, 9, 10] and bench.parse_samples("3") == [1, 2, 3]
    with pytest.raises(ValueError, match="samples"):
        bench.parse_samples("0-4")


def test_3d_cases_carry_their_ground_truth():
    b3 = _load("bench_registration_3d")
    assert len(b3.LEVEL_NAMES) == 3 * 16
    for surface in b3.SURFACES:
        x = b3.sample_surface(surface, 200, np.random.default_rng(1))
        assert np.allclose(x.mean(axis=0), 0, atol=1e-12) and np.sum(x**2) / len(x) == pytest.approx(1)
    # rotation 0: the target is the truth, shuffled; the warp moves no point further than its amplitude sum
    c = b3.make_case("torus_rot_1", 1, points=150)
    assert np.allclose(np.sort(c["y"], axis=0), np.sort(c["truth"], axis=0))
    assert np.max(np.linalg.norm(c["truth"] - c["x"], axis=1)) <= 4 * b3.BASE_AMPLITUDE + 1e-12
    # the levels of a sample share the set and the warp: deformation scales the displacement, rotation
    # moves the warped set rigidly (its pairwise distances kept), and level 1 of each is the base warp
    def1, def3 = (b3.make_case(f"torus_def_{i}", 1, points=150) for i in (1, 3))
    np.testing.assert_allclose(def3["truth"] - def3["x"], 3 * (def1["truth"] - def1["x"]), atol=1e-12)
    np.testing.assert_allclose(def1["truth"], c["truth"], atol=1e-12)
    r4 = b3.make_case("torus_rot_4", 1, points=150)["truth"]
    d = lambda a: np.linalg.norm(a[:, None] - a[None], axis=2)  # noqa: E731
    np.testing.assert_allclose(d(r4), d(c["truth"]), atol=1e-10)
    assert np.max(np.linalg.norm(r4 - c["truth"], axis=1)) > 0.5
    # occlusion and outliers change the number of target points by their level's fraction
    assert len(b3.make_case("sphere_occlusion_3", 2, points=200)["y"]) == 200 - 60
    assert len(b3.make_case("sphere_outlier_2", 2, points=200)["y"]) == 300
    assert np.array_equal(b3.make_case("sphere_noise_1", 3)["y"], b3.make_case("sphere_noise_1", 3)["y"])  # seeded
    with pytest.raises(ValueError, match="name"):
        b3.make_case("cube_def_1", 1)


def test_a_peer_that_raises_is_a_failure_scored_as_the_unmoved_source():
    # probreg imports open3d, which needs the system's libusb-1.0 (.ci/run installs it)
    import_or_missing("probreg", "probreg (the study extra) and open3d's libusb-1.0")
    peers = _load("_peers")
    rng = np.random.default_rng(0)
    x = rng.normal(size=(40, 2))
    # probreg's GMMTree takes 3-D points only: a planar set (z = 0) makes its tree's covariances singular
    moved, seconds, info = peers.run("probreg_gmmtree", x, 1.1 * x + 0.2)
    assert info["exception"] is not None and moved is not None and np.array_equal(moved, x) and seconds >= 0
    # probreg's non-rigid CPD runs in 2-D and recovers a small similarity of the same points
    moved, _, info = peers.run("probreg_cpd", x, 1.1 * x + 0.2)
    assert info["exception"] is None and np.mean(np.linalg.norm(moved - (1.1 * x + 0.2), axis=1)) < 0.05


@pytest.mark.processes
def test_a_peer_over_the_time_limit_is_killed_in_its_child_process_and_the_next_one_runs():
    """With a time limit the peers run in a child process: one still running at the limit (here pycpd on
    800 points against a limit of a millisecond) is a TimeoutError scored as the unmoved source, its
    process is killed, and the next registration runs in a new one."""
    import_or_missing("probreg", "probreg (the study extra) and open3d's libusb-1.0")
    sys.path.insert(0, str(ROOT))
    from benchmarks import _peers as peers

    rng = np.random.default_rng(1)
    big = rng.normal(size=(800, 2))
    try:
        moved, seconds, info = peers.run("cpd", big, 1.1 * big, time_limit=1e-3)
        assert info["exception"] == "TimeoutError" and np.array_equal(moved, big) and seconds == 1e-3
        assert not peers._CHILD  # the overrunning process is gone
        x = rng.normal(size=(40, 2))
        moved, seconds, info = peers.run("cpd", x, 1.1 * x + 0.2, time_limit=60.0)
        assert info["exception"] is None and 0 < seconds < 60.0
        assert np.mean(np.linalg.norm(moved - (1.1 * x + 0.2), axis=1)) < 0.05
        proc = peers._CHILD[0].proc
        assert proc.is_alive()
    finally:
        peers._close_child()
    assert not proc.is_alive() and not peers._CHILD


def test_the_landmarks_benchmark_pairs_only_exact_true_points_and_counts_by_range():
    """bench_registration_landmarks: a landmark is a spread template point whose true position is a target
    point (none where the target is noisy); the summary counts failures, flags and families per range."""
    bench = _load("bench_registration_landmarks")
    rng = np.random.default_rng(2)
    x = rng.normal(size=(30, 2))
    truth = x @ [[0, -1], [1, 0]]
    perm = rng.permutation(30)
    y = truth[perm]
    lm = bench.landmarks_of(x, y, truth, 3)
    assert lm.shape == (3, 2) and len(set(lm[:, 0])) == 3
    np.testing.assert_array_equal(y[lm[:, 1]], truth[lm[:, 0]])  # each pair: the true position, found exactly
    d = np.linalg.norm(x[lm[:, 0]][:, None] - x[lm[:, 0]][None], axis=2)
    assert d[np.triu_indices(3, 1)].min() > 0.5  # spread over the template (farthest points)
    assert bench.landmarks_of(x, y + 1e-9, truth, 3) is None  # no exact true point: no landmark
    assert bench.landmarks_of(x, y, truth, 0) is None
    y_part = y[np.isin(perm, lm[1:, 0])]  # the first landmark's true point occluded
    assert len(bench.landmarks_of(x, y_part, truth, 3)) == 2
    cell = {"samples": list(range(1, 11)), "errors": [0.01] * 4 + [0.2] + [0.01] * 3 + [0.3, 0.04],
            "given": [3] * 9 + [0], "reliable": [True] * 4 + [False] + [True] * 3 + [True, True], "times": [0.1] * 10}
    s = bench.summarise({"3": {"fish_noise_2": cell}}, list(range(1, 11)))
    assert list(s) == ["1-5", "6-10", "1-10"]
    assert s["1-5"]["3"] == {"registrations": 5, "with_all_landmarks": 5, "with_some_landmarks": 5, "failures": 1,
                             "mean_error": pytest.approx(0.048), "failures_flagged": 1,
                             "failures_by_family": {"noise": 1}}
    assert s["6-10"]["3"]["failures"] == 1 and s["6-10"]["3"]["failures_flagged"] == 0
    assert s["6-10"]["3"]["with_all_landmarks"] == 4 and s["1-10"]["3"]["failures"] == 2
