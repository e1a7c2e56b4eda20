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
