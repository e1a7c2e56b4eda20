"""Global integration (the slope of log partial-warp variance on log bending energy) against
independent computations: bending energies from the spline's kernel projected by hand, geomorph's
``globalIntegration`` redone step by step, data built with an exact variance profile along the
partial warps, the known slopes of self-similar, integrated and isotropic variation, pose, size,
order and labelling invariances, and the errors at the public door."""

import numpy as np
import pytest
from scipy.linalg import null_space

import shapelib as sl
from shapelib.statistics.integration import GlobalIntegrationResult

MEAN_2D = np.array([[0, 0], [1, 0], [2, 0.1], [2, 1], [1, 1.2], [0, 1], [0.6, 0.5], [1.5, 0.4]])
MEAN_3D = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0.2], [1, 0.1, 1], [0.2, 1, 1],
                    [1, 1, 1.1], [0.5, 0.4, 0.6]])


def _rot(t):
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def _kernel(x, geomorph=False):
    """The thin-plate kernel by loops: r² log r in 2-D (r² log r² in geomorph's), −r in 3-D."""
    k, d = x.shape
    u = np.zeros((k, k))
    for a in range(k):
        for b in range(k):
            r = np.sqrt(sum((x[a, c] - x[b, c]) ** 2 for c in range(d)))
            if d == 3:
                u[a, b] = -r
            elif r > 0:
                u[a, b] = r**2 * np.log(r**2 if geomorph else r)
    return u


def _energies_by_projection(x):
    """The nonzero eigenvalues of the bending-energy matrix without inverting the bordered matrix:
    ``L_K = N (Nᵀ U N)⁻¹ Nᵀ`` with ``N`` an orthonormal basis of the non-affine vectors."""
    basis = null_space(np.c_[np.ones(len(x)), x].T)
    return np.sort(1.0 / np.linalg.eigvalsh(basis.T @ _kernel(x) @ basis))


def _partial_warps(mean):
    lam, e = np.linalg.eigh(sl.bending_energy_matrix(mean))
    m = len(mean) - mean.shape[1] - 1
    return lam[-m:], e[:, -m:]


def _exact_profile(mean, sd, n, rng):
    """n specimens ``mean + Σ_j e_j z_ijᵀ`` whose scores on partial warp j have sample variance
    exactly ``sd[j]²`` in each coordinate (and mean 0)."""
    _, e = _partial_warps(mean)
    m, d = e.shape[1], mean.shape[1]
    assert n > m * d, "the centred columns need n > m d specimens"
    z = rng.normal(size=(n, m * d))
    q, _ = np.linalg.qr(z - z.mean(axis=0))  # orthonormal, centred columns
    scores = np.sqrt(n - 1) * q.reshape(n, m, d) * np.asarray(sd)[None, :, None]
    return mean + np.einsum("km,nmc->nkc", e, scores)


def _geomorph(a):
    """geomorph's globalIntegration step by step: its kernel, solve(L), eigen (decreasing), each
    specimen's projections as one row (x of every warp, then y), var, the k rows summed, lm."""
    ref = a.mean(axis=0)
    p, k = ref.shape
    big = np.zeros((p + k + 1, p + k + 1))
    big[:p, :p] = _kernel(ref, geomorph=True)
    big[:p, p:] = np.c_[np.ones(p), ref]
    big[p:, :p] = big[:p, p:].T
    be_matrix = np.linalg.solve(big, np.eye(p + k + 1))[:p, :p]
    vals, vecs = np.linalg.eigh(be_matrix)
    vals, vecs = vals[::-1], vecs[:, ::-1]
    m = p - k - 1
    be, emat = vals[:m], vecs[:, :m]
    rows = np.array([(a[i].T @ emat).T.flatten(order="F") for i in range(len(a))])
    wvar = rows.var(axis=0, ddof=1)
    pwvar = np.log(wvar.reshape(k, m).sum(axis=0))
    slope, _ = np.polyfit(np.log(be), pwvar, 1)
    return slope, be


@pytest.mark.parametrize("mean", [MEAN_2D, MEAN_3D], ids=["2-D", "3-D"])
def test_the_bending_energies_are_the_nonzero_eigenvalues_of_the_kernel_projected_off_the_affine_part(mean):
    rng = np.random.default_rng(0)
    dev = 0.01 * rng.normal(size=(4,) + mean.shape)
    shapes = np.concatenate([mean + dev, mean - dev])  # mean exactly ``mean`` up to rounding
    res = sl.global_integration(shapes, procrustes=False)
    expected = _energies_by_projection(mean)
    assert len(res.bending_energies) == len(mean) - mean.shape[1] - 1
    np.testing.assert_allclose(res.bending_energies, expected, rtol=1e-8)
    np.testing.assert_allclose(res.mean, mean, atol=1e-15)


@pytest.mark.parametrize("mean", [MEAN_2D, MEAN_3D], ids=["2-D", "3-D"])
def test_the_partial_warps_are_orthonormal_and_free_of_the_affine_part(mean):
    res = sl.global_integration(_exact_profile(mean, np.ones(len(mean) - mean.shape[1] - 1), 20,
                                               np.random.default_rng(1)), procrustes=False)
    e = res.partial_warps
    np.testing.assert_allclose(e.T @ e, np.eye(e.shape[1]), atol=1e-12)
    np.testing.assert_allclose(np.c_[np.ones(len(mean)), res.mean].T @ e, 0, atol=1e-10)
    assert np.all(np.diff(res.bending_energies) > 0)


@pytest.mark.parametrize("mean", [MEAN_2D, MEAN_3D], ids=["2-D", "3-D"])
def test_the_slope_is_geomorph_s_redone_step_by_step(mean):
    rng = np.random.default_rng(2)
    shapes = mean + 0.02 * rng.normal(size=(30,) + mean.shape) * rng.uniform(0.2, 2, size=(1, len(mean), 1))
    res = sl.global_integration(shapes, procrustes=False)
    slope, be = _geomorph(shapes)
    assert res.value == pytest.approx(slope, rel=1e-10)
    # geomorph's 2-D kernel r² log r² is twice r² log r: its bending energies are half of these
    factor = 0.5 if mean.shape[1] == 2 else 1.0
    np.testing.assert_allclose(be[::-1], factor * res.bending_energies, rtol=1e-8)


@pytest.mark.parametrize("beta", [-2.0, -1.0, -0.5, 0.0, 0.7])
@pytest.mark.parametrize("mean", [MEAN_2D, MEAN_3D], ids=["2-D", "3-D"])
def test_variances_proportional_to_a_power_of_the_bending_energy_give_that_power_as_the_slope(mean, beta):
    lam, _ = _partial_warps(mean)
    sd = 0.01 * (lam / lam[0]) ** (beta / 2)
    res = sl.global_integration(_exact_profile(mean, sd, 30, np.random.default_rng(3)), procrustes=False)
    assert res.value == pytest.approx(beta, abs=1e-9)
    np.testing.assert_allclose(res.variances, mean.shape[1] * sd**2, rtol=1e-9)
    # the line goes through every point: log v = intercept + slope log λ
    np.testing.assert_allclose(np.log(res.variances), res.intercept + res.value * np.log(res.bending_energies),
                               atol=1e-9)


@pytest.mark.parametrize("beta", [-2.0, -1.0, -0.3])
def test_a_random_sample_with_a_power_profile_aligned_by_procrustes_recovers_the_power(beta):
    rng = np.random.default_rng(4)
    lam, e = _partial_warps(MEAN_2D)
    scores = rng.normal(size=(3000, len(lam), 2)) * 0.01 * (lam / lam[0])[:, None] ** (beta / 2)
    shapes = MEAN_2D + np.einsum("km,nmc->nkc", e, scores)
    shapes = np.einsum("nkc,nbc->nkb", shapes, np.array([_rot(t) for t in rng.uniform(0, 6, 3000)]))
    res = sl.global_integration(shapes * rng.uniform(0.5, 3, (3000, 1, 1)) + rng.normal(size=(3000, 1, 2)))
    assert res.value == pytest.approx(beta, abs=0.05)


@pytest.mark.parametrize("mean", [MEAN_2D, MEAN_3D], ids=["2-D", "3-D"])
def test_isotropic_landmark_noise_gives_a_slope_near_zero_not_minus_one(mean):
    rng = np.random.default_rng(5)
    res = sl.global_integration(mean + 0.01 * rng.normal(size=(3000,) + mean.shape))
    assert abs(res.value) < 0.05
    assert res.reading == "disintegrated"


def test_the_slope_is_free_of_each_specimen_s_position_orientation_and_size():
    rng = np.random.default_rng(6)
    shapes = MEAN_2D + 0.03 * rng.normal(size=(25, 8, 2))
    ref = sl.global_integration(shapes)
    moved = (np.einsum("nkc,nbc->nkb", shapes, np.array([_rot(t) for t in rng.uniform(0, 6, 25)]))
             * rng.uniform(0.1, 10, (25, 1, 1)) + rng.normal(scale=5, size=(25, 1, 2)))
    res = sl.global_integration(moved)
    assert res.value == pytest.approx(ref.value, rel=1e-7)
    np.testing.assert_allclose(res.variances, ref.variances, rtol=1e-6)
    np.testing.assert_allclose(res.bending_energies, ref.bending_energies, rtol=1e-7)


@pytest.mark.parametrize("procrustes", [True, False])
def test_the_slope_is_free_of_the_order_of_the_specimens_and_of_the_landmarks(procrustes):
    rng = np.random.default_rng(7)
    shapes = MEAN_2D + 0.03 * rng.normal(size=(25, 8, 2))
    ref = sl.global_integration(shapes, procrustes=procrustes)
    shuffled = shapes[rng.permutation(25)][:, rng.permutation(8)]
    res = sl.global_integration(shuffled, procrustes=procrustes)
    assert res.value == pytest.approx(ref.value, rel=1e-8)
    np.testing.assert_allclose(res.bending_energies, ref.bending_energies, rtol=1e-8)
    np.testing.assert_allclose(res.variances, ref.variances, rtol=1e-7)


@pytest.mark.parametrize("scale", [1e-6, 7.0, 1e6])
@pytest.mark.parametrize("mean, power", [(MEAN_2D, -2), (MEAN_3D, -1)], ids=["2-D", "3-D"])
def test_scaling_the_coordinates_scales_the_bending_energies_by_a_power_of_the_size_and_keeps_the_slope(
        mean, power, scale):
    rng = np.random.default_rng(8)
    shapes = mean + 0.02 * rng.normal(size=(15,) + mean.shape)
    ref = sl.global_integration(shapes, procrustes=False)
    res = sl.global_integration(scale * shapes, procrustes=False)
    np.testing.assert_allclose(res.bending_energies, scale**power * ref.bending_energies, rtol=1e-8)
    np.testing.assert_allclose(res.variances, scale**2 * ref.variances, rtol=1e-8)
    assert res.value == pytest.approx(ref.value, rel=1e-8)


def test_the_slope_is_the_same_on_coordinates_projected_onto_the_tangent_space_at_the_mean():
    """gpagen's projection (geomorph's ``orp``): each aligned specimen's component along the
    unit-size mean removed, that mean added back."""
    rng = np.random.default_rng(13)
    shapes = MEAN_2D + 0.15 * rng.normal(size=(40, 8, 2))  # very variable shapes: far from the tangent space
    res = sl.global_integration(shapes)
    aligned = sl.procrustes_coordinates(shapes)
    mu = aligned.mean(axis=0)  # centred, as the aligned specimens are
    mu /= np.linalg.norm(mu)
    tangent = aligned @ (np.eye(16) - np.outer(mu, mu)) + mu
    assert np.abs(tangent - aligned).max() > 1e-3  # the projection moves them
    projected = sl.global_integration(tangent.reshape(40, 8, 2), procrustes=False)
    assert projected.value == pytest.approx(res.value, rel=1e-9)


def test_residuals_from_the_mean_are_refused_as_coordinates():
    shapes = MEAN_2D + 0.02 * np.random.default_rng(14).normal(size=(20, 8, 2))
    with pytest.raises(ValueError) as info:
        sl.global_integration(shapes - shapes.mean(axis=0), procrustes=False)
    assert str(info.value) == ("shapes: the mean configuration is nearly a single point (below 1e-8 of the "
                               "specimens' size): pass landmark coordinates, not residuals from the mean")


def _result(value, tolerance):
    return GlobalIntegrationResult(value=value, intercept=0.0, bending_energies=np.ones(3), variances=np.ones(3),
                                   partial_warps=np.eye(3), mean=np.zeros((3, 2)), n_specimens=10, tolerance=tolerance)


@pytest.mark.parametrize("value, tolerance, reading", [
    (-1.0, 0.5, "self-similar"), (-1.5, 0.5, "self-similar"), (-0.5, 0.5, "self-similar"),
    (-1.5000001, 0.5, "integrated"), (-0.4999999, 0.5, "disintegrated"),
    (-1.3, 0.25, "integrated"), (-0.7, 0.25, "disintegrated"), (0.0, 0.25, "disintegrated"),
    (-3.0, 0.25, "integrated")])
def test_a_slope_reads_as_self_similar_within_the_tolerance_of_minus_one(value, tolerance, reading):
    assert _result(value, tolerance).reading == reading
    assert f", {reading} (" in _result(value, tolerance).summary()


def test_the_summary_names_the_sample_the_slope_and_how_it_reads():
    lam, _ = _partial_warps(MEAN_2D)
    res = sl.global_integration(_exact_profile(MEAN_2D, 0.01 * (lam / lam[0]) ** -1.0, 40,
                                               np.random.default_rng(9)), procrustes=False)
    text = res.summary()
    assert res.reading == "integrated"
    assert "40 specimens, 5 partial warps" in text
    assert "= -2," in text and "integrated (steeper than −1" in text
    wider = sl.global_integration(_exact_profile(MEAN_2D, 0.01 * (lam / lam[0]) ** -1.0, 40,
                                                 np.random.default_rng(9)), procrustes=False, tolerance=1.5)
    assert wider.reading == "self-similar" and "within 1.5 of −1" in wider.summary()
    assert wider.value == res.value


@pytest.mark.parametrize("value, text", [
    (-2.0, "slope of log variance on log bending energy = -2, integrated (steeper than −1: relatively more "
           "variation at the large scales; −1 is self-similarity, 0 isotropic landmark noise)"),
    (-0.9, "slope of log variance on log bending energy = -0.9, self-similar (within 0.25 of −1: the same "
           "variation at every scale; −1 is self-similarity, 0 isotropic landmark noise)"),
    (-0.25, "slope of log variance on log bending energy = -0.25, disintegrated (shallower than −1: relatively "
            "more variation at the small scales; −1 is self-similarity, 0 isotropic landmark noise)"),
])
def test_the_summary_reads_each_slope_in_words(value, text):
    assert _result(value, 0.25).summary() == "global integration (10 specimens, 3 partial warps): " + text


def test_the_default_tolerance_is_a_tenth():
    lam, _ = _partial_warps(MEAN_2D)
    for beta, reading in [(-1.09, "self-similar"), (-1.11, "integrated"), (-0.89, "disintegrated")]:
        shapes = _exact_profile(MEAN_2D, 0.01 * (lam / lam[0]) ** (beta / 2), 20, np.random.default_rng(10))
        res = sl.global_integration(shapes, procrustes=False)
        assert res.tolerance == 0.1 and res.reading == reading


@pytest.mark.parametrize("shapes, match", [
    (MEAN_2D[:4] + np.zeros((10, 1, 1)), r"^shapes: at least 5 landmarks are needed in 2-D \(two partial warps, "
                                         r"K − 3, for a slope\); got shape \(10, 4, 2\)$"),
    (MEAN_3D[:5] + np.zeros((10, 1, 1)), r"^shapes: at least 6 landmarks are needed in 3-D \(two partial warps, "
                                         r"K − 4, for a slope\); got shape \(10, 5, 3\)$"),
    (MEAN_2D + np.zeros((2, 1, 1)), r"^shapes: at least 3 specimens are needed; got shape \(2, 8, 2\)$"),
    (MEAN_2D, "^shapes must have shape"),
    (np.zeros((10, 8, 4)), "^shapes: landmarks must have d = 2 or 3"),
])
def test_malformed_shapes_are_refused_naming_the_parameter(shapes, match):
    with pytest.raises(ValueError, match=match) as info:
        sl.global_integration(shapes + np.random.default_rng(0).normal(scale=0.01, size=np.shape(shapes)))
    assert "shapes" in str(info.value)


@pytest.mark.parametrize("mean", [MEAN_2D, MEAN_3D], ids=["2-D", "3-D"])
def test_the_fewest_specimens_and_landmarks_give_a_slope(mean):
    """Three specimens and d + 3 landmarks: two partial warps, a line through two points."""
    rng = np.random.default_rng(12)
    small = mean[: mean.shape[1] + 3]
    res = sl.global_integration(small + 0.02 * rng.normal(size=(3,) + small.shape))
    assert len(res.bending_energies) == 2 and np.isfinite(res.value)
    expected = np.diff(np.log(res.variances)) / np.diff(np.log(res.bending_energies))
    assert res.value == pytest.approx(expected[0], rel=1e-12)


def test_a_non_finite_coordinate_is_refused():
    shapes = MEAN_2D + 0.01 * np.random.default_rng(0).normal(size=(10, 8, 2))
    shapes[3, 2, 1] = np.nan
    with pytest.raises(ValueError, match=r"^shapes\[3\] contains non-finite values"):
        sl.global_integration(shapes, procrustes=False)


@pytest.mark.parametrize("procrustes", [True, False])
def test_identical_specimens_have_no_variation_to_fit(procrustes):
    with pytest.raises(ValueError, match="shapes: the specimens do not vary along partial warp 0"):
        sl.global_integration(MEAN_2D + np.zeros((5, 1, 1)), procrustes=procrustes)


def test_variation_missing_at_one_scale_is_named():
    lam, _ = _partial_warps(MEAN_2D)
    sd = np.ones(len(lam))
    sd[2] = 0.0
    with pytest.raises(ValueError) as info:
        sl.global_integration(_exact_profile(MEAN_2D, 0.01 * sd, 20, np.random.default_rng(0)), procrustes=False)
    assert str(info.value) == (f"shapes: the specimens do not vary along partial warp 2 (bending energy {lam[2]:.4g}); "
                               "the slope needs variation at every scale")


def _collinear(rng):
    s = np.arange(6.0) + 0.01 * rng.normal(size=(20, 6))
    return np.stack([s, 2 * s + 1], axis=-1)  # on the line y = 2x + 1


def _coplanar(rng):
    xy = np.c_[np.arange(7.0), np.sin(np.arange(7.0))] + 0.01 * rng.normal(size=(20, 7, 2))
    return np.concatenate([xy, np.ones((20, 7, 1))], axis=-1)  # on the plane z = 1


def _coinciding(rng):
    dev = 0.01 * rng.normal(size=(10, 8, 2))
    mean = MEAN_2D * [1, 0.1]  # extents about 2.1 and 0.13 along the principal axes
    mean[7] = mean[6] + [3e-9, 0]  # closer than 1e-8 of the largest extent
    return np.concatenate([mean + dev, mean - dev])


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("make", [_collinear, _coplanar, _coinciding], ids=["collinear", "coplanar", "coinciding"])
def test_a_mean_configuration_without_a_thin_plate_spline_is_refused_at_any_scale(make, scale):
    with pytest.raises(ValueError) as info:
        sl.global_integration(scale * make(np.random.default_rng(0)), procrustes=False)
    assert str(info.value) == ("shapes: the mean configuration has no thin-plate spline: its landmarks lie on one "
                               "line (one plane in 3-D) or two of them coincide")


def test_landmarks_a_millionth_of_the_extent_apart_are_kept():
    dev = 0.01 * np.random.default_rng(0).normal(size=(10, 8, 2))
    mean = MEAN_2D * [1, 0.1]
    mean[7] = mean[6] + [2e-6, 0]
    res = sl.global_integration(np.concatenate([mean + dev, mean - dev]), procrustes=False)
    assert len(res.bending_energies) == 5


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_variation_of_a_ten_billionth_of_the_size_is_fitted_at_any_scale(scale):
    lam, _ = _partial_warps(MEAN_2D)
    shapes = scale * _exact_profile(MEAN_2D, 1e-10 * (lam / lam[0]) ** -1.0, 20, np.random.default_rng(15))
    res = sl.global_integration(shapes, procrustes=False)
    assert res.value == pytest.approx(-2.0, abs=1e-3)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_affine_copies_of_one_configuration_have_no_variation_to_fit_at_any_scale(scale):
    rng = np.random.default_rng(11)
    maps = rng.normal(size=(10, 2, 2))
    shapes = scale * (np.einsum("kc,nbc->nkb", MEAN_2D, maps) + rng.normal(size=(10, 1, 2)))
    with pytest.raises(ValueError, match="^shapes: the specimens do not vary along partial warp 0 "):
        sl.global_integration(shapes, procrustes=False)


@pytest.mark.parametrize("tolerance", [0, -0.1, np.nan, "0.1"])
def test_a_tolerance_that_is_not_positive_is_refused(tolerance):
    shapes = MEAN_2D + 0.01 * np.random.default_rng(0).normal(size=(10, 8, 2))
    with pytest.raises(ValueError, match="^tolerance must be a positive finite number"):
        sl.global_integration(shapes, tolerance=tolerance)
