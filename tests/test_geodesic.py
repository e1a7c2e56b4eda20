import warnings

import numpy as np
import pytest

from shapelib.solver.energy import path_energy as _energy
from shapelib.solver.geodesic import GeodesicWarning, fisher_rao_lower_bound, geodesic, path_length
from shapelib.solver.linalg import block_cholesky as _block_cholesky
from shapelib.solver.linalg import block_solve as _block_solve
from shapelib.solver.linalg import block_tridiagonal_dense
from shapelib.solver.linalg import hess_vec as _hess_vec
from shapelib.solver.path_metric import path_metric

METRICS = ["alpha", "fisher_rao"]


def rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


@pytest.fixture
def pair(rng):
    u = np.array([[0.0, 0.0], [1.0, 0.2], [2.0, 0.0], [1.0, -0.8]])
    v = u @ rot(0.6).T + [0.3, 0.1] + 0.2 * rng.normal(size=u.shape)
    return u, v


@pytest.mark.parametrize("s2", [0.3, 1.0])
def test_single_landmark_closed_forms(s2):
    """K = 1: g_FR = I/σ² and g_α = I/(8πσ⁴) are flat, geodesics are straight lines."""
    u, v = np.array([[0.0, 0.0]]), np.array([[1.5, -0.5]])
    dist = np.linalg.norm(v - u)
    fr = geodesic(u, v, metric="fisher_rao", sigma2=s2, n_steps=4)
    al = geodesic(u, v, metric="alpha", sigma2=s2, n_steps=4)
    assert fr.length == pytest.approx(dist / np.sqrt(s2), rel=1e-6)
    assert al.length == pytest.approx(dist / (s2 * np.sqrt(8 * np.pi)), rel=1e-10)
    assert np.allclose(fr.path[:, 0], np.linspace(u[0], v[0], 5), atol=1e-6)


@pytest.mark.parametrize("metric", METRICS)
def test_certificate_bounds(pair, metric):
    u, v = pair
    s2 = 0.5
    r = geodesic(u, v, metric=metric, sigma2=s2, n_steps=8)
    assert r.converged
    straight = path_length(np.linspace(u, v, 9), metric=metric, sigma2=s2)
    assert r.lower_bound <= r.length * (1 + 1e-9)
    assert r.length <= straight * (1 + 1e-9)
    assert r.length**2 <= r.energy * (1 + 1e-9)  # Cauchy–Schwarz
    assert np.allclose(r.path[0], u) and np.allclose(r.path[-1], v)
    if metric == "fisher_rao":  # g_FR ≼ I/(Kσ²)
        assert r.energy <= np.sum((v - u) ** 2) / (len(u) * s2)


@pytest.mark.parametrize("metric", METRICS)
def test_zero_symmetry_and_rigid_invariance(pair, metric):
    u, v = pair
    s2 = 0.5
    assert geodesic(u, u, metric=metric, sigma2=s2).length == 0.0
    d = geodesic(u, v, metric=metric, sigma2=s2, n_steps=8).length
    assert geodesic(v, u, metric=metric, sigma2=s2, n_steps=8).length == pytest.approx(d, rel=1e-4)
    r = rot(2.0)
    moved = geodesic(u @ r.T + [5, -3], v @ r.T + [5, -3], metric=metric, sigma2=s2, n_steps=8).length
    assert moved == pytest.approx(d, rel=1e-4)


def test_crossing_landmarks_cannot_undercut_the_bound():
    """Two landmarks swapping places: a midpoint rule would let them meet at no cost."""
    u = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    v = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])
    for metric in METRICS:
        r = geodesic(u, v, metric=metric, sigma2=0.1, n_steps=4, warn=False)
        assert r.length >= r.lower_bound and r.energy >= r.lower_bound**2


def test_length_decreases_with_n_steps_towards_the_bound(pair):
    u, v = pair
    lengths = [geodesic(u, v, metric="alpha", sigma2=0.3, n_steps=n, tol=1e-9).length for n in (2, 4, 8, 16)]
    lb = geodesic(u, v, metric="alpha", sigma2=0.3, n_steps=1).lower_bound
    assert all(a >= b - 1e-12 for a, b in zip(lengths, lengths[1:]))
    gaps = np.diff(lengths)
    assert abs(gaps[-1]) < abs(gaps[0])  # converging
    assert lengths[-1] >= lb


def test_fisher_rao_lower_bound_matches_bhattacharyya_quadrature(pair):
    from shapelib.geometry.gmm import gmm_density
    from shapelib.geometry.quadrature import make_grid

    u, v = pair
    grid = make_grid(np.stack([u, v]), sigma2=0.5, grid_spacing=0.1, grid_margin=10)
    bc = grid.integrate(np.sqrt(gmm_density(grid.nodes, u, sigma2=0.5) * gmm_density(grid.nodes, v, sigma2=0.5)))
    assert fisher_rao_lower_bound(u, v, sigma2=0.5) == pytest.approx(2 * np.arccos(bc), rel=1e-6)


def test_non_convergence_warns(pair):
    u, v = pair
    with pytest.warns(GeodesicWarning, match="did not converge"):
        r = geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=8, max_iter=1)
    assert not r.converged and r.n_iter == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", GeodesicWarning)  # (the pair is rotated on purpose: a PoseWarning)
        geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=8, max_iter=1, warn=False)


def test_result_helpers(pair):
    u, v = pair
    r = geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=4)
    assert np.allclose(r.shape_at(0.0), u) and np.allclose(r.shape_at(1.0), v)
    assert np.allclose(r.shape_at(0.5), r.path[2])
    assert r.velocities.shape == (4, 4, 2) and len(r.times) == 5
    assert r.max_step_over_sigma > 0 and r.log["energy"][0] >= r.energy
    with pytest.raises(ValueError, match="t must lie"):
        r.shape_at(1.5)


def test_errors(pair):
    u, v = pair
    with pytest.raises(ValueError, match="metric must be"):
        geodesic(u, v, metric="euclid", sigma2=1.0)
    with pytest.raises(ValueError, match="n_steps"):
        geodesic(u, v, sigma2=1.0, n_steps=0)
    for bad in (True, -1, 2.5, "3", None):
        with pytest.raises(ValueError, match=r"max_iter must be a non-negative integer; got"):
            geodesic(u, v, sigma2=1.0, max_iter=bad)
    with pytest.raises(ValueError, match="sigma2"):
        geodesic(u, v, sigma2=-1.0)
    with pytest.raises(ValueError, match="same number of landmarks"):
        geodesic(u, v[:3], sigma2=1.0)
    with pytest.raises(ValueError, match="init must have shape"):
        geodesic(u, v, sigma2=1.0, n_steps=4, init=np.zeros((3, 4, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        geodesic(u, np.full_like(v, np.nan), sigma2=1.0)


@pytest.mark.parametrize("metric", METRICS)
def test_shooting_the_geodesic_ode_lands_on_the_target(metric):
    """Independent check: integrate eq. (11) from the solved path's initial velocity (RK4) and
    land near the target; the miss shrinks ~4× when n_steps doubles (second-order velocity)."""
    from shapelib.solver.geodesic import shoot

    u = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    v = u @ rot(-np.pi / 2).T
    misses = []
    for n in (16, 32):
        p = geodesic(u, v, metric=metric, sigma2=0.5, n_steps=n, tol=1e-10, max_iter=500).path
        v0 = n * (-3 * p[0] + 4 * p[1] - p[2]) / 2
        misses.append(np.abs(shoot(u, v0, metric=metric, sigma2=0.5, n_steps=100)[-1] - v).max() / np.abs(v - u).max())
    assert misses[1] < 5e-3
    assert misses[1] < misses[0] / 2.5


_dense = block_tridiagonal_dense


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_exact_path_hessian_against_finite_differences(pair, rng, metric):
    """The path energy's exact Hessian (block tridiagonal in time) is the FD of its gradient."""
    u, v = pair
    n = 4
    path = np.linspace(u, v, n + 1) + 0.1 * rng.normal(size=(n + 1,) + u.shape)
    path[0], path[-1] = u, v
    model = path_metric(metric, 0.5, grid_spacing=0.35, grid_margin=6.0)
    _, grad, (diag, upper) = _energy(model, path, hessian="exact")
    h = _dense(diag, upper)
    eps = 1e-6
    fd = np.zeros_like(h)
    for j in range(h.shape[0]):
        e = np.zeros(h.shape[0])
        e[j] = eps
        plus, minus = path.copy(), path.copy()
        plus[1:-1] += e.reshape(path[1:-1].shape)
        minus[1:-1] -= e.reshape(path[1:-1].shape)
        fd[:, j] = (_energy(model, plus)[1] - _energy(model, minus)[1]).ravel() / (2 * eps)
    assert np.allclose(h, fd, atol=1e-7 * np.abs(h).max())
    assert np.allclose(_hess_vec(diag, upper, grad.reshape(n - 1, -1)).ravel(), h @ grad.ravel())


def test_block_cholesky_solves_and_rejects_indefinite(rng):
    m, q = 4, 3
    a = rng.normal(size=(m * q, m * q))
    band = np.abs(np.subtract.outer(np.arange(m * q) // q, np.arange(m * q) // q)) <= 1
    h = (a @ a.T) * band + 0.1 * np.eye(m * q)  # block tridiagonal, positive definite
    diag = np.stack([h[t * q:(t + 1) * q, t * q:(t + 1) * q] for t in range(m)])
    upper = np.stack([h[t * q:(t + 1) * q, (t + 1) * q:(t + 2) * q] for t in range(m - 1)])
    rhs = rng.normal(size=(m, q))
    x = _block_solve(_block_cholesky(diag, upper, 0.5), rhs)
    assert np.allclose((h + 0.5 * np.eye(m * q)) @ x.ravel(), rhs.ravel())
    lowest = np.linalg.eigvalsh(h)[0]
    with pytest.raises(np.linalg.LinAlgError):
        _block_cholesky(diag, upper, -lowest - 1e-3)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_solution_is_a_certified_local_minimum(pair, metric):
    """Stopped by the Newton decrement: exact Hessian positive definite, gradient ~ 0, and no
    random perturbation of the interior points lowers the energy."""
    u, v = pair
    r = geodesic(u, v, metric=metric, sigma2=0.5, n_steps=6, tol=1e-12, max_iter=500)
    assert r.converged and r.log["stopped_by"] == "newton_decrement" and r.log["hessian"] == "exact"
    assert r.log["newton_decrement"] < 1e-12 * r.energy
    model = path_metric(metric, 0.5, grid_spacing=0.35, grid_margin=6.0)
    energy, grad, blocks = _energy(model, r.path, hessian="exact")
    assert np.linalg.eigvalsh(_dense(*blocks))[0] > 0
    gen = np.random.default_rng(1)
    for _ in range(20):
        trial = r.path.copy()
        trial[1:-1] += 1e-3 * gen.normal(size=trial[1:-1].shape)
        assert _energy(model, trial, gradient=False)[0] > energy


def test_model_hessian_reaches_the_exact_hessian_minimum(pair):
    """``hessian="model"`` (metric frozen at segment midpoints) is a slower route to the same
    Fisher–Rao path: same energy to the tolerance, more iterations, no Newton certificate."""
    u, v = pair
    exact = geodesic(u, v, metric="fisher_rao", sigma2=0.5, n_steps=6, tol=1e-10, max_iter=500)
    model = geodesic(u, v, metric="fisher_rao", sigma2=0.5, n_steps=6, tol=1e-10, max_iter=2000, hessian="model",
                     warn=False)
    assert exact.log["hessian"] == "exact" and model.log["hessian"] == "model"
    assert model.log["stopped_by"] != "newton_decrement"
    assert model.n_iter > exact.n_iter
    assert model.energy >= exact.energy * (1 - 1e-10)
    assert model.energy == pytest.approx(exact.energy, rel=1e-6)
    with pytest.raises(ValueError, match="hessian must be"):
        geodesic(u, v, metric="fisher_rao", sigma2=0.5, hessian="bfgs")


@pytest.mark.parametrize("metric", METRICS)
def test_target_energy_stop(pair, metric):
    """minimise_path(target_energy=E): stops on the step that reaches E, reports that path's
    energy (no gradient is evaluated there: grad_norm None), and takes a given lower bound."""
    from shapelib.solver.geodesic import minimise_path

    u, v = pair
    model = path_metric(metric, 0.5, grid_spacing=0.35, grid_margin=6.0)
    opts = dict(n_steps=4, tol=1e-12, window=2, init=None, warn=False, length_scale=np.sqrt(0.5), sigma2=0.5)
    e0 = _energy(model, minimise_path(model, u, v, max_iter=0, **opts).path, gradient=False)[0]
    one = minimise_path(model, u, v, max_iter=1, **opts)
    assert one.energy < e0 and one.grad_norm > 0
    hit = minimise_path(model, u, v, max_iter=5, target_energy=one.energy * (1 + 1e-12), lower_bound=0.123, **opts)
    assert hit.n_iter == 1 and hit.converged and hit.log["stopped_by"] == "target_energy"
    assert hit.grad_norm is None and hit.lower_bound == 0.123
    np.testing.assert_array_equal(hit.path, one.path)
    assert hit.energy == pytest.approx(_energy(model, hit.path, gradient=False)[0], rel=1e-14)
    start = minimise_path(model, u, v, max_iter=5, target_energy=e0, **opts)  # the start already does
    assert start.n_iter == 0 and start.converged and start.grad_norm is None
    assert start.lower_bound == model.lower_bound(u, v)
