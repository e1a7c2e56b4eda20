"""Bilateral symmetry against independent computations: exact limits (symmetric specimens, a known
directional asymmetry), the sums of squares redone by plain loops over the cells and by NumPy's
least squares, pose and order invariance, the symmetry of the symmetric component, matching symmetry
of a specimen and its mirror image against object symmetry, and one RRPP permutation redone."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.statistics.symmetry import bilateral_symmetry

#: a face: two eyes (0, 1), the nose (2, on the midline), two mouth corners (3, 4), the chin (5)
FACE = np.array([[-1.0, 1.0], [1.0, 1.0], [0.0, 0.0], [-0.6, -1.0], [0.6, -1.0], [0.0, -1.6]])
PAIRS = np.array([[0, 1], [3, 4]])
#: a 3-D skull: pairs (0, 1), (2, 3); landmarks 4 and 5 on the midline plane x = 0
SKULL = np.array([[-1.0, 0.5, 0.2], [1.0, 0.5, 0.2], [-0.7, -1.0, 0.0], [0.7, -1.0, 0.0],
                  [0.0, 1.2, 0.8], [0.0, -0.3, -1.0]])


def _rot(t):
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def _mirror(x, pairs):
    """The test's own mirror image: x negated, each pair's landmarks exchanged (landmark by landmark)."""
    out = np.array(x, dtype=float)
    for k in range(x.shape[-2]):
        partner = k
        for a, b in pairs:
            partner = b if k == a else a if k == b else partner
        out[..., k, :] = x[..., partner, :]
    out[..., 0] = -out[..., 0]
    return out


def _symmetric_faces(rng, n):
    """Symmetric faces: each pair moved together, mirrored; midline landmarks moved along the midline."""
    faces = np.repeat(FACE[None], n, axis=0)
    for a, b in PAIRS:
        d = rng.normal(scale=0.05, size=(n, 2))
        faces[:, a] += d
        faces[:, b] += d * [-1, 1]
    faces[:, [2, 5], 1] += rng.normal(scale=0.05, size=(n, 2))
    return faces


def _rotation_free_distance(a, b):
    """min over rotations R of |a − b R| for centred a, b (Kabsch), by the SVD."""
    a, b = a - a.mean(axis=0), b - b.mean(axis=0)
    u, _, vt = np.linalg.svd(b.T @ a)
    s = np.ones(len(u))
    s[-1] = np.sign(np.linalg.det(u @ vt))
    return np.linalg.norm(a - b @ (u * s) @ vt)


def _brute_force_ss(y, ind, side):
    """Classical two-way sums of squares of a balanced design, by loops over the cells: ind, side, ind:side,
    residual, total (y rows (M, p))."""
    grand = y.mean(axis=0)
    inds, sides = sorted(set(ind)), sorted(set(side))
    ss = np.zeros(5)
    for i in inds:
        rows_i = [r for r in range(len(y)) if ind[r] == i]
        ss[0] += len(rows_i) * np.sum((y[rows_i].mean(axis=0) - grand) ** 2)
    for s in sides:
        rows_s = [r for r in range(len(y)) if side[r] == s]
        ss[1] += len(rows_s) * np.sum((y[rows_s].mean(axis=0) - grand) ** 2)
    for i in inds:
        mi = y[[r for r in range(len(y)) if ind[r] == i]].mean(axis=0)
        for s in sides:
            ms = y[[r for r in range(len(y)) if side[r] == s]].mean(axis=0)
            cell = [r for r in range(len(y)) if ind[r] == i and side[r] == s]
            mc = y[cell].mean(axis=0)
            ss[2] += len(cell) * np.sum((mc - mi - ms + grand) ** 2)
            for r in cell:
                ss[3] += np.sum((y[r] - mc) ** 2)
    ss[4] = np.sum((y - grand) ** 2)
    return ss


def _sequential_ss(y, designs):
    """Type I sums of squares by NumPy's least squares on nested designs."""
    rss = []
    for x in designs:
        coef = np.linalg.lstsq(x, y, rcond=None)[0]
        rss.append(np.sum((y - x @ coef) ** 2))
    return -np.diff(rss)


# --- exact limits -----------------------------------------------------------------------------------

@pytest.mark.parametrize("dim", [2, 3])
def test_symmetric_specimens_have_no_asymmetry(dim):
    rng = np.random.default_rng(0)
    if dim == 2:
        shapes, pairs = _symmetric_faces(rng, 8), PAIRS
    else:
        shapes, pairs = np.repeat(SKULL[None], 8, axis=0), np.array([[0, 1], [2, 3]])
        d = rng.normal(scale=0.05, size=(8, 3))
        shapes[:, 0] += d
        shapes[:, 1] += d * [-1, 1, 1]
        shapes[:, 4:, 1:] += rng.normal(scale=0.05, size=(8, 2, 2))
    # each specimen in its own pose: the symmetry plane is not x = 0 in the data
    if dim == 2:
        shapes = np.stack([2.0 * s @ _rot(t).T + 3.0 for s, t in zip(shapes, rng.uniform(0, 6, 8))])
    res = bilateral_symmetry(shapes, land_pairs=pairs, n_permutations=19)
    assert np.max(np.abs(res.asymmetric)) < 1e-9
    assert res.ss[1] < 1e-18 * res.ss[-1] and res.ss[2] < 1e-18 * res.ss[-1]
    assert res.ss[0] == pytest.approx(res.ss[-1], rel=1e-9)
    # nothing to test: F is not a number where its denominator vanishes
    assert np.all(np.isnan(res.value)) and np.all(np.isnan(res.p_value))


def test_a_known_directional_asymmetry_is_in_the_side_term():
    rng = np.random.default_rng(1)
    shapes = _symmetric_faces(rng, 20) + rng.normal(scale=0.01, size=(20, 6, 2))  # small fluctuating asymmetry
    base = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=99)
    shifted = shapes.copy()
    shifted[:, 1, 1] += 0.15  # the right eye higher in every face
    res = bilateral_symmetry(shifted, land_pairs=PAIRS, n_permutations=99)
    assert res.p_value[1] == pytest.approx(0.01) and res.value[1] > 50
    assert base.p_value[1] > 0.05
    # the fluctuating part is what it was: only its pose changes a little
    assert res.ss[2] == pytest.approx(base.ss[2], rel=0.3)
    assert res.ss[1] > 20 * res.ss[2]
    # the directional component: half of the eye's rise, with the opposite sign at its mirror landmark
    # (the specimen's eye 1 is up, the mirror's eye 1 was eye 0), in Procrustes units: the centroid size is ~2.6
    size = np.sqrt(np.sum((FACE - FACE.mean(axis=0)) ** 2))
    da = res.directional - base.directional
    assert da[1, 1] == pytest.approx(0.075 / size, rel=0.25)
    assert da[0, 1] == pytest.approx(-0.075 / size, rel=0.25)
    np.testing.assert_allclose(res.fluctuating.mean(axis=0), 0.0, atol=1e-12)


def test_a_fluctuating_asymmetry_is_in_the_interaction_not_in_the_side_term():
    rng = np.random.default_rng(2)
    shapes = _symmetric_faces(rng, 20)
    shapes[:, 1, 1] += rng.normal(scale=0.1, size=20)  # each face's own asymmetry, of mean zero
    shapes[:, 1, 1] -= shapes[:, 1, 1].mean() - 1.0
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=99)
    assert res.ss[2] > 10 * res.ss[1]
    assert res.p_value[1] > 0.05


# --- the sums of squares ----------------------------------------------------------------------------

def _replicated(rng, n_ind=6, n_rep=2):
    faces = _symmetric_faces(rng, n_ind) + rng.normal(scale=0.02, size=(n_ind, 6, 2))
    shapes = np.repeat(faces, n_rep, axis=0) + rng.normal(scale=0.005, size=(n_ind * n_rep, 6, 2))
    return shapes, np.repeat(np.arange(n_ind), n_rep), np.tile(np.arange(n_rep), n_ind)


def test_the_sums_of_squares_redone_by_loops_over_the_cells():
    rng = np.random.default_rng(3)
    shapes, ind, rep = _replicated(rng)
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, ind=ind, replicate=rep, n_permutations=19)
    assert res.rows == ("ind", "side", "ind:side", "ind:side:replicate", "Total")
    both = np.concatenate([shapes, _mirror(shapes, PAIRS)])
    y = sl.procrustes_coordinates(both)
    expect = _brute_force_ss(y, list(ind) * 2, [0] * len(shapes) + [1] * len(shapes))
    np.testing.assert_allclose(res.ss, expect, rtol=1e-7)
    assert res.ss[:-1].sum() == pytest.approx(res.ss[-1], rel=1e-12)
    n = 6
    assert res.df.tolist() == [n - 1, 1, n - 1, 2 * len(shapes) - 2 * n, 2 * len(shapes) - 1]
    np.testing.assert_allclose(res.ms[:-1], res.ss[:-1] / res.df[:-1])
    # ind and side over ind:side, ind:side over the measurement error
    f = [res.ms[0] / res.ms[2], res.ms[1] / res.ms[2], res.ms[2] / res.ms[3]]
    np.testing.assert_allclose(res.value[:3], f, rtol=1e-12)
    assert np.isnan(res.value[3:]).all() and np.isnan(res.p_value[3:]).all()


def test_without_replicates_the_interaction_is_the_residual():
    rng = np.random.default_rng(4)
    shapes = _symmetric_faces(rng, 7) + rng.normal(scale=0.02, size=(7, 6, 2))
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=19)
    y = sl.procrustes_coordinates(np.concatenate([shapes, _mirror(shapes, PAIRS)]))
    expect = _brute_force_ss(y, list(range(7)) * 2, [0] * 7 + [1] * 7)
    assert expect[3] == pytest.approx(0.0, abs=1e-25)
    np.testing.assert_allclose(res.ss, expect[[0, 1, 2, 4]], rtol=1e-7)
    assert res.df.tolist() == [6, 1, 6, 13]
    np.testing.assert_allclose(res.value[:2], res.ms[:2] / res.ms[2], rtol=1e-12)
    assert res.individuals.tolist() == list(range(7)) and res.sides == ("original", "mirror")
    assert res.rows == ("ind", "side", "ind:side", "Total")


def test_unbalanced_replicates_give_numpys_sequential_sums_of_squares():
    rng = np.random.default_rng(5)
    shapes, ind, rep = _replicated(rng, n_ind=5, n_rep=3)
    keep = np.ones(len(shapes), bool)
    keep[[1, 2, 7]] = False  # individual 0 digitised once, individual 2 twice
    shapes, ind, rep = shapes[keep], ind[keep], rep[keep]
    # matching symmetry of the specimens and their mirror images, one side with one replicate fewer
    both = np.concatenate([shapes, _mirror(shapes, PAIRS)[:-1]])
    ind2, side = np.concatenate([ind, ind[:-1]]), np.repeat(["L", "R"], [len(shapes), len(shapes) - 1])
    res = bilateral_symmetry(both, side=side, ind=ind2, replicate=np.arange(len(both)), n_permutations=19)
    y = sl.procrustes_coordinates(both)
    one = np.ones((len(y), 1))
    dummies = (ind2[:, None] == np.unique(ind2)[None]).astype(float)
    right = (side == "R").astype(float)[:, None]
    cells = dummies * right
    designs = [one, np.hstack([one, dummies]), np.hstack([one, dummies, right]),
               np.hstack([one, dummies, right, cells])]
    expect = _sequential_ss(y, designs)
    np.testing.assert_allclose(res.ss[:3], expect, rtol=1e-7)
    resid = y - designs[-1] @ np.linalg.lstsq(designs[-1], y, rcond=None)[0]
    assert res.ss[3] == pytest.approx(np.sum(resid ** 2), rel=1e-7)
    assert res.ss[:-1].sum() == pytest.approx(res.ss[-1], rel=1e-12)


def test_matching_symmetry_of_specimens_and_their_mirrors_is_object_symmetry():
    rng = np.random.default_rng(6)
    shapes = _symmetric_faces(rng, 9) + rng.normal(scale=0.02, size=(9, 6, 2))
    obj = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=49, seed=3)
    relabelled = _mirror(shapes, PAIRS)
    relabelled[..., 0] *= -1  # relabelled, not reflected: mirror_side reflects it
    both = np.concatenate([shapes, relabelled])
    match = bilateral_symmetry(both, side=np.repeat(["left", "right"], 9), ind=np.tile(np.arange(9), 2),
                               mirror_side="right", n_permutations=49, seed=3)
    assert match.kind == "matching" and obj.kind == "object" and match.sides == ("left", "right")
    np.testing.assert_allclose(match.ss, obj.ss, rtol=1e-9)
    np.testing.assert_allclose(match.value, obj.value, rtol=1e-7)
    np.testing.assert_array_equal(match.p_value, obj.p_value)
    np.testing.assert_allclose(match.asymmetric, obj.asymmetric, atol=1e-10)
    # geomorph's convention: the side given reflected already
    done = both.copy()
    done[9:, :, 0] *= -1
    again = bilateral_symmetry(done, side=np.repeat(["left", "right"], 9), ind=np.tile(np.arange(9), 2),
                               n_permutations=49, seed=3)
    np.testing.assert_allclose(again.ss, obj.ss, rtol=1e-9)


# --- invariances ------------------------------------------------------------------------------------

def test_matching_symmetry_does_not_depend_on_which_side_comes_first():
    rng = np.random.default_rng(23)
    left = _symmetric_faces(rng, 6) + rng.normal(scale=0.02, size=(6, 6, 2))
    right = left + rng.normal(scale=0.02, size=(6, 6, 2)) + [0.0, 0.03]  # reflected already, shifted a little
    shapes = np.concatenate([left, right])
    ind = np.tile(np.arange(6), 2)
    res = bilateral_symmetry(shapes, side=np.repeat(["a", "b"], 6), ind=ind, n_permutations=19)
    swapped = bilateral_symmetry(shapes, side=np.repeat(["b", "a"], 6), ind=ind, n_permutations=19)
    assert swapped.sides == res.sides == ("a", "b")
    np.testing.assert_allclose(swapped.ss, res.ss, rtol=1e-9)
    np.testing.assert_allclose(swapped.value, res.value, rtol=1e-7)
    # the components are the same up to the sides' order: the asymmetric one changes sign
    np.testing.assert_allclose(swapped.symmetric, res.symmetric, atol=1e-12)
    np.testing.assert_allclose(swapped.asymmetric, -res.asymmetric, atol=1e-12)
    np.testing.assert_allclose(swapped.directional, -res.directional, atol=1e-12)


def test_invariant_to_each_specimen_s_pose_and_to_their_order():
    rng = np.random.default_rng(7)
    shapes, ind, rep = _replicated(rng, n_ind=5, n_rep=2)
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, ind=ind, replicate=rep, n_permutations=49)
    moved = np.stack([s0 * s @ _rot(t).T + c for s, t, s0, c in
                      zip(shapes, rng.uniform(0, 6, 10), rng.uniform(0.5, 3, 10), rng.normal(size=(10, 1, 2)))])
    again = bilateral_symmetry(moved, land_pairs=PAIRS, ind=ind, replicate=rep, n_permutations=49)
    np.testing.assert_allclose(again.ss, res.ss, rtol=1e-7)
    np.testing.assert_allclose(again.value, res.value, rtol=1e-6)
    order = rng.permutation(10)
    names = np.array(list("vwxyz"))[ind]  # individuals renamed, their order changed
    shuffled = bilateral_symmetry(moved[order], land_pairs=PAIRS, ind=names[order], replicate=rep[order],
                                  n_permutations=49)
    np.testing.assert_allclose(shuffled.ss, res.ss, rtol=1e-7)
    np.testing.assert_allclose(shuffled.value, res.value, rtol=1e-6)
    assert shuffled.individuals.tolist() == list("vwxyz")
    # the individuals' components follow their labels, up to the consensus' rotation
    for k in range(5):
        assert _rotation_free_distance(shuffled.symmetric[k], res.symmetric[k]) < 1e-6


def test_a_reflected_specimen_is_the_same_specimen():
    rng = np.random.default_rng(8)
    shapes = _symmetric_faces(rng, 8) + rng.normal(scale=0.02, size=(8, 6, 2))
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=19)
    flipped = shapes.copy()
    flipped[:3] = _mirror(shapes[:3], PAIRS)  # three specimens given by their mirror images
    again = bilateral_symmetry(flipped, land_pairs=PAIRS, n_permutations=19)
    # the individuals and their total asymmetry are unchanged; only which side is which moves
    assert again.ss[0] == pytest.approx(res.ss[0], rel=1e-7)
    assert again.ss[1] + again.ss[2] == pytest.approx(res.ss[1] + res.ss[2], rel=1e-7)
    for k in range(8):
        assert _rotation_free_distance(again.symmetric[k], res.symmetric[k]) < 1e-7


def test_the_symmetric_component_and_the_consensus_are_symmetric():
    rng = np.random.default_rng(9)
    shapes = _symmetric_faces(rng, 8) + rng.normal(scale=0.05, size=(8, 6, 2))
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=19)
    for sym, asym in zip(res.symmetric, res.asymmetric):
        assert _rotation_free_distance(_mirror(sym, PAIRS), sym) < 1e-7
        assert np.linalg.norm(asym) > 1e-3  # the specimens were not symmetric
    assert _rotation_free_distance(_mirror(res.consensus, PAIRS), res.consensus) < 1e-9
    np.testing.assert_allclose(res.consensus, res.symmetric.mean(axis=0))
    # each aligned copy is its individual's symmetric component plus or minus its asymmetric one
    np.testing.assert_allclose(res.aligned[:8], res.symmetric + res.asymmetric, atol=1e-12)
    np.testing.assert_allclose(res.aligned[8:], res.symmetric - res.asymmetric, atol=1e-12)
    assert res.ind_index.tolist() == list(range(8)) * 2 and res.side_index.tolist() == [0] * 8 + [1] * 8


# --- the test ---------------------------------------------------------------------------------------

def test_one_rrpp_permutation_redone_by_least_squares():
    rng = np.random.default_rng(10)
    shapes, ind, rep = _replicated(rng, n_ind=4, n_rep=2)
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, ind=ind, replicate=rep, n_permutations=19, seed=5)
    y = sl.procrustes_coordinates(np.concatenate([shapes, _mirror(shapes, PAIRS)]))
    m = len(y)
    ind2, side = np.tile(ind, 2), np.repeat([0.0, 1.0], len(shapes))
    one = np.ones((m, 1))
    dummies = (ind2[:, None] == np.arange(4)[None]).astype(float)
    designs = [one, np.hstack([one, dummies]), np.hstack([one, dummies, side[:, None]]),
               np.hstack([one, dummies, side[:, None], dummies * side[:, None]])]

    def fit(x, v):
        return x @ np.linalg.lstsq(x, v, rcond=None)[0]

    perm = np.random.default_rng(5).permutation(m)  # the first permutation drawn
    ss, rss = [], []
    for k in range(3):
        reduced = fit(designs[k], y)
        y_b = reduced + (y - reduced)[perm]
        ss.append(np.sum((fit(designs[k + 1], y_b) - fit(designs[k], y_b)) ** 2))
        rss.append(np.sum((y_b - fit(designs[3], y_b)) ** 2))
    df = res.df
    expect = [(ss[0] / df[0]) / (ss[2] / df[2]), (ss[1] / df[1]) / (ss[2] / df[2]),
              (ss[2] / df[2]) / (rss[2] / df[3])]
    np.testing.assert_allclose(res.null[0], expect, rtol=1e-7)
    assert res.null.shape == (19, 3)
    counts = [np.sum(res.null[:, k] >= res.value[k] * (1 - 1e-12)) for k in range(3)]
    np.testing.assert_allclose(res.p_value[:3], (1 + np.array(counts)) / 20)


def test_the_seed_fixes_the_p_values():
    rng = np.random.default_rng(11)
    shapes = _symmetric_faces(rng, 10) + rng.normal(scale=0.03, size=(10, 6, 2))
    a = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=29, seed=4)
    b = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=29, seed=4)
    c = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=29, seed=5)
    np.testing.assert_array_equal(a.null, b.null)
    assert not np.array_equal(a.null, c.null)
    assert a.n_permutations == 29 and np.all((a.p_value[:2] >= 1 / 30) & (a.p_value[:2] <= 1))


def test_the_summary_lists_the_table():
    rng = np.random.default_rng(12)
    shapes, ind, rep = _replicated(rng, n_ind=4, n_rep=2)
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, ind=ind, replicate=rep, n_permutations=19)
    text = res.summary().splitlines()
    assert text[1].split() == ["Df", "SS", "MS", "F", "p"]
    assert text[2].split()[3:] == [f"{res.ms[0]:.5g}", f"{res.value[0]:.4g}", f"{res.p_value[0]:.4g}"]
    assert "object symmetry, 4 individuals" in text[0] and "19 permutations" in text[0]
    assert [line.split()[0] for line in text[2:]] == list(res.rows)
    assert text[2].split()[1:3] == ["3", f"{res.ss[0]:.5g}"]
    assert text[-1].split() == ["Total", str(res.df[-1]), f"{res.ss[-1]:.5g}"]
    assert len(text[5].split()) == 4  # the measurement error: no F, no p


# --- input errors -----------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, message", [
    (dict(), "give land_pairs (object symmetry) or side (matching symmetry), one of the two"),
    (dict(land_pairs=PAIRS, side=[0, 1] * 3), "give land_pairs (object symmetry) or side (matching symmetry), "
                                              "one of the two"),
    (dict(land_pairs=[[0, 1, 2]]), "land_pairs must be a (P, 2) array of landmark indices; got shape (1, 3)"),
    (dict(land_pairs=[[0, 1], [2]]), "land_pairs must be a (P, 2) array of landmark indices: *"),
    (dict(land_pairs=[[0.0, 1.0]]), "land_pairs must hold integer landmark indices; got dtype float64"),
    (dict(land_pairs=[[0, 6]]), "land_pairs: indices must lie in [0, 6); got 0..6"),
    (dict(land_pairs=[[0, -1]]), "land_pairs: indices must lie in [0, 6); got -1..0"),
    (dict(land_pairs=[[0, 1], [1, 3]]), "land_pairs: a landmark appears twice (each is in at most one pair, "
                                        "never paired with itself)"),
    (dict(land_pairs=[[2, 2]]), "land_pairs: a landmark appears twice *"),
    (dict(land_pairs=PAIRS, mirror_side="R"), "mirror_side is for matching symmetry (side=...); object symmetry "
                                              "mirrors every specimen"),
    (dict(land_pairs=PAIRS, replicate=[0] * 6), "ind: give each replicate's individual"),
    (dict(land_pairs=PAIRS, ind=[0, 0, 1, 1, 2]), "ind: expected one label per specimen (6), got shape (5,)"),
    (dict(land_pairs=PAIRS, ind=[0, 1, 2, 2, 3, 4]), "replicate: individual 2 has several configurations on one "
                                                     "side; label them with replicate=..."),
    (dict(land_pairs=PAIRS, ind=[0] * 6, replicate=range(6)), "ind: need at least two individuals"),
    (dict(land_pairs=PAIRS, ind=range(6), replicate=range(6)), "replicate: no side of any individual has two "
                                                              "replicates (no measurement error to estimate)"),
    (dict(land_pairs=PAIRS, ind=[0, 0, 1, 1, 2, 2], replicate=[0, 1]), "replicate: expected one label per "
                                                                       "specimen (6), got shape (2,)"),
    (dict(side=["L", "R"] * 3), "ind: matching symmetry needs the individual of each configuration"),
    (dict(side=["L", "R"] * 3, ind=[0, 0, 1]), "ind: expected one label per specimen (6), got shape (3,)"),
    (dict(side=["L", "R"], ind=range(6)), "side: expected one label per specimen (6), got shape (2,)"),
    (dict(side=["L", "R", "M"] * 2, ind=range(6)), "side: expected two sides; got 3: ['L', 'M', 'R']"),
    (dict(side=["L", "R"] * 3, ind=[0, 0, 1, 1, 2, 3]), "ind: individual 2 is not on both sides"),
    (dict(side=["L", "R"] * 3, ind=[0, 0, 1, 1, 2, 2], mirror_side="X"), "mirror_side: 'X' is not a side; the "
                                                                         "sides are ['L', 'R']"),
    (dict(side=["L", "R"] * 3, ind=[0, 0, 0, 0, 0, 0], replicate=range(6)), "ind: need at least two individuals"),
    (dict(land_pairs=PAIRS, n_permutations=10), "n_permutations must be at least 19; got 10"),
    (dict(land_pairs=PAIRS, n_permutations=0), "n_permutations*"),
])
def test_bad_input_is_named(kwargs, message):
    shapes = _symmetric_faces(np.random.default_rng(13), 6)
    with pytest.raises(ValueError) as err:
        bilateral_symmetry(shapes, **{"n_permutations": 19, **kwargs})
    if message.endswith("*"):
        assert str(err.value).startswith(message[:-1])
    else:
        assert str(err.value) == message


def test_the_individual_with_several_configurations_is_named():
    shapes = _symmetric_faces(np.random.default_rng(15), 10)
    side = ["L", "R", "L", "R", "L", "R", "R", "L", "L", "R"]
    ind = [0, 0, 1, 1, 2, 2, 2, 3, 3, 3]  # 2 twice on the right, 3 twice on the left
    with pytest.raises(ValueError, match="^replicate: individual 2 has several"):
        bilateral_symmetry(shapes, side=side, ind=ind, n_permutations=19)


def test_one_individual_without_replicates_is_refused():
    shapes = _symmetric_faces(np.random.default_rng(14), 2)
    with pytest.raises(ValueError, match="^ind: need at least two individuals$"):
        bilateral_symmetry(shapes, side=["L", "R"], ind=[0, 0], n_permutations=19)
    with pytest.raises(ValueError, match="^shapes must contain at least 2"):
        bilateral_symmetry(shapes[:1], land_pairs=PAIRS, n_permutations=19)


def test_the_top_level_names():
    assert sl.bilateral_symmetry is bilateral_symmetry
    assert sl.SymmetryResult.__name__ == "SymmetryResult" and "bilateral_symmetry" in sl.__all__


def test_the_defaults_are_999_permutations_from_seed_0():
    rng = np.random.default_rng(16)
    shapes = _symmetric_faces(rng, 5) + rng.normal(scale=0.02, size=(5, 6, 2))
    res = bilateral_symmetry(shapes, land_pairs=PAIRS)
    again = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=999, seed=0)
    assert res.n_permutations == 999 and res.null.shape == (999, 2)
    np.testing.assert_array_equal(res.null, again.null)


# --- more limits ------------------------------------------------------------------------------------

def test_planar_skulls_without_pairs_have_no_asymmetry():
    """3-D configurations on one plane, no landmark pairs: each is its own mirror image (a rotation)."""
    rng = np.random.default_rng(18)
    flat = np.zeros((6, 5, 3))
    flat[:, :, 1:] = rng.normal(size=(6, 5, 2))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    shapes = flat @ q.T  # the plane is not x = 0
    res = bilateral_symmetry(shapes, land_pairs=[], n_permutations=19)
    assert np.max(np.abs(res.asymmetric)) < 1e-9
    assert res.ss[1] < 1e-18 * res.ss[-1] and res.ss[0] == pytest.approx(res.ss[-1], rel=1e-9)


def test_identical_symmetric_specimens_have_nothing_to_test():
    res = bilateral_symmetry(np.repeat(FACE[None], 4, axis=0), land_pairs=PAIRS, n_permutations=19)
    assert np.all(res.ss < 1e-24) and np.all(np.isnan(res.value)) and np.all(np.isnan(res.p_value))
    assert np.all(np.isnan(res.null))


def test_tiny_variation_keeps_its_f_ratios():
    """F does not depend on how small the variation is (the Procrustes coordinates are then linear in it)."""
    rng = np.random.default_rng(19)
    noise = rng.normal(size=(8, 6, 2))
    big = bilateral_symmetry(FACE + 1e-4 * noise, land_pairs=PAIRS, n_permutations=19)
    tiny = bilateral_symmetry(FACE + 1e-7 * noise, land_pairs=PAIRS, n_permutations=19)
    assert np.all(np.isfinite(tiny.value[:2]))
    np.testing.assert_allclose(tiny.value[:2], big.value[:2], rtol=1e-3)
    assert tiny.ss[-1] == pytest.approx(big.ss[-1] * 1e-6, rel=1e-3)


def test_permutations_that_relabel_the_individuals_are_ties():
    """Two individuals: a permutation that exchanges them (and or the sides) as wholes gives the observed
    F of ``ind`` again, to rounding, and must count as at least as large."""
    rng = np.random.default_rng(20)
    shapes = _symmetric_faces(rng, 2) + rng.normal(scale=0.03, size=(2, 6, 2))
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, n_permutations=199, seed=1)
    assert res.rows == ("ind", "side", "ind:side", "Total") and res.df.tolist() == [1, 1, 1, 3]
    # rows: specimen 0, specimen 1, mirror 0, mirror 1; the same permutations as the function's
    draw = np.random.default_rng(1)
    perms = [draw.permutation(4) for _ in range(199)]
    wholes = {(0, 1, 2, 3), (1, 0, 3, 2), (2, 3, 0, 1), (3, 2, 1, 0)}
    ties = sum(tuple(p) in wholes for p in perms)
    assert ties > 20
    assert res.p_value[0] >= (1 + ties) / 200
    np.testing.assert_allclose(res.null[[tuple(p) in wholes for p in perms], 0], res.value[0], rtol=1e-9)


def test_two_individuals_with_replicates_are_enough():
    rng = np.random.default_rng(21)
    shapes, ind, rep = _replicated(rng, n_ind=2, n_rep=2)
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, ind=ind, replicate=rep, n_permutations=19)
    assert res.df.tolist() == [1, 1, 1, 4, 7] and np.all(np.isfinite(res.value[:3]))


def test_the_components_average_the_replicates():
    rng = np.random.default_rng(22)
    shapes, ind, rep = _replicated(rng, n_ind=3, n_rep=3)
    res = bilateral_symmetry(shapes, land_pairs=PAIRS, ind=ind, replicate=rep, n_permutations=19)
    n = len(shapes)
    for i in range(3):
        original = res.aligned[:n][ind == i].mean(axis=0)
        mirrored = res.aligned[n:][ind == i].mean(axis=0)
        np.testing.assert_allclose(res.symmetric[i], (original + mirrored) / 2, atol=1e-14)
        np.testing.assert_allclose(res.asymmetric[i], (original - mirrored) / 2, atol=1e-14)
    np.testing.assert_allclose(res.directional, res.asymmetric.mean(axis=0), atol=1e-15)
