"""Linear models on shape (shape_lm): closed forms — one factor is PERMANOVA (Goodall's F), type I
sums of squares add up to the model's, a balanced orthogonal design gives type I = type II — and
residual randomisation that keeps its size and finds a real effect."""

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.distance import cdist

import shapelib as sl
from shapelib.statistics.distance_based import permanova
from shapelib.statistics.linear_model import procrustes_coordinates, shape_lm
from tests.conftest import ellipse_population


@pytest.fixture
def balanced(rng):
    """24 shapes, genus × sex balanced (6 per cell), genus moves one landmark, size a covariate."""
    x = ellipse_population(rng, 24, k=8, noise=0.03)
    data = pd.DataFrame({"genus": np.repeat(["a", "b", "c"], 8), "sex": np.tile(["f", "m"], 12),
                         "size": rng.uniform(1, 2, 24)})
    x[data["genus"].to_numpy() == "b", 0, 0] += 1.0
    return x, data


def test_one_factor_is_permanova_on_the_procrustes_coordinates(balanced):
    x, data = balanced
    fit = shape_lm("~ genus", data, x, n_permutations=99, seed=4)
    y = procrustes_coordinates(x)
    perm = permanova(cdist(y, y), {"genus": data["genus"]}, permute="rows", n_permutations=99, seed=4).table
    assert fit.table.loc["genus", "F"] == pytest.approx(perm.loc["genus", "pseudo_F"], rel=1e-10)
    assert fit.table.loc["genus", "sum_of_squares"] == pytest.approx(perm.loc["genus", "sum_of_squares"], rel=1e-10)
    assert fit.table.loc["genus", "p_value"] == perm.loc["genus", "p_value"]  # same draws: RRPP permutes rows here
    assert fit.table.loc["genus", "p_value"] <= 0.05


def test_type_one_sums_add_up_and_balanced_orthogonal_designs_give_type_one_equal_type_two(balanced):
    x, data = balanced
    one = shape_lm("~ genus * sex", data, x, ss_type="I", n_permutations=19).table
    two = shape_lm("~ genus * sex", data, x, ss_type="II", n_permutations=19).table
    terms = ["genus", "sex", "genus:sex"]
    assert one.loc[terms, "sum_of_squares"].sum() + one.loc["Residual", "sum_of_squares"] == \
        pytest.approx(one.loc["Total", "sum_of_squares"], rel=1e-12)
    np.testing.assert_allclose(one.loc[terms, "sum_of_squares"], two.loc[terms, "sum_of_squares"], rtol=1e-9)
    assert list(one["ss_type"][:3]) == ["I (sequential)"] * 3 and two.loc["genus", "reduced_model"] == "sex"
    # an unbalanced covariate makes them differ, as it must
    one = shape_lm("~ size + genus", data, x, ss_type="I", n_permutations=19).table
    three = shape_lm("~ size + genus", data, x, ss_type="III", n_permutations=19).table
    assert one.loc["size", "sum_of_squares"] != pytest.approx(three.loc["size", "sum_of_squares"], rel=1e-6)
    assert one.loc["genus", "sum_of_squares"] == pytest.approx(three.loc["genus", "sum_of_squares"], rel=1e-10)


def test_gram_input_equals_coordinates_and_a_null_term_keeps_its_size(rng):
    x = ellipse_population(rng, 20, k=6, noise=0.05)
    y = procrustes_coordinates(x)
    yc = y - y.mean(axis=0)
    data = pd.DataFrame({"g": np.tile(["p", "q"], 10), "c": rng.normal(size=20)})
    a = shape_lm("~ g + c", data, x, n_permutations=49).table
    b = shape_lm("~ g + c", data, gram=yc @ yc.T, n_permutations=49).table
    pd.testing.assert_frame_equal(a, b, rtol=1e-8)
    rejections = 0
    for seed in range(30):  # no effect: p below 0.1 in about a tenth of the data sets
        r = np.random.default_rng(100 + seed)
        xs = ellipse_population(r, 16, k=6, noise=0.05)
        d = pd.DataFrame({"g": np.tile(["p", "q"], 8), "c": r.normal(size=16)})
        rejections += shape_lm("~ c + g", d, xs, n_permutations=39, seed=seed).table.loc["g", "p_value"] <= 0.1
    assert rejections <= 8


def test_bad_formulas_and_data_are_value_errors(balanced):
    x, data = balanced
    with pytest.raises(ValueError, match="no residual degrees of freedom"):
        shape_lm("~ genus * sex", data.iloc[[0, 1, 8, 9, 16, 17]], x[[0, 1, 8, 9, 16, 17]], n_permutations=19)
    with pytest.raises(ValueError, match="formula"):
        shape_lm("~ nope", data, x, n_permutations=19)
    with pytest.raises(ValueError, match="ss_type"):
        shape_lm("~ genus", data, x, ss_type="IV")
    assert sl.shape_lm is shape_lm


def test_allometry_recovers_a_known_allometric_vector_and_corrects_for_size(rng):
    from shapelib.statistics.allometry import allometry

    base = ellipse_population(rng, 1, k=7, noise=0.0)[0]
    direction = np.zeros_like(base)
    direction[0] = [0.2, 0.1]  # landmark 1 moves out as log size grows
    log_size = rng.uniform(0.0, 1.5, 40)
    shapes = np.stack([np.exp(s) * (base + s * direction) for s in log_size])
    shapes = shapes + rng.normal(scale=0.002, size=shapes.shape) * np.exp(log_size)[:, None, None]
    res = allometry(shapes, n_permutations=99)
    np.testing.assert_allclose(res.centroid_size, [sl.geometry.procrustes.centroid_size(s) for s in shapes])
    assert res.r2 > 0.9 and res.p_value == pytest.approx(0.01)
    # the slope's direction is the known one, seen in the unit-size Procrustes frame: compare by
    # regressing the aligned coordinates on log size directly
    y = procrustes_coordinates(shapes)
    c = np.log(res.centroid_size) - np.log(res.centroid_size).mean()
    np.testing.assert_allclose(res.slope.ravel(), c @ (y - y.mean(axis=0)) / (c @ c), atol=1e-12)
    # size-corrected shapes no longer depend on size
    corr = res.corrected.reshape(len(shapes), -1)
    assert np.abs(c @ (corr - corr.mean(axis=0))).max() < 1e-10
    with pytest.raises(ValueError, match="same centroid size"):
        allometry(sl.to_centroid_size(shapes, 1.0))


def test_allometry_of_rectangles_against_hand_made_procrustes_coordinates(rng):
    """Rectangles with half-sides (a, b) centred on the axes: their Procrustes coordinates at unit
    size are the corners over the centroid size 2 √(a² + b²) (two such rectangles are already at
    their best rotation, the identity), so the slope, mean and r² follow from a least-squares fit
    of those coordinates on [1, log CS], whatever common frame the alignment picks."""
    from scipy.linalg import orthogonal_procrustes

    from shapelib.statistics.allometry import allometry

    size = np.exp(rng.uniform(0.0, 1.5, 12))
    a, b = size * (1 + 0.3 * np.log(size)), size  # elongates as it grows
    corners = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    shapes = np.stack([corners * [ai, bi] for ai, bi in zip(a, b)])
    cs = 2 * np.sqrt(a ** 2 + b ** 2)
    y = (shapes / cs[:, None, None]).reshape(len(size), -1)  # hand-made Procrustes coordinates
    design = np.column_stack([np.ones_like(cs), np.log(cs) - np.log(cs).mean()])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ coef
    r2 = 1 - np.sum(resid ** 2) / np.sum((y - y.mean(axis=0)) ** 2)

    res = allometry(shapes, n_permutations=19)
    np.testing.assert_allclose(res.centroid_size, cs, rtol=1e-12)
    rot, _ = orthogonal_procrustes(coef[0].reshape(4, 2), res.mean)  # the alignment's common frame
    np.testing.assert_allclose(res.mean, coef[0].reshape(4, 2) @ rot, atol=1e-9)
    np.testing.assert_allclose(res.slope, coef[1].reshape(4, 2) @ rot, atol=1e-9)
    assert res.r2 == pytest.approx(r2, rel=1e-9)
    assert res.F == pytest.approx(r2 / (1 - r2) * (len(size) - 2), rel=1e-9)  # one term, n − 2 residual df
    assert res.n_permutations == 19
    assert res.summary().startswith(f"allometry: shape on log centroid size (12 shapes, size {cs.min():.4g} … "
                                    f"{cs.max():.4g}): R² = {r2:.4g}, F = {res.F:.4g}, permutation p = ")
    assert res.summary().endswith("(19 permutations)")
    np.testing.assert_allclose(res.corrected.reshape(len(size), -1),
                               ((coef[0] + resid).reshape(-1, 4, 2) @ rot).reshape(len(size), -1), atol=1e-9)


def test_allometry_tests_by_shape_lm_with_its_seed_and_checks_its_input(rng):
    """The permutation test is shape_lm's on log centroid size, with the seed given (0 by default,
    999 permutations); a size effect too weak to find, so that the p-value depends on the draws."""
    from shapelib.statistics.allometry import allometry

    x = ellipse_population(rng, 10, k=5, noise=0.05) * rng.uniform(1, 2, 10)[:, None, None]
    data = pd.DataFrame({"log_size": np.log([sl.geometry.procrustes.centroid_size(s) for s in x])})
    y = procrustes_coordinates(x)
    p = {seed: shape_lm("~ log_size", data, y, n_permutations=49, seed=seed).table.loc["log_size", "p_value"]
         for seed in (0, 1, 5)}
    assert len(set(p.values())) > 1  # the draws matter here
    assert allometry(x, n_permutations=49, seed=5).p_value == p[5]
    assert allometry(x, n_permutations=49).p_value == p[0]
    full = allometry(x)
    assert full.n_permutations == 999 and full.p_value == \
        shape_lm("~ log_size", data, y, seed=0).table.loc["log_size", "p_value"]
    assert allometry(x[:3], n_permutations=19).centroid_size.shape == (3,)  # three shapes are enough
    with pytest.raises(ValueError, match=r"^shapes must contain at least 3 shape"):
        allometry(x[:2])
    # sizes equal to 1e-11 of the size itself: the same size, whatever the units
    same = np.stack([sl.to_centroid_size(s, 1000.0 * (1 + 1e-14 * i)) for i, s in enumerate(x[:4])])
    with pytest.raises(ValueError, match="the shapes all have the same centroid size: were they scaled to unit size "
                                         "already[?] allometry needs the shapes as measured"):
        allometry(same)
