"""Scale checks (shapelib.geometry.scale, shapelib._validate): σ against the landmarks, layout, grid size."""

import warnings

import numpy as np
import pytest

from shapelib.geometry import quadrature
from shapelib.solver.bracket import distance_bracket
from shapelib.solver.geodesic import GeodesicWarning, geodesic
from shapelib.geometry.procrustes import centroid_size
from shapelib.geometry.scale import ScaleWarning, landmark_spacing, sigma_ratio, to_centroid_size


def square_lattice(n, step):
    g = np.arange(n) * step
    return np.array([[x, y] for x in g for y in g], dtype=float)


def test_landmark_spacing_of_a_lattice_and_its_invariances(rng):
    x = square_lattice(4, 0.7)
    assert landmark_spacing(x) == pytest.approx(0.7, rel=1e-12)
    c, s = np.cos(1.1), np.sin(1.1)
    moved = 3.0 * x @ np.array([[c, -s], [s, c]]).T + [5.0, -2.0]
    assert landmark_spacing(np.stack([x, moved])) == pytest.approx(0.5 * (0.7 + 2.1), rel=1e-12)
    assert sigma_ratio(x, sigma2=0.49) == pytest.approx(1.0, rel=1e-12)
    assert sigma_ratio(np.zeros((3, 2)), sigma2=1.0) == np.inf
    with pytest.raises(ValueError, match="at least 2 landmarks"):
        landmark_spacing(np.zeros((1, 2)))


def test_to_centroid_size_is_the_study_scale(rng):
    shapes = rng.normal(size=(4, 6, 2)) * 100.0 + 300.0
    out = to_centroid_size(shapes, size=20.0)
    assert np.allclose([centroid_size(s) for s in out], 20.0) and np.allclose(out.mean(axis=1), 0.0)
    assert np.array_equal(to_centroid_size(shapes), to_centroid_size(shapes, size=20.0))  # the default is the study's
    one = to_centroid_size(shapes[0], size=3.0)
    assert one.shape == (6, 2) and centroid_size(one) == pytest.approx(3.0)
    with pytest.raises(ValueError, match="size"):
        to_centroid_size(shapes, size=0.0)


@pytest.mark.parametrize("entry", ["geodesic", "bracket"])
def test_landmark_dimension_must_be_2_or_3(rng, entry):
    u = rng.normal(size=(2, 10))  # a (K, d) shape passed as (d, K), or a p x k x n array misread
    f = geodesic if entry == "geodesic" else distance_bracket
    with pytest.raises(ValueError, match=r"10 dimensions.*\(K, d\).*shapelib.io.from_pkn"):
        f(u, u + 0.1, metric="alpha", sigma2=0.5)


@pytest.mark.parametrize("entry", ["geodesic", "bracket"])
def test_sigma_far_below_the_spacing_warns_and_says_what_to_do(entry):
    u = square_lattice(3, 50.0)  # pixel-like units
    f = geodesic if entry == "geodesic" else distance_bracket
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GeodesicWarning)
        with pytest.warns(ScaleWarning, match=r"0.0141 times the mean nearest-landmark spacing 50.*to_centroid_size"):
            f(u, u + 1.0, metric="alpha", sigma2=0.5)


def test_sigma_far_above_the_shape_warns():
    u = square_lattice(3, 0.1)
    with pytest.warns(ScaleWarning, match="single blob"):
        geodesic(u, u * 1.1, metric="alpha", sigma2=4.0, n_steps=2)


def test_the_paper_regime_does_not_warn():
    u = square_lattice(3, 0.5) - 0.5  # centred: u * 1.1 differs in size only, not in pose
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        geodesic(u, u * 1.1, metric="alpha", sigma2=0.5, n_steps=4)


def test_underflowing_gradient_is_not_convergence():
    """Landmarks 50 σ apart: the Gaussians never interact, the gradient is zero to machine
    precision at the straight line, and the solver "converges" in 0 iterations — reported as not
    converged, with the reason."""
    u = square_lattice(3, 50.0)
    v = u + [3.0, 1.0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        with pytest.warns(GeodesicWarning, match=r"not converged: .*gradient underflows.*to_centroid_size"):
            r = geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=4)
    assert not r.converged and r.n_iter == 0 and r.log["stopped_by"] == "underflow"
    assert "do not interact" in r.log["reason"] and r.length > 2 * r.lower_bound
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        with pytest.warns(GeodesicWarning, match=r"stalled.*do not interact.*to_centroid_size"):
            b = distance_bracket(u, v, metric="alpha", sigma2=0.5)
    assert not b.converged and b.rel_gap > 1.0 and b.lower <= b.upper


def test_underflowing_energy_is_not_convergence():
    u = square_lattice(2, 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)  # sigma far above the shape: warned too
        with pytest.warns(GeodesicWarning, match=r"path energy underflows to 0.0 between distinct shapes"):
            r = geodesic(u, u * 1.2, metric="alpha", sigma2=1e200, n_steps=4)
    assert not r.converged and r.log["stopped_by"] == "underflow"


def test_fisher_rao_grid_is_refused_before_it_is_built():
    # 660 units across, sigma 3.6 (0.06 spacings: just above the degenerate-quadrature error of
    # check_fisher_rao_scale): hundreds of thousands of nodes x 144 landmarks
    u = square_lattice(12, 60.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        for f in (geodesic, distance_bracket):
            with pytest.raises(ValueError, match=r"would have [\d,]+ nodes .*GiB.*to_centroid_size"):
                f(u, u + 1.0, metric="fisher_rao", sigma2=13.0)
    with pytest.raises(ValueError, match="above the limit of 10 nodes x landmarks"):
        quadrature.make_grid(np.zeros((1, 2)), sigma2=1.0, max_entries=10)
    with pytest.raises(ValueError, match="non-finite"):
        quadrature.make_grid(np.array([[0.0, np.nan]]), sigma2=1.0)


# ---------------------------------------------------------------------------------------------
# the scale checks on shapes whose spacing and extent are known by construction
# ---------------------------------------------------------------------------------------------

SQUARE3 = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]])  # spacing 3, extent 3


def test_landmark_spacing_is_the_nearest_not_the_second_nearest_and_names_its_input():
    """A 1 x 2 rectangle: nearest neighbours 1 apart, second nearest 2; two landmarks 5 apart."""
    assert landmark_spacing([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 2.0]]) == 1.0
    assert landmark_spacing(np.array([[0.0, 0.0], [3.0, 4.0]])) == 5.0
    with pytest.raises(ValueError, match=r"^shapes need at least 2 landmarks"):
        landmark_spacing([[1.0, 2.0]])
    for bad in (np.zeros((3, 1)), np.zeros((2, 3, 1))):
        with pytest.raises(ValueError, match=r"^shapes\b"):
            landmark_spacing(bad)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # coincident landmarks: spacing 0, no division by zero
        assert sigma_ratio([[1.0, 1.0], [1.0, 1.0]], sigma2=0.5) == float("inf")


def test_fisher_rao_scale_threshold_message_and_given_ratio():
    """σ/h below 1/√(8 ln(1/ε)) = 1/√(8 · 52 ln 2) ≈ 0.059 (ε = 2⁻⁵²) is refused, with the σ² that
    would do, (0.059 h)², and h² for σ at one spacing; a given ratio is used as it is."""
    from shapelib.geometry.scale import FISHER_RAO_RATIO_MIN, check_fisher_rao_scale

    rmin = 1 / np.sqrt(8 * 52 * np.log(2.0))
    assert FISHER_RAO_RATIO_MIN == pytest.approx(rmin, rel=1e-15)
    want = (r"^fisher_rao: sigma2 = 0.0225 is too small for these landmarks: sigma = 0.15 is 0.05 times their mean "
            r"nearest-landmark spacing 3, below 0.059, .* Use sigma2 >= {:.3g} \(sigma at one spacing: 9\), or "
            r"bring the shapes to a scale that fits sigma2 \(shapelib.to_centroid_size\)$").format((rmin * 3) ** 2)
    with pytest.raises(ValueError, match=want):
        check_fisher_rao_scale(SQUARE3, sigma2=0.15 ** 2)
    with pytest.raises(ValueError, match=want):  # the ratio given, not measured on the (other) shapes
        check_fisher_rao_scale(SQUARE3 * 100, sigma2=0.15 ** 2, ratio=0.05)
    assert check_fisher_rao_scale(SQUARE3 * 100, sigma2=1e-8, ratio=0.06) is None
    with pytest.raises(ValueError, match=r"^alpha: sigma2"):
        check_fisher_rao_scale(SQUARE3, sigma2=0.15 ** 2, metric="alpha")
    assert check_fisher_rao_scale(SQUARE3, sigma2=0.18 ** 2) is None  # σ/h = 0.06
    assert check_fisher_rao_scale(SQUARE3 / 10, sigma2=0.018 ** 2) is None  # the same below h = 1
    with pytest.raises(ValueError, match="too small"):
        check_fisher_rao_scale(SQUARE3 / 10, sigma2=0.015 ** 2)
    with pytest.raises(ValueError, match="too small"):  # two landmarks have a spacing too
        check_fisher_rao_scale(SQUARE3[:2], sigma2=0.15 ** 2)
    assert check_fisher_rao_scale(SQUARE3[:1], sigma2=1e-12) is None  # one landmark: nothing to resolve
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # coincident: spacing 0, ratio inf without a division by zero
        assert check_fisher_rao_scale(np.zeros((3, 2)), sigma2=1e-12) is None


def test_check_scale_facts_and_messages_small_and_large():
    """σ = 0.15 on a square of side 3 is 0.05 spacings (small); σ = 4 exceeds its extent 3 (large),
    also far from the origin (the extent is per coordinate over the landmarks); one shape has no
    estimate, so the advice is just the fix."""
    from shapelib.geometry.scale import check_scale

    fix = ("Bring the shapes to a scale that fits sigma2, e.g. shapelib.to_centroid_size(shapes) (the study's "
           "centroid size 20, where the paper's sigma2 = 0.1-1.5 give sigma = 1.1-4.5 spacings), or estimate "
           "sigma2 from the data.")
    with pytest.warns(ScaleWarning) as caught:
        assert check_scale(SQUARE3, 0.15 ** 2) == pytest.approx(0.05)
    w = caught[0].message
    assert w.facts == {"kind": "small", "sigma2": pytest.approx(0.0225), "ratio": pytest.approx(0.05),
                       "spacing": 3.0, "estimate": None}
    assert str(w) == ("sigma = 0.15 (sigma2 = 0.0225) is 0.05 times the mean nearest-landmark spacing 3: the Gaussians "
                      "of neighbouring landmarks do not overlap, so the metric sees isolated points, not a shape, and "
                      "energies and gradients underflow. " + fix)
    with pytest.warns(ScaleWarning) as caught:
        assert check_scale(SQUARE3 + [100.0, 0.0], 16.0) == pytest.approx(4 / 3)
    w = caught[0].message
    assert w.facts == {"kind": "large", "sigma2": 16.0, "ratio": pytest.approx(4 / 3), "spacing": 3.0, "estimate": None}
    assert str(w) == ("sigma = 4 (sigma2 = 16) exceeds the largest extent of the shapes (3): each shape is a single "
                      "blob and distances between shapes nearly vanish. " + fix)
    with pytest.warns(ScaleWarning, match="0.05 times"):  # two landmarks are measured too
        check_scale(SQUARE3[:2], 0.15 ** 2)
    with pytest.warns(ScaleWarning, match="0.05 times the mean nearest-landmark spacing 0.3:"):  # below 1 too
        check_scale(SQUARE3 / 10, 0.015 ** 2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_scale(SQUARE3[:1], 1e-6) == float("inf")  # one landmark: no spacing, no warning
        assert check_scale(np.ones((3, 2)), 1.0) == float("inf")  # coincident landmarks: no extent
        assert check_scale(SQUARE3, 1.0) == pytest.approx(1 / 3)


def test_check_scale_keeps_quiet_at_the_shapes_own_estimate_and_advises_otherwise(rng):
    """Sixty noisy copies of a square of side 3 (σ = 0.15, so 0.05 spacings): σ² within 1e-3 of
    estimate_sigma2's is the data's own, not a misfit; 1 % off it warns, with the estimate, and the
    σ² from which paths bend, (0.2 h)² = 0.36."""
    from shapelib.geometry.scale import check_scale, estimate_sigma2

    x = SQUARE3 + 0.15 * rng.normal(size=(60, 4, 2))
    est = estimate_sigma2(x)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_scale(x, est.sigma2 * (1 + 5e-4))
    with pytest.warns(ScaleWarning) as caught:
        check_scale(x, est.sigma2 * 1.01)
    w = caught[0].message
    assert w.facts["estimate"] == est.sigma2 and w.facts["kind"] == "small"
    spacing = landmark_spacing(x)
    assert str(w).endswith(f": shapelib.estimate_sigma2(shapes) gives sigma2 = {est.sigma2:.3g} here (the landmarks' "
                           f"scatter around their mean, sigma = {est.sigma_over_spacing:.2g} spacings); that is below "
                           f"0.2 spacings too: the landmarks vary less than they are apart. At such sigma the "
                           f"closed-form bounds (alpha_bound, fisher_rao_bound) are still exact and compare the shapes "
                           f"landmark by landmark, while geodesics are straight lines (paths bend from sigma2 = "
                           f"{(0.2 * spacing) ** 2:.3g}).")
    assert spacing == pytest.approx(3.0, rel=0.1)
    with pytest.warns(ScaleWarning) as caught:  # large: the estimate is advised too
        check_scale(x, 16.0)
    assert caught[0].message.facts["kind"] == "large"
    assert f"extent of the shapes ({np.ptp(x, axis=1).max():.3g})" in str(caught[0].message)
    assert f"shapelib.estimate_sigma2(shapes) gives sigma2 = {est.sigma2:.3g} here" in str(caught[0].message)


def test_estimate_sigma2_fields_and_summary(rng):
    """Counts and spacing of the estimate (two-landmark shapes too: their spacing is their length),
    and the summary's lines for each method."""
    from shapelib.geometry.scale import estimate_sigma2

    x = SQUARE3 + 0.15 * rng.normal(size=(20, 4, 2))
    est = estimate_sigma2(x)
    assert (est.n_shapes, est.n_landmarks, est.dim, est.method) == (20, 4, 2, "scatter")
    lines = est.summary().split("\n")
    assert lines[0] == (f"sigma2 = {est.sigma2:.4g} ± {est.standard_error:.2g} (landmark scatter: the maximum-likelihood "
                        f"variance of each landmark around the mean shape, per coordinate; 20 shapes x 4 landmarks "
                        f"in 2-D)")
    assert lines[1] == (f"sigma = {est.sigma:.4g} = {est.sigma_over_spacing:.3g} x the mean nearest-landmark spacing "
                        f"{est.spacing:.4g}")
    assert lines[3].startswith("the Gaussians of neighbouring landmarks barely overlap at this sigma (below 0.2 spacings)")
    assert len(lines) == 4
    pred = estimate_sigma2(x, method="predictive")
    assert (pred.n_shapes, pred.n_landmarks, pred.dim, pred.standard_error) == (20, 4, 2, None)
    assert pred.summary().split("\n")[0] == (f"sigma2 = {pred.sigma2:.4g} (held-out prediction: half the variance at "
                                             f"which one shape's mixture best predicts another's landmarks; 20 shapes "
                                             f"x 4 landmarks in 2-D)")
    two = np.array([[0.0, 0.0], [5.0, 0.0]]) + 0.1 * rng.normal(size=(6, 2, 2))
    assert estimate_sigma2(two).spacing == pytest.approx(np.mean(np.linalg.norm(two[:, 1] - two[:, 0], axis=1)))
    with pytest.raises(ValueError, match=r"^shapes must contain at least 2 shape"):
        estimate_sigma2(x[:1])


def test_to_centroid_size_of_one_shape_and_its_errors():
    """One shape of two landmarks 2 apart: centred ±1, centroid size √2, so at size 20 ±10√2."""
    out = to_centroid_size(np.array([[0.0, 0.0], [2.0, 0.0]]))
    np.testing.assert_allclose(out, [[-10 * np.sqrt(2), 0.0], [10 * np.sqrt(2), 0.0]], rtol=1e-14)
    with pytest.raises(ValueError, match=r"^shapes must have at least 2 landmark"):
        to_centroid_size(np.array([[1.0, 2.0]]))
    with pytest.raises(ValueError, match=r"^size\b"):
        to_centroid_size(SQUARE3, size=-1.0)
