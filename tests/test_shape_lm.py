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


def _lm_data(rng, n=12):
    x = rng.normal(size=n)
    g = np.tile(["a", "b"], n // 2)
    y = rng.normal(size=(n, 3)) + np.c_[x, x, -x] * 0.5
    return pd.DataFrame({"x": x, "g": g}), y


def test_table_rows_and_coefficients_against_least_squares(rng):
    """Responses given as an (N, p) matrix, ~ x + g: every number of the table from numpy's least
    squares on the design [1, x, g == b] (type I: x after the intercept, g after x), the residual and
    total rows, the effect size and p from the returned null, the coefficients, fitted and residuals."""
    data, y = _lm_data(rng)
    n = len(y)
    fit = shape_lm("shape~x+g", data, y, n_permutations=99)
    design = np.c_[np.ones(n), data["x"], data["g"] == "b"].astype(float)

    def rss(cols):
        beta = np.linalg.lstsq(design[:, cols], y, rcond=None)[0]
        return float(np.sum((y - design[:, cols] @ beta) ** 2))

    total, r1, r12, r_full = float(np.sum((y - y.mean(0)) ** 2)), rss([0]), rss([0, 1]), rss([0, 1, 2])
    t = fit.table
    assert list(t.columns) == ["df", "sum_of_squares", "r2", "F", "p_value", "z", "ss_type", "reduced_model"]
    assert list(t.index) == ["x", "g", "Residual", "Total"]
    np.testing.assert_allclose(t["sum_of_squares"], [r1 - r12, r12 - r_full, r_full, total], rtol=1e-10)
    np.testing.assert_allclose(t["r2"], np.array([r1 - r12, r12 - r_full, r_full, total]) / total, rtol=1e-10)
    assert t["df"].tolist() == [1, 1, n - 3, n - 1]
    np.testing.assert_allclose(t["F"][:2], np.array([r1 - r12, r12 - r_full]) / (r_full / (n - 3)), rtol=1e-10)
    assert t.loc["x", "reduced_model"] == "1" and t.loc["g", "reduced_model"] == "x"
    assert t.loc["x", "ss_type"] == "I (sequential)"
    for row in ("Residual", "Total"):
        assert t.loc[row, ["F", "p_value", "z", "ss_type", "reduced_model"]].isna().all()
    for term in ("x", "g"):
        null, f = fit.null[term], t.loc[term, "F"]
        assert null.shape == (99,) and np.all(np.isfinite(null)) and np.all(null > 0)
        assert t.loc[term, "p_value"] == (1 + np.sum(null >= f)) / 100
        z = (np.log(f) - np.log(null).mean()) / np.log(null).std(ddof=1)
        assert t.loc[term, "z"] == pytest.approx(z, rel=1e-12)
    beta = np.linalg.lstsq(design, y, rcond=None)[0]
    assert list(fit.coefficients.index) == ["Intercept", "x", "g[T.b]"]
    np.testing.assert_allclose(fit.coefficients.to_numpy(), beta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fit.fitted, design @ beta - y.mean(0), atol=1e-12)
    np.testing.assert_allclose(fit.residuals, y - design @ beta, atol=1e-12)
    again = shape_lm("x + g", data, y, n_permutations=99, seed=0)  # no response, the default seed
    assert again.table.equals(fit.table)
    lines = again.summary().split("\n")
    assert lines[0] == ("shape ~ x + g: sums of squares type I (sequential), RRPP with 99 permutations (residuals "
                        "of each term's reduced model permuted)")
    assert lines[-2:] == ["p of x: residuals of ~ 1 permuted", "p of g: residuals of ~ x permuted"]


def test_a_model_without_intercept_counts_from_zero(rng):
    """~ 0 + x: nothing is centred, the total is ‖Y‖² on N degrees of freedom, x's sum of squares is
    that of the projection on x alone."""
    data, y = _lm_data(rng)
    fit = shape_lm("~ 0 + x", data, y, n_permutations=19)
    x = data["x"].to_numpy()
    ss_x = float(np.sum((np.outer(x, x @ y) / (x @ x)) ** 2))  # ‖x xᵀ Y / xᵀx‖²
    assert fit.table.loc["Total", "df"] == len(y) and fit.table.loc["Residual", "df"] == len(y) - 1
    assert fit.table.loc["Total", "sum_of_squares"] == pytest.approx(np.sum(y ** 2), rel=1e-12)
    assert fit.table.loc["x", "sum_of_squares"] == pytest.approx(ss_x, rel=1e-10)


def test_shape_lm_input_errors_say_what_is_wrong(rng):
    data, y = _lm_data(rng)
    g = y @ y.T
    with pytest.raises(ValueError, match=r"^give shapes \(N, K, d\) or gram \(N, N\), one of the two$"):
        shape_lm("~ x", data)
    with pytest.raises(ValueError, match=r"^give shapes \(N, K, d\) or gram \(N, N\), one of the two$"):
        shape_lm("~ x", data, y, gram=g)
    with pytest.raises(ValueError, match=r"^gram must be a symmetric \(N, N\) matrix; got shape \(12, 11\)$"):
        shape_lm("~ x", data, gram=g[:, :11])
    bad = g.copy()
    bad[0, 1] += 0.1 * np.abs(g).max()
    with pytest.raises(ValueError, match=r"^gram must be a symmetric \(N, N\) matrix; got shape \(12, 12\)$"):
        shape_lm("~ x", data, gram=bad)
    bad = g.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match=r"^gram has non-finite values$"):
        shape_lm("~ x", data, gram=bad)
    with pytest.raises(ValueError, match=r"^shapes must be a 2-D array; got shape \(12,\)$"):
        shape_lm("~ x", data, y[:, 0])
    with pytest.raises(ValueError, match=r"^the shapes do not vary: there is nothing to model$"):
        shape_lm("~ x", data, np.ones((12, 3)))
    twice = data.assign(x2=2 * data["x"])
    with pytest.raises(ValueError, match=r"^term x2 is collinear with x: it adds no independent column to the model "
                                         r"\(a covariate that repeats another, or an empty cell\)$"):
        shape_lm("~ x + x2", twice, y)
    with pytest.raises(ValueError, match=r"^n_permutations\b"):
        shape_lm("~ x", data, y, n_permutations=0)
    with pytest.raises(ValueError, match=r"^formula '~ x': "):
        shape_lm("~ x", data.assign(x=np.r_[np.nan, data["x"][1:]]), y)


def test_gram_within_rounding_of_symmetric_is_taken(rng):
    """Rows 0 and 1 of Y orthogonal, so G[0, 1] = 0, where only the absolute tolerance (1e-12 of the
    largest entry) can accept a rounding-level asymmetry."""
    data, y = _lm_data(rng)
    y[1] -= (y[1] @ y[0]) / (y[0] @ y[0]) * y[0]
    g = y @ y.T
    g[0, 1] = 0.0
    g[1, 0] = 1e-13 * np.abs(g).max()
    ref = shape_lm("~ x", data, y, n_permutations=19).table
    got = shape_lm("~ x", data, gram=g, n_permutations=19).table
    np.testing.assert_allclose(got["sum_of_squares"], ref["sum_of_squares"], rtol=1e-9)


def test_procrustes_coordinates_of_two_shapes_and_its_errors(rng):
    x = rng.normal(size=(2, 4, 2))
    out = procrustes_coordinates(x)
    assert out.shape == (2, 8)
    with pytest.raises(ValueError, match=r"^shapes must contain at least 2 shape"):
        procrustes_coordinates(x[:1])
