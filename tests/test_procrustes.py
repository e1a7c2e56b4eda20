import itertools
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.spatial import procrustes as scipy_procrustes

from shapelib.geometry.procrustes import (
    PoseWarning,
    centroid_size,
    generalized_procrustes,
    pose_align,
    preshape,
    procrustes_align,
    procrustes_distance,
)
from tests.conftest import ROOT, requires_data


def rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def test_preshape_is_centred_unit_size(rng):
    p = preshape(rng.normal(size=(10, 2)) * 5 + 3)
    assert np.allclose(p.mean(0), 0) and np.isclose(np.linalg.norm(p), 1)


def test_distance_invariant_to_similarity_transforms_of_either_shape(rng):
    u, v = rng.normal(size=(2, 12, 2))
    d = procrustes_distance(u, v)
    v2 = 3.7 * v @ rot(1.1).T + [5, -2]
    u2 = 0.2 * u @ rot(-2.0).T + [-1, 9]
    assert procrustes_distance(u2, v2) == pytest.approx(d, rel=1e-12)


def test_symmetry_zero_and_range(rng):
    u, v = rng.normal(size=(2, 9, 2))
    assert procrustes_distance(u, v) == pytest.approx(procrustes_distance(v, u), rel=1e-12)
    assert procrustes_distance(u, 2 * u @ rot(0.3).T) == pytest.approx(0, abs=1e-7)
    assert 0 <= procrustes_distance(u, v) <= np.pi / 2


def test_reflection_is_not_a_symmetry():
    u = np.array([[0, 0], [2, 0], [0, 1], [0.3, 0.2]], float)
    mirrored = u * [-1, 1]
    assert procrustes_distance(u, mirrored) > 0.1


def test_kinds_related_in_closed_form(rng):
    u, v = rng.normal(size=(2, 15, 2))
    rho = procrustes_distance(u, v, kind="angle")
    assert procrustes_distance(u, v, kind="full") == pytest.approx(np.sin(rho), rel=1e-12)
    assert procrustes_distance(u, v, kind="partial") == pytest.approx(2 * np.sin(rho / 2), rel=1e-12)


def test_full_distance_squared_is_scipy_disparity(rng):
    u = rng.normal(size=(20, 2))
    v = u @ rot(0.7).T * 2 + rng.normal(scale=0.2, size=(20, 2))  # close: optimum is a rotation
    _, _, disparity = scipy_procrustes(u, v)
    assert procrustes_distance(u, v, kind="full") ** 2 == pytest.approx(disparity, rel=1e-10)


def test_align_recovers_a_similarity_transform(rng):
    x = rng.normal(size=(8, 2))
    y = 0.5 * x @ rot(2.2).T + [3, 4]
    assert np.allclose(procrustes_align(x, y), x, atol=1e-12)
    y_no_scale = procrustes_align(x, y, scaling=False)
    assert centroid_size(y_no_scale) == pytest.approx(centroid_size(y))


def test_gpa_aligns_rotated_copies_and_is_idempotent(rng):
    base = rng.normal(size=(10, 2))
    shapes = np.stack([s * base @ rot(t).T + off for s, t, off in [(1, 0, 0), (2, 1, 3), (0.5, -2, -1)]])
    aligned, mean = generalized_procrustes(shapes, scaling=False)
    assert np.allclose(aligned, aligned[0], atol=1e-10)
    assert np.isclose(np.linalg.norm(mean), 1)
    again, _ = generalized_procrustes(aligned, scaling=False)
    for a in again:  # aligned shapes stay the same shapes
        assert procrustes_distance(a, preshape(base)) == pytest.approx(0, abs=1e-6)


def test_gpa_reduces_sum_of_squares(rng):
    shapes = rng.normal(size=(5, 12, 2))
    aligned, mean = generalized_procrustes(shapes, scaling=False)
    pre = np.stack([preshape(s) for s in shapes])
    ss = lambda arr: np.sum((arr - arr.mean(0)) ** 2)
    assert ss(aligned) < ss(pre)


@pytest.mark.parametrize("kind", ["angle", "full"])
def test_errors(kind):
    with pytest.raises(ValueError, match="same number of landmarks"):
        procrustes_distance(np.zeros((3, 2)), np.zeros((4, 2)), kind=kind)
    with pytest.raises(ValueError, match="at least 2 landmark"):
        procrustes_distance(np.zeros((1, 2)), np.zeros((1, 2)), kind=kind)
    with pytest.raises(ValueError, match="zero centroid size"):
        procrustes_distance(np.ones((3, 2)), np.eye(3, 2), kind=kind)
    with pytest.raises(ValueError, match="non-finite"):
        procrustes_distance(np.full((3, 2), np.nan), np.eye(3, 2), kind=kind)
    with pytest.raises(ValueError, match="kind must be"):
        procrustes_distance(np.eye(3, 2), np.eye(3, 2), kind="bogus")


@requires_data
def test_table1_procrustes_column_is_reproduced():
    """17 of the 21 computable pairs agree to print precision; all within 0.5 %."""
    from shapelib.datasets import load_corpus_callosum

    shapes, ids = load_corpus_callosum()
    ref = pd.read_csv(ROOT / "data" / "reference" / "table1.csv", comment="#").set_index("key")
    exact, rel = 0, []
    for i, j in itertools.combinations(range(7), 2):
        a, b = sorted((ids[i], ids[j]))
        paper = ref.loc[f"table1/procrustes/{a}-{b}", "value"]
        ours = procrustes_distance(shapes[i], shapes[j])
        exact += abs(ours - paper) <= 0.5e-4 + 1e-12
        rel.append(abs(ours / paper - 1))
    assert exact >= 17
    assert max(rel) < 0.005


# ---------------------------------------------------------------------------------------------
# pose: closed forms for a rectangle moved rigidly (centroid size √5)
# ---------------------------------------------------------------------------------------------

RECT = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])


def _turned(theta, shift=(0.0, 0.0)):
    c = RECT.mean(axis=0)
    r = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    return (RECT - c) @ r.T + c + np.asarray(shift)


def test_pose_change_of_rigid_moves_scalings_and_points():
    """Turned by θ about its centroid: every landmark moves 2 sin(θ/2) of its distance to the centroid,
    so moved = 2 sin(θ/2), nothing remains; shifted by (3, 4): moved = 5 √K / S; scaled by 1.1 about
    the centroid: nothing to move, 0.1 S remains over the mean size 1.05 S; a point v: only its
    position, ‖p − c‖ √K / (S/2), and u's whole size remains (2)."""
    from shapelib.geometry.procrustes import pose_change

    s = np.sqrt(5.0)
    moved, remaining = pose_change(RECT, _turned(0.6))
    assert moved == pytest.approx(2 * np.sin(0.3), rel=1e-12) and remaining == pytest.approx(0.0, abs=1e-12)
    moved, remaining = pose_change(RECT, RECT + [3.0, 4.0])
    assert moved == pytest.approx(5 * 2 / s, rel=1e-12) and remaining == pytest.approx(0.0, abs=1e-12)
    c = RECT.mean(axis=0)
    moved, remaining = pose_change(RECT, c + 1.1 * (RECT - c))
    assert moved == pytest.approx(0.0, abs=1e-12) and remaining == pytest.approx(0.1 / 1.05, rel=1e-12)
    moved, remaining = pose_change(RECT, np.full((4, 2), 5.0))
    assert moved == pytest.approx(np.linalg.norm([4.0, 4.5]) * 2 / (s / 2), rel=1e-12)
    assert remaining == pytest.approx(2.0, rel=1e-12)
    assert pose_change(np.zeros((3, 2)), np.zeros((3, 2))) == (0.0, 0.0)


def test_pose_align_of_two_turned_copies_meets_halfway():
    """A rectangle and its copy turned by θ: the mean lies halfway, each is turned by θ/2 onto it, so
    each moves 2 sin(θ/4) of its size, and the two aligned copies coincide (sizes kept)."""
    aligned, moved = pose_align(np.stack([RECT, _turned(0.6, shift=(0.0, 0.0))]))
    np.testing.assert_allclose(moved, [2 * np.sin(0.15)] * 2, rtol=1e-10)
    np.testing.assert_allclose(aligned[0], aligned[1], atol=1e-12)
    assert centroid_size(aligned[0]) == pytest.approx(np.sqrt(5.0), rel=1e-12)


def test_check_pose_warns_with_the_amounts_and_returns_them():
    """A pair: the warning names the metric, the move 2 sin(0.3) = 59.1 % and what remains; a scaled
    copy (no pose to change) and shapes within tol pass quietly; three shapes: the count and the worst."""
    from shapelib.geometry.procrustes import check_pose

    with pytest.warns(PoseWarning, match=r"^alpha depends on the pose of the shapes, and u and v are not aligned: "
                                         r"rotating and translating v onto u moves it by 59.1 % of their size, "
                                         r"against a shape difference of .* % that remains, so the distance measures "
                                         r"their relative pose as well as their shapes. Align them first: v = "
                                         r"shapelib.procrustes_align\(u, v, scaling=False\), or "
                                         r"shapelib.pose_align\(shapes\)\[0\] for a whole set.$"):
        assert check_pose(np.stack([RECT, _turned(0.6)]), metric="alpha") == pytest.approx(2 * np.sin(0.3))
    c = RECT.mean(axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_pose(np.stack([RECT, c + 1.1 * (RECT - c)]), metric="alpha") == pytest.approx(0.0, abs=1e-12)
        assert check_pose(np.stack([RECT, _turned(1e-4)]), metric="alpha") == pytest.approx(2 * np.sin(5e-5))
        assert check_pose(np.stack([RECT, _turned(1e-4), RECT]), metric="alpha") < 1e-3
        assert check_pose(RECT[None, :1], metric="alpha") == 0.0
    with pytest.warns(PoseWarning, match=r"^fisher_rao depends on the pose of the shapes, and these are not aligned: "
                                         r"aligning them \(rotations and translations\) moves 3 of 3 shapes by more "
                                         r"than 0.1 % of their size, shapes\[2\] by .* %\. Align them first"):
        check_pose(np.stack([RECT, RECT, _turned(0.6)]), metric="fisher_rao")


def test_optimal_rotation_of_a_mirror_image_against_a_brute_force_search(rng):
    """y a mirror image of x: the best proper rotation (no reflection), found by scanning the angle
    and polishing with a bounded search, gives the same R and the same Σ s = max_θ tr(R(θ)ᵀ yᵀx);
    with reflection allowed the mirror itself, with Σ s the sum of the singular values."""
    from scipy.optimize import minimize_scalar

    from shapelib.geometry.procrustes import optimal_rotation

    x = rng.normal(size=(7, 2))
    x -= x.mean(axis=0)
    y = x * [1.0, -1.0] @ np.array([[np.cos(0.4), -np.sin(0.4)], [np.sin(0.4), np.cos(0.4)]])

    def rot(t):
        return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])

    def fit(t):
        return np.trace(rot(t).T @ y.T @ x)

    grid = np.linspace(-np.pi, np.pi, 721)
    t0 = grid[np.argmax([fit(t) for t in grid])]
    best = minimize_scalar(lambda t: -fit(t), bounds=(t0 - 0.01, t0 + 0.01), method="bounded",
                           options={"xatol": 1e-12})
    r, tr = optimal_rotation(x, y)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    assert tr == pytest.approx(-best.fun, rel=1e-10)
    np.testing.assert_allclose(r, rot(best.x), atol=1e-6)
    r, tr = optimal_rotation(x, y, reflection=True)
    assert np.linalg.det(r) == pytest.approx(-1.0, abs=1e-12)
    assert tr == pytest.approx(np.linalg.svd(y.T @ x, compute_uv=False).sum(), rel=1e-12)
    np.testing.assert_allclose(y @ r, x, atol=1e-12)


def test_procrustes_functions_name_their_arguments_and_sizes_without_overflow():
    """Errors name x, y and shapes; a zero-size y cannot be scaled; centroid sizes of coordinates near
    1e200 and 1e-200 (whose squares overflow and underflow) keep their closed form L / √2 for two
    landmarks L apart; procrustes_align maps a similarity copy back without reflecting by default."""
    from shapelib.geometry.procrustes import center, check_pose

    flat = np.zeros(3)
    sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    for f in (center, preshape):
        with pytest.raises(ValueError, match=r"^x\b"):
            f(flat)
    with pytest.raises(ValueError, match=r"^x\b"):
        procrustes_align(flat, sq)
    with pytest.raises(ValueError, match=r"^y\b"):
        procrustes_align(sq, flat)
    with pytest.raises(ValueError, match=r"^shapes\b"):
        pose_align(flat)
    with pytest.raises(ValueError, match=r"^shapes\b"):
        check_pose(flat, metric="alpha")
    with pytest.raises(ValueError, match=r"^y has zero centroid size \(all landmarks coincide\); cannot scale it$"):
        procrustes_align(sq, np.ones((4, 2)))
    for big in (1e200, 1e-200):
        two = np.array([[0.0, 0.0], [big, 0.0]])
        assert centroid_size(two) == pytest.approx(big / np.sqrt(2), rel=1e-14, abs=0)
    c, s = np.cos(0.5), np.sin(0.5)
    copy = 2.5 * (sq - 3.0) @ np.array([[c, -s], [s, c]]).T
    np.testing.assert_allclose(procrustes_align(sq, copy), sq, atol=1e-12)
    mirror = sq * [-1.0, 1.0] + [0.3, 0.0]
    assert np.abs(procrustes_align(sq, mirror) - sq).max() > 0.1  # no reflection unless asked
    np.testing.assert_allclose(procrustes_align(sq, mirror, reflection=True), sq, atol=1e-12)


def test_optimal_rotation_of_a_3d_mirror_image_is_scipy_align_vectors(rng):
    """3-D, y a noisy mirror image of x: the best proper rotation is the one scipy's Rotation.align_vectors
    finds (Kabsch), and Σ s is the correlation tr(xᵀ y R) = (‖x‖² + ‖y‖² − rssd²) / 2 at it."""
    from scipy.spatial.transform import Rotation

    from shapelib.geometry.procrustes import optimal_rotation

    x = rng.normal(size=(12, 3)) * [3.0, 2.0, 1.0]
    x -= x.mean(axis=0)
    y = x @ np.diag([-1.0, 1.0, 1.0]) @ Rotation.random(random_state=2).as_matrix() + 0.05 * rng.normal(size=(12, 3))
    y -= y.mean(axis=0)
    r, trace = optimal_rotation(x, y)
    best, rssd = Rotation.align_vectors(x, y)
    np.testing.assert_allclose(r, best.as_matrix().T, atol=1e-10)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert trace == pytest.approx((np.sum(x ** 2) + np.sum(y ** 2) - rssd ** 2) / 2, rel=1e-10)
    assert trace == pytest.approx(np.sum(x * (y @ r)), rel=1e-12)


def test_pose_align_turns_small_shapes_too_and_keeps_a_lone_shape_where_it_is():
    """Sizes below 1 are aligned like any other (two turned copies of size √5 / 100 meet halfway); a set
    with one shape of non-zero size leaves it, and the shapes of zero size, where they are."""
    small = 0.01 * RECT
    aligned, moved = pose_align(np.stack([small, 0.01 * _turned(0.6, shift=(0.0, 0.0))]))
    np.testing.assert_allclose(moved, [2 * np.sin(0.15)] * 2, rtol=1e-10)
    np.testing.assert_allclose(aligned[0], aligned[1], atol=1e-14)
    point = np.full((4, 2), 3.0)
    aligned, moved = pose_align(np.stack([RECT + 7.0, point]))
    np.testing.assert_allclose(aligned, [RECT + 7.0, point], atol=1e-12)
    np.testing.assert_allclose(moved, 0.0, atol=1e-12)


def test_pose_functions_refuse_single_landmarks_and_a_point_counts_by_its_position():
    from shapelib.geometry.procrustes import check_pose, pose_change

    with pytest.raises(ValueError, match=r"^shapes\[0\] must have at least 2 landmark"):
        pose_align(np.zeros((2, 1, 2)))
    with pytest.raises(ValueError, match=r"at least 2 landmark"):
        pose_change(np.zeros((1, 2)), np.ones((1, 2)))
    # v a point at (5, 7): it moves by ‖(5, 7) − c_u‖ √K over the mean size S(u)/2; u's whole size remains
    s = np.sqrt(5.0)
    moved, remaining = pose_change(RECT, np.tile([5.0, 7.0], (4, 1)))
    assert moved == pytest.approx(np.linalg.norm([5.0, 7.0] - RECT.mean(axis=0)) * 2 / (s / 2), rel=1e-12)
    assert remaining == pytest.approx(2.0, rel=1e-12)
    # two-landmark shapes have a pose: a segment and its copy turned by 0.6 rad
    seg = np.array([[-1.0, 0.0], [1.0, 0.0]])  # centred: turned about its centroid
    with pytest.warns(PoseWarning):
        assert check_pose(np.stack([seg, seg @ rot(0.6).T]), metric="alpha") == pytest.approx(2 * np.sin(0.3))


def test_preshape_at_the_edges_of_double_precision():
    """Scale invariance up to coordinates of 1e200 (whose squares overflow); coordinates that overflow
    when centred are refused with the largest of them."""
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    np.testing.assert_allclose(preshape(1e200 * tri), preshape(tri), rtol=1e-14)
    huge = np.array([[1.7e308, 0.0], [1.7e308, 1.0], [0.0, 0.0]])
    with np.errstate(over="ignore"), pytest.raises(ValueError, match=(
            r"^configuration of shape \(3, 2\) has coordinates too large to centre in double precision "
            r"\(largest 1.7e\+308\): rescale them$")):
        preshape(huge)
