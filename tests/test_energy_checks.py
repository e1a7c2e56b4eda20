"""The discrete path energy (shapelib.solver.energy) checked against independent values, on small
paths (3 or 4 landmarks, 3 or 4 segments: each check takes well under a second): the nodes against
NumPy's linear interpolation, a single landmark (a flat metric) against the closed forms of its
energy, gradient, Hessians and length, curved paths against a 20-point Gauss–Legendre quadrature of
the integral the 3-point rule evaluates, the gradient against central differences of the energy and
the exact Hessian against central differences of the gradient (every route: the compiled α pass, the
node-by-node α route, Fisher–Rao), the model Hessian against the second derivative of the energy with
the metric frozen at the segments' midpoints."""

import numpy as np
import pytest

import shapelib
from shapelib.solver.energy import exact_path_hessian, metric_length, path_energy, path_hessian_weights, segment_nodes
from shapelib.solver.linalg import block_tridiagonal_dense
from shapelib.solver.path_metric import GL3_NODES, path_metric

S2 = 0.5
ROUTES = [("alpha", None), ("alpha", "model"), ("alpha", "exact"), ("fisher_rao", None), ("fisher_rao", "model"),
          ("fisher_rao", "exact")]


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


def _curved_path(n, k=4, seed=0):
    """A wiggly path of ``n`` segments between two shapes of ``k`` landmarks (steps ≲ 0.3 σ)."""
    rng = np.random.default_rng(seed)
    u = np.array([[0.0, 0.0], [1.0, 0.2], [2.0, 0.0], [1.0, -0.8]])[:k]
    v = u @ _rot(0.3).T + [0.2, 0.1] + 0.1 * rng.normal(size=u.shape)
    path = np.linspace(u, v, n + 1) + 0.05 * rng.normal(size=(n + 1, *u.shape))
    path[0], path[-1] = u, v
    return path


def _model(metric):
    return path_metric(metric, S2)


def _fd_gradient(model, path, eps=1e-6):
    """Central differences of the energy in the interior points."""
    out = np.zeros(path[1:-1].shape)
    for idx in np.ndindex(*out.shape):
        plus, minus = path.copy(), path.copy()
        plus[(idx[0] + 1, *idx[1:])] += eps
        minus[(idx[0] + 1, *idx[1:])] -= eps
        e_plus, e_minus = path_energy(model, plus, gradient=False)[0], path_energy(model, minus, gradient=False)[0]
        out[idx] = (e_plus - e_minus) / (2 * eps)
    return out


def _fd_hessian(model, path, eps=1e-6):
    """Central differences of the gradient (no Hessian asked for): the dense Hessian of the interior."""
    q = path[1:-1].size
    h = np.zeros((q, q))
    for j in range(q):
        step = np.zeros(q)
        step[j] = eps
        plus, minus = path.copy(), path.copy()
        plus[1:-1] += step.reshape(path[1:-1].shape)
        minus[1:-1] -= step.reshape(path[1:-1].shape)
        h[:, j] = (path_energy(model, plus)[1] - path_energy(model, minus)[1]).ravel() / (2 * eps)
    return h


def _fine_quadrature(model, path, f, nodes=20):
    """``Σ_t (1/n) ∫₀¹ f(Q(θ_t + s Δ_t, n Δ_t)) ds`` with NumPy's ``nodes``-point Gauss–Legendre rule."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    s, w = (x + 1) / 2, w / 2
    n = len(path) - 1
    total = 0.0
    for t in range(n):
        delta = path[t + 1] - path[t]
        theta = path[t] + s[:, None, None] * delta
        vel = np.broadcast_to(n * delta, theta.shape)
        total += np.sum(w * f(model.qform(theta, vel, model.prepare(path)))) / n
    return total


def test_the_nodes_are_the_linear_interpolation_of_the_path_and_its_derivative():
    path = _curved_path(3)
    nodes = np.array([0.0, 0.2, 0.7, 1.0])
    theta, vel = segment_nodes(path, nodes)
    assert theta.shape == (3, 4, 4, 2) and vel.shape == (3, 4, 2)
    times = np.linspace(0.0, 1.0, 4)  # the path's points at t = 0, 1/3, 2/3, 1
    for t in range(3):
        at = (t + nodes) / 3
        for k in range(4):
            for d in range(2):
                assert np.allclose(theta[t, :, k, d], np.interp(at, times, path[:, k, d]), atol=1e-14)
                # the velocity is the slope of that interpolation in t ∈ [0, 1]
                slope = np.gradient(np.interp([at[1] - 1e-3, at[1] + 1e-3], times, path[:, k, d]), 2e-3)[0]
                assert np.isclose(vel[t, k, d], slope, rtol=1e-9)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_a_single_landmark_has_the_flat_closed_forms(metric):
    """K = 1: ``g = c I`` with ``c = 1/(8πσ⁴)`` (α) or ``1/σ²`` (Fisher–Rao), so
    ``E = n c Σ|Δ_t|²``, ``∂E/∂θ_t = 2 n c (2θ_t − θ_{t−1} − θ_{t+1})``, both Hessians the
    time Laplacian ``(4 n c I, −2 n c I)`` and the length ``√c Σ|Δ_t|``."""
    c = 1 / (8 * np.pi * S2**2) if metric == "alpha" else 1 / S2
    rtol = 1e-12 if metric == "alpha" else 1e-6  # Fisher–Rao: the grid's quadrature
    path = np.array([[[0.0, 0.0]], [[0.3, 0.1]], [[0.5, 0.5]], [[1.2, 0.4]]])
    n = 3
    steps = np.diff(path, axis=0)[:, 0]
    model = _model(metric)
    for hessian in (None, "model", "exact"):
        e, grad, blocks = path_energy(model, path, hessian=hessian)
        assert e == pytest.approx(n * c * np.sum(steps**2), rel=rtol)
        assert np.allclose(grad[:, 0], 2 * n * c * (2 * path[1:-1, 0] - path[:-2, 0] - path[2:, 0]), rtol=rtol, atol=0)
        if hessian is not None:
            diag, upper = blocks
            assert np.allclose(diag, 4 * n * c * np.eye(2), rtol=rtol, atol=rtol * c)
            assert np.allclose(upper, -2 * n * c * np.eye(2), rtol=rtol, atol=rtol * c)
    assert metric_length(model, path) == pytest.approx(np.sqrt(c) * np.sum(np.linalg.norm(steps, axis=1)), rel=rtol)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_energy_and_length_are_the_integrals_the_rules_evaluate(metric):
    """On short segments of a curved path the 3-point (energy) and 5-point (length) rules agree with
    a 20-point rule for the same integrals; and ``L² ≤ E`` (Cauchy–Schwarz)."""
    path = _curved_path(4)
    model = _model(metric)
    e = path_energy(model, path, gradient=False)[0]
    assert e == pytest.approx(_fine_quadrature(model, path, lambda q: q), rel=1e-6)
    assert path_energy(model, path)[0] == pytest.approx(e, rel=1e-13)  # the same number with the gradient
    length = metric_length(model, path)
    assert length == pytest.approx(_fine_quadrature(model, path, np.sqrt), rel=1e-7)
    assert length**2 <= e


def test_a_path_that_stands_still_has_zero_length():
    u = _curved_path(1)[0]
    path = np.stack([u, u, u])
    model = _model("alpha")
    assert metric_length(model, path) == 0.0
    assert path_energy(model, path, gradient=False)[0] == 0.0


@pytest.mark.parametrize("metric,hessian", ROUTES)
def test_the_gradient_is_the_derivative_of_the_energy(metric, hessian):
    path = _curved_path(4, k=3)
    model = _model(metric)
    e, grad, _ = path_energy(model, path, hessian=hessian)
    assert grad.shape == path[1:-1].shape
    fd = _fd_gradient(model, path)
    assert np.allclose(grad, fd, rtol=0, atol=1e-7 * np.abs(fd).max())


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_the_exact_hessian_is_the_derivative_of_the_gradient(metric):
    """Every route to the exact Hessian: ``path_energy`` (α: the compiled pass over the path;
    Fisher–Rao: node by node) and ``exact_path_hessian`` from the node Hessians."""
    path = _curved_path(4, k=3)
    n, (k, d) = len(path) - 1, path.shape[1:]
    model = _model(metric)
    fd = _fd_hessian(model, path)
    _, _, (diag, upper) = path_energy(model, path, hessian="exact")
    assert diag.shape == (n - 1, k * d, k * d) and upper.shape == (n - 2, k * d, k * d)
    tol = 1e-6 * np.abs(fd).max()
    assert np.allclose(block_tridiagonal_dense(diag, upper), fd, rtol=0, atol=tol)
    theta, vel = segment_nodes(path, GL3_NODES)
    flat_t, flat_v = theta.reshape(-1, k, d), np.repeat(vel, len(GL3_NODES), axis=0)
    ctx = model.prepare(path)
    diag2, upper2 = exact_path_hessian(model, flat_t, flat_v, ctx, n)
    assert np.allclose(block_tridiagonal_dense(diag2, upper2), fd, rtol=0, atol=tol)
    given = exact_path_hessian(model, flat_t, flat_v, ctx, n, model.qform_hessian(flat_t, flat_v, ctx))
    assert np.allclose(block_tridiagonal_dense(*given), fd, rtol=0, atol=tol)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_the_model_hessian_freezes_the_metric_at_the_midpoints(metric):
    """``hessian="model"``: the Hessian of ``Σ_t n Δ_tᵀ g(m_t) Δ_t`` with ``g`` held at the
    segments' midpoints ``m_t`` (the metric tensors of :mod:`shapelib.geometry.metrics`), i.e. the
    quadratic form ``xᵀ H x = 2 Σ_t n (x_{t+1} − x_t)ᵀ g(m_t) (x_{t+1} − x_t)`` (x₀ = x_n = 0)."""
    path = _curved_path(4, k=3)
    n = len(path) - 1
    _, _, (diag, upper) = path_energy(_model(metric), path, hessian="model")
    h = block_tridiagonal_dense(diag, upper)
    tensor = shapelib.alpha_metric if metric == "alpha" else shapelib.fisher_rao_metric
    g = [tensor(0.5 * (path[t] + path[t + 1]), sigma2=S2) for t in range(n)]
    rng = np.random.default_rng(5)
    for _ in range(3):
        x = np.zeros((n + 1, path[0].size))
        x[1:-1] = rng.normal(size=(n - 1, path[0].size))
        frozen = 2 * sum(n * (x[t + 1] - x[t]) @ g[t] @ (x[t + 1] - x[t]) for t in range(n))
        # (Fisher–Rao: the tensors on their own grids, not the path's; they agree to ~1e-8)
        assert x[1:-1].ravel() @ h @ x[1:-1].ravel() == pytest.approx(frozen, rel=1e-7)
    assert np.allclose(h, h.T)


def test_without_the_gradient_only_the_energy_comes_back():
    path = _curved_path(3)
    for metric, hessian in ROUTES:
        model = _model(metric)
        e, grad, blocks = path_energy(model, path, gradient=False, hessian=hessian)
        assert grad is None and blocks is None
        assert e == pytest.approx(path_energy(model, path, hessian=hessian)[0], rel=1e-13)
    e, grad, blocks = path_energy(_model("alpha"), path)
    assert grad is not None and blocks is None  # no Hessian unless asked for


def test_an_unknown_hessian_is_refused():
    with pytest.raises(ValueError, match="unknown hessian 'newton'"):
        path_energy(_model("alpha"), _curved_path(3), hessian="newton")


def test_the_hessian_weights_are_read_only_and_cached():
    w = path_hessian_weights(5)
    assert w.shape == (3, 3, 4) and not w.flags.writeable
    with pytest.raises(ValueError):
        w[0, 0, 0] = 1.0
    assert path_hessian_weights(5) is w
