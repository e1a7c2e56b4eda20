import numpy as np
import pytest

from shapelib.geometry.gmm import gaussian_overlap, gmm_density, gmm_log_density, l2_distance, l2_inner
from shapelib.geometry.quadrature import make_grid


def test_density_integrates_to_one_and_matches_formula(rng):
    theta = rng.normal(size=(6, 2))
    s2 = 0.3
    grid = make_grid(theta, sigma2=s2, grid_spacing=0.25, grid_margin=8)
    p = gmm_density(grid.nodes, theta, sigma2=s2)
    assert grid.integrate(p) == pytest.approx(1.0, abs=1e-12)
    x = rng.normal(size=(5, 2))
    direct = np.mean([np.exp(-np.sum((x - t) ** 2, 1) / (2 * s2)) / (2 * np.pi * s2) for t in theta], axis=0)
    assert np.allclose(gmm_density(x, theta, sigma2=s2), direct, rtol=1e-13)


def test_log_density_is_stable_far_away():
    theta = np.zeros((3, 2))
    lp = gmm_log_density(np.array([[100.0, 0.0]]), theta, sigma2=0.01)
    assert np.isfinite(lp).all() and lp[0] == pytest.approx(-100.0**2 / 0.02 - np.log(2 * np.pi * 0.01))


def test_dimension_agnostic_normalisation(rng):
    theta = rng.normal(size=(2, 3))
    grid = make_grid(theta, sigma2=0.5, grid_spacing=0.5, grid_margin=7)
    assert grid.integrate(gmm_density(grid.nodes, theta, sigma2=0.5)) == pytest.approx(1.0, abs=1e-9)


def test_overlap_and_l2_distance_against_quadrature(rng):
    u, v = rng.normal(size=(2, 5, 2))
    s2 = 0.4
    grid = make_grid(np.stack([u, v]), sigma2=s2, grid_spacing=0.25, grid_margin=8)
    pu, pv = gmm_density(grid.nodes, u, sigma2=s2), gmm_density(grid.nodes, v, sigma2=s2)
    assert l2_inner(u, v, sigma2=s2) == pytest.approx(grid.integrate(pu * pv), rel=1e-11)
    assert l2_distance(u, v, sigma2=s2) == pytest.approx(np.sqrt(grid.integrate((pu - pv) ** 2)), rel=1e-9)
    g = gaussian_overlap(u, v, sigma2=s2)
    assert g.shape == (5, 5) and np.all(g > 0)


def test_l2_distance_is_a_metric(rng):
    u, v, w = rng.normal(size=(3, 4, 2))
    assert l2_distance(u, u, sigma2=0.5) == pytest.approx(0.0, abs=1e-9)
    assert l2_distance(u, v, sigma2=0.5) == pytest.approx(l2_distance(v, u, sigma2=0.5))
    assert l2_distance(u, w, sigma2=0.5) <= l2_distance(u, v, sigma2=0.5) + l2_distance(v, w, sigma2=0.5) + 1e-15


def test_l2_distance_invariant_to_rigid_motions_and_permutations(rng):
    u, v = rng.normal(size=(2, 6, 2))
    c, s = np.cos(0.8), np.sin(0.8)
    r = np.array([[c, -s], [s, c]])
    d = l2_distance(u, v, sigma2=0.2)
    assert l2_distance(u @ r.T + 3, v @ r.T + 3, sigma2=0.2) == pytest.approx(d, rel=1e-12)
    perm = rng.permutation(6)
    assert l2_distance(u[perm], v, sigma2=0.2) == pytest.approx(d, rel=1e-12)  # a GMM is a set


@pytest.mark.parametrize("s2", [0, -1, np.nan])
def test_bad_sigma2(s2):
    with pytest.raises(ValueError, match="sigma2"):
        gmm_density(np.zeros((1, 2)), np.zeros((2, 2)), sigma2=s2)


def test_bad_shapes():
    with pytest.raises(ValueError, match="same number of landmarks"):
        l2_distance(np.zeros((3, 2)), np.zeros((2, 2)), sigma2=1.0)
    with pytest.raises(ValueError, match="dimension"):
        gmm_density(np.zeros((1, 3)), np.zeros((2, 2)), sigma2=1.0)


def test_point_set_errors_name_the_argument():
    """Each function names the point set at fault, and both when their dimensions differ."""
    flat = np.zeros(3)
    with pytest.raises(ValueError, match=r"^a must be a 2-D array"):
        gaussian_overlap(flat, np.zeros((2, 2)), sigma2=1.0)
    with pytest.raises(ValueError, match=r"^b must be a 2-D array"):
        gaussian_overlap(np.zeros((2, 2)), flat, sigma2=1.0)
    with pytest.raises(ValueError, match=r"^a and b must have the same dimension; got \(1, 2\) and \(2, 3\)$"):
        gaussian_overlap(np.zeros((1, 2)), np.zeros((2, 3)), sigma2=1.0)
    with pytest.raises(ValueError, match=r"^x must be a 2-D array"):
        gmm_log_density(flat, np.zeros((2, 2)), sigma2=1.0)
    with pytest.raises(ValueError, match=r"^theta must be a 2-D array"):
        gmm_log_density(np.zeros((2, 2)), flat, sigma2=1.0)
    with pytest.raises(ValueError, match=r"^x and theta must have the same dimension"):
        gmm_density(np.zeros((1, 3)), np.zeros((2, 2)), sigma2=1.0)


@pytest.mark.parametrize("d", [2, 3])
def test_overlap_is_the_density_of_the_difference(rng, d):
    """∫ N(x; a, σ²I) N(x; b, σ²I) dx = N(a − b; 0, 2σ²I): scipy's multivariate normal, in 2-D and 3-D
    (where the normalising power d/2 is not 1)."""
    from scipy.stats import multivariate_normal

    a, b = rng.normal(size=(3, d)), rng.normal(size=(4, d))
    s2 = 0.3
    want = np.array([[multivariate_normal(np.zeros(d), 2 * s2 * np.eye(d)).pdf(p - q) for q in b] for p in a])
    np.testing.assert_allclose(gaussian_overlap(a, b, sigma2=s2), want, rtol=1e-12)
