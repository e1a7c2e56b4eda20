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
