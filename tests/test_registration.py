"""shapelib.register: a known rigid motion recovered at any angle (2-D, 3-D, a mirror when asked),
the target's order irrelevant, different sizes, a known smooth deformation recovered with its
correspondences, outliers and a missing part, the geodesic path and the warp of new points, and
one clear error for each bad input."""

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import shapelib as sl


def fish(n=50):
    """A closed outline with no symmetry: a body and a tail, thicker in front."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])


def rot2(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def bend(x, amount=0.25):
    """A smooth non-rigid warp: the outline bent upwards at its ends."""
    return x + np.column_stack([0.05 * np.sin(2 * x[:, 1]), amount * x[:, 0] ** 2])


@pytest.mark.parametrize("angle", [30.0, 100.0, 180.0, 250.0])
def test_a_rigid_motion_is_recovered_exactly_at_any_angle_with_its_correspondences(angle):
    x = fish()
    y = x @ rot2(np.radians(angle)).T + [2.0, -1.0]
    perm = np.random.default_rng(int(angle)).permutation(len(y))
    res = sl.register(x, y[perm], transform="rigid")
    assert res.converged and res.transform == "rigid"
    assert np.abs(res.points - y).max() < 1e-6
    assert np.array_equal(perm[res.correspondence], np.arange(len(x)))
    assert (res.pose.angle - angle + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-5)
    assert np.allclose(res.warp(x), y, atol=1e-6)  # the pose moves new points too


def test_a_mirror_is_recovered_when_asked_and_only_then():
    x = fish()[:35]  # an open piece of outline: no symmetry at all
    y = x @ np.diag([1.0, -1.0]) @ rot2(2.0).T
    res = sl.register(x, y, transform="rigid", reflection=True)
    assert res.pose.reflection and np.abs(res.points - y).max() < 1e-6
    assert not sl.register(x, y, transform="rigid").pose.reflection


def test_three_dimensional_rigid_and_similarity():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(40, 3)) * [3.0, 2.0, 1.0]
    r = Rotation.random(random_state=3).as_matrix()
    y = 1.5 * x @ r.T + [1.0, 2.0, 3.0]
    res = sl.register(x, y[::-1], transform="similarity")
    assert np.abs(res.points - y).max() < 1e-5 and res.pose.scale == pytest.approx(1.5, rel=1e-7)
    assert np.array_equal(res.correspondence, np.arange(40)[::-1])


@pytest.fixture(scope="module")
def bent():
    """A fish bent and turned by 140 degrees, registered non-rigidly (source 50 points)."""
    x = fish()
    y = bend(x) @ rot2(np.radians(140)).T + [0.5, 0.3]
    perm = np.random.default_rng(1).permutation(len(y))
    return x, y, perm, sl.register(x, y[perm])


def test_a_known_smooth_deformation_is_recovered_with_its_correspondences(bent):
    x, y, perm, res = bent
    size = np.sqrt(np.mean(np.sum((y - y.mean(0)) ** 2, axis=1)))
    assert res.converged and res.stop_reason == "tolerance"
    assert np.abs(res.points - y).max() < 1e-3 * size
    assert np.array_equal(perm[res.correspondence], np.arange(len(x)))
    assert res.objective < 1e-3
    assert "nonrigid registration (alpha) of 50 points onto 50" in res.summary()


def test_shuffling_the_target_changes_nothing(bent):
    x, y, perm, res = bent
    again = sl.register(x, y)
    assert np.allclose(again.points, res.points, atol=1e-7)
    assert np.array_equal(again.correspondence, perm[res.correspondence])


def test_the_deformation_path_is_a_geodesic_from_the_posed_source_and_the_warp_moves_new_points():
    x = fish(24)
    y = bend(x) @ rot2(np.radians(60)).T
    res = sl.register(x, y, n_steps=4)
    path = res.path
    assert path.shape == (5, 24, 2)
    assert np.allclose(path[0], res.rigid_points) and np.allclose(path[-1], res.points)
    assert res.geodesic.length >= res.geodesic.lower_bound > 0
    # the kernel carries the source exactly onto the fitted points
    assert np.allclose(res.warp(x), res.points, atol=1e-8)
    size = np.sqrt(np.mean(np.sum((y - y.mean(0)) ** 2, axis=1)))
    mid = 0.5 * (x[3] + x[4])  # a point between two outline points lands between their images
    assert np.linalg.norm(res.warp(mid[None])[0] - 0.5 * (y[3] + y[4])) < 0.02 * size
    # the extrinsic flow along the geodesic (§III-E) brings the source nearer the fit than the pose alone
    flow = res.warp(x, method="extrinsic", grid_size=32)
    assert np.mean(np.linalg.norm(flow - res.points, axis=1)) < 0.7 * np.mean(
        np.linalg.norm(res.rigid_points - res.points, axis=1))


def test_different_sizes_a_missing_part_and_outliers():
    x = fish(60)
    truth = bend(x, 0.2) @ rot2(np.radians(-70)).T
    keep = np.r_[0:45]  # the last quarter of the outline is missing from the target
    rng = np.random.default_rng(2)
    lo, hi = truth.min(0) - 0.3, truth.max(0) + 0.3
    outliers = lo + (hi - lo) * rng.random((15, 2))
    y = np.vstack([truth[keep], outliers])  # 45 inliers, 15 outliers
    res = sl.register(x, y, w="auto")
    size = np.sqrt(np.mean(np.sum((truth - truth.mean(0)) ** 2, axis=1)))
    err = np.linalg.norm(res.points[keep] - truth[keep], axis=1)
    assert np.median(err) < 0.02 * size
    assert np.mean(res.target_correspondence[45:] == -1) > 0.6  # the 15 outliers are mostly unmatched
    c = res.correspondence
    assert np.mean(c[keep] == keep) > 0.5  # most kept points find their counterparts
    assert np.mean(c[45:] == -1) > 0.6  # the missing part is mostly unmatched


def test_three_dimensional_nonrigid():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(40, 3)) * [2.0, 1.0, 0.7]
    r = Rotation.random(random_state=4).as_matrix()
    y = (x + 0.1 * np.sin(x[:, [1, 2, 0]])) @ r.T
    res = sl.register(x, y[::-1])
    assert np.abs(res.points - y).max() < 0.02
    assert np.allclose(res.warp(x), res.points, atol=1e-8)
    with pytest.raises(ValueError, match="implemented in 2-D"):
        res.warp(x, method="extrinsic")


def test_fisher_rao_nonrigid_registration_recovers_a_bend_and_its_correspondences():
    x = fish(30)
    y = bend(x) @ rot2(np.radians(150)).T
    res = sl.register(x, y[::-1], metric="fisher_rao")
    assert res.metric == "fisher_rao" and np.abs(res.points - y).max() < 1e-3
    assert np.array_equal(res.correspondence, np.arange(30)[::-1])
    with pytest.raises(ValueError, match="closed-form alpha kernel"):
        res.warp(x)


def test_fisher_rao_registration_recovers_a_rotation():
    x = fish(30)
    y = x @ rot2(np.radians(200)).T
    res = sl.register(x, y, transform="rigid", metric="fisher_rao", sigma2=0.01)
    assert np.abs(res.points - y).max() < 1e-4


@pytest.mark.parametrize("kwargs, words", [
    (dict(transform="spline"), "transform must be one of"),
    (dict(metric="procrustes"), "metric must be one of"),
    (dict(w=1.0), "w must be in [0, 1) or 'auto'"),
    (dict(w="sometimes"), "w must be a number in [0, 1) or 'auto'"),
    (dict(sigma2=-1.0), "sigma2 must be a positive"),
    (dict(lam=0), "lam must be a positive"),
    (dict(kernel="tps"), "kernel must be one of"),
])
def test_bad_options_get_one_clear_error_each(kwargs, words):
    with pytest.raises(ValueError) as info:
        sl.register(fish(10), fish(12), **kwargs)
    assert words in str(info.value)


def test_bad_point_sets_are_named():
    with pytest.raises(sl.InputError, match=r"target: point 2 has a non-finite coordinate 0"):
        sl.register(fish(10), np.vstack([fish(5)[:2], [[np.nan, 0.0]]]))
    with pytest.raises(sl.InputError, match="source has d = 2 coordinates per point and target d = 3"):
        sl.register(fish(10), np.random.default_rng(0).normal(size=(5, 3)))
    with pytest.raises(sl.InputError, match="source has 1 point"):
        sl.register([[0.0, 0.0]], fish(10))


def test_probabilities_are_posteriors():
    x = fish(20)
    y = np.vstack([x @ rot2(0.5).T, [[5.0, 5.0]]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = sl.register(x, y, transform="rigid", w="auto")
    p = res.probabilities
    assert p.shape == (20, 21) and np.all(p >= 0) and np.all(p.sum(axis=0) <= 1 + 1e-12)
    assert p[:, 20].sum() < 1e-3  # the far point is an outlier
