"""The log and exp maps (shapelib.solver.logexp) against independent values: closed forms of one-landmark
shapes (flat metrics: the geodesic is the straight line, the log the difference, the length |Δ|·√g), the
dense metric tensor of shapelib.alpha_metric and NumPy's eigendecomposition, finite differences of the
path energy (shapelib.solver.energy) for the segment derivatives, the first-order condition of the path
energy along the exponential's path, round trips, and the documented option checks."""

import time
import warnings

import numpy as np
import pytest

import shapelib as sl
from shapelib.solver import logexp
from shapelib.solver.energy import path_energy
from shapelib.solver.logexp import (GeodesicOptions, LogResult, TangentSpace, exp_map, exp_path, log_map, log_maps,
                                    magnify, path_as_result, segment_derivatives, tangent_space)
from shapelib.solver.path_metric import path_metric

U = np.array([[0.0, 0.0], [1.5, 0.2], [1.2, 1.6], [-0.3, 1.1]])
V0 = np.array([[0.3, -0.2], [-0.1, 0.4], [0.2, 0.1], [-0.3, -0.2]])
A, B = np.array([[0.0, 0.0]]), np.array([[1.0, 0.4]])  # one landmark: a flat metric
G_ALPHA = lambda s2: 1 / (8 * np.pi * s2**2)  # noqa: E731  g_α = I/(8πσ⁴) for K = 1, d = 2
G_FR = lambda s2: 1 / s2  # noqa: E731  g_FR = I/σ²


# --------------------------------------------------------------------------------------------- options


def test_options_refuse_each_bad_value_by_name():
    for kw, name in [(dict(metric="l2"), "metric"), (dict(sigma2=0.0), "sigma2"), (dict(n_steps=0), "n_steps"),
                     (dict(tol=0.0), "tol"), (dict(max_iter=-1), "max_iter"), (dict(window=0), "window"),
                     (dict(rcond=0.0), "rcond"), (dict(rcond=1.0), "rcond"), (dict(rcond=1.5), "rcond"),
                     (dict(grid_spacing=0.0), "grid_spacing"), (dict(grid_margin=0.0), "grid_margin"),
                     (dict(backend="tpu"), "backend"), (dict(device="tpu"), "device")]:
        args = {"metric": "alpha", "sigma2": 0.5, **kw}
        with pytest.raises(ValueError, match=f"^{name} must"):
            GeodesicOptions(**args)
    with pytest.raises(ValueError, match=r"rcond must lie in \(0, 1\); got 1.0"):
        GeodesicOptions("alpha", 0.5, rcond=1.0)
    with pytest.raises(ValueError, match=r"metric must be one of \('alpha', 'fisher_rao'\); got 'l2'"):
        GeodesicOptions("l2", 0.5)
    with pytest.raises(ValueError, match="backend must be one of"):
        GeodesicOptions("alpha", 0.5, backend="tpu")
    with pytest.raises(ValueError, match="device must be None, 'cpu' or 'gpu'; got 'tpu'"):
        GeodesicOptions("alpha", 0.5, device="tpu")


def test_options_keep_and_convert_good_values():
    opts = GeodesicOptions("fisher_rao", 1, n_steps=np.int64(3), tol=1e-4, max_iter=0, window=2, rcond=0.999,
                           grid_spacing=0.5, grid_margin=7.0, backend="jax", device="cpu")
    assert (opts.sigma2, opts.n_steps, opts.tol, opts.max_iter, opts.window, opts.rcond) == (1.0, 3, 1e-4, 0, 2, 0.999)
    assert type(opts.n_steps) is int and type(opts.sigma2) is float
    # every number is stored as the checked Python value, not as given
    odd = GeodesicOptions("alpha", np.float32(0.5), n_steps=np.int64(3), tol=np.float32(1e-4), max_iter=np.int64(7),
                          window=np.int64(2), rcond=np.float32(0.25))
    assert [type(getattr(odd, f)) for f in ("sigma2", "n_steps", "tol", "max_iter", "window", "rcond")] \
        == [float, int, float, int, int, float]
    model = opts.model()
    assert model.name == "fisher_rao" and model.s2 == 1.0 and (model.spacing, model.margin) == (0.5, 7.0)
    again = opts.replace(n_steps=8)
    assert again.n_steps == 8 and again.grid_margin == 7.0 and again.backend == "jax" and opts.n_steps == 3
    with pytest.raises(ValueError, match="rcond"):
        opts.replace(rcond=1.0)


# --------------------------------------------------------------------------------------------- tangent space


def test_tangent_space_is_the_eigendecomposition_of_the_alpha_metric():
    g = sl.alpha_metric(U, sigma2=0.5)
    ref = np.linalg.eigvalsh(g)[::-1]
    ts = tangent_space(U, sigma2=0.5)
    assert ts.shape == (4, 2) and np.array_equal(ts.base, U)
    assert np.allclose(ts.metric_tensor, g, rtol=1e-12, atol=0) and np.array_equal(ts.metric_tensor, ts.metric_tensor.T)
    assert np.allclose(ts.eigenvalues, ref, rtol=1e-9, atol=1e-12 * ref[0])
    u = ts.eigenvectors
    assert np.allclose(u.T @ u, np.eye(8), atol=1e-12)
    assert np.allclose(g @ u, u * ts.eigenvalues, atol=1e-12 * ref[0])
    for rcond in (1e-6, 0.05, 0.3, 0.9):
        t = tangent_space(U, sigma2=0.5, rcond=rcond)
        assert t.rank == np.count_nonzero(ref > rcond * ref[0]) and t.rcond == rcond
        assert t.basis.shape == (8, t.rank) and np.array_equal(t.basis, t.eigenvectors[:, :t.rank])
    assert tangent_space(U, sigma2=0.5, rcond=0.3).rank < 8


def test_tangent_space_options_record_wins():
    opts = GeodesicOptions("fisher_rao", 0.5, rcond=0.2, grid_margin=7.0)
    ts = tangent_space(U, metric="alpha", sigma2=3.0, rcond=1e-6, options=opts)
    assert ts.rcond == 0.2
    fr = sl.fisher_rao_metric(U, sigma2=0.5, grid_margin=7.0)
    assert np.allclose(ts.metric_tensor, 0.5 * (fr + fr.T), rtol=1e-10, atol=1e-14)
    # the Fisher–Rao metric of one landmark is I/σ²; its grid options are those given
    one = tangent_space(A, metric="fisher_rao", sigma2=0.5, grid_margin=9.0)
    assert np.allclose(one.metric_tensor, np.eye(2) / 0.5, rtol=1e-13, atol=1e-13)
    coarse = tangent_space(A, metric="fisher_rao", sigma2=0.5, grid_margin=3.0)
    assert abs(coarse.metric_tensor[0, 0] * 0.5 - 1) > 1e-4
    assert abs(tangent_space(A, metric="fisher_rao", sigma2=0.5, grid_spacing=2.0, grid_margin=9.0)
               .metric_tensor[0, 0] * 0.5 - 1) > 1e-4
    with pytest.raises(ValueError, match="^base contains non-finite"):
        tangent_space(np.full((3, 2), np.nan), sigma2=0.5)


def test_tangent_space_refuses_a_metric_that_overflows_or_underflows():
    """g_α = I/(8πK²σ⁴) on the diagonal: σ² = 1e-200 overflows it (eigh of inf failed with NumPy's
    "Eigenvalues did not converge"), σ² = 1e200 underflows it to zero (the error said σ² was too small)."""
    with np.errstate(divide="ignore", invalid="ignore"), \
            pytest.raises(ValueError, match=r"^the metric tensor at base is not finite \(sigma2 far too small"):
        tangent_space(U, sigma2=1e-200)
    with pytest.raises(ValueError, match=r"^the metric tensor at base is zero \(sigma2 far too large"):
        tangent_space(U, sigma2=1e200)
    assert tangent_space(U, sigma2=1e100).eigenvalues[0] > 0  # tiny (1e-202) but not zero: accepted


def test_tangent_space_products_are_those_of_the_metric_tensor():
    rng = np.random.default_rng(0)
    g = sl.alpha_metric(U, sigma2=0.5)
    ts = tangent_space(U, sigma2=0.5)
    vs = rng.normal(size=(3, 4, 2))
    explicit = np.array([[a.ravel() @ g @ b.ravel() for b in vs] for a in vs])
    assert np.allclose(ts.gram(vs), explicit, rtol=1e-12)
    assert np.allclose(ts.inner(vs, vs[0]), explicit[:, 0], rtol=1e-12)  # broadcast
    assert np.allclose(ts.norm(vs), np.sqrt(np.diag(explicit)), rtol=1e-12)
    assert ts.norm(1e-3 * vs[0]) == pytest.approx(1e-3 * np.sqrt(explicit[0, 0]), rel=1e-12)
    assert ts.norm(np.zeros((4, 2))) == 0.0
    z = ts.coords(vs)
    assert z.shape == (3, 8) and np.allclose(z @ z.T, explicit, rtol=1e-10)
    assert np.allclose(ts.vectors(z), vs, atol=1e-10)
    with pytest.raises(ValueError, match=r"tangent vectors must have shape \(\.\.\., 4, 2\); got \(3, 2\)"):
        ts.inner(np.zeros((3, 2)), np.zeros((3, 2)))


def test_projection_and_discarded_share_on_a_truncated_space():
    """With rcond = 0.3 some eigen-directions are dropped: a vector along a kept one and a dropped one
    loses exactly the dropped eigenvalue's share of its squared metric norm."""
    ts = tangent_space(U, sigma2=0.5, rcond=0.3)
    r = ts.rank
    lam, vec = ts.eigenvalues, ts.eigenvectors
    kept, dropped = vec[:, 0].reshape(4, 2), vec[:, r].reshape(4, 2)
    mix = 2 * kept + 3 * dropped
    assert np.allclose(ts.project(mix), 2 * kept, atol=1e-12)
    assert np.allclose(ts.project(ts.project(mix)), ts.project(mix), atol=1e-12)
    assert ts.project(np.stack([mix, dropped])).shape == (2, 4, 2)
    share = 9 * lam[r] / (4 * lam[0] + 9 * lam[r])
    assert ts.discarded_fraction(mix[None]) == pytest.approx(share, rel=1e-9)
    assert ts.discarded_fraction(np.stack([kept, dropped])) == pytest.approx(lam[r] / (lam[0] + lam[r]), rel=1e-9)
    assert ts.discarded_fraction(kept[None]) == pytest.approx(0.0, abs=1e-12)
    assert ts.discarded_fraction(np.zeros((2, 4, 2))) == 0.0
    assert ts.vectors(ts.coords(mix)) == pytest.approx(2 * kept, abs=1e-10)


def test_tangent_space_record_can_be_made_by_hand():
    ts = TangentSpace(base=A, metric_tensor=np.eye(2) * 4.0, eigenvalues=np.array([4.0, 4.0]),
                      eigenvectors=np.eye(2), rank=1, rcond=0.1)
    v = np.array([[1.0, 2.0]])
    assert ts.norm(v) == pytest.approx(2 * np.sqrt(5))
    assert np.allclose(ts.coords(v), [2.0]) and np.allclose(ts.project(v), [[1.0, 0.0]])
    assert ts.discarded_fraction(v[None]) == pytest.approx(4 / 5)


# --------------------------------------------------------------------------------------------- log map


@pytest.mark.parametrize("metric, g", [("alpha", G_ALPHA), ("fisher_rao", G_FR)])
def test_log_of_one_landmark_is_the_difference(metric, g):
    """Flat metric: the discrete geodesic is the straight line, log = v − u, energy = g |v − u|²."""
    res = log_map(A, B, metric=metric, sigma2=0.5, n_steps=3, grid_margin=9.0, return_result=True)
    assert isinstance(res, LogResult)
    assert np.allclose(res.vector, B - A, atol=1e-9)
    assert np.allclose(res.path[:, 0], np.linspace(A[0], B[0], 4), atol=1e-9)
    assert res.energy == pytest.approx(g(0.5) * np.sum((B - A) ** 2), rel=1e-10)
    assert res.converged and res.seconds > 0 and isinstance(res.n_iter, int)
    assert isinstance(log_map(A, B, metric=metric, sigma2=0.5), np.ndarray)


def test_log_map_solver_options_reach_the_solve():
    rng = np.random.default_rng(1)
    v = sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False)
    with pytest.warns(sl.GeodesicWarning, match=r"log map: the alpha path solver stopped after 0 iterations "
                                                r"without converging \(max_iter\)") as seen:
        t0 = time.perf_counter()
        stuck = log_map(U, v, sigma2=0.5, max_iter=0, return_result=True)
        elapsed = time.perf_counter() - t0
    assert len([w for w in seen if issubclass(w.category, sl.GeodesicWarning)]) == 1  # the log map's own only
    assert 0 < stuck.seconds <= elapsed
    assert stuck.n_iter == 0 and not stuck.converged and stuck.stop_reason == "max_iter"
    assert np.allclose(stuck.path, np.linspace(U, v, 5))  # the straight start, untouched
    best = log_map(U, v, sigma2=0.5, n_steps=5, tol=1e-12, return_result=True)
    assert best.path.shape == (6, 4, 2) and best.converged
    assert np.allclose(best.vector, 5 * (best.path[1] - best.path[0]))
    # the geodesic solver's energy for the same problem is the log map's
    geo = sl.geodesic(U, v, sigma2=0.5, n_steps=5, tol=1e-12)
    assert best.energy == pytest.approx(geo.energy, rel=1e-9)
    loose = log_map(U, v, sigma2=0.5, n_steps=5, tol=1e-2, return_result=True)
    assert loose.n_iter < best.n_iter
    summary = best.summary()
    assert summary.startswith(f"log map: energy {best.energy:.6g}, {best.n_iter} iterations, converged True (")


def test_log_map_warm_start_is_used_when_it_fits():
    rng = np.random.default_rng(2)
    v = sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False)
    cold = log_map(U, v, sigma2=0.5, tol=1e-12, return_result=True)
    warm = log_map(U, v, sigma2=0.5, tol=1e-12, init=cold.path, return_result=True)
    assert warm.n_iter < cold.n_iter and np.allclose(warm.vector, cold.vector, atol=1e-7)
    other = log_map(U, v, sigma2=0.5, tol=1e-12, init=np.linspace(U, v, 9), return_result=True)  # n = 8: ignored
    assert other.n_iter == cold.n_iter and np.array_equal(other.path, cold.path)
    lists = log_map(U, v, sigma2=0.5, tol=1e-12, init=cold.path.tolist(), return_result=True)
    assert lists.n_iter == warm.n_iter


def test_log_map_checks_its_input_by_name():
    with pytest.raises(ValueError, match="base and shape"):
        log_map(U, U[:3], sigma2=0.5)
    with pytest.raises(ValueError, match=r"metric must be one of \('alpha', 'fisher_rao'\); got 'l2'"):
        log_map(U, U, metric="l2", sigma2=0.5)
    with pytest.raises(ValueError, match="base.*d = 2 or 3"):
        log_map(np.zeros((3, 4)), np.zeros((3, 4)), sigma2=0.5)
    with pytest.warns(sl.ScaleWarning):
        log_map(10 * U, 10 * U, sigma2=0.01)


def test_log_maps_take_one_base_per_shape():
    rng = np.random.default_rng(3)
    shapes = np.stack([sl.procrustes_align(U, U + 0.2 * rng.normal(size=U.shape), scaling=False) for _ in range(2)])
    bases = np.stack([U, shapes[1]])
    opts = GeodesicOptions("alpha", 0.5, tol=1e-10)
    out = log_maps(bases, shapes, options=opts)
    assert len(out) == 2 and np.allclose(out[1].vector, 0.0)
    one = log_map(U, shapes[0], sigma2=0.5, tol=1e-10)
    assert np.allclose(out[0].vector, one, atol=1e-8)
    shared = log_maps(U, shapes, options=opts, inits=[None, None])
    assert np.allclose(shared[0].vector, one, atol=1e-8)
    assert log_maps(U, np.zeros((0, 4, 2)), options=opts) == []


# --------------------------------------------------------------------------------------------- segment derivatives


def _segment_energy(model, a, b, n):
    """S(a, b): the path energy of ``[a, b, b, …, b]`` (n segments, all but the first at rest)."""
    return path_energy(model, np.stack([a, b] + [b] * (n - 1)), gradient=False)[0]


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_segment_derivatives_are_finite_differences_of_the_path_energy(metric):
    model = path_metric(metric, 0.5)
    n, h = 3, 1e-5
    a, b = U, U + 0.1 * V0
    ctx = model.prepare(np.stack([a, b] + [b] * (n - 1)))
    da, db, mixed = segment_derivatives(model, a, b, n, ctx, hessian=True)
    fd_a, fd_b = np.zeros(8), np.zeros(8)
    for i in range(8):
        e = np.zeros(8)
        e[i] = h
        e = e.reshape(4, 2)
        fd_a[i] = (_segment_energy(model, a + e, b, n) - _segment_energy(model, a - e, b, n)) / (2 * h)
        fd_b[i] = (_segment_energy(model, a, b + e, n) - _segment_energy(model, a, b - e, n)) / (2 * h)
    scale = np.abs(fd_a).max()
    assert np.allclose(da.ravel(), fd_a, atol=1e-6 * scale) and np.allclose(db.ravel(), fd_b, atol=1e-6 * scale)
    # the mixed block: central differences in b of ∂S/∂a (rows a, columns b)
    fd_m = np.zeros((8, 8))
    for j in range(8):
        e = np.zeros(8)
        e[j] = h
        e = e.reshape(4, 2)
        plus = segment_derivatives(model, a, b + e, n, ctx, hessian=False)
        minus = segment_derivatives(model, a, b - e, n, ctx, hessian=False)
        assert plus[2] is None
        fd_m[:, j] = (plus[0] - minus[0]).ravel() / (2 * h)
    assert np.allclose(mixed, fd_m, atol=1e-5 * np.abs(fd_m).max())


def test_segment_derivatives_of_a_flat_metric_are_closed_form():
    """g = c I: S(a, b) = n c |b − a|², ∂S/∂a = −2nc (b − a), ∂²S/∂a∂b = −2nc I."""
    c, n = G_FR(0.5), 4
    model = path_metric("fisher_rao", 0.5, grid_margin=9.0)
    a, b = A, A + [[0.3, -0.1]]
    da, db, mixed = segment_derivatives(model, a, b, n, model.prepare(np.stack([a, b])), hessian=True)
    assert np.allclose(da, -2 * n * c * (b - a), rtol=1e-9) and np.allclose(db, 2 * n * c * (b - a), rtol=1e-9)
    assert np.allclose(mixed, -2 * n * c * np.eye(2), rtol=1e-8, atol=1e-8)


# --------------------------------------------------------------------------------------------- exp map


@pytest.mark.parametrize("metric, g", [("alpha", G_ALPHA), ("fisher_rao", G_FR)])
def test_exp_of_one_landmark_is_a_straight_step(metric, g):
    res = exp_map(A, B - A, metric=metric, sigma2=0.5, n_steps=3, grid_margin=9.0, return_result=True)
    assert isinstance(res, sl.GeodesicResult)
    assert np.allclose(res.path[:, 0], np.linspace(A[0], B[0], 4), atol=1e-9)
    dist = np.linalg.norm(B - A)
    assert res.length == pytest.approx(dist * np.sqrt(g(0.5)), rel=1e-10)
    assert res.energy == pytest.approx(dist**2 * g(0.5), rel=1e-10)
    assert res.max_step_over_sigma == pytest.approx(dist / 3 / np.sqrt(0.5), rel=1e-12)
    assert res.metric == metric and res.sigma2 == 0.5 and res.n_iter == 0 and res.converged
    assert res.grad_norm is None and res.rel_energy_change == 0.0
    assert res.stop_reason is sl.StopReason.TRIVIAL and res.log["exp"]["converged"]
    if metric == "fisher_rao":
        assert res.lower_bound == pytest.approx(2 * np.arccos(np.exp(-dist**2 / (8 * 0.5))), rel=1e-10)
    else:
        gauss = lambda d2: np.exp(-d2 / 2.0) / (2 * np.pi)  # noqa: E731  overlap N(·; 0, 2σ²I) at σ² = 0.5
        assert res.lower_bound == pytest.approx(np.sqrt(2 * (gauss(0.0) - gauss(dist**2))), rel=1e-10)
    assert np.allclose(exp_map(A, B - A, metric=metric, sigma2=0.5), B, atol=1e-9)


def test_exp_path_satisfies_the_first_order_condition_of_the_path_energy():
    """The exponential's path is a discrete geodesic: the path energy (shapelib.solver.energy) is
    stationary in its interior points, while a perturbed path is not."""
    for metric in ("alpha", "fisher_rao"):
        opts = GeodesicOptions(metric, 0.5, n_steps=5)
        path, info = exp_path(U, V0, options=opts)
        assert path.shape == (6, 4, 2) and np.array_equal(path[0], U)
        assert np.allclose(path[1], U + V0 / 5)
        assert info["converged"] and len(info["newton_iters"]) == 4 and len(info["residuals"]) == 4
        assert max(info["residuals"]) <= 1e-5
        model = opts.model()
        grad = path_energy(model, path)[1]
        bent = path.copy()
        bent[2:-1] += 1e-3 * np.random.default_rng(4).normal(size=bent[2:-1].shape)
        ref = np.abs(path_energy(model, bent)[1]).max()
        assert np.abs(grad).max() < 1e-4 * ref
        assert np.abs(path[-1] - U - V0).max() > 0.02  # curved: not the straight line


def test_exp_path_options():
    opts = GeodesicOptions("alpha", 0.5, n_steps=4)
    six, _ = exp_path(U, V0, options=opts, n_steps=6)
    assert six.shape == (7, 4, 2)
    assert np.allclose(six[-1], exp_map(U, V0, sigma2=0.5, n_steps=6), atol=1e-12)
    still, info = exp_path(U, np.zeros_like(U), options=opts)
    assert np.array_equal(still, np.stack([U] * 5)) and info == {"converged": True, "newton_iters": [],
                                                                   "residuals": []}
    # one Newton step to a tolerance of 1e-14 does not converge, and says so
    short, info = exp_path(U, V0, options=opts, newton_tol=1e-14, max_newton=1)
    assert not info["converged"] and info["newton_iters"] == [1, 1, 1] and min(info["residuals"]) > 1e-14
    loose, info = exp_path(U, V0, options=opts, newton_tol=0.5)
    assert info["converged"] and max(info["newton_iters"]) <= 1
    tight, info = exp_path(U, V0, options=opts, newton_tol=1e-12)
    assert info["converged"] and max(info["residuals"]) <= 1e-12


def test_exp_map_passes_its_grid_and_checks_the_scale():
    own = exp_map(U, V0, metric="fisher_rao", sigma2=0.5)
    wide = exp_map(U, V0, metric="fisher_rao", sigma2=0.5, grid_spacing=2.5)
    narrow = exp_map(U, V0, metric="fisher_rao", sigma2=0.5, grid_margin=2.0)
    assert np.abs(wide - own).max() > 1e-5 and np.abs(narrow - own).max() > 1e-5
    with pytest.warns(sl.ScaleWarning):
        exp_map(10 * U, V0, sigma2=0.01)


def test_exp_path_converged_only_if_every_point_did():
    """A long step whose first point needs more Newton iterations than the later ones: with a budget
    of two, the first point stops short and the path is not converged although the last point is."""
    opts = GeodesicOptions("alpha", 0.5, n_steps=4)
    far = 10 * np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    _, info = exp_path(U, far, options=opts, max_newton=2)
    iters = info["newton_iters"]
    assert iters[0] == 2 and iters[-1] < 2  # the first point stopped at the budget, the last converged
    assert info["converged"] is False
    _, info = exp_path(U, far, options=opts, max_newton=6)
    assert info["converged"] and all(i < 6 for i in info["newton_iters"])


def test_exp_path_without_newton_iterations():
    """max_newton = 0: every point is the constant-velocity guess, none converged, residual inf."""
    opts = GeodesicOptions("alpha", 0.5, n_steps=4)
    path, info = exp_path(U, V0, options=opts, max_newton=0)
    assert not info["converged"] and info["newton_iters"] == [0, 0, 0] and info["residuals"] == [np.inf] * 3
    assert np.allclose(path, U + np.linspace(0, 1, 5)[:, None, None] * V0)


def test_exp_map_warns_when_a_newton_solve_stops(monkeypatch):
    real = logexp.exp_path
    monkeypatch.setattr(logexp, "exp_path", lambda *a, **k: real(*a, **k, newton_tol=1e-14, max_newton=1))
    with pytest.warns(sl.GeodesicWarning, match=r"exp map: a Newton solve of the discrete Euler–Lagrange "
                                                r"recursion stopped at relative step \d\.\de-\d\d"):
        exp_map(U, V0, sigma2=0.5)


def test_exp_and_log_are_inverse_on_a_curved_metric():
    """exp(log(v)) = v and log(exp(w)) = w at the same n (4 well separated landmarks: well conditioned)."""
    for metric in ("alpha", "fisher_rao"):
        w = exp_map(U, V0, metric=metric, sigma2=0.5, n_steps=4)
        back = log_map(U, w, metric=metric, sigma2=0.5, n_steps=4, tol=1e-12)
        assert np.abs(back - V0).max() < 1e-5 * np.abs(V0).max()


def test_exp_map_truncation():
    """rcond close to 1 keeps only the strongest direction of each Newton system: the other
    directions keep the constant velocity of the first step, so the path moves off the geodesic."""
    full = exp_map(U, V0, sigma2=0.5, n_steps=4)
    cut = exp_map(U, V0, sigma2=0.5, n_steps=4, rcond=0.999)
    assert np.abs(cut - full).max() > 1e-3
    with pytest.raises(ValueError, match="rcond"):
        exp_map(U, V0, sigma2=0.5, rcond=1.0)
    with pytest.raises(ValueError, match="base and vector"):
        exp_map(U, V0[:3], sigma2=0.5)


def test_path_as_result_measures_a_straight_path():
    path = np.linspace(A, B, 5)
    r = path_as_result(path.tolist(), options=GeodesicOptions("alpha", 0.5), log={"note": 1})
    dist = np.linalg.norm(B - A)
    assert r.length == pytest.approx(dist * np.sqrt(G_ALPHA(0.5)), rel=1e-10)
    assert r.max_step_over_sigma == pytest.approx(dist / 4 / np.sqrt(0.5), rel=1e-12)
    assert r.log == {"stopped_by": "trivial", "note": 1}
    assert path_as_result(path, options=GeodesicOptions("alpha", 0.5)).log == {"stopped_by": "trivial"}
    ints = path_as_result([[[0, 0]], [[1, 0]], [[2, 0]]], options=GeodesicOptions("alpha", 0.5))
    assert ints.path.dtype == np.float64 and ints.length == pytest.approx(2 * np.sqrt(G_ALPHA(0.5)), rel=1e-10)


# --------------------------------------------------------------------------------------------- magnify


def test_magnify_a_flat_geodesic_scales_the_straight_line():
    a, b = A + [[0.5, -0.3]], B + [[0.5, -0.3]]  # away from the origin: the velocity is a difference
    geo = sl.geodesic(a, b, metric="fisher_rao", sigma2=0.5, n_steps=4, grid_margin=9.0)
    for mag, steps in [(1.5, 6), (0.4, 2), (0.1, 1), (2.2, 9)]:  # round(mag · 4), at least 1
        out = magnify(geo, mag)
        assert out.n_steps == steps and out.log["magnification"] == mag and out.log["exp"]["converged"]
        assert np.allclose(out.path[-1], a + mag * (b - a), atol=1e-9)
        assert np.allclose(out.path[:, 0], np.linspace(a[0], (a + mag * (b - a))[0], steps + 1), atol=1e-9)
        assert out.length == pytest.approx(mag * geo.length, rel=1e-9)
        assert out.metric == "fisher_rao" and out.sigma2 == 0.5
    # the grid of the result (a 3σ margin: errors of 1e-3) is the magnified one's
    coarse = sl.geodesic(A, B, metric="fisher_rao", sigma2=0.5, n_steps=4, grid_margin=3.0)
    assert magnify(coarse, 2.0).length == pytest.approx(2 * coarse.length, rel=1e-2)
    twice = magnify(coarse, 2.0)
    on_coarse = sl.path_length(twice.path, metric="fisher_rao", sigma2=0.5, grid_margin=3.0)
    on_fine = sl.path_length(twice.path, metric="fisher_rao", sigma2=0.5, grid_margin=9.0)
    assert twice.length == pytest.approx(on_coarse, rel=1e-12) and abs(on_coarse / on_fine - 1) > 1e-4
    wide = sl.geodesic(A, B, metric="fisher_rao", sigma2=0.5, n_steps=4, grid_spacing=2.0, grid_margin=9.0)
    twice = magnify(wide, 2.0)
    on_wide = sl.path_length(twice.path, metric="fisher_rao", sigma2=0.5, grid_spacing=2.0, grid_margin=9.0)
    on_fine = sl.path_length(twice.path, metric="fisher_rao", sigma2=0.5, grid_margin=9.0)
    assert twice.length == pytest.approx(on_wide, rel=1e-12) and abs(on_wide / on_fine - 1) > 1e-4


def test_magnify_passes_its_truncation_to_the_exponential():
    """rcond close to 1 leaves the geodesic (test_exp_map_truncation): the magnified path does too."""
    v = sl.procrustes_align(U, U + 0.5 * V0, scaling=False)
    geo = sl.geodesic(U, v, sigma2=0.5, n_steps=4, tol=1e-12)
    full, cut = magnify(geo, 2.0), magnify(geo, 2.0, rcond=0.999)
    assert np.allclose(full.path[:5], geo.path, atol=1e-5)
    assert np.abs(cut.path[-1] - full.path[-1]).max() > 1e-3


def test_magnify_refuses_what_it_cannot_magnify():
    geo = sl.geodesic(A, B, metric="alpha", sigma2=0.5, n_steps=4)
    with pytest.raises(ValueError, match="mag must be a positive finite number"):
        magnify(geo, -1.0)
    other = sl.GeodesicResult(path=geo.path, length=1.0, energy=1.0, lower_bound=0.0, converged=True, n_iter=0,
                              grad_norm=None, rel_energy_change=0.0, max_step_over_sigma=1.0,
                              metric="diffeomorphism", sigma2=0.5, log={"stopped_by": "trivial"})
    with pytest.raises(ValueError, match="magnify needs an alpha or fisher_rao geodesic; got metric 'diffeomorphism'"):
        magnify(other, 2.0)
    other.metric, other.sigma2 = "alpha", None
    with pytest.raises(ValueError, match="magnify needs"):
        magnify(other, 2.0)
    assert magnify(geo, 1.0) is geo
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.allclose(magnify(geo, 3.0, rcond=0.5).path[-1], A + 3 * (B - A), atol=1e-9)


# --------------------------------------------------------------------------------------------- backend="jax" glue


def test_jax_log_maps_glue_gives_the_cpu_log_maps(monkeypatch):
    """backend="jax" hands the population to shapelib.solver.batched.batched_geodesics as one batch. With
    that batch solved pair by pair by the CPU solver instead (no JAX needed), the log maps must be the
    CPU backend's: the same straight or warm starts, iteration budget ×JAX_ITER_FACTOR, zero lower bounds."""
    calls = []

    def batch_on_the_cpu(us, vs, *, metric, sigma2, n_steps, tol, max_iter, window, init, grid_spacing,
                         grid_margin, lower_bounds, device, warn):
        calls.append(dict(max_iter=max_iter, init=np.array(init), lower_bounds=np.array(lower_bounds), device=device,
                          warn=warn, us=np.array(us), n_steps=n_steps, grid=(grid_spacing, grid_margin)))
        return [sl.geodesic(u, v, metric=metric, sigma2=sigma2, n_steps=n_steps, tol=tol, max_iter=500, window=window,
                            init=i, grid_spacing=grid_spacing, grid_margin=grid_margin, warn=False)
                for u, v, i in zip(us, vs, init)]

    monkeypatch.setattr(logexp, "batched_geodesics", batch_on_the_cpu)
    rng = np.random.default_rng(5)
    shapes = np.stack([sl.procrustes_align(U, U + 0.2 * rng.normal(size=U.shape), scaling=False) for _ in range(3)])
    cpu = log_maps(U, shapes, options=GeodesicOptions("fisher_rao", 0.5, tol=1e-10, grid_margin=7.0))
    warm = cpu[1].path
    opts = GeodesicOptions("fisher_rao", 0.5, tol=1e-10, max_iter=30, grid_margin=7.0, backend="jax", device="cpu")
    t0 = time.perf_counter()
    jx = log_maps(U, shapes, options=opts, inits=[None, warm, np.zeros((3, 4, 2))])
    elapsed = time.perf_counter() - t0
    assert len(calls) == 1 and len(jx) == 3
    call = calls[0]
    assert call["max_iter"] == 30 * logexp.JAX_ITER_FACTOR and call["device"] == "cpu" and call["warn"] is False
    assert np.array_equal(call["lower_bounds"], np.zeros(3)) and call["n_steps"] == 4 and call["grid"] == (0.35, 7.0)
    assert np.array_equal(call["us"], np.stack([U] * 3))
    t = np.linspace(0, 1, 5)[:, None, None]
    assert np.allclose(call["init"][0], (1 - t) * U + t * shapes[0]) and np.array_equal(call["init"][1], warm)
    assert np.allclose(call["init"][2], (1 - t) * U + t * shapes[2])  # a start of the wrong shape is not used
    for a, b in zip(jx, cpu):
        assert np.allclose(a.vector, b.vector, atol=1e-7) and a.energy == pytest.approx(b.energy, rel=1e-8)
        assert np.allclose(a.vector, 4 * (a.path[1] - a.path[0]))
        assert a.converged and isinstance(a.n_iter, int) and a.stop_reason == b.stop_reason
        assert 0 < a.seconds <= elapsed / 3  # each pair's share of the batch's time
    per_base = log_maps(np.stack([U, shapes[1], U]), shapes, options=opts)
    assert np.allclose(per_base[1].vector, 0.0, atol=1e-9) and np.array_equal(calls[-1]["us"][1], shapes[1])
