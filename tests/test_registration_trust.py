"""shapelib.register with its defaults, on the degradations of the Chui–Rangarajan benchmark made
small: a deformation, noise, outliers in the target, a part of the source that the target lacks,
any rotation — each recovered against its known truth; and a
result that says when it probably failed (a near-symmetric shape, a target of pure noise), in the
right units, whatever the order of the points."""

import inspect
import warnings

import numpy as np
import pytest

import shapelib as sl
import shapelib.pointsets._nonrigid
from shapelib.cli import EXIT_UNCONVERGED, build_parser, main
from test_registration import fish as _fish
from test_registration import rot2


def fish(n=60):
    return _fish(n)


def warp(x, amount=0.3):
    """A smooth non-rigid map: a bend and a bulge."""
    return x + np.column_stack([0.05 * np.sin(2 * x[:, 1]), amount * x[:, 0] ** 2 - 0.1])


def size(y):
    return float(np.sqrt(np.mean(np.sum((y - y.mean(0)) ** 2, axis=1))))


def register_quietly(x, y, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sl.register(x, y, **kw)
    return res, [w for w in caught if issubclass(w.category, sl.RegistrationWarning)]


def outliers(rng, y, k):
    lo, hi = y.min(0) - 0.3, y.max(0) + 0.3
    return lo + (hi - lo) * rng.random((k, 2))


CASES = {
    # name: (target builder, indices of the source with a known image, tolerance in units of the target's size)
    "deformation": lambda x, rng: (warp(x, 0.25), np.arange(len(x)), 0.01),
    "noise": lambda x, rng: (warp(x) + 0.02 * rng.normal(size=x.shape), np.arange(len(x)), 0.03),
    "outliers": lambda x, rng: (np.vstack([warp(x), outliers(rng, warp(x), 60)]), np.arange(len(x)), 0.01),
    "rotation 180": lambda x, rng: (warp(x) @ rot2(np.pi).T * 2.0 + [3.0, -1.0], np.arange(len(x)), 0.01),
}


@pytest.mark.parametrize("name", list(CASES))
def test_each_degradation_is_recovered_with_the_defaults_and_said_reliable(name):
    x = fish()
    rng = np.random.default_rng(7)
    y, known, tol = CASES[name](x, rng)
    truth = y[: len(known)] if name != "noise" else warp(x)
    res, warned = register_quietly(x, rng.permutation(y, axis=0))
    err = np.mean(np.linalg.norm(res.points[known] - truth, axis=1))
    assert err < tol * size(truth), (name, err)
    assert res.reliable and not res.reasons and not warned, res.reasons


def test_outliers_in_the_target_are_unmatched():
    x = fish()
    rng = np.random.default_rng(3)
    y = np.vstack([warp(x), outliers(rng, warp(x), 60)])  # half the target is clutter
    res, _ = register_quietly(x, y)
    assert res.w in sl.pointsets._nonrigid.W_GRID
    tc = res.target_correspondence
    assert np.mean(tc[60:] == -1) > 0.9  # the clutter has no source point
    off = np.abs(tc[:60] - np.arange(60))
    assert np.mean(np.minimum(off, 60 - off) <= 1) > 0.9  # the outline keeps its counterparts (± one point)


def test_a_part_only_the_source_has_matches_nothing():
    x = fish()
    y = warp(x, 0.25)[:52]  # the last eight points of the outline are missing from the target
    res, _ = register_quietly(x, y)
    assert np.sum(res.correspondence[53:] == -1) >= 5  # inside the missing part: no counterpart
    assert np.mean(res.target_correspondence >= 0) > 0.8  # and most target points have one


def test_a_fit_leaving_over_a_third_of_the_source_unmatched_is_flagged_and_a_small_gap_is_not():
    x = fish()
    small, _ = register_quietly(x, warp(x, 0.25)[:52])  # 8 of 60 source points without a counterpart
    assert small.reliable, small.reasons
    large, warned = register_quietly(x, warp(x, 0.25)[:42])  # 18 of 60: the warp only extrapolates them
    assert not large.reliable and warned
    assert any("match no target point" in r for r in large.reasons)
    # the share it reports is that of the source points whose posteriors sum to under one half
    share = float(np.mean(large.probabilities.sum(axis=1) < 0.5))
    assert large.diagnostics["unmatched_source_share"] == pytest.approx(share)
    assert share > 1 / 3 > float(np.mean(small.probabilities.sum(axis=1) < 0.5))


def test_a_symmetric_shape_is_flagged_as_ambiguous():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    ellipse = np.column_stack([1.6 * np.cos(t), np.sin(t)])  # the same shape after a half turn
    res, warned = register_quietly(ellipse, ellipse @ rot2(0.4).T)
    assert not res.reliable and warned
    assert any("another pose" in r for r in res.reasons)
    assert "NOT RELIABLE" in res.summary()


def _angle(res):
    a = res.pose.matrix
    return float(np.arctan2(a[1, 0], a[0, 0]))


def test_of_a_symmetric_shapes_two_poses_the_one_that_turns_the_source_less_wins_and_is_flagged():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    ellipse = np.column_stack([1.6 * np.cos(t), np.sin(t)])  # the same shape after a half turn
    target = ellipse @ rot2(0.6).T + 0.01 * np.random.default_rng(4).normal(size=ellipse.shape)
    res, _ = register_quietly(ellipse, target)
    assert abs(_angle(res)) < np.pi / 2  # turned by about 0.6, not by π + 0.6
    assert not res.reliable and any("another pose" in r for r in res.reasons)
    # the target turned by a further half turn: now the other pose is the one that turns the source less
    res, _ = register_quietly(ellipse, target @ rot2(np.pi).T)
    assert abs(_angle(res)) < np.pi / 2
    # a negative price is refused
    with pytest.raises(ValueError, match="pose_prior must be a non-negative finite number"):
        sl.register(ellipse, target, pose_prior=-0.1)


def test_a_price_on_the_turn_the_data_cannot_pay_keeps_the_source_unturned_and_says_so():
    x = fish(40)
    y = warp(x) @ rot2(2.0).T
    free, _ = register_quietly(x, y, pose_prior=0.0)
    assert abs(_angle(free) - 2.0) < 0.3 and free.reliable
    stiff, _ = register_quietly(x, y, pose_prior=50.0)  # 50 nats per point for a quarter turn
    assert abs(_angle(stiff)) < 1.0 and not stiff.reliable
    assert any("explains the target better" in r for r in stiff.reasons)


def test_the_command_lines_pose_prior_is_registers(tmp_path, capsys):
    src, dst = tmp_path / "a.npy", tmp_path / "b.npy"
    x = fish(40)
    np.save(src, x)
    np.save(dst, warp(x) @ rot2(2.0).T)
    moved = {}
    for extra, kw in (([], {}), (["--pose-prior", "0"], {"pose_prior": 0.0}), (["--pose-prior", "50"], {"pose_prior": 50.0})):
        status = main(["register", str(src), str(dst), "-o", str(tmp_path / "m.npy")] + extra)
        res, _ = register_quietly(x, warp(x) @ rot2(2.0).T, **kw)
        assert status == (0 if res.reliable else EXIT_UNCONVERGED)
        moved[kw.get("pose_prior")] = np.load(tmp_path / "m.npy")
        np.testing.assert_array_equal(moved[kw.get("pose_prior")], res.points)
    assert np.abs(moved[50.0] - moved[0.0]).max() > 0.1   # the value given is the one used
    assert main(["register", str(src), str(dst), "-o", str(tmp_path / "m.npy"), "--pose-prior", "-1"]) == 1
    assert "pose_prior must be a non-negative finite number" in capsys.readouterr().err
    default = inspect.signature(sl.register).parameters["pose_prior"].default
    assert default == shapelib.pointsets._nonrigid.POSE_PRIOR == 0.12
    args = build_parser().parse_args(["register", str(src), str(dst), "-o", "m.npy"])
    assert args.pose_prior == default   # the command line's default is register's


def test_a_target_of_pure_noise_is_flagged_not_reported_as_a_good_fit():
    x = fish()
    y = np.random.default_rng(0).uniform(-1.5, 1.5, size=(80, 2))
    res, warned = register_quietly(x, y)
    assert not res.reliable and warned and res.reasons


def test_reordering_either_set_only_reorders_the_result():
    x, y = fish(), warp(fish()) @ rot2(2.0).T
    rng = np.random.default_rng(1)
    ps, pt = rng.permutation(60), rng.permutation(60)
    a, _ = register_quietly(x, y)
    b, _ = register_quietly(x[ps], y[pt])
    assert np.allclose(b.points, a.points[ps], atol=1e-4 * size(y))  # EM stops at its tolerance
    assert np.mean(pt[b.correspondence] == a.correspondence[ps]) > 0.95


def test_sigma2_and_the_objective_are_in_the_target_units():
    x, y = fish(), warp(fish())
    a, _ = register_quietly(x, y)
    b, _ = register_quietly(x, 10.0 * y + 5.0)  # the same target in other units
    assert b.sigma2 == pytest.approx(100.0 * a.sigma2, rel=1e-6)
    assert b.sigma2_objective == pytest.approx(100.0 * a.sigma2_objective, rel=1e-6)
    assert np.allclose(b.points, 10.0 * a.points + 5.0, atol=1e-6)
    # the objective is the L2 distance of the moved source's and the target's mixtures at sigma2_objective
    for r, t in ((a, y), (b, 10.0 * y + 5.0)):
        independent = np.sqrt(sl.l2_distance_sq(r.points, t, sigma2=r.sigma2_objective))
        assert r.objective == pytest.approx(independent, rel=1e-6)


def test_the_em_sigma2_of_an_exact_fit_is_tiny_and_of_a_noisy_fit_near_the_noise():
    x = fish()
    y = warp(x) + np.random.default_rng(5).normal(scale=0.03, size=x.shape)
    res, _ = register_quietly(x, y)
    # sigma2 estimates the residual variance per coordinate, between the noise's share left after the
    # smooth fit and the noise itself
    assert 0.2 * 0.03 ** 2 < res.sigma2 < 1.5 * 0.03 ** 2


def test_the_kernel_on_the_means_interpolates_and_follows_a_mild_bend():
    x = fish(30)
    y = warp(x, 0.1)
    res, _ = register_quietly(x, y, kernel="means")
    assert np.allclose(res.warp(x), res.points, atol=1e-8)  # the kernel carries the source onto the fit
    assert np.mean(np.linalg.norm(res.points - y, axis=1)) < 0.05 * size(y)


def test_three_dimensional_rotation_and_bend_are_recovered():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(2)
    x = rng.normal(size=(60, 3)) * [2.0, 1.0, 0.6]
    y = (x + 0.15 * np.sin(x[:, [1, 2, 0]])) @ Rotation.from_euler("zyx", [150, 40, 70], degrees=True).as_matrix().T
    res, _ = register_quietly(x, y[::-1])
    assert np.median(np.linalg.norm(res.points - y, axis=1)) < 0.01 * size(y)  # the far tails of a
    assert res.reliable  # Gaussian cloud have few neighbours to follow


@pytest.mark.parametrize("kwargs, words", [
    (dict(sigma2="sometimes"), "sigma2 must be a positive number or 'auto'"),
    (dict(sigma2=0.0), "sigma2"),
])
def test_bad_sigma2_gets_one_clear_error(kwargs, words):
    with pytest.raises(ValueError, match=words):
        sl.register(fish(10), fish(12), **kwargs)


def test_command_line_sigma2_auto_and_the_exit_status_of_a_probable_failure(tmp_path, capsys):
    src, good, noise = tmp_path / "s.csv", tmp_path / "t.csv", tmp_path / "n.csv"
    sl.write_point_set(src, fish())
    sl.write_point_set(good, warp(fish()))
    sl.write_point_set(noise, np.random.default_rng(0).uniform(-1.5, 1.5, size=(80, 2)))
    assert main(["register", str(src), str(good), "-o", str(tmp_path / "m.csv"), "--sigma2", "auto"]) == 0
    out = capsys.readouterr().out
    assert "reliable" in out and "NOT RELIABLE" not in out
    assert main(["register", str(src), str(noise), "-o", str(tmp_path / "m2.csv")]) == EXIT_UNCONVERGED
    captured = capsys.readouterr()
    assert "NOT RELIABLE" in captured.out and "probably failed" in captured.err
    assert main(["register", str(src), str(good), "-o", str(tmp_path / "m3.csv"), "--sigma2", "big"]) == 1
    assert "--sigma2 must be a positive number or 'auto'" in capsys.readouterr().err


def test_large_sets_go_through_subsets_and_every_point_is_carried(monkeypatch):
    """Over MAX_POINTS the registration runs on farthest-point subsets and its kernel warp moves
    every source point (here with a small MAX_POINTS, on 300-point outlines)."""
    from shapelib.pointsets import registration

    monkeypatch.setattr(registration, "MAX_POINTS", 80)
    x = fish(300)
    y = warp(x, 0.25)
    res, _ = register_quietly(x, y[::-1])
    assert res.diagnostics["subsets"] == (80, 80)
    assert res.points.shape == (300, 2)
    from scipy.spatial import cKDTree

    # on the warped outline (a densely sampled curve: points may slide along it), and near their own images
    assert np.median(cKDTree(y).query(res.points)[0]) < 0.01 * size(y)
    assert np.median(np.linalg.norm(res.points - y, axis=1)) < 0.05 * size(y)
    assert np.mean(res.correspondence >= 0) > 0.95
    with pytest.raises(ValueError, match="not kept for sets over 80 points"):
        res.probabilities
    with pytest.raises(ValueError, match="metric='alpha' and kernel='weights'"):
        sl.register(x, y, metric="fisher_rao")


def test_farthest_points_spread_over_the_set():
    from shapelib.pointsets.registration import farthest_points

    a = np.vstack([np.zeros((50, 2)), [[10.0, 0.0]], np.ones((50, 2)) * [0, 5]])
    idx = farthest_points(a, 3)
    assert sorted(map(tuple, a[idx])) == sorted([(0.0, 0.0), (10.0, 0.0), (0.0, 5.0)])


def test_a_large_rigid_registration_runs_on_subsets_and_moves_every_point_by_the_pose(monkeypatch):
    """The rigid transforms go through the subsets too (no (n, m) matrix of the whole sets): a known
    rotation and shift are recovered and applied to every point."""
    from shapelib.pointsets import registration

    monkeypatch.setattr(registration, "MAX_POINTS", 80)
    monkeypatch.setattr(registration, "WARP_BLOCK", 64)  # several blocks
    x = fish(300)
    y = x @ rot2(1.1).T + [0.3, -0.2]
    res = sl.register(x, y[::-1], transform="rigid")
    assert res.diagnostics["subsets"] == (80, 80)
    np.testing.assert_allclose(res.pose.matrix, rot2(1.1), atol=1e-3)
    np.testing.assert_allclose(res.points, x @ res.pose.matrix.T + res.pose.translation, atol=1e-12)
    assert np.max(np.linalg.norm(res.points - y, axis=1)) < 0.01 * size(y)


def test_progress_is_reported_for_every_start_and_fit_and_checked():
    x = fish(40)
    calls = []
    register_quietly(x, warp(x, 0.2), progress=lambda done, total: calls.append((done, total)))
    nr = shapelib.pointsets._nonrigid
    # every start, then every final fit; the total counts the source as given among the kept starts until
    # the screening says whether it is one of the N_KEEP best (here, the target as posed: it is)
    n_fits = len(calls) - nr.N_ROT_2D
    assert n_fits == nr.N_KEEP * len(nr.W_GRID)
    assert calls == ([(k, nr.N_ROT_2D + (nr.N_KEEP + 1) * len(nr.W_GRID)) for k in range(1, nr.N_ROT_2D + 1)]
                     + [(nr.N_ROT_2D + k, nr.N_ROT_2D + n_fits) for k in range(1, n_fits + 1)])
    calls.clear()
    sl.register(x, x + 0.1, transform="similarity", progress=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 2), (2, 2)]
    with pytest.raises(ValueError, match="progress must be a callable"):
        sl.register(x, x, progress=3)


def test_the_command_line_takes_the_em_options_its_message_names(tmp_path, capsys):
    x = fish(40)
    src, dst = tmp_path / "a.csv", tmp_path / "b.csv"
    for path, pts in ((src, x), (dst, warp(x, 0.2))):
        path.write_text("x,y\n" + "\n".join(f"{a},{b}" for a, b in pts) + "\n")
    assert main(["register", str(src), str(dst), "-o", str(tmp_path / "m.csv"), "--max-iter", "2"]) == EXIT_UNCONVERGED
    assert "raise --max-iter or loosen --tol" in capsys.readouterr().err
    assert main(["register", str(src), str(dst), "-o", str(tmp_path / "m.csv"), "--max-iter", "400", "--tol", "1e-4"]) == 0
    assert main(["register", str(src), str(dst), "-o", str(tmp_path / "m.csv"), "--max-iter", "0"]) == 1
    assert "max_iter" in capsys.readouterr().err


def test_a_large_registration_is_checked_by_the_same_fit_on_other_subsets(monkeypatch):
    """Over MAX_POINTS a second fit runs on other farthest-point subsets (each grown from the point farthest
    from its set's centroid); on a well-determined outline both put the points in the same places. The
    distance reported is the one between the result and that second fit, redone here by the public API;
    progress counts both fits."""
    from shapelib.pointsets import registration

    monkeypatch.setattr(registration, "MAX_POINTS", 80)
    x = fish(300)
    y = warp(x, 0.25)[::-1]
    calls = []
    res = sl.register(x, y, progress=lambda done, total: calls.append((done, total)), warn=False)
    assert not any("other subsets" in r for r in res.reasons)
    far = [int(np.argmax(np.sum((a - a.mean(axis=0)) ** 2, axis=1))) for a in (x, y)]
    jx, jy = (registration.farthest_points(a, 80, first=f) for a, f in zip((x, y), far))
    assert len(set(jx) ^ set(registration.farthest_points(x, 80))) > 0  # other subsets indeed
    other = sl.register(x[jx], y[jy], warn=False)
    apart = np.mean(np.linalg.norm(res.points - other.warp(x), axis=1)) / size(y)
    assert res.diagnostics["subset_disagreement"] == pytest.approx(apart, rel=1e-9)
    assert apart < registration.SUBSET_DISAGREEMENT
    # both fits counted: done rises by one to the total at the end, which no total said before undercuts
    assert [c[0] for c in calls] == list(range(1, len(calls) + 1)) and calls[-1][1] == len(calls)
    assert all(done <= total for done, total in calls) and min(t for _, t in calls) >= len(calls) // 2


def test_a_large_surface_whose_points_slide_along_it_is_flagged_by_the_second_fit(monkeypatch):
    """A densely sampled smooth surface registered through subsets a tenth of its size: the landmarks fix
    the pose, but not where along the surface each point goes, and two fits on different subsets put the
    points apart. The result says so — and it is indeed wrong."""
    from shapelib.pointsets import registration

    monkeypatch.setattr(registration, "MAX_POINTS", 200)
    from test_registration_landmarks import _egg

    x, y, truth, lm = _egg(2000, 1)
    with pytest.warns(sl.RegistrationWarning, match="^register: the registration is probably wrong: a fit on other "
                                                     "subsets of the points moves them"):
        res = sl.register(x, y, landmarks=lm)
    assert res.reliable is False
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # warn=False: said in the result only
        quiet = sl.register(x, y, landmarks=lm, warn=False)
    assert quiet.reasons == res.reasons
    assert [r for r in res.reasons if "other subsets" in r] == list(res.reasons[-1:])
    assert res.diagnostics["subset_disagreement"] > registration.SUBSET_DISAGREEMENT
    assert "other subsets" in res.summary()
    error = np.mean(np.linalg.norm(res.points - truth, axis=1)) / size(truth)
    assert error > 0.05
