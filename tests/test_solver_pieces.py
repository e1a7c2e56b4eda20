"""The path solver's pieces on their own: the damped subproblem, the Newton certificate, the
accept loop, the stop reasons, and the PathMetric protocol with a metric written by a user."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.solver.energy import path_energy
from shapelib.solver.linalg import block_tridiagonal_dense
from shapelib.solver.minimise import accept_step, damped_newton_step, minimise_path, newton_certificate


_dense = block_tridiagonal_dense


def _spd_blocks(rng, m=4, q=3, shift=0.0):
    a = rng.normal(size=(m * q, m * q))
    h = a @ a.T / (m * q) + shift * np.eye(m * q)
    # keep the block-tridiagonal part only, then make it positive definite by a diagonal shift
    diag = np.stack([h[t * q:(t + 1) * q, t * q:(t + 1) * q] for t in range(m)])
    upper = np.stack([h[t * q:(t + 1) * q, (t + 1) * q:(t + 2) * q] for t in range(m - 1)])
    ev = np.linalg.eigvalsh(_dense(diag, upper)).min()
    diag = diag + (shift - min(ev, 0.0) + 0.1) * np.eye(q)
    return diag, upper


class FlatMetric(sl.PathMetric):
    """A user's metric: ``Q = c |v|²`` (g = c I), with its exact Hessian."""

    name = "flat"
    has_exact_hessian = True

    def __init__(self, c):
        self.c = c

    def qform(self, theta, vel, ctx):
        return self.c * np.einsum("mkd,mkd->m", vel, vel)

    def qform_grad(self, theta, vel, ctx):
        return self.qform(theta, vel, ctx), np.zeros_like(theta), 2 * self.c * vel

    def tensors(self, theta, ctx):
        m, k, d = theta.shape
        return np.broadcast_to(self.c * np.eye(k * d), (m, k * d, k * d)).copy()

    def qform_hessian(self, theta, vel, ctx):
        m, k, d = theta.shape
        z = np.zeros((m, k * d, k * d))
        return z, z.copy(), np.broadcast_to(2 * self.c * np.eye(k * d), (m, k * d, k * d)).copy()

    def lower_bound(self, u, v):
        return float(np.sqrt(self.c) * np.linalg.norm(v - u))


def test_damped_step_solves_the_shifted_system(rng):
    diag, upper = _spd_blocks(rng)
    g = rng.normal(size=(4, 3))
    step, lam, tries = damped_newton_step((diag, upper), g, 0.5, 2.0)
    h = _dense(diag, upper) + lam * 2.0 * np.eye(12)
    np.testing.assert_allclose(h @ step.ravel(), -g.ravel(), atol=1e-10)
    assert tries == 0 and lam == 0.5


def test_damped_step_doubles_the_damping_until_positive_definite(rng):
    diag, upper = _spd_blocks(rng)
    ev_min = np.linalg.eigvalsh(_dense(diag, upper)).min()
    diag = diag - (ev_min + 1.0) * np.eye(3)  # smallest eigenvalue -1
    g = rng.normal(size=(4, 3))
    step, lam, tries = damped_newton_step((diag, upper), g, 1e-3, 1.0)
    assert tries > 0 and lam == pytest.approx(1e-3 * 2 ** tries) and lam > 1.0 and lam / 2 <= 1.0 + 1e-12
    np.testing.assert_allclose((_dense(diag, upper) + lam * np.eye(12)) @ step.ravel(), -g.ravel(), atol=1e-9)
    none, _, spent = damped_newton_step((diag, upper), g, 1e-3, 1.0, budget=3)
    assert none is None and spent == 3


def test_newton_certificate_is_half_g_h_inverse_g(rng):
    diag, upper = _spd_blocks(rng)
    g = rng.normal(size=(4, 3))
    h = _dense(diag, upper)
    step, dec = newton_certificate((diag, upper), g, energy=1e6, tol=1.0)
    np.testing.assert_allclose(step.ravel(), -np.linalg.solve(h, g.ravel()), atol=1e-10)
    assert dec == pytest.approx(0.5 * g.ravel() @ np.linalg.solve(h, g.ravel()), rel=1e-12)
    # an indefinite Hessian has no certificate
    indefinite = (diag - 100 * np.eye(3), upper)
    assert newton_certificate(indefinite, g, energy=1.0, tol=1.0) == (None, None)
    # a damped decrement already above tol·E skips the factorisation: it cannot pass
    damped = -np.linalg.solve(h + np.eye(12), g.ravel()).reshape(4, 3)
    assert newton_certificate((diag, upper), g, energy=1.0, tol=1e-9, damped_step=damped) == (None, None)


def test_accept_step_lowers_the_energy_or_keeps_the_path(rng):
    u, v = rng.normal(size=(5, 2)), rng.normal(size=(5, 2))
    model = FlatMetric(2.0)
    n = 4
    path = np.linspace(u, v, n + 1) + np.r_[0, 1, 1, 1, 0][:, None, None] * 0.3 * rng.normal(size=(1, 5, 2))
    energy, grad, hess = path_energy(model, path, hessian="exact")
    out = accept_step(model, path, energy, hess, grad.reshape(n - 1, -1), 1e-3, 1.0)
    assert out.accepted and out.energy < energy and out.decrease == pytest.approx(energy - out.energy)
    assert path_energy(model, out.path, gradient=False)[0] == pytest.approx(out.energy, rel=1e-14)
    # at the minimum no step can lower the energy
    best = np.linspace(u, v, n + 1)
    e0, g0, h0 = path_energy(model, best, hessian="exact")
    stuck = accept_step(model, best, e0, h0, g0.reshape(n - 1, -1), 1e-3, 1.0)
    assert not stuck.accepted and stuck.path is best


def test_a_users_path_metric_gives_the_straight_line_and_a_certificate(rng):
    """Flat metric g = c I: the geodesic is the straight line, energy = length² = c |v − u|²."""
    u, v = rng.normal(size=(6, 2)), rng.normal(size=(6, 2))
    model = FlatMetric(3.0)
    init = np.linspace(u, v, 9) + np.r_[0, [1] * 7, 0][:, None, None] * 0.2 * rng.normal(size=(9, 6, 2))
    r = minimise_path(model, u, v, n_steps=8, tol=1e-10, max_iter=50, window=3, init=init, warn=True,
                      length_scale=1.0)
    assert r.converged and r.stop_reason is sl.StopReason.NEWTON_DECREMENT and r.stop_reason.converged
    np.testing.assert_allclose(r.path, np.linspace(u, v, 9), atol=1e-7)
    assert r.energy == pytest.approx(3.0 * np.sum((v - u) ** 2), rel=1e-10)
    assert r.length == pytest.approx(r.lower_bound, rel=1e-8)


def test_every_result_reports_a_stop_reason(corpus):
    u, v = corpus
    r = sl.geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=4)
    assert isinstance(r.stop_reason, sl.StopReason) and r.stop_reason.converged == r.converged
    assert r.stop_reason.value in r.summary()
    stopped = sl.geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=4, max_iter=1, warn=False)
    assert stopped.stop_reason is sl.StopReason.MAX_ITER and not stopped.converged
    assert sl.geodesic(u, u, metric="alpha", sigma2=0.5).stop_reason is sl.StopReason.TRIVIAL
    b = sl.distance_bracket(u, v, metric="alpha", sigma2=0.5, rtol=1e-2)
    assert isinstance(b.stop_reason, sl.BracketStopReason) and b.stop_reason.converged == b.converged
    d = sl.landmark_diffeomorphism(u[::6], v[::6], n_steps=4)
    assert isinstance(d.stop_reason, sl.StopReason)


@pytest.fixture
def corpus():
    from shapelib.datasets import load_corpus_callosum

    shapes, ids = load_corpus_callosum()
    x = sl.to_centroid_size(shapes)
    return x[list(ids).index(1)], x[list(ids).index(2)]
