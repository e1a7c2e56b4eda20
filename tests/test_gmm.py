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
