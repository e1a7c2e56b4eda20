"""Missing landmarks: deleted from real outlines and estimated back, by thin-plate spline and by
regression, more closely than a rigid fit of the mean; the spline reproduces affine maps exactly."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.comparison.missing import _fit_onto
from shapelib.geometry.procrustes import generalized_procrustes
from tests.conftest import requires_data


def test_the_spline_interpolates_and_reproduces_affine_maps(rng):
    s = rng.normal(size=(9, 2))
    t = s + 0.1 * rng.normal(size=(9, 2))
    np.testing.assert_allclose(sl.tps_map(s, t, s), t, atol=1e-10)  # exact at the landmarks
    a = np.array([[1.2, 0.3], [-0.2, 0.9]])
    q = rng.normal(size=(5, 2))
    np.testing.assert_allclose(sl.tps_map(s, s @ a.T + [2, -1], q), q @ a.T + [2, -1], atol=1e-10)
    s3, q3 = rng.normal(size=(8, 3)), rng.normal(size=(3, 3))
    np.testing.assert_allclose(sl.tps_map(s3, 2 * s3 + 1, q3), 2 * q3 + 1, atol=1e-10)  # 3-D kernel too


@requires_data
@pytest.mark.parametrize("method", ["tps", "regression"])
def test_deleted_landmarks_of_real_outlines_are_estimated_back(method):
    from shapelib.datasets import load_adhd200

    x = load_adhd200()[0][:60, ::2]
    spacing = sl.landmark_spacing(x)
    rng = np.random.default_rng(0)
    gone, deleted = x.copy(), []
    for i in range(10):
        ks = rng.choice(x.shape[1], 2, replace=False)
        gone[i, ks] = np.nan
        deleted.append((i, ks))
    res = sl.estimate_missing(gone, method=method)
    assert res.estimated.sum() == 20 and res.n_reference == 50
    assert np.isfinite(res.shapes).all()
    np.testing.assert_array_equal(res.shapes[~res.estimated], x[~res.estimated])  # the rest untouched
    err = np.mean([np.linalg.norm(res.shapes[i, ks] - x[i, ks], axis=1) for i, ks in deleted])
    # baseline: the mean of the complete specimens fitted rigidly (with scale) onto the present landmarks
    mean = generalized_procrustes(x[10:], scaling=False)[0].mean(axis=0)
    base = np.mean([np.linalg.norm(_fit_onto(mean[np.setdiff1d(np.arange(25), ks)], x[i, np.setdiff1d(
        np.arange(25), ks)])(mean[ks]) - x[i, ks], axis=1) for i, ks in deleted])
    assert err < 0.6 * base and err < 0.15 * spacing, (err / spacing, base / spacing)


def test_too_few_complete_specimens_or_landmarks_are_value_errors(rng):
    x = rng.normal(size=(4, 5, 2))
    x[:2, 0] = np.nan
    with pytest.raises(ValueError, match="complete specimen"):
        sl.estimate_missing(x)
    y = rng.normal(size=(8, 4, 2))
    y[0, :2] = np.nan
    with pytest.raises(ValueError, match="specimen 0: 2 landmark"):
        sl.estimate_missing(y)
    with pytest.raises(ValueError, match="method"):
        sl.estimate_missing(y, method="mean")


@pytest.mark.parametrize("d, kernel", [(2, "thin_plate_spline"), (3, "linear")])
def test_tps_map_is_scipys_thin_plate_interpolant(rng, d, kernel):
    """The spline of tps_map against scipy's RBFInterpolator with the same radial function (r² log r in
    2-D, −r in 3-D) and a linear polynomial: an independent solve of the same interpolation problem;
    d + 1 landmarks (the fewest) give the affine map."""
    from scipy.interpolate import RBFInterpolator

    s = rng.normal(size=(9, d))
    t = s + 0.3 * rng.normal(size=s.shape)
    q = rng.normal(size=(6, d))
    want = RBFInterpolator(s, t, kernel=kernel, degree=1)(q)
    np.testing.assert_allclose(sl.tps_map(s, t, q), want, rtol=1e-8, atol=1e-10)
    few = s[: d + 1]
    a = rng.normal(size=(d, d)) + 2 * np.eye(d)
    np.testing.assert_allclose(sl.tps_map(few, few @ a.T + 1.0, q), q @ a.T + 1.0, atol=1e-10)
    with pytest.raises(ValueError, match=rf"^a thin-plate spline in {d}-D needs at least {d + 1} landmarks; got {d}$"):
        sl.tps_map(s[:d], t[:d], q)


def test_fit_onto_a_similarity_image(rng):
    """Scaled by 1.7, turned and shifted: the similarity fit maps ref onto target exactly and carries
    any other point along the same way."""
    ref, other = rng.normal(size=(6, 2)), rng.normal(size=(3, 2))
    c, s = np.cos(0.7), np.sin(0.7)
    move = lambda p: 1.7 * p @ np.array([[c, -s], [s, c]]).T + [4.0, -2.0]  # noqa: E731
    f = _fit_onto(ref, move(ref))
    np.testing.assert_allclose(f(ref), move(ref), atol=1e-12)
    np.testing.assert_allclose(f(other), move(other), atol=1e-12)


def test_estimate_missing_counts_refusals_and_nothing_missing(rng):
    """Nothing missing: the shapes back, nothing estimated; tps needs d + 2 complete specimens,
    regression 3; a specimen needs d + 1 present landmarks; infinities are refused."""
    x = rng.normal(size=(6, 5, 2))
    res = sl.estimate_missing(x, method="regression")
    np.testing.assert_array_equal(res.shapes, x)
    assert not res.estimated.any() and res.method == "regression" and res.n_reference == 6
    y = x.copy()
    y[3:, 0] = np.nan  # three complete specimens
    with pytest.raises(ValueError, match=r"^3 complete specimen\(s\): estimating missing landmarks needs at least 4$"):
        sl.estimate_missing(y)
    assert sl.estimate_missing(y, method="regression").n_reference == 3
    z = x.copy()
    z[0, :2] = np.nan  # three landmarks present: enough in 2-D
    res = sl.estimate_missing(z)
    assert res.estimated.sum() == 2 and res.n_reference == 5 and np.isfinite(res.shapes).all()
    z[0, 2] = np.nan
    with pytest.raises(ValueError, match=r"^specimen 0: 2 landmark\(s\) present; at least 3 are needed to place the "
                                         r"others$"):
        sl.estimate_missing(z)
    with pytest.raises(ValueError, match=r"^shapes must be an \(N, K, d\) array; got shape \(5, 2\)$"):
        sl.estimate_missing(x[0])
    z = x.copy()
    z[1, 1, 0] = np.inf
    with pytest.raises(ValueError, match=r"^shapes have infinite coordinates; only NaN marks a missing landmark$"):
        sl.estimate_missing(z)


def test_the_methods_on_a_population_without_shape_variation(rng):
    """Complete specimens that are similarity copies of one shape, and a sheared copy missing a
    landmark: the thin-plate spline bends the mean affinely onto the present landmarks, so it returns
    the sheared landmark exactly (a similarity fit of the mean would not: a shear is no similarity)."""
    base = rng.normal(size=(7, 2))
    copies = []
    for k in range(5):
        c, s = np.cos(0.3 * k), np.sin(0.3 * k)
        copies.append((1 + 0.1 * k) * base @ np.array([[c, -s], [s, c]]).T + k)
    shear = base @ np.array([[1.0, 0.4], [0.0, 1.0]]).T
    x = np.stack(copies + [shear])
    x[5, 3] = np.nan
    tps = sl.estimate_missing(x)
    np.testing.assert_allclose(tps.shapes[5, 3], shear[3], atol=1e-8)
    have = np.arange(7) != 3
    assert np.linalg.norm(_fit_onto(base[have], shear[have])(base[3:4])[0] - shear[3]) > 1e-2
    assert tps.method == "tps" and sl.estimate_missing(x, method="regression").method == "regression"
    x[2, :2] = np.nan  # two landmarks of a second specimen: 3 in 2 specimens, 4 complete ones left
    assert sl.estimate_missing(x).summary() == ("3 missing landmark(s) in 2 specimen(s) estimated by thin-plate "
                                                "spline from the mean of 4 complete specimens")
    assert sl.estimate_missing(x, method="regression").summary() == (
        "3 missing landmark(s) in 2 specimen(s) estimated by multivariate regression on 4 complete specimens")
