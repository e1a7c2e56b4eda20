"""The path minimiser's pieces against closed forms: on a flat metric ``g = c I`` the discrete path
energy is exactly quadratic in the interior points, ``E = n c Σ_t |θ_{t+1} − θ_t|²``, so a damped
step, its predicted decrease, the Newton decrement and the minimum are all known in closed form
(dense NumPy solves of the same linear systems). A Hessian passed to the accept loop scaled by ``a``
gives the gain ratio ``ρ = 2 − 1/a`` exactly, which places a step on either side of each damping
threshold of the accept rule."""

import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import shapelib as sl
from shapelib.solver import minimise as minimise_module
from shapelib.solver.energy import path_energy
from shapelib.solver.linalg import block_tridiagonal_dense
from shapelib.solver.minimise import (
    MAX_FACTORISATIONS,
    _energy_window_met,
    accept_step,
    damped_newton_step,
    minimise_path,
    newton_certificate,
)

from test_solver_pieces import FlatMetric  # Q = c |v|², exact Hessian: the path energy is a quadratic

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions
#: go through a trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(minimise_module))



def _ends(rng, k=5):
    return rng.normal(size=(k, 2)), rng.normal(size=(k, 2))


def _bent(u, v, n, rng, amount=0.3):
    """The straight line from u to v in n steps with its interior points moved."""
    bump = np.r_[0.0, np.ones(n - 1), 0.0][:, None, None]
    return np.linspace(u, v, n + 1) + bump * amount * rng.normal(size=(n + 1,) + u.shape)


def _flat_energy(c, path):
    """E_n = Σ_t (1/n) c |n Δ_t|² = n c Σ_t |Δ_t|², independently of the solver."""
    n = len(path) - 1
    return n * c * float(np.sum(np.diff(path, axis=0) ** 2))


def _quadratic(model, path):
    """Energy, gradient (n − 1, q) and the exact Hessian's blocks and dense matrix at ``path``."""
    n = len(path) - 1
    e, g, hess = path_energy(model, path, hessian="exact")
    return e, g.reshape(n - 1, -1), hess, block_tridiagonal_dense(*hess)


# ----------------------------------------------------------------------------------------------
# damped_newton_step
# ----------------------------------------------------------------------------------------------

def test_damping_from_zero_starts_at_1e_minus_12_and_doubles():
    """lam = 0 on an indefinite H: the first failure sets lam to 1e-12, then each one doubles it."""
    diag = np.array([[[-1.0]], [[-1.0]]])
    upper = np.array([[[0.0]]])
    g = np.array([[1.0], [2.0]])
    step, lam, tries = damped_newton_step((diag, upper), g, 0.0, 1.0)
    # H + lam I is positive definite first for lam > 1: lam = 1e-12 · 2^(tries − 1), the first such
    want_tries = 1 + int(np.ceil(np.log2(1.0 / 1e-12)))
    assert 1e-12 * 2 ** (want_tries - 2) <= 1.0 < 1e-12 * 2 ** (want_tries - 1)
    assert tries == want_tries and lam == 1e-12 * 2 ** (tries - 1)
    np.testing.assert_allclose(step.ravel(), -g.ravel() / (lam - 1.0), rtol=1e-12)


def test_damped_step_spends_the_whole_budget_of_sixty_factorisations():
    """An H no damping in the budget can shift to positive definite: 60 failures, lam doubled 60 times."""
    diag, upper = np.array([[[-1e30]], [[-1e30]]]), np.array([[[0.0]]])
    step, lam, tries = damped_newton_step((diag, upper), np.ones((2, 1)), 1e-3, 1.0)
    assert MAX_FACTORISATIONS == 60
    assert step is None and tries == 60 and lam == 1e-3 * 2.0 ** 60
    step, lam, tries = damped_newton_step((diag, upper), np.ones((2, 1)), 1e-3, 1.0, budget=0)
    assert step is None and tries == 0 and lam == 1e-3


def test_the_damping_scales_with_scale():
    """(H + lam·s·I) x = −g: the shift is the product lam·s, checked with a dense solve."""
    diag = np.array([[[2.0, 0.3], [0.3, 1.0]], [[3.0, 0.0], [0.0, 2.0]]])
    upper = np.array([[[0.5, 0.1], [0.0, 0.2]]])
    g = np.array([[1.0, -1.0], [0.5, 2.0]])
    h = block_tridiagonal_dense(diag, upper)
    step, lam, tries = damped_newton_step((diag, upper), g, 0.25, 3.0)
    np.testing.assert_allclose(step.ravel(), -np.linalg.solve(h + 0.75 * np.eye(4), g.ravel()), rtol=1e-12)


# ----------------------------------------------------------------------------------------------
# newton_certificate
# ----------------------------------------------------------------------------------------------

def test_the_damped_shortcut_skips_only_beyond_its_relative_slack(rng):
    """The factorisation is skipped when the damped decrement δ_μ ≥ tol·E·(1 + 1e-6); δ_μ within the
    slack, or below tol·E, still gets the exact decrement ½ gᵀH⁻¹g (a dense solve)."""
    diag = np.array([[[2.0]], [[2.0]], [[2.0]]])
    upper = np.array([[[-1.0]], [[-1.0]]])
    h = block_tridiagonal_dense(diag, upper)
    g = np.array([[1.0], [-0.5], [0.25]])
    exact = 0.5 * g.ravel() @ np.linalg.solve(h, g.ravel())
    damped = -np.linalg.solve(h + 0.1 * np.eye(3), g.ravel()).reshape(3, 1)
    dec_damped = -0.5 * float(np.sum(g * damped))
    assert 0 < dec_damped < exact
    for target in (dec_damped / (1 + 0.5e-6), dec_damped, 1.5 * dec_damped, 3 * dec_damped):
        step, dec = newton_certificate((diag, upper), g, energy=1.0, tol=target, damped_step=damped)
        assert dec == pytest.approx(exact, rel=1e-12), target
        np.testing.assert_allclose(step.ravel(), -np.linalg.solve(h, g.ravel()), rtol=1e-12)
    for target in (dec_damped / (1 + 2e-6), 0.5 * dec_damped, 0.3 * dec_damped):
        assert newton_certificate((diag, upper), g, energy=1.0, tol=target, damped_step=damped) == (None, None)
    # tol · E, not tol alone nor E alone
    assert newton_certificate((diag, upper), g, energy=4.0, tol=0.5 * dec_damped, damped_step=damped)[1] is not None
    assert newton_certificate((diag, upper), g, energy=0.25, tol=2 * dec_damped, damped_step=damped)[1] is None


# ----------------------------------------------------------------------------------------------
# accept_step: the gain ratio on an exact quadratic
# ----------------------------------------------------------------------------------------------

@pytest.fixture
def quadratic(rng):
    u, v = _ends(rng)
    model = FlatMetric(0.05)
    path = _bent(u, v, 4, rng)
    return model, path, *_quadratic(model, path)


@pytest.mark.parametrize("a, factor", [(1.0, 1 / 3), (0.81, 1 / 3), (0.79, 1.0), (0.7, 1.0), (0.58, 1.0),
                                       (0.56, 4.0), (0.52, 4.0)])
def test_the_damping_follows_the_gain_ratio(quadratic, a, factor):
    """Hessian passed as a·H on the exact quadratic, damping ~0: the step is −(aH)⁻¹g, the actual
    decrease (1/a − 1/(2a²)) gᵀH⁻¹g, the predicted one gᵀH⁻¹g/(2a), so ρ = 2 − 1/a: λ/3 above 0.75
    (a > 0.8), kept in [0.25, 0.75], ×4 below 0.25 (a < 4/7)."""
    model, path, e, g, (hd, ho), h = quadratic
    lam = 1e-9
    out = accept_step(model, path, e, (a * hd, a * ho), g, lam, 1e-9)
    assert out.accepted
    q = g.ravel() @ np.linalg.solve(h, g.ravel())
    assert out.decrease == pytest.approx((1 / a - 1 / (2 * a * a)) * q, rel=1e-6)
    assert out.energy == pytest.approx(_flat_energy(model.c, out.path), rel=1e-12)
    assert out.lam == pytest.approx(lam * factor, rel=1e-12)
    step = -np.linalg.solve(a * h, g.ravel())
    np.testing.assert_allclose((out.path - path)[1:-1].ravel(), step, rtol=1e-6, atol=1e-12)
    np.testing.assert_array_equal(out.path[[0, -1]], path[[0, -1]])


def test_a_rejected_step_multiplies_the_damping_by_ten(quadratic):
    """a = 0.4 < 1/2: the step −(aH)⁻¹g overshoots so far that the energy rises; with one attempt
    the path is kept, nothing decreases, and λ comes back ×10 (at least 1e-12)."""
    model, path, e, g, (hd, ho), h = quadratic
    out = accept_step(model, path, e, (0.4 * hd, 0.4 * ho), g, 1e-3, 1e-9, budget=1)
    assert out.accepted is False and out.path is path and out.energy == e and out.decrease == 0.0
    assert out.lam == pytest.approx(1e-2, rel=1e-12)
    out = accept_step(model, path, e, (0.4 * hd, 0.4 * ho), g, 0.0, 1e-9, budget=1)
    assert not out.accepted and out.lam == 1e-12
    # with more attempts λ grows by 10 until (aH + λ s I)⁻¹ is short enough to lower the energy
    out = accept_step(model, path, e, (0.4 * hd, 0.4 * ho), g, 1e-3, 1.0)
    tries = 0
    lam = 1e-3
    while True:
        step = -np.linalg.solve(0.4 * h + lam * np.eye(len(h)), g.ravel())
        trial = path.copy()
        trial[1:-1] += step.reshape(trial[1:-1].shape)
        if _flat_energy(model.c, trial) < e:
            break
        lam *= 10
        tries += 1
    assert tries >= 1 and out.accepted
    np.testing.assert_allclose(out.path, trial, rtol=1e-10, atol=1e-12)


def test_an_indefinite_hessian_is_shifted_until_a_step_is_found(quadratic):
    """−H passed: every factorisation fails until λ·s exceeds H's largest eigenvalue (doubling from
    1e-12); the step then found is −(−H + λ s I)⁻¹ g, accepted when it lowers the energy."""
    model, path, e, g, (hd, ho), h = quadratic
    out = accept_step(model, path, e, (-hd, -ho), g, 0.0, 1.0)
    assert out.accepted and out.energy < e
    lam_max = np.linalg.eigvalsh(h).max()
    mu = 1e-12
    while mu <= lam_max:
        mu *= 2
    step = -np.linalg.solve(-h + mu * np.eye(len(h)), g.ravel())
    trial = path.copy()
    trial[1:-1] += step.reshape(trial[1:-1].shape)
    assert _flat_energy(model.c, trial) < e  # the first positive definite shift already lowers it
    np.testing.assert_allclose(out.path, trial, rtol=1e-10, atol=1e-12)
    one = accept_step(model, path, e, (-hd, -ho), g, 0.0, 1.0, budget=1)
    assert not one.accepted and one.lam == 1e-12


def test_a_pending_step_is_tried_first_and_a_non_positive_prediction_counts_as_a_poor_ratio(rng):
    """``pending``: the exact Newton step, tried before any solve; with the Hessian passed as 3H its
    predicted decrease q − 3q/2 is negative, so ρ counts as 0 and λ is multiplied by 4; with H
    itself (small energies: predicted q < 1) ρ = 1 and λ is divided by 3."""
    u, v = _ends(rng)
    model = FlatMetric(0.05)
    path = _bent(u, v, 4, rng, amount=0.05)
    e, g, (hd, ho), h = _quadratic(model, path)
    newton = -np.linalg.solve(h, g.ravel()).reshape(g.shape)
    q = g.ravel() @ np.linalg.solve(h, g.ravel())
    assert 0 < q / 2 < 1
    out = accept_step(model, path, e, (3 * hd, 3 * ho), g, 0.1, 1.0, pending=newton)
    assert out.accepted and out.lam == pytest.approx(0.4, rel=1e-12)
    assert out.decrease == pytest.approx(q / 2, rel=1e-9)
    exact = accept_step(model, path, e, (hd, ho), g, 0.1, 1.0, pending=newton)
    assert exact.lam == pytest.approx(0.1 / 3, rel=1e-12)
    straight = np.linspace(path[0], path[-1], len(path))
    np.testing.assert_allclose(exact.path, straight, atol=1e-12)


def test_the_damping_never_falls_below_1e_minus_14(quadratic):
    model, path, e, g, (hd, ho), h = quadratic
    out = accept_step(model, path, e, (hd, ho), g, 1e-14, 1e-9)
    assert out.accepted and out.lam == 1e-14
    out = accept_step(model, path, e, (hd, ho), g, 6e-14, 1e-9)
    assert out.lam == pytest.approx(2e-14, rel=1e-12)


def test_a_zero_step_is_no_decrease():
    """At the exact minimum with a zero gradient the step is zero and the energy cannot fall."""
    u = np.array([[0.0, 0.0], [1.0, 0.0]])
    v = np.array([[2.0, 0.0], [3.0, 2.0]])
    model = FlatMetric(1.0)
    path = np.linspace(u, v, 3)
    e, g, hess = path_energy(model, path, hessian="exact")
    assert not np.any(g)  # the midpoint of a line: the gradient vanishes exactly
    out = accept_step(model, path, e, hess, g.reshape(1, -1), 1e-3, 1.0, budget=3)
    assert not out.accepted and out.decrease == 0.0 and out.lam == pytest.approx(1.0, rel=1e-12)


# ----------------------------------------------------------------------------------------------
# the stop rules and minimise_path
# ----------------------------------------------------------------------------------------------

def test_energy_window_rule():
    """Relative decrease over the last ``window`` iterations below tol: (E[-1-w] − E[-1]) < tol·E[-1]."""
    assert not _energy_window_met([10.0, 9.0], 2, 0.5)  # fewer than window + 1 energies
    assert not _energy_window_met([10.0, 9.0, 8.0], 3, 1.0)
    assert _energy_window_met([10.0, 9.0, 8.0], 2, 0.3)  # (10 − 8)/8 = 0.25
    assert not _energy_window_met([10.0, 9.0, 8.0], 2, 0.25)  # equal is not below
    assert not _energy_window_met([10.0, 9.0, 8.0], 2, 0.2)
    # the window reaches back exactly w iterations: (100 − 8)/8 is large, (9 − 8)/8 small
    assert _energy_window_met([100.0, 9.0, 8.0], 1, 0.2)
    assert not _energy_window_met([100.0, 9.0, 8.0], 2, 0.2)
    assert not _energy_window_met([9.0, 8.5, 8.0], 1, 0.05)  # (8.5 − 8)/8 = 0.0625


def test_a_newton_decrement_stop_lands_on_the_minimum_of_the_quadratic(rng):
    """Flat metric, tol loose enough for the start: the decrement E₀ − E* (the quadratic's own gap)
    passes at once, the Newton step lands on the straight line, and E* = c|v − u|²."""
    u, v = _ends(rng)
    model = FlatMetric(2.0)
    init = _bent(u, v, 6, rng)
    e0 = _flat_energy(2.0, init)
    e_star = 2.0 * float(np.sum((v - u) ** 2))
    r = minimise_path(model, u, v, n_steps=6, tol=1.0, max_iter=20, window=3, init=init, warn=True,
                      length_scale=0.5)
    assert r.stop_reason is sl.StopReason.NEWTON_DECREMENT and r.converged and r.n_iter == 0
    assert r.log["newton_decrement"] == pytest.approx(e0 - e_star, rel=1e-9)
    assert r.log["energy"] == [pytest.approx(e0, rel=1e-12), pytest.approx(e_star, rel=1e-12)]
    assert r.log["damping"] == [] and r.log["hessian"] == "exact"
    np.testing.assert_allclose(r.path, np.linspace(u, v, 7), atol=1e-10)
    assert r.energy == pytest.approx(e_star, rel=1e-12) and r.grad_norm < 1e-9
    assert r.length == pytest.approx(np.sqrt(e_star), rel=1e-10)
    assert r.lower_bound == pytest.approx(np.sqrt(e_star), rel=1e-12)
    step = np.max(np.linalg.norm((v - u) / 6, axis=1))
    assert r.max_step_over_sigma == pytest.approx(step / 0.5, rel=1e-9)
    assert r.log["n_steps"] == 6 and r.log["tol"] == 1.0 and r.metric == "flat"
    t0 = time.perf_counter()
    again = minimise_path(model, u, v, n_steps=6, tol=1.0, max_iter=20, window=3, init=init, warn=True,
                          length_scale=0.5)
    assert 0.0 <= again.log["seconds"] <= time.perf_counter() - t0


def test_one_damped_step_is_the_levenberg_marquardt_step_of_the_mean_diagonal(rng):
    """max_iter = 1, tol too tight for any certificate: the result is the start plus the step
    −(H + 1e-3·s·I)⁻¹ g with s the mean diagonal entry of H (a dense solve); on a quadratic
    ρ = 1, so the damping recorded is 1e-3 / 3."""
    u, v = _ends(rng)
    model = FlatMetric(0.7)
    init = _bent(u, v, 4, rng)
    e0, g, _, h = _quadratic(model, init)
    s = np.trace(h) / len(h)
    step = -np.linalg.solve(h + 1e-3 * s * np.eye(len(h)), g.ravel())
    want = init.copy()
    want[1:-1] += step.reshape(want[1:-1].shape)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = minimise_path(model, u, v, n_steps=4, tol=1e-300, max_iter=1, window=2, init=init, warn=True,
                          length_scale=1.0, sigma2=0.3)
    np.testing.assert_allclose(r.path, want, rtol=1e-10, atol=1e-12)
    assert r.log["damping"] == [pytest.approx(1e-3 / 3, rel=1e-12)]
    # the damped decrement was far above tol·E: the exact factorisation was skipped, nothing recorded
    assert r.log["newton_decrement"] is None
    assert r.stop_reason is sl.StopReason.MAX_ITER and not r.converged and r.n_iter == 1
    e1 = _flat_energy(0.7, want)
    assert r.energy == pytest.approx(e1, rel=1e-10)
    assert r.rel_energy_change == pytest.approx((e0 - e1) / e0, rel=1e-9)  # relative to the energy before
    _, g1, _, _ = _quadratic(model, r.path)
    assert r.grad_norm == pytest.approx(np.linalg.norm(g1), rel=1e-9) and r.sigma2 == 0.3
    assert [w.category for w in caught] == [sl.GeodesicWarning]
    msg = str(caught[0].message)
    assert msg.startswith("flat geodesic did not converge in 1 iterations")
    assert f"{(e0 - e1) / e1:.2e} > tol 1.0e-300" in msg and f"gradient norm {np.linalg.norm(g1):.2e}" in msg
    assert "shapelib" not in Path(caught[0].filename).parts  # not inside the library
    # one frame above minimise_path: here, or under mutmut its trampoline (a frame of its own)
    if UNDER_MUTMUT:
        assert "mutmut" in Path(caught[0].filename).parts
    else:
        assert caught[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quiet = minimise_path(model, u, v, n_steps=4, tol=1e-300, max_iter=1, window=2, init=init, warn=False,
                              length_scale=1.0)
    assert not quiet.converged


def test_the_warning_measures_the_window_it_names(rng):
    """Three iterations and a window of w: the relative change reported is (E₃₋w − E₃)/E₃."""
    u, v = _ends(rng)
    model = FlatMetric(0.01)  # energies below 1
    init = _bent(u, v, 4, rng, amount=1.0)
    for window, back in ((2, 1), (1, 2)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            r = minimise_path(model, u, v, n_steps=4, tol=1e-300, max_iter=3, window=window, init=init, warn=True,
                              length_scale=1.0, hessian="model")
        e = r.log["energy"]
        assert len(e) == 4 and r.n_iter == 3 and r.log["hessian"] == "model" and 0 < e[3] < e[back] < 1
        assert f"over the last {window} iterations {(e[back] - e[3]) / e[3]:.2e}" in str(caught[0].message)


def test_a_start_at_or_below_the_target_energy_stops_at_once(rng):
    u, v = _ends(rng)
    model = FlatMetric(1.5)
    e_line = minimise_path(model, u, v, n_steps=5, tol=1e-8, max_iter=0, window=2, init=None, warn=False,
                           length_scale=1.0)
    np.testing.assert_allclose(e_line.path, np.linspace(u, v, 6), atol=1e-15)
    assert e_line.stop_reason is sl.StopReason.MAX_ITER and e_line.energy == pytest.approx(
        1.5 * np.sum((v - u) ** 2), rel=1e-12)
    r = minimise_path(model, u, v, n_steps=5, tol=1e-8, max_iter=10, window=2, init=None, warn=False,
                      length_scale=1.0, target_energy=e_line.energy)
    assert r.stop_reason is sl.StopReason.TARGET_ENERGY and r.converged and r.n_iter == 0
    assert r.grad_norm is None and r.log["energy"] == [e_line.energy]
    # identical ends: trivial, whatever the target
    same = minimise_path(model, u, u, n_steps=5, tol=1e-8, max_iter=10, window=2, init=None, warn=False,
                         length_scale=1.0, target_energy=1.0)
    assert same.stop_reason is sl.StopReason.TRIVIAL and same.grad_norm == 0.0 and same.energy < 1e-25
    assert same.rel_energy_change == 0.0


def test_a_target_reached_by_a_step_stops_without_a_new_gradient(rng):
    u, v = _ends(rng)
    model = FlatMetric(1.5)
    init = _bent(u, v, 4, rng)
    e_star = 1.5 * float(np.sum((v - u) ** 2))
    r = minimise_path(model, u, v, n_steps=4, tol=1e-300, max_iter=10, window=2, init=init, warn=False,
                      length_scale=1.0, target_energy=e_star * (1 + 1e-4))
    assert r.stop_reason is sl.StopReason.TARGET_ENERGY and r.converged and r.n_iter == 1
    assert r.grad_norm is None and len(r.log["energy"]) == 2 and len(r.log["damping"]) == 1
    assert r.energy <= e_star * (1 + 1e-4) and r.energy == pytest.approx(_flat_energy(1.5, r.path), rel=1e-12)
    # a target equal to the energy a step reaches stops there ("at or below")
    kw = dict(n_steps=4, tol=1e-300, window=2, init=init, warn=False, length_scale=1.0)
    one = minimise_path(model, u, v, max_iter=1, **kw)
    at = minimise_path(model, u, v, max_iter=10, target_energy=one.energy, **kw)
    assert at.stop_reason is sl.StopReason.TARGET_ENERGY and at.n_iter == 1 and at.energy == one.energy


def test_one_time_step_is_trivial_and_init_ends_are_replaced(rng):
    u, v = _ends(rng)
    model = FlatMetric(1.0)
    r = minimise_path(model, u, v, n_steps=1, tol=1e-8, max_iter=10, window=2, init=None, warn=True,
                      length_scale=1.0)
    assert r.stop_reason is sl.StopReason.TRIVIAL and r.converged and r.n_iter == 0 and r.grad_norm == 0.0
    np.testing.assert_array_equal(r.path, np.stack([u, v]))
    assert r.energy == pytest.approx(np.sum((v - u) ** 2), rel=1e-12)
    init = np.round(_bent(u, v, 3, rng)).astype(int)  # integers, ends off: the ends become u and v exactly
    init[0] += 5
    init[-1] -= 5
    r = minimise_path(model, u, v, n_steps=3, tol=1e-8, max_iter=0, window=2, init=init.tolist(), warn=False,
                      length_scale=1.0, lower_bound=7.0)
    assert r.path.dtype == np.float64
    np.testing.assert_array_equal(r.path[0], u)
    np.testing.assert_array_equal(r.path[-1], v)
    np.testing.assert_array_equal(r.path[1:-1], init[1:-1])
    assert r.lower_bound == 7.0 and r.n_iter == 0 and r.log["energy"] == [pytest.approx(_flat_energy(1.0, r.path))]


def test_no_decrease_is_reported_at_the_minimum_without_a_certificate():
    """``hessian="model"`` (no certificate) started at the exact minimum: no step can lower the
    energy, so the solver stops with NO_DECREASE after one iteration, converged."""
    u = np.array([[0.0, 0.0], [1.0, 0.0]])
    v = np.array([[2.0, 0.0], [3.0, 2.0]])
    r = minimise_path(FlatMetric(1.0), u, v, n_steps=2, tol=1e-12, max_iter=5, window=2, init=None, warn=True,
                      length_scale=1.0, hessian="model")
    assert r.stop_reason is sl.StopReason.NO_DECREASE and r.converged and r.n_iter == 1
    assert r.log["hessian"] == "model" and r.log["damping"] == [] and r.rel_energy_change == 0.0
    assert r.log["newton_decrement"] is None  # no certificate without the exact Hessian


@pytest.mark.parametrize("kwargs, match", [
    ({"n_steps": 0}, "^n_steps must"), ({"window": 0}, "^window must"), ({"max_iter": -1}, "^max_iter must"),
    ({"tol": 0.0}, "^tol must"), ({"hessian": "bfgs"}, "^hessian must be 'exact' or 'model'; got 'bfgs'"),
    ({"init": np.zeros((3, 2, 2))}, r"^init must have shape \(5, 2, 2\); got \(3, 2, 2\)"),
    ({"init": np.full((5, 2, 2), np.nan)}, "^init contains non-finite values$"),
])
def test_bad_settings_are_refused_naming_them(kwargs, match):
    u, v = np.zeros((2, 2)), np.ones((2, 2))
    settings = dict(n_steps=4, tol=1e-6, max_iter=5, window=2, init=None, warn=False, length_scale=1.0) | kwargs
    with pytest.raises(ValueError, match=match):
        minimise_path(FlatMetric(1.0), u, v, **settings)


def test_the_gain_ratio_thresholds_are_inclusive_and_a_zero_prediction_is_no_gain():
    """One landmark, one interior point at (1, 1) between (0, 0) and (2, 0), g = I: E = 8, gradient
    (0, 8), Hessian 8 I, all exact in binary. A pending step (0, −t) lowers E by 8t − 4t²; with the
    Hessian passed as zero the prediction is 8t, so t = 1/2 gives ρ = 3/4 and t = 3/2 gives ρ = 1/4
    exactly: both keep λ (the rule's middle band is closed). With the Hessian passed as 2H and t = 1
    the prediction is 8 − 8 = 0: no ratio, λ × 4."""
    model = FlatMetric(1.0)
    path = np.array([[[0.0, 0.0]], [[1.0, 1.0]], [[2.0, 0.0]]])
    e, g, (hd, ho) = path_energy(model, path, hessian="exact")
    g = g.reshape(1, -1)
    np.testing.assert_allclose(g, [[0.0, 8.0]], rtol=1e-15)
    np.testing.assert_allclose(hd, [8.0 * np.eye(2)], rtol=1e-15)
    for t, rho in ((0.5, 0.75), (1.5, 0.25)):
        pending = np.array([[0.0, -t]])
        out = accept_step(model, path, e, (0 * hd, 0 * ho), g, 0.3, 1.0, pending=pending)
        assert out.decrease / float(g[0, 1] * t) == rho  # the boundary, exactly (rounding is kind here)
        assert out.accepted and out.lam == 0.3
    out = accept_step(model, path, e, (2 * hd, 2 * ho), g, 0.3, 1.0, pending=np.array([[0.0, -1.0]]))
    assert out.accepted and out.decrease == pytest.approx(4.0, rel=1e-12) and out.lam == pytest.approx(1.2, rel=1e-12)


def test_the_certificate_skips_at_exactly_its_threshold():
    """δ_μ ≥ tol·E·(1 + 1e-6), equality included: a tol for which the product rounds to δ_μ exactly."""
    diag = np.array([[[2.0]], [[2.0]]])
    upper = np.array([[[-1.0]]])
    g = np.array([[1.0], [0.0]])
    damped = np.array([[-0.5], [0.0]])
    dec = -0.5 * float(np.sum(g * damped))  # 0.25
    tol = dec / (1 + 1e-6)
    assert tol * 1.0 * (1 + 1e-6) == dec  # the quotient rounds back
    assert newton_certificate((diag, upper), g, energy=1.0, tol=tol, damped_step=damped) == (None, None)
    assert newton_certificate((diag, upper), g, energy=1.0, tol=tol * (1 + 1e-12), damped_step=damped)[1] \
        == pytest.approx(1 / 3, rel=1e-12)


def test_the_certificate_needs_the_decrement_strictly_below_tol_e():
    """A tol for which tol·E₀ is exactly the start's Newton decrement: not certified at the start
    (strictly below is the rule), certified after one step; slightly looser, certified at once."""
    rng = np.random.default_rng(0)
    u, v = _ends(rng)
    model = FlatMetric(2.0)
    init = _bent(u, v, 4, rng)
    kw = dict(n_steps=4, max_iter=20, window=3, init=init, warn=False, length_scale=1.0)
    first = minimise_path(model, u, v, tol=1.0, **kw)
    dec, e0 = first.log["newton_decrement"], first.log["energy"][0]
    assert dec == pytest.approx(e0 - 2.0 * np.sum((v - u) ** 2), rel=1e-9)
    tol = dec / e0
    assert tol * e0 == dec  # the quotient rounds back (checked for this seed)
    at = minimise_path(model, u, v, tol=tol, **kw)
    assert at.stop_reason is sl.StopReason.NEWTON_DECREMENT and at.n_iter == 1
    assert minimise_path(model, u, v, tol=tol * (1 + 1e-9), **kw).n_iter == 0


def test_a_zero_newton_step_at_the_minimum_adds_no_energy():
    """Started at the exact minimum (zero gradient): the decrement 0 certifies at once and the zero
    Newton step, which does not lower the energy, is not taken: one energy in the log."""
    u = np.array([[0.0, 0.0], [1.0, 0.0]])
    v = np.array([[2.0, 0.0], [3.0, 2.0]])
    r = minimise_path(FlatMetric(1.0), u, v, n_steps=2, tol=1e-12, max_iter=5, window=2, init=None, warn=True,
                      length_scale=1.0)
    assert r.stop_reason is sl.StopReason.NEWTON_DECREMENT and r.n_iter == 0
    assert r.log["newton_decrement"] == 0.0 and len(r.log["energy"]) == 1
    assert r.energy == pytest.approx(np.sum((v - u) ** 2), rel=1e-12) and r.grad_norm == 0.0


def test_a_stalled_energy_stops_by_the_window_converged(rng):
    """Without the certificate (``hessian="model"``) a loose tol ends the run by the energy window,
    counted as converged, near the straight line."""
    u, v = _ends(rng)
    init = _bent(u, v, 4, rng)
    r = minimise_path(FlatMetric(1.0), u, v, n_steps=4, tol=1e-3, max_iter=50, window=1, init=init, warn=True,
                      length_scale=1.0, hessian="model")
    assert r.stop_reason is sl.StopReason.ENERGY_WINDOW and r.converged
    e = r.log["energy"]
    assert (e[-2] - e[-1]) < 1e-3 * e[-1] and all((a - b) >= 1e-3 * b for a, b in zip(e[:-2], e[1:-1]))
    assert r.energy == pytest.approx(np.sum((v - u) ** 2), rel=1e-3)
