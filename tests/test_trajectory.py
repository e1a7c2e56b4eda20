"""Phenotypic trajectory analysis against hand-made trajectories with known attributes, brute-force
recomputations (cell means and path lengths by loops, principal axes by eigendecomposition, shapes
by SciPy's orthogonal Procrustes), invariances and the behaviour of the RRPP test."""

import numpy as np
import pytest
from scipy.linalg import orthogonal_procrustes
from scipy.stats import ortho_group

import shapelib as sl
from shapelib.statistics.group import MIN_PERMUTATIONS


def _rotation(t, p=3):
    r = np.eye(p)
    r[:2, :2] = [[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]
    return r


def _specimens(means, n=3, scale=0.1, seed=0):
    """Specimens whose cell means are exactly ``means`` (G, T, p): n deviations summing to zero per cell."""
    rng = np.random.default_rng(seed)
    g, t, p = means.shape
    rows, groups, points = [], [], []
    for a in range(g):
        for b in range(t):
            dev = rng.normal(scale=scale, size=(n, p))
            rows.append(means[a, b] + dev - dev.mean(axis=0))
            groups += [f"g{a}"] * n
            points += [b] * n
    return np.concatenate(rows), np.array(groups), np.array(points)


def _run(y, groups, points, **kwargs):
    kwargs.setdefault("n_permutations", MIN_PERMUTATIONS)
    return sl.trajectory_analysis(y, groups, points, **kwargs)


# a bent trajectory whose first principal axis is exactly the first coordinate: the centred points
# (-3, -0.5), (-1, 0.5), (1, 0.5), (3, -0.5) have a diagonal covariance with the larger variance in x
BENT = np.array([[-3, 0, 0], [-1, 1, 0], [1, 1, 0], [3, 0, 0.0]])
BENT_LENGTH = 3 * 0 + 2 * np.sqrt(5) + 2  # two steps of (2, ±1) and one of (2, 0)


def test_hand_made_path_lengths():
    y, g, t = _specimens(np.stack([BENT, BENT + 5]))
    res = _run(y, g, t)
    assert res.magnitudes == pytest.approx([BENT_LENGTH] * 2, rel=1e-12)
    assert res.magnitude_differences[0, 1] == pytest.approx(0, abs=1e-12)


@pytest.mark.parametrize("factor", [0.5, 2.0, 3.0])
def test_a_scaled_and_shifted_copy_is_parallel_with_the_same_shape(factor):
    means = np.stack([BENT, factor * BENT + [1.0, -2.0, 4.0]])
    res = _run(*_specimens(means))
    assert res.angles[0, 1] == pytest.approx(0, abs=1e-10)
    assert res.shape_distances[0, 1] == pytest.approx(0, abs=1e-12)
    assert res.magnitudes[1] / res.magnitudes[0] == pytest.approx(factor, rel=1e-12)
    assert res.magnitude_differences[0, 1] == pytest.approx(abs(factor - 1) * BENT_LENGTH, rel=1e-12)


@pytest.mark.parametrize("degrees", [10.0, 30.0, 60.0, 90.0, 120.0, 150.0])
def test_a_copy_rotated_in_the_plane_of_its_axis_makes_that_angle(degrees):
    rotated = BENT @ _rotation(np.radians(degrees)).T + [0.5, 0.5, 0.5]
    y, g, t = _specimens(np.stack([BENT, rotated]))
    axis = _run(y, g, t)
    path = _run(y, g, t, direction="path")
    assert path.angles[0, 1] == pytest.approx(degrees, abs=1e-10)
    assert axis.angles[0, 1] == pytest.approx(min(degrees, 180 - degrees), abs=1e-10)
    # a rotation keeps the path length and the shape
    assert axis.magnitude_differences[0, 1] == pytest.approx(0, abs=1e-12)
    assert axis.shape_distances[0, 1] == pytest.approx(0, abs=1e-12)


def test_a_reversed_trajectory_is_180_degrees_along_its_path_and_0_as_an_axis():
    y, g, t = _specimens(np.stack([BENT, BENT[::-1] + 1.0]))
    assert _run(y, g, t, direction="path").angles[0, 1] == pytest.approx(180, abs=1e-10)
    assert _run(y, g, t).angles[0, 1] == pytest.approx(0, abs=1e-10)


def test_the_path_direction_does_not_depend_on_the_svd_s_signs():
    """Random walks whose first axis, as NumPy's SVD returns it, points forwards for some and backwards
    for others: the angles along their paths are the brute force's, whose axes follow the paths."""
    walks = np.cumsum(np.random.default_rng(0).normal(size=(4, 4, 3)), axis=1)
    centred = walks - walks.mean(axis=1, keepdims=True)
    raw = np.linalg.svd(centred, full_matrices=False)[2][:, 0]
    forward = np.einsum("gp,gp->g", raw, walks[:, -1] - walks[:, 0]) > 0
    assert forward.any() and not forward.all()  # the precondition: the SVD's signs disagree
    y, g, t = _specimens(walks)
    res = _run(y, g, t, direction="path")
    assert res.angles == pytest.approx(_brute_force(y, g, t, [0, 1, 2, 3], "path")[2], abs=1e-8)


def test_a_known_shape_distance():
    """A straight line against a right angle, both three points: their Procrustes distance by hand."""
    line = np.array([[0, 0.0], [1, 0], [2, 0]])
    corner = np.array([[0, 0.0], [1, 0], [1, 1]])
    res = _run(*_specimens(np.stack([line, corner])))
    a = (line - line.mean(axis=0)) / np.linalg.norm(line - line.mean(axis=0))
    b = (corner - corner.mean(axis=0)) / np.linalg.norm(corner - corner.mean(axis=0))
    # in the plane the best rotation of b onto a turns it by atan2(Σ a×b, Σ a·b)
    dot, cross = np.sum(a * b), np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert res.shape_distances[0, 1] == pytest.approx(np.sqrt(2 - 2 * np.hypot(dot, cross)), rel=1e-10)
    assert 0 < res.shape_distances[0, 1] < 2


def _brute_force(y, groups, points, levels, direction):
    """Cell means by loops, path lengths by loops, axes by eigh, shapes by SciPy's orthogonal Procrustes."""
    names = sorted(set(groups))
    means = np.array([[np.mean([y[i] for i in range(len(y)) if groups[i] == g and points[i] == t], axis=0)
                       for t in levels] for g in names])
    lengths = []
    for traj in means:
        total = 0.0
        for k in range(len(traj) - 1):
            total += np.sqrt(sum((traj[k + 1][j] - traj[k][j]) ** 2 for j in range(len(traj[k]))))
        lengths.append(total)
    axes, units = [], []
    for traj in means:
        c = traj - traj.mean(axis=0)
        w, v = np.linalg.eigh(c.T @ c)
        u = v[:, -1]
        if direction == "path" and u @ (traj[-1] - traj[0]) < 0:
            u = -u
        axes.append(u)
        units.append(c / np.sqrt(np.sum(c ** 2)))
    n = len(names)
    angles, shapes = np.zeros((n, n)), np.zeros((n, n))
    for a in range(n):
        for b in range(n):
            cos = axes[a] @ axes[b]
            if direction == "axis":
                cos = abs(cos)
            angles[a, b] = np.degrees(np.arccos(min(cos, 1.0)))
            r, _ = orthogonal_procrustes(units[b], units[a])
            shapes[a, b] = np.linalg.norm(units[a] - units[b] @ r)
    np.fill_diagonal(angles, 0)
    return means, np.array(lengths), angles, shapes


@pytest.mark.parametrize("direction", ["axis", "path"])
@pytest.mark.parametrize("p", [2, 5])
def test_against_a_brute_force_recomputation(direction, p):
    rng = np.random.default_rng(3)
    n = 60
    groups = rng.choice(["x", "y", "z"], size=n)
    points = rng.choice(["early", "mid", "late"], size=n)
    groups[:9], points[:9] = np.repeat(["x", "y", "z"], 3), np.tile(["early", "mid", "late"], 3)  # no empty cell
    y = rng.normal(size=(n, p)) + (points == "late")[:, None] * rng.normal(size=p)
    levels = ["early", "mid", "late"]
    res = _run(y, groups, points, levels=levels, direction=direction)
    means, lengths, angles, shapes = _brute_force(y, groups, points, levels, direction)
    assert list(res.groups) == ["x", "y", "z"] and list(res.levels) == levels
    assert res.trajectories == pytest.approx(means, rel=1e-12, abs=1e-12)
    assert res.magnitudes == pytest.approx(lengths, rel=1e-12)
    assert res.magnitude_differences == pytest.approx(np.abs(lengths[:, None] - lengths[None, :]), abs=1e-12)
    assert res.angles == pytest.approx(angles, abs=1e-6)
    assert res.shape_distances == pytest.approx(shapes, abs=1e-7)
    counts = [[np.sum((groups == g) & (points == t)) for t in levels] for g in "xyz"]
    assert res.sizes.tolist() == counts and res.sizes.dtype.kind == "i"
    for m in (res.magnitude_differences, res.angles, res.shape_distances):
        assert np.diag(m).tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("direction", ["axis", "path"])
def test_the_p_values_and_effect_sizes_redone_by_least_squares_and_loops(direction):
    """RRPP redone: the reduced model fitted with other contrasts (a column per level of each factor,
    through NumPy's least squares), each permutation's cell means and attributes by brute force; z with
    the standard deviation of divisor n − 1, as R's ``sd``."""
    # random walks whose SVD axes point forwards (0, 2) and backwards (1), obtuse to each other
    means = np.cumsum(np.random.default_rng(0).normal(size=(3, 4, 3)), axis=1)
    y, g, t = _specimens(means, n=3, scale=0.5)
    t = t.astype(str)
    n, levels = len(y), ["0", "1", "2", "3"]
    res = _run(y, g, t, levels=levels, n_permutations=29, seed=11, direction=direction)
    design = np.column_stack([(g == "g1"), (g == "g2"), *[(t == level) for level in levels]]).astype(float)
    fitted = design @ np.linalg.lstsq(design, y, rcond=None)[0]
    resid = y - fitted
    upper = np.triu_indices(3, k=1)

    def stats(values):
        _, lengths, angles, shapes = _brute_force(values, g, t, levels, direction)
        return np.stack([np.abs(lengths[:, None] - lengths[None, :])[upper], angles[upper], shapes[upper]])

    observed = stats(y)
    rng = np.random.default_rng(11)
    null = np.stack([stats(fitted + resid[rng.permutation(n)]) for _ in range(29)])
    p = (1 + np.sum(null >= observed - 1e-9, axis=0)) / 30
    z = (observed - null.mean(axis=0)) / null.std(axis=0, ddof=1)
    got_p = np.stack([res.magnitude_p_values[upper], res.angle_p_values[upper], res.shape_p_values[upper]])
    got_z = np.stack([res.magnitude_z[upper], res.angle_z[upper], res.shape_z[upper]])
    assert got_p == pytest.approx(p, abs=1e-12)
    assert got_z == pytest.approx(z, rel=1e-6, abs=1e-8)
    assert len(set(p.ravel())) > 3  # the p-values are not all alike


def test_invariant_to_rotating_every_specimen_and_to_reordering_them():
    rng = np.random.default_rng(5)
    y, g, t = _specimens(np.stack([BENT, BENT @ _rotation(0.7).T, 1.5 * BENT]), scale=0.4)
    y = np.column_stack([y, rng.normal(size=(len(y), 2))])  # p = 5
    res = _run(y, g, t)
    turned = _run(y @ ortho_group.rvs(5, random_state=1), g, t)
    for name in ("magnitudes", "magnitude_differences", "angles", "shape_distances", "magnitude_p_values",
                 "angle_p_values", "shape_p_values", "magnitude_z", "angle_z", "shape_z"):
        assert getattr(turned, name) == pytest.approx(getattr(res, name), abs=1e-8), name
    order = rng.permutation(len(y))
    shuffled = _run(y[order], g[order], t[order])
    for name in ("magnitudes", "magnitude_differences", "angles", "shape_distances"):
        assert getattr(shuffled, name) == pytest.approx(getattr(res, name), abs=1e-10), name
    assert shuffled.trajectories == pytest.approx(res.trajectories, abs=1e-12)


def test_landmarks_are_aligned_so_each_specimen_s_pose_does_not_matter():
    rng = np.random.default_rng(6)
    base = np.array([[0, 0], [2, 0], [2.5, 1], [1, 1.6], [0, 1.0]])
    groups, points = np.repeat(["a", "b"], 12), np.tile(np.repeat([0, 1, 2], 4), 2)
    shapes = base + rng.normal(scale=0.03, size=(24, 5, 2))
    shapes[:, 2, 0] += 0.1 * points * np.where(groups == "a", 1, -1)
    res = sl.trajectory_analysis(shapes, groups, points, n_permutations=19)
    angles = rng.uniform(0, 2 * np.pi, size=24)
    posed = np.stack([3 * s @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) + 7
                      for s, a in zip(shapes, angles)])
    moved = sl.trajectory_analysis(posed, groups, points, n_permutations=19)
    for name in ("magnitudes", "angles", "shape_distances", "angle_p_values", "magnitude_p_values"):
        assert getattr(moved, name) == pytest.approx(getattr(res, name), abs=1e-7), name
    aligned = sl.trajectory_analysis(sl.procrustes_coordinates(shapes), groups, points, n_permutations=19)
    assert aligned.angles == pytest.approx(res.angles, abs=1e-10)


def test_relabelling_the_groups_and_reversing_the_levels():
    y, g, t = _specimens(np.stack([BENT, BENT @ _rotation(0.5).T * 2, BENT + [0, 0, 1]]), scale=0.5)
    res = _run(y, g, t)
    names = {"g0": "zeta", "g1": "alpha", "g2": "mu"}  # sorted: alpha (g1), mu (g2), zeta (g0)
    relabelled = _run(y, np.array([names[x] for x in g]), t)
    order = [1, 2, 0]
    for name in ("magnitude_differences", "angles", "shape_distances", "magnitude_p_values", "angle_p_values",
                 "shape_p_values"):
        assert getattr(relabelled, name) == pytest.approx(getattr(res, name)[np.ix_(order, order)], abs=1e-12)
    reversed_ = _run(y, g, t, levels=[3, 2, 1, 0])
    assert reversed_.trajectories == pytest.approx(res.trajectories[:, ::-1], abs=1e-12)
    for name in ("magnitudes", "angles", "shape_distances"):
        assert getattr(reversed_, name) == pytest.approx(getattr(res, name), abs=1e-8), name


def test_the_angle_ranges():
    rng = np.random.default_rng(7)
    y, g, t = rng.normal(size=(40, 3)), np.repeat(list("abcd"), 10), np.tile(np.repeat([0, 1], 5), 4)
    y[:, 0] += 3 * t * np.array([1, -1, 1, -1]).repeat(10)  # b and d run backwards
    axis, path = _run(y, g, t), _run(y, g, t, direction="path")
    assert np.all((axis.angles >= 0) & (axis.angles <= 90))
    assert np.all((path.angles >= 0) & (path.angles <= 180))
    assert path.angles[0, 1] > 150 and axis.angles[0, 1] < 30
    assert axis.angles == pytest.approx(np.minimum(path.angles, 180 - path.angles), abs=1e-8)
    # two levels: every trajectory is a segment, the same shape as every other, whatever the permutation
    assert axis.shape_distances.tolist() == np.zeros((4, 4)).tolist()
    assert axis.shape_p_values.tolist() == np.ones((4, 4)).tolist()


def _additive(seed, interaction=0.0):
    """Two groups, four levels, ~ groups + points (+ interaction in the first variable's step of g1)."""
    rng = np.random.default_rng(seed)
    g, t = np.repeat(["a", "b"], 24), np.tile(np.repeat([0, 1, 2, 3], 6), 2)
    y = rng.normal(size=(48, 4))
    y[:, 0] += t + (g == "b")
    y[:, 1] += 0.5 * t ** 2
    y[:, 2] += interaction * t * (g == "b")
    return y, g, t


def test_no_interaction_gives_large_p_values_and_a_strong_one_small_p_values():
    small = 0
    for seed in range(6):
        res = _run(*_additive(seed), n_permutations=49)
        small += sum(p[0, 1] < 0.05 for p in (res.magnitude_p_values, res.angle_p_values, res.shape_p_values))
    assert small <= 4  # of 18 tests at 5 %: about one expected
    strong = _run(*_additive(0, interaction=3.0), n_permutations=49)
    assert strong.magnitude_p_values[0, 1] < 0.05 and strong.angle_p_values[0, 1] < 0.05
    assert strong.angle_z[0, 1] > 2 and strong.magnitude_z[0, 1] > 2


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("unit", [1.0, 1e6])
def test_exactly_additive_data_are_left_as_they_are_by_every_permutation(unit):
    """Every specimen on its cell's mean and every trajectory a translated copy of one: the reduced
    model fits the data, every permutation of its (zero) residuals keeps the trajectories to rounding,
    so all p-values are 1 and all effect sizes 0, without a warning."""
    y, g, t = _specimens(np.stack([BENT, BENT + [0.1, 0.7, np.pi], BENT - [np.e, 2 / 3, 0.3]]), scale=0.0)
    res = _run(unit * y, g, t)  # in any unit (micrometres: the magnitudes' rounding grows with them)
    for m in (res.magnitude_p_values, res.angle_p_values, res.shape_p_values):
        assert m.tolist() == np.ones((3, 3)).tolist()
    for m in (res.magnitude_z, res.angle_z, res.shape_z):
        assert m.tolist() == np.zeros((3, 3)).tolist()


def test_parallel_trajectories_with_noise_have_p_1_and_negative_effect_sizes():
    """Observed trajectories exactly parallel (statistics 0, the least possible), residuals that move
    them apart in the permutations: p = 1 and z < 0 for every pair."""
    y, g, t = _specimens(np.stack([BENT, BENT + 1, BENT - [0, 2, 0]]), scale=0.3)
    res = _run(y, g, t)
    off = ~np.eye(3, dtype=bool)
    for m in (res.magnitude_p_values, res.angle_p_values, res.shape_p_values):
        assert m.tolist() == np.ones((3, 3)).tolist()
    for m in (res.magnitude_z, res.angle_z, res.shape_z):
        assert np.all(m[off] < 0)


def test_the_seed_fixes_the_p_values_and_the_diagonals():
    y, g, t = _additive(1, interaction=0.3)
    a, b = _run(y, g, t, seed=3), _run(y, g, t, seed=3)
    assert a.angle_p_values.tolist() == b.angle_p_values.tolist()
    for m in (a.magnitude_p_values, a.angle_p_values, a.shape_p_values):
        assert np.diag(m).tolist() == [1.0, 1.0]
        assert m[0, 1] == m[1, 0] and m[0, 1] in {k / 20 for k in range(1, 21)}
    for m in (a.magnitude_z, a.angle_z, a.shape_z):
        assert np.diag(m).tolist() == [0.0, 0.0]


def test_the_defaults_are_999_permutations_and_the_axis_angle():
    y, g, t = _additive(2)
    res = sl.trajectory_analysis(y, g, t)
    assert res.n_permutations == 999 and res.direction == "axis"
    assert res.angle_p_values[0, 1] == sl.trajectory_analysis(y, g, t, seed=0).angle_p_values[0, 1]


def test_the_summary_lists_the_trajectories_and_the_pairs():
    y, g, t = _specimens(np.stack([BENT, 2 * BENT, BENT + 1]))
    text = _run(y, g, t).summary()
    lines = text.splitlines()
    assert lines[0].startswith("trajectory analysis: 3 trajectories of 4 points in 3 variables, 19 RRPP")
    assert lines[0].endswith("angles in degrees, 0-90")
    assert len(lines) == 1 + 3 + 3
    assert lines[1] == f"  {'g0':>12}  path length = {BENT_LENGTH:.4g}"
    assert lines[4].startswith("  g0 vs g1: |ΔL| = ") and lines[-1].startswith("  g1 vs g2: ")
    assert _run(y, g, t, direction="path").summary().splitlines()[0].endswith("angles in degrees, 0-180")


@pytest.mark.parametrize("kwargs, message", [
    ({"direction": "sign"}, "direction must be one of"),
    ({"n_permutations": 10}, "n_permutations must be at least 19"),
    ({"n_permutations": 0}, "n_permutations must be a positive integer"),
    ({"levels": [0, 1, 2]}, "levels: [0, 1, 2] are not the levels of points"),
    ({"levels": [0, 1, 1, 3]}, "levels: expected distinct labels"),
])
def test_bad_options_are_named(kwargs, message):
    y, g, t = _specimens(np.stack([BENT, BENT]))
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        sl.trajectory_analysis(y, g, t, **kwargs)


def test_bad_factors_are_named():
    y, g, t = _specimens(np.stack([BENT, BENT]))
    with pytest.raises(ValueError, match=r"groups: expected one label per specimen \(24\)"):
        sl.trajectory_analysis(y, g[:-1], t)
    with pytest.raises(ValueError, match=r"points: expected one label per specimen \(24\)"):
        sl.trajectory_analysis(y, g, t[:, None])
    with pytest.raises(ValueError, match="^groups: need at least two trajectories to compare$"):
        sl.trajectory_analysis(y, np.full(24, "a"), t)
    with pytest.raises(ValueError, match=r"^points: need at least two levels \(points of a trajectory\)$"):
        sl.trajectory_analysis(y, g, np.zeros(24))
    keep = ~((g == "g1") & (t == 2))
    with pytest.raises(ValueError, match="^points: group 'g1' has no specimen at level 2; every group needs "
                                         "a specimen at every level$"):
        sl.trajectory_analysis(y[keep], g[keep], t[keep])
    with pytest.raises(ValueError, match="shapes"):
        sl.trajectory_analysis(np.where(np.arange(3) == 1, np.nan, y), g, t)


def test_aligned_landmarks_are_only_flattened():
    """``aligned=True``: the landmarks' own coordinates are the variables, as the flattened table."""
    rng = np.random.default_rng(8)
    shapes = rng.normal(size=(24, 4, 2)) + np.arange(24)[:, None, None]  # not aligned: each one moved
    g, t = np.repeat(["a", "b"], 12), np.tile(np.repeat([0, 1, 2], 4), 2)
    res = _run(shapes, g, t, aligned=True)
    table = _run(shapes.reshape(24, 8), g, t)
    assert res.trajectories == pytest.approx(table.trajectories, abs=1e-12)
    assert res.angle_p_values.tolist() == table.angle_p_values.tolist()
    assert _run(shapes, g, t).trajectories.shape == (2, 3, 8)
    assert not np.allclose(_run(shapes, g, t).trajectories, table.trajectories, atol=1e-3)


def test_the_top_level_names():
    from shapelib.statistics.trajectory import TrajectoryResult, trajectory_analysis

    assert sl.trajectory_analysis is trajectory_analysis and sl.TrajectoryResult is TrajectoryResult
