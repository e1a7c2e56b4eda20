"""The device solves of shapelib.solver.batched, run small on JAX's CPU backend (3 landmarks, 4 steps, a few
pairs; seconds of compilation, warm from JAX's persistent cache in the mutation runs): the lengths against the
CPU quadrature path by path and the Fisher–Rao length of one landmark (``‖Δ‖/σ``); the first L-BFGS
iterations against the textbook dense BFGS update (Nocedal & Wright, eq. 7.19) on the CPU energy and gradient;
the stop words against the energy traces; the geodesics against the CPU solver pair by pair, in any order and
batch size; a grid made too small by construction against the regrid rule. tests/test_jax_backend.py checks
the same paths on larger problems (slower)."""

import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import import_or_missing

import shapelib
from shapelib.solver.energy import path_energy
from shapelib.solver.path_metric import path_metric
from shapelib.solver.result import GeodesicWarning, StopReason

if "jax" not in sys.modules:  # compile time dominates these small problems: XLA's cheapest code generation
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_backend_optimization_level=0").strip()
jax = import_or_missing("jax", "JAX (the dev or jax extra) is not installed")

from shapelib.solver import batched  # noqa: E402

S2 = 0.5
#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions go through a
#: trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(batched))
N = 4  # segments of every path here (one compiled program per metric and batch size)
GRID = dict(grid_spacing=0.6, grid_margin=4.0)  # coarser than the default: small Fisher–Rao grids


def _shapes(seed=5):
    """A start shape and two aligned end shapes of 3 landmarks (σ about half their spacing)."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(3, 2)) * 1.6
    vs = [shapelib.procrustes_align(u, u + rng.normal(size=u.shape) * s, scaling=False) for s in (0.3, 0.7)]
    return u, vs


def _wiggly(rng, u, v):
    path = np.linspace(u, v, N + 1) + 0.3 * rng.normal(size=(N + 1,) + u.shape)
    path[0], path[-1] = u, v
    return path


@pytest.fixture(scope="module")
def paths():
    u, (v1, v2) = _shapes()
    rng = np.random.default_rng(1)
    return np.stack([_wiggly(rng, u, v1), _wiggly(rng, v1, v2), np.linspace(u, v2, N + 1)])


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_batched_lengths_are_the_cpu_quadrature_of_each_path_in_any_order(paths, metric):
    length, energy = batched.batched_lengths(paths, metric=metric, sigma2=S2, device="cpu", **GRID)
    model = path_metric(metric, S2, **GRID)
    for p, ell, e in zip(paths, length, energy):
        assert ell == pytest.approx(shapelib.path_length(p, metric=metric, sigma2=S2, **GRID), rel=1e-11)
        assert e == pytest.approx(path_energy(model, p, gradient=False)[0], rel=1e-11)
        assert ell <= np.sqrt(e) * (1 + 1e-12)  # Cauchy–Schwarz: L² ≤ E
    assert len(set(np.round(length, 6))) == 3
    rev = batched.batched_lengths(paths[::-1], metric=metric, sigma2=S2, device="cpu", **GRID)
    np.testing.assert_allclose(np.stack(rev)[:, ::-1], np.stack([length, energy]), rtol=1e-13)
    # nine paths: a device batch of ten lanes, the last a copy of the first, cut off
    nine = np.concatenate([paths, paths + 0.5, paths[:, ::-1]])
    length9, energy9 = batched.batched_lengths(nine, metric=metric, sigma2=S2, device="cpu", **GRID)
    assert length9.shape == energy9.shape == (9,)
    np.testing.assert_allclose(length9[:3], length, rtol=1e-13)
    np.testing.assert_allclose(length9[6:], length, rtol=1e-12)  # a path backwards has the same length
    for p, ell in zip(nine[3:6], length9[3:6]):
        assert ell == pytest.approx(shapelib.path_length(p, metric=metric, sigma2=S2, **GRID), rel=1e-11)


def test_the_fisher_rao_length_of_one_landmark_is_its_displacement_over_sigma():
    """K = 1: the Fisher information of a Gaussian's mean is I/σ², so a straight path has length ‖Δ‖/σ
    (here ``N‖step‖/σ``)."""
    steps = np.array([[1, 2], [-3, 1]])
    paths = np.arange(N + 1)[None, :, None, None] * steps[:, None, None, :]  # integers, read as floats
    length, energy = batched.batched_lengths(paths, metric="fisher_rao", sigma2=S2, device="cpu")
    exact = N * np.linalg.norm(steps, axis=1) / np.sqrt(S2)
    np.testing.assert_allclose(length, exact, rtol=1e-6)
    np.testing.assert_allclose(energy, exact ** 2, rtol=1e-6)  # constant speed: E = L²


# -------------------------------------------------------------------------------------------------
# L-BFGS on the device
# -------------------------------------------------------------------------------------------------


def _energy_and_grad(model, ends, shape):
    def fg(x):
        path = np.concatenate([ends[:1], x.reshape(shape), ends[1:]])
        e, g, _ = path_energy(model, path)
        return e, g.reshape(-1)
    return fg


def _dense_lbfgs(path, n_iter, history):
    """Preconditioned L-BFGS in its matrix form: H₀ = γ P (P the inverse time Laplacian ⊗ I, by np.linalg.inv),
    then H ← VᵀHV + ρssᵀ, V = I − ρysᵀ, over the last ``history`` pairs; the first step −P g scaled so that no
    coordinate moves by more than FIRST_STEP·σ; Armijo backtracking by halving from 1. The CPU energy."""
    model = path_metric("alpha", S2)
    m = len(path) - 2
    shape = path[1:-1].shape
    lap = 2 * np.eye(m) - np.eye(m, k=1) - np.eye(m, k=-1)
    P = np.kron(np.linalg.inv(lap), np.eye(int(np.prod(shape[1:]))))
    fg = _energy_and_grad(model, path[[0, -1]], shape)
    x = path[1:-1].reshape(-1).copy()
    f, g = fg(x)
    pairs = []
    for _ in range(n_iter):
        if pairs:
            s, y = pairs[-1]
            H = (s @ y) / (y @ P @ y) * P
            for s, y in pairs[-history:]:
                rho = 1.0 / (y @ s)
                V = np.eye(len(x)) - rho * np.outer(y, s)
                H = V.T @ H @ V + rho * np.outer(s, s)
            d = -H @ g
        else:
            d = -P @ g * (batched.FIRST_STEP * np.sqrt(S2) / np.abs(P @ g).max())
        assert g @ d < 0
        a = 1.0
        while True:
            fn, gn = fg(x + a * d)
            if fn <= f + 1e-4 * a * (g @ d) and fn < f:
                break
            a /= 2
        pairs.append((a * d, gn - g))
        x, f, g = x + a * d, fn, gn
    out = path.copy()
    out[1:-1] = x.reshape(shape)
    return out, f


@pytest.fixture(scope="module")
def starts():
    """Nine wiggly α paths (a batch padded to 10 lanes by bucket)."""
    rng = np.random.default_rng(2)
    u, vs = _shapes()
    return np.stack([_wiggly(rng, u, vs[i % 2]) for i in range(9)])


@pytest.mark.parametrize("n_iter", [1, 4])
def test_the_first_lbfgs_iterations_are_the_dense_bfgs_updates(starts, n_iter):
    """history=2 and 4 iterations: the oldest pair leaves the memory (the ring buffer wraps)."""
    r = batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, tol=1e-300, max_iter=n_iter, device="cpu",
                            history=2)
    assert list(r["n_iter"]) == [n_iter] * 9 and r["stopped_by"] == [StopReason.MAX_ITER] * 9
    for i in (0, 3, 8):
        ref, f = _dense_lbfgs(starts[i], n_iter, 2)
        np.testing.assert_allclose(r["path"][i], ref, rtol=0, atol=1e-9)
        assert r["energy"][i] == pytest.approx(f, rel=1e-10)
    if n_iter == 1:  # the first step moves no coordinate by more than FIRST_STEP·σ, and one by exactly that
        moved = np.abs(r["path"] - starts).max(axis=(1, 2, 3))
        np.testing.assert_allclose(moved, batched.FIRST_STEP * np.sqrt(S2), rtol=1e-12)


def test_a_full_memory_lbfgs_run_follows_the_dense_updates(starts):
    """The default memory (10 pairs) never fills in 5 iterations: every pair is used."""
    r = batched.lbfgs_solve(starts[:2], metric="alpha", sigma2=S2, tol=1e-300, max_iter=5, device="cpu")
    for i in range(2):
        ref, _ = _dense_lbfgs(starts[i], 5, 10)
        np.testing.assert_allclose(r["path"][i], ref, rtol=0, atol=1e-9)


def _check_trace(r, i, start, stop):
    model = path_metric("alpha", S2)
    it = r["n_iter"][i]
    trace = r["energies"][i]
    assert trace[0] == pytest.approx(path_energy(model, start, gradient=False)[0], rel=1e-12)
    assert np.all(np.isnan(trace[it + 1:])) and np.all(np.isfinite(trace[:it + 1]))
    assert np.all(np.diff(trace[:it + 1]) < 0)
    assert r["energy"][i] == trace[it] == pytest.approx(path_energy(model, r["path"][i], gradient=False)[0],
                                                         rel=1e-12)
    g = path_energy(model, r["path"][i])[1]
    assert r["grad_norm"][i] == pytest.approx(np.linalg.norm(g), rel=1e-8)
    if stop == StopReason.NO_DECREASE or not it:  # the last step was refused, or none was taken
        assert r["rel_change"][i] == 0.0
    else:
        assert r["rel_change"][i] == pytest.approx((trace[it - 1] - trace[it]) / trace[it - 1], rel=1e-12, abs=0)
    assert r["stopped_by"][i] == stop
    np.testing.assert_array_equal(r["path"][i][[0, -1]], start[[0, -1]])


def test_the_stop_words_are_those_of_the_energy_traces(starts):
    tol, window = 1e-4, 3
    r = batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, tol=tol, max_iter=200, window=window, device="cpu")
    for i in range(9):
        _check_trace(r, i, starts[i], StopReason.ENERGY_WINDOW)
        e, it = r["energies"][i], r["n_iter"][i]
        fired = [j >= window and e[j - window] - e[j] < tol * e[j] for j in range(1, it + 1)]
        assert fired[-1] and not any(fired[:-1])  # the first iteration where the window's decrease fell below tol
    # targets: each pair stops at the first iteration at or below its own (the same iterates up to there)
    target = np.array([r["energies"][i][min(2 + i % 3, r["n_iter"][i])] for i in range(9)])
    t = batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, tol=tol, max_iter=200, window=window,
                            target_energy=target, device="cpu")
    for i in range(9):
        _check_trace(t, i, starts[i], StopReason.TARGET_ENERGY)
        assert t["n_iter"][i] == min(2 + i % 3, r["n_iter"][i])
        np.testing.assert_allclose(t["energies"][i][:t["n_iter"][i] + 1], r["energies"][i][:t["n_iter"][i] + 1],
                                   rtol=1e-12)
    # a target met by the start itself (the device's own start energy): no step
    at0 = batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, tol=tol, max_iter=200, window=window,
                              target_energy=r["energies"][:, 0], device="cpu")
    assert list(at0["n_iter"]) == [0] * 9 and at0["stopped_by"] == [StopReason.TARGET_ENERGY] * 9
    # a tolerance no decrease can meet: every pair stops as soon as the window is full
    wide = batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, tol=1e3, max_iter=200, window=window,
                               device="cpu")
    assert list(wide["n_iter"]) == [window] * 9 and wide["stopped_by"] == [StopReason.ENERGY_WINDOW] * 9
    # no iteration: the start itself; without the window: until no step lowers the energy
    z = batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, max_iter=0, device="cpu")
    assert list(z["n_iter"]) == [0] * 9 and z["stopped_by"] == [StopReason.MAX_ITER] * 9
    np.testing.assert_array_equal(z["path"], starts)
    assert np.all(z["rel_change"] == 0)
    nd = batched.lbfgs_solve(starts[:2], metric="alpha", sigma2=S2, tol=0.0, max_iter=400, device="cpu")
    for i in range(2):
        _check_trace(nd, i, starts[i], StopReason.NO_DECREASE)
        assert nd["n_iter"][i] < 400 and nd["grad_norm"][i] < 1e-6 * np.linalg.norm(
            path_energy(path_metric("alpha", S2), starts[i])[1])


# -------------------------------------------------------------------------------------------------
# Batched geodesics
# -------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def alpha_pairs():
    u, (v1, v2) = _shapes()
    us, vs = np.stack([u, v1, u]), np.stack([v1, v2, v2])
    kw = dict(metric="alpha", sigma2=S2, n_steps=N, tol=1e-9, max_iter=300)
    cpu = [shapelib.geodesic(a, b, **kw) for a, b in zip(us, vs)]
    return us, vs, kw, cpu, batched.batched_geodesics(us, vs, device="cpu", **kw)


def test_batched_alpha_geodesics_are_the_cpu_geodesics_pair_by_pair(alpha_pairs):
    us, vs, kw, cpu, res = alpha_pairs
    model = path_metric("alpha", S2)
    for a, b, c, r in zip(us, vs, cpu, res):
        assert c.converged and r.converged
        assert r.stop_reason in (StopReason.ENERGY_WINDOW, StopReason.NO_DECREASE)
        np.testing.assert_array_equal(r.path[[0, -1]], np.stack([a, b]))
        assert r.energy == pytest.approx(c.energy, rel=1e-8) and r.length == pytest.approx(c.length, rel=1e-7)
        np.testing.assert_allclose(r.path, c.path, atol=1e-5)
        assert r.length == pytest.approx(shapelib.path_length(r.path, metric="alpha", sigma2=S2), rel=1e-11)
        assert r.energy == pytest.approx(path_energy(model, r.path, gradient=False)[0], rel=1e-11)
        assert r.lower_bound == pytest.approx(c.lower_bound, rel=1e-13) and r.lower_bound <= r.length
        assert r.grad_norm == pytest.approx(np.linalg.norm(path_energy(model, r.path)[1]), rel=1e-6)
        straight = path_energy(model, np.linspace(a, b, N + 1), gradient=False)[0]
        log = r.log
        assert log["energy"][0] == pytest.approx(straight, rel=1e-12)
        assert log["energy"][-1] == pytest.approx(r.energy, rel=1e-12)
        assert len(log["energy"]) == r.n_iter + 1 and r.n_iter > 0
        assert np.all(np.diff(log["energy"]) < 0)
        assert log["stopped_by"] == r.stop_reason.value and log["regrids"] == 0 and log["n_steps"] == N
        assert log["tol"] == kw["tol"] and log["seconds"] > 0
        assert (log["solver"], log["backend"], log["device"], log["hessian"]) == (
            "lbfgs", "jax", str(jax.devices("cpu")[0]), None)
        steps = np.linalg.norm(np.diff(r.path, axis=0), axis=2)
        assert r.max_step_over_sigma == pytest.approx(steps.max() / np.sqrt(S2), rel=1e-12)
        e = log["energy"]  # the last accepted step's decrease; none after a failed line search
        last = (e[-2] - e[-1]) / e[-2] if r.stop_reason == StopReason.ENERGY_WINDOW else 0.0
        assert r.rel_energy_change == pytest.approx(last, rel=1e-10, abs=0)


def test_a_pair_gets_the_same_geodesic_alone_in_any_order_and_batch_size(alpha_pairs):
    us, vs, kw, _, res = alpha_pairs
    rev = batched.batched_geodesics(us[::-1], vs[::-1], device="cpu", **kw)[::-1]
    ones = batched.batched_geodesics(us, vs, device="cpu", batch_size=1, **kw)
    for r, q, o in zip(res, rev, ones):
        for other in (q, o):
            assert other.n_iter == r.n_iter and other.stop_reason == r.stop_reason
            np.testing.assert_allclose(other.path, r.path, rtol=0, atol=1e-12)
            assert other.length == pytest.approx(r.length, rel=1e-12)


def test_identical_and_one_step_pairs_are_trivial_beside_solved_ones(alpha_pairs):
    us, vs, kw, _, res = alpha_pairs
    mixed = batched.batched_geodesics(np.stack([us[0], us[1], us[0]]), np.stack([vs[0], us[1], us[0]]),
                                      device="cpu", **kw)
    assert mixed[0].path == pytest.approx(res[0].path, abs=1e-12)
    for r in mixed[1:]:
        assert r.stop_reason == StopReason.TRIVIAL and r.converged and r.n_iter == 0
        assert (r.length, r.energy, r.lower_bound, r.grad_norm) == (0.0, 0.0, 0.0, 0.0)
        assert r.log["energy"] == [0.0]
    one = batched.batched_geodesics(us, vs, device="cpu", **{**kw, "n_steps": 1})
    for a, b, r in zip(us, vs, one):
        assert r.stop_reason == StopReason.TRIVIAL and r.path.shape == (2,) + a.shape
        assert r.log["energy"] == [r.energy]
        ell = shapelib.path_length(np.stack([a, b]), metric="alpha", sigma2=S2)
        assert r.length == pytest.approx(ell, rel=1e-11) and r.energy == pytest.approx(ell ** 2, rel=1e-11)


def test_init_targets_lower_bounds_and_the_warning(alpha_pairs):
    us, vs, kw, cpu, res = alpha_pairs
    # from the CPU geodesics (their ends moved off: the pairs' own ends are put back): stops within a few steps
    init = np.stack([c.path for c in cpu])
    init[:, 0] += 1.0
    warm = batched.batched_geodesics(us, vs, device="cpu", init=init, lower_bounds=[0.1, 0.2, 0.3], **kw)
    for a, b, c, r, lb in zip(us, vs, cpu, warm, (0.1, 0.2, 0.3)):
        np.testing.assert_array_equal(r.path[[0, -1]], np.stack([a, b]))
        assert r.energy == pytest.approx(c.energy, rel=1e-8) and r.lower_bound == lb
        assert r.log["energy"][0] == pytest.approx(c.energy, rel=1e-6)
    # a target above the start's energy: stopped at once; one below the minimum: the usual solve
    tgt = batched.batched_geodesics(us, vs, device="cpu", target_energy=[1e9, 0.0, 1e9], **kw)
    assert [r.stop_reason for r in tgt] == [StopReason.TARGET_ENERGY, res[1].stop_reason, StopReason.TARGET_ENERGY]
    assert [r.n_iter for r in tgt] == [0, res[1].n_iter, 0]
    assert tgt[0].length == pytest.approx(shapelib.path_length(np.linspace(us[0], vs[0], N + 1), metric="alpha",
                                                               sigma2=S2), rel=1e-11)
    # tol and window reach the device loop: a tolerance no decrease can meet stops each pair once its window is full
    wide = batched.batched_geodesics(us, vs, device="cpu", **{**kw, "tol": 1e3, "window": 2})
    assert [r.n_iter for r in wide] == [2, 2, 2] and all(r.stop_reason == StopReason.ENERGY_WINDOW for r in wide)
    # one iteration: the pair with a target met at the start converged, the two others did not
    with pytest.warns(GeodesicWarning) as w:
        t0 = time.perf_counter()
        short = batched.batched_geodesics(us, vs, device="cpu", target_energy=[1e9, 0.0, 0.0], **{**kw, "max_iter": 1})
        wall = time.perf_counter() - t0
    assert [r.stop_reason for r in short] == [StopReason.TARGET_ENERGY] + [StopReason.MAX_ITER] * 2
    assert len(w) == 1 and str(w[0].message) == ("alpha geodesic did not converge for 2 of 3 pairs in 1 L-BFGS "
                                                 f"iterations (first: {short[1].summary()})")
    # at the caller's line (under mutmut, at its trampoline's: one frame more between the caller and the code)
    assert Path(w[0].filename).name == ("trampoline.py" if UNDER_MUTMUT else Path(__file__).name)
    assert 0 < sum(r.log["seconds"] for r in short) <= wall  # the call's time shared among its pairs
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        batched.batched_geodesics(us, vs, device="cpu", warn=False, **{**kw, "max_iter": 1})
    with pytest.raises(ValueError, match=r"init must have shape \(3, 5, 3, 2\)"):
        batched.batched_geodesics(us, vs, device="cpu", init=init[:, :-1], **kw)
    bad = init.copy()
    bad[1, 2, 0, 0] = np.nan
    with pytest.raises(ValueError, match="init contains non-finite values"):
        batched.batched_geodesics(us, vs, device="cpu", init=bad, **kw)
    with pytest.raises(ValueError, match="metric must be one of"):
        batched.batched_geodesics(us, vs, device="cpu", **{**kw, "metric": "euclid"})


@pytest.fixture(scope="module")
def fr_pairs():
    u, (v1, _) = _shapes()
    us, vs = np.stack([u, v1]), np.stack([v1, u])
    kw = dict(metric="fisher_rao", sigma2=S2, n_steps=N, tol=1e-9, max_iter=300, **GRID)
    return us, vs, kw, [shapelib.geodesic(a, b, **kw) for a, b in zip(us, vs)]


def test_batched_fisher_rao_geodesics_are_the_cpu_geodesics(fr_pairs):
    """A pair and its reverse: the CPU solver's geodesics (the reverse one its path backwards)."""
    us, vs, kw, cpu = fr_pairs
    res = batched.batched_geodesics(us, vs, device="cpu", **kw)
    for c, r in zip(cpu, res):
        assert r.converged and r.log["regrids"] == 0 and (r.log["grid_spacing"], r.log["grid_margin"]) == (0.6, 4.0)
        assert r.length == pytest.approx(c.length, rel=1e-6) and r.energy == pytest.approx(c.energy, rel=1e-6)
        assert r.length == pytest.approx(shapelib.path_length(r.path, metric="fisher_rao", sigma2=S2, **GRID),
                                         rel=1e-11)
        assert r.lower_bound == pytest.approx(c.lower_bound, rel=1e-13)
    np.testing.assert_allclose(res[1].path, res[0].path[::-1], atol=1e-4)
    # one step: nothing to solve, the straight segment's length on the grid asked for
    one = batched.batched_geodesics(us[:1], vs[:1], device="cpu", **{**kw, "n_steps": 1})[0]
    assert one.stop_reason == StopReason.TRIVIAL
    assert one.length == pytest.approx(shapelib.path_length(np.stack([us[0], vs[0]]), metric="fisher_rao", sigma2=S2,
                                                            **GRID), rel=1e-11)


def test_a_path_that_leaves_its_grid_is_solved_again_on_a_new_grid(fr_pairs, monkeypatch):
    """A solve grid with 1σ less margin than the CPU grid never covers the returned path: every pair is solved
    MAX_REGRIDS more times, each round from where the last stopped, and its log joins the rounds' traces."""
    us, vs, kw, cpu = fr_pairs
    monkeypatch.setattr(batched, "GRID_PAD", -1.0)
    res = batched.batched_geodesics(us, vs, device="cpu", **kw)
    for c, r in zip(cpu, res):
        assert r.log["regrids"] == batched.MAX_REGRIDS
        assert len(r.log["energy"]) == r.n_iter + 1 and r.log["energy"][-1] == pytest.approx(r.energy, rel=1e-2)
        assert r.length == pytest.approx(shapelib.path_length(r.path, metric="fisher_rao", sigma2=S2, **GRID),
                                         rel=1e-11)
        assert r.length == pytest.approx(c.length, rel=1e-3)
    # two iterations a round (fewer than a solve takes): each round adds two to the count and to the log
    short = batched.batched_geodesics(us, vs, device="cpu", warn=False, **{**kw, "max_iter": 2})
    for r in short:
        assert r.log["regrids"] == batched.MAX_REGRIDS and r.stop_reason == StopReason.MAX_ITER
        assert r.n_iter == 2 * (batched.MAX_REGRIDS + 1) and len(r.log["energy"]) == r.n_iter + 1


# -------------------------------------------------------------------------------------------------
# Padding, dtypes, defaults and devices of the device solves
# -------------------------------------------------------------------------------------------------


def test_integer_paths_are_solved_as_their_float_copies(starts):
    whole = np.round(2 * starts).astype(int)  # landmarks on a half-unit lattice, as integers
    r_int = batched.lbfgs_solve(whole, metric="alpha", sigma2=S2, tol=1e-300, max_iter=2, device="cpu")
    r_float = batched.lbfgs_solve(whole.astype(float), metric="alpha", sigma2=S2, tol=1e-300, max_iter=2,
                                  device="cpu")
    assert r_int["path"].dtype == np.float64
    np.testing.assert_array_equal(r_int["path"], r_float["path"])
    np.testing.assert_array_equal(r_int["energy"], r_float["energy"])


def test_a_batch_three_lanes_short_of_its_bucket_gives_each_pair_what_it_gets_in_another_batch(starts, paths):
    """17 pairs run as 20 lanes (three idle copies of the first pair): pair by pair the results of the nine-pair
    batch (ten lanes, one idle)."""
    many = np.concatenate([starts, starts[:8]])
    assert batched.bucket(len(many)) - len(many) == 3
    kw = dict(metric="alpha", sigma2=S2, tol=1e-300, max_iter=2, device="cpu")
    r17, r9 = batched.lbfgs_solve(many, **kw), batched.lbfgs_solve(starts, **kw)
    for key in ("path", "energy", "n_iter", "grad_norm", "rel_change"):
        assert len(r17[key]) == 17
        np.testing.assert_allclose(r17[key], np.concatenate([r9[key], r9[key][:8]]), rtol=1e-13, atol=0)
    assert r17["stopped_by"] == r9["stopped_by"] + r9["stopped_by"][:8]
    seventeen = np.concatenate([paths] * 5 + [paths[:2]])
    length17, energy17 = batched.batched_lengths(seventeen, metric="alpha", sigma2=S2, device="cpu")
    length3, energy3 = batched.batched_lengths(paths, metric="alpha", sigma2=S2, device="cpu")
    np.testing.assert_allclose(length17, np.concatenate([length3] * 5 + [length3[:2]]), rtol=1e-13)
    np.testing.assert_allclose(energy17, np.concatenate([energy3] * 5 + [energy3[:2]]), rtol=1e-13)


def test_the_energy_trace_has_room_for_every_iteration_of_a_long_run(starts):
    """max_iter beyond the shortest trace (TRACE_MIN): the trace still holds max_iter + 1 energies."""
    max_iter = batched.TRACE_MIN
    r = batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, tol=1e3, max_iter=max_iter, window=1, device="cpu")
    assert r["energies"].shape[1] >= max_iter + 1
    assert list(r["n_iter"]) == [1] * 9 and np.all(np.isnan(r["energies"][:, 2:]))


def test_lbfgs_solves_defaults_are_shapelib_geodesics(starts, monkeypatch):
    """With no stop options, lbfgs_solve asks its device loop for shapelib.geodesic's tolerance, iterations and
    window (the loop itself replaced by a spy: no solve)."""
    import inspect

    cpu = {name: p.default for name, p in inspect.signature(shapelib.geodesic).parameters.items()}
    seen = []

    class Stop(Exception):
        pass

    def program(metric, trace, history):
        def loop(x0, ends, s2, nodes, weights, tol, target, step0, f, g, max_iter, window):
            seen.append(dict(trace=trace, tol=tol, max_iter=max_iter, window=window))
            raise Stop
        return loop

    monkeypatch.setattr(batched, "_compiled_solver", program)
    with pytest.raises(Stop):
        batched.lbfgs_solve(starts, metric="alpha", sigma2=S2, device="cpu")
    (call,) = seen
    assert (call["tol"], call["max_iter"], call["window"]) == (cpu["tol"], cpu["max_iter"], cpu["window"])
    assert call["trace"] >= cpu["max_iter"] + 1


def test_every_device_lookup_of_a_call_is_the_device_asked_for(alpha_pairs, fr_pairs, monkeypatch):
    """device="cpu" reaches every JAX computation of a call (the solves, the lengths, a one-step pair's length,
    the auto batch's memory, the log), as a device lookup of "cpu"."""
    us, vs, kw, _, _ = alpha_pairs
    asked = []
    lookup = batched.jax_device

    def recorded(device=None):
        asked.append(device)
        return lookup(device)

    monkeypatch.setattr(batched, "jax_device", recorded)
    batched.batched_geodesics(us, vs, device="cpu", **kw)
    fr_us, fr_vs, fr_kw, _ = fr_pairs
    batched.batched_geodesics(fr_us[:1], fr_vs[:1], device="cpu", **{**fr_kw, "n_steps": 1})
    batched.batched_lengths(np.linspace(us, vs, N + 1, axis=1), metric="alpha", sigma2=S2, device="cpu")
    assert len(asked) >= 7 and set(asked) == {"cpu"}
