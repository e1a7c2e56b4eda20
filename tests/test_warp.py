import numpy as np
import pytest

from shapelib import ScaleWarning, geodesic, procrustes_align
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


def _log_p(x, theta, sigma2):
    """log p(x | θ) of the equal-weight isotropic GMM (eq. 5) at the rows of x, by log-sum-exp."""
    from scipy.special import logsumexp

    sq = ((x[:, None, :] - theta[None]) ** 2).sum(-1)
    return logsumexp(-sq / (2 * sigma2), axis=1) - np.log(len(theta)) - np.log(2 * np.pi * sigma2)


def _energy(flow, theta, vel, sigma2, axes, lam, h=1e-5):
    """The discretised eq. (26), Σ_nodes λ[(∇²u)² + (∇²v)²] + (∇_θ log p · θ̇ + ∇_x log p · (u, v))², with the
    gradients of log p by central differences and the 5-point Laplacian with reflecting borders by edge
    padding (a mirror node beyond each border carries the border's value)."""
    xx, yy = np.meshgrid(axes[0], axes[1], indexing="ij")
    nodes = np.column_stack([xx.ravel(), yy.ravel()])
    gx = (_log_p(nodes + [h, 0], theta, sigma2) - _log_p(nodes - [h, 0], theta, sigma2)) / (2 * h)
    gy = (_log_p(nodes + [0, h], theta, sigma2) - _log_p(nodes - [0, h], theta, sigma2)) / (2 * h)
    gt = (_log_p(nodes, theta + h * vel, sigma2) - _log_p(nodes, theta - h * vel, sigma2)) / (2 * h)
    hx, hy = axes[0][1] - axes[0][0], axes[1][1] - axes[1][0]

    def lap(f):
        p = np.pad(f, 1, mode="edge")
        return (p[2:, 1:-1] - 2 * f + p[:-2, 1:-1]) / hx ** 2 + (p[1:-1, 2:] - 2 * f + p[1:-1, :-2]) / hy ** 2

    residual = gt + gx * flow[..., 0].ravel() + gy * flow[..., 1].ravel()
    return lam * (np.sum(lap(flow[..., 0]) ** 2) + np.sum(lap(flow[..., 1]) ** 2)) + np.sum(residual ** 2)


def test_flow_of_a_non_rigid_motion_minimises_the_discretised_energy():
    """E is quadratic in the flow, so at its minimiser the first-order change E(f + δ) − E(f − δ) = 2∇E·δ
    vanishes against the second-order one E(f + δ) + E(f − δ) − 2E(f) = 2δᵀHδ, for any δ; E here
    computed independently of the solver (module docstring: eq. 26 on the grid)."""
    rng = np.random.default_rng(3)
    theta, vel = rng.normal(size=(5, 2)), rng.normal(size=(5, 2))
    axes = [np.linspace(-3.0, 3.0, 17), np.linspace(-2.5, 2.0, 13)]
    f = likelihood_flow(theta, vel, sigma2=0.4, axes=axes, lam=1e-2)
    e0 = _energy(f, theta, vel, 0.4, axes, 1e-2)
    for _ in range(3):
        d = rng.normal(size=f.shape) * np.abs(f).mean()
        ep, em = _energy(f + d, theta, vel, 0.4, axes, 1e-2), _energy(f - d, theta, vel, 0.4, axes, 1e-2)
        assert abs(ep - em) < 1e-7 * (ep + em - 2 * e0)


def test_translation_flow_stays_constant_thirty_sigma_from_every_landmark(rng):
    """Nodes 30σ and more from every landmark: their Gaussian weights underflow unless each node's are
    scaled by its own largest; the translation's flow is the constant translation there too."""
    theta = rng.normal(size=(5, 2))
    axes = [np.linspace(-40.0, 40.0, 30)] * 2
    flow = likelihood_flow(theta, np.tile([0.7, -0.3], (5, 1)), sigma2=0.4, axes=axes, lam=1e-2)
    assert np.all(np.isfinite(flow)) and np.abs(flow - [0.7, -0.3]).max() < 1e-5


def test_warp_integrates_each_segments_flow_to_second_order():
    """Four segments of a non-rigid path: the points against a fine Runge–Kutta integration (100 RK4
    steps per segment) of the same segment flows, on the same grids (the points stay inside the landmarks'
    box, so each grid spans the two shapes of its segment and the margin). The midpoint rule's error is
    O(1/n²), here 1.4e-3 on displacements of 0.44; a first-order rule's, O(1/n), is tens of times larger."""
    from scipy.interpolate import RegularGridInterpolator

    u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    v = procrustes_align(u, [[0.0, 0.0], [1.4, 0.1], [1.2, 1.3], [-0.1, 0.9]], scaling=False)
    r = geodesic(u, v, metric="alpha", sigma2=0.3, n_steps=4, max_iter=0, warn=False)
    pts = np.array([[0.5, 0.5], [0.3, 0.7], [0.8, 0.2], [0.6, 0.9]])
    warped = extrinsic_warp(pts, r, grid_size=40, margin=1.0)
    path, n, x = r.path, 4, pts.copy()
    for t in range(n):
        lo = np.minimum(path[t].min(0), path[t + 1].min(0)) - 1.0
        hi = np.maximum(path[t].max(0), path[t + 1].max(0)) + 1.0
        axes = [np.linspace(lo[i], hi[i], 40) for i in range(2)]
        flow = likelihood_flow(0.5 * (path[t] + path[t + 1]), n * (path[t + 1] - path[t]), sigma2=0.3, axes=axes,
                               lam=1e-3)
        interp = [RegularGridInterpolator(axes, flow[..., i]) for i in range(2)]
        f = lambda y: np.column_stack([g(y) for g in interp])  # noqa: E731
        h = 1.0 / n / 100
        for _ in range(100):
            k1 = f(x)
            k2 = f(x + h / 2 * k1)
            k3 = f(x + h / 2 * k2)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + f(x + h * k3))
    assert np.abs(warped[-1] - x).max() < 0.01


@pytest.mark.filterwarnings("ignore::shapelib.PoseWarning")  # the translation is the motion here
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_points_on_the_grid_edge_moving_out_of_it_still_translate(rng, sign):
    """With no margin the grid ends at the outermost point, and a translation carries it out of the grid
    within the first half step: the midpoint is held on the grid, where the flow is the same constant,
    so every point still translates (forwards, and backwards past the other edge)."""
    u = rng.normal(size=(4, 2))
    c = sign * np.array([1.0, 0.5])
    r = geodesic(u, u + c, metric="alpha", sigma2=0.5, n_steps=4, max_iter=0, warn=False)
    lo, hi = np.minimum(u, u + c).min(0), np.maximum(u, u + c).max(0)
    pts = np.vstack([u[:2], lo - 0.3, hi + 0.3])
    warped = extrinsic_warp(pts, r, grid_size=24, margin=0.0)
    assert np.allclose(warped[-1], pts + c, atol=1e-4)


def test_default_margin_is_four_sigma_and_a_geodesic_without_sigma2_is_refused():
    from dataclasses import replace

    u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    v = procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    r = geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=2, max_iter=0, warn=False)
    pts = np.array([[0.5, 0.5], [0.5, -0.2]])
    assert np.array_equal(extrinsic_warp(pts, r, grid_size=24),
                          extrinsic_warp(pts, r, grid_size=24, margin=4 * np.sqrt(0.5)))
    with pytest.raises(ValueError, match=r"^extrinsic_warp needs a GMM geodesic \(alpha or fisher_rao\) with sigma2$"):
        extrinsic_warp(pts, replace(r, sigma2=None))
