import numpy as np
import pytest

from shapelib import ScaleWarning, geodesic
from shapelib.comparison.warp import extrinsic_warp, likelihood_flow


def test_translation_gives_a_constant_flow(rng):
    """A pure translation keeps every likelihood constant with a constant flow (zero Laplacian)."""
    theta = rng.normal(size=(5, 2))
    c = np.array([0.7, -0.3])
    axes = [np.linspace(-4, 4, 30), np.linspace(-4, 4, 30)]
    flow = likelihood_flow(theta, np.tile(c, (5, 1)), sigma2=0.5, axes=axes, lam=1e-2)
    assert np.allclose(flow[..., 0], c[0], atol=1e-6) and np.allclose(flow[..., 1], c[1], atol=1e-6)


def test_warp_translates_points_with_translated_landmarks(rng):
    u = rng.normal(size=(4, 2))
    # the straight-line path (max_iter=0): every landmark translates, so must every point
    r = geodesic(u, u + [1.0, 0.5], metric="alpha", sigma2=0.5, n_steps=4, max_iter=0, warn=False)
    pts = u + 0.1 * rng.normal(size=u.shape)
    warped = extrinsic_warp(pts, r, grid_size=40)
    assert warped.shape == (5, 4, 2)
    assert np.allclose(warped[-1], pts + [1.0, 0.5], atol=1e-4)


def test_points_near_landmarks_follow_them():
    u = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]])
    v = u + np.array([[0.5, 0.0], [0.0, 0.5], [-0.5, 0.0]])
    # three isolated landmarks (σ ≈ 0.1 spacing) on purpose: each point must follow its own
    # landmark; the scale check says the metric sees isolated points, which is the point here
    with pytest.warns(ScaleWarning, match="spacing"):
        r = geodesic(u, v, metric="alpha", sigma2=0.1, n_steps=8)
    warped = extrinsic_warp(u + 0.01, r, lam=1e-4, grid_size=64)
    assert np.abs(warped[-1] - (v + 0.01)).max() < 0.15
    assert np.abs(warped[-1] - (v + 0.01)).max() < np.abs(v - u).max() / 2


def test_errors(rng):
    u = rng.normal(size=(3, 2))
    r = geodesic(u, u + 1, sigma2=0.5, n_steps=2)
    with pytest.raises(ValueError, match=r"^lam\b"):
        extrinsic_warp(u, r, lam=0)
    with pytest.raises(ValueError, match="2-D"):
        extrinsic_warp(np.zeros((2, 3)), r)
    with pytest.raises(ValueError, match=r"^points\b"):
        extrinsic_warp(np.zeros(3), r)


def test_grid_laplacian_of_a_quadratic_and_the_axes():
    """Δ(x² + 3y²) = 2 + 6 = 8 at every interior node of a grid with unequal steps (the stencil is
    exact on quadratics); the axes run from the points' minimum − margin to maximum + margin."""
    from shapelib.comparison.warp import _axes, _laplacian

    x, y = np.linspace(-1.0, 2.0, 13), np.linspace(0.0, 1.0, 9)
    xx, yy = np.meshgrid(x, y, indexing="ij")
    lap = _laplacian(len(x), len(y), x[1] - x[0], y[1] - y[0]) @ (xx ** 2 + 3 * yy ** 2).ravel()
    np.testing.assert_allclose(lap.reshape(len(x), len(y))[1:-1, 1:-1], 8.0, rtol=1e-10)
    axes = _axes(np.array([[1.0, 5.0], [2.0, -1.0], [0.0, 3.0]]), 7, 0.5)
    np.testing.assert_allclose(axes[0], np.linspace(-0.5, 2.5, 7))
    np.testing.assert_allclose(axes[1], np.linspace(-1.5, 5.5, 7))


def test_flow_of_the_mirrored_problem_is_the_mirrored_flow(rng):
    """Swapping x and y in the landmarks, their velocities and the grid swaps the two components of the
    flow and transposes the grid: on a grid with different x and y axes, so no axis stands in for
    the other."""
    theta = rng.normal(size=(5, 2))
    vel = rng.normal(size=(5, 2))
    axes = [np.linspace(-3.0, 3.0, 17), np.linspace(-2.5, 2.0, 13)]
    f = likelihood_flow(theta, vel, sigma2=0.4, axes=axes, lam=1e-2)
    g = likelihood_flow(theta[:, ::-1], vel[:, ::-1], sigma2=0.4, axes=axes[::-1], lam=1e-2)
    assert f.shape == (17, 13, 2) and g.shape == (13, 17, 2)
    np.testing.assert_allclose(g, np.transpose(f, (1, 0, 2))[:, :, ::-1], rtol=1e-8, atol=1e-10 * np.abs(f).max())
