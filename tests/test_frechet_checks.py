"""The Fréchet mean's parts checked against independent computations, on a small population (5 shapes
of 6 landmarks, 4-segment geodesics: each mean takes a few hundredths of a second): the Procrustes
start against its closed form for similar copies, the certificate against the metric tensor written
out, every field of the result against what it documents (geodesics recomputed, the retained
subspace from the eigenvectors), the iteration's history and stop, the options and the refusals."""

import warnings

import numpy as np
import pytest

import shapelib
from shapelib.solver.logexp import DEFAULT_LOG_STEPS, DEFAULT_RCOND, tangent_space
from shapelib.statistics import frechet as frechet_module
from shapelib.statistics.frechet import frechet_mean, geodesic_options, karcher_iteration, mean_certificate, \
    procrustes_mean
from tests.conftest import CountingExecutor, ellipse_population

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions go
#: through a trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(frechet_module))
SIGMA2 = 1.0
OPTS = {"sigma2": SIGMA2, "n_steps": 4, "n_jobs": 1}


@pytest.fixture(scope="module")
def x():
    return ellipse_population(np.random.default_rng(7), 5, 6, 2, noise=0.3)


@pytest.fixture(scope="module")
def res(x):
    return frechet_mean(x, tol=1e-6, **OPTS)


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


def _kabsch(a, b):
    """The rotation R (det +1) minimising ‖a R − b‖ for centred a, b (numpy's SVD, not the library's)."""
    u, _, vt = np.linalg.svd(a.T @ b)
    s = np.eye(a.shape[1])
    s[-1, -1] = np.sign(np.linalg.det(u @ vt))
    return u @ s @ vt


@pytest.mark.parametrize("k", [2, 6])
@pytest.mark.parametrize("n", [2, 4])
def test_the_procrustes_mean_of_similar_copies_is_the_base_at_the_mean_size_on_the_mean(k, n):
    """Copies ``s_i B R_i + t_i`` of one base ``B``: the GPA mean is ``B``'s shape, so the mean is a
    rotated copy of ``B`` at the mean centroid size, rotated and moved onto the arithmetic mean."""
    rng = np.random.default_rng(k + n)
    base = rng.normal(size=(k, 2))
    base -= base.mean(axis=0)
    sizes = rng.uniform(0.5, 2.0, n)
    x = np.stack([s * base @ _rot(a) + t for s, a, t in zip(sizes, rng.uniform(-0.6, 0.6, n), rng.normal(size=(n, 2)))])
    m = procrustes_mean(x)
    cs = lambda y: np.sqrt(np.sum((y - y.mean(axis=0)) ** 2))  # noqa: E731 - centroid size
    assert cs(m) == pytest.approx(np.mean([cs(y) for y in x]), rel=1e-9)
    mc = m - m.mean(axis=0)
    r = _kabsch(base, mc)
    np.testing.assert_allclose(base @ r * cs(m) / cs(base), mc, atol=1e-8)      # the base's shape
    xbar = x.mean(axis=0)
    np.testing.assert_allclose(m.mean(axis=0), xbar.mean(axis=0), atol=1e-10)  # the best translation
    np.testing.assert_allclose(_kabsch(mc, xbar - xbar.mean(axis=0)), np.eye(2), atol=1e-7)  # the best rotation
    np.testing.assert_allclose(procrustes_mean(x[::-1]), m, atol=1e-9)


def test_the_procrustes_mean_of_one_shape_or_of_copies_is_that_shape():
    y = np.random.default_rng(0).normal(size=(5, 2))
    np.testing.assert_array_equal(procrustes_mean(y[None]), y)
    copies = np.repeat(y[None], 3, axis=0)
    m = procrustes_mean(copies)
    np.testing.assert_array_equal(m, y)
    m[0, 0] += 1.0
    assert copies[0, 0, 0] == y[0, 0]  # a new array, not a view of the input
    one = np.array([[[1.0, 2.0]], [[3.0, 0.0]]])  # one landmark: the arithmetic mean
    np.testing.assert_array_equal(procrustes_mean(one), [[2.0, 1.0]])


def test_the_certificate_against_the_metric_tensor_written_out(x):
    ts = tangent_space(x[0], sigma2=SIGMA2)
    g = ts.metric_tensor
    logs = np.random.default_rng(1).normal(size=x.shape)
    flat = logs.reshape(len(logs), -1)
    mean = flat.mean(axis=0)
    grad = np.sqrt(mean @ g @ mean)
    spread = np.sqrt(np.mean([f @ g @ f for f in flat]))
    got = mean_certificate(ts, logs)
    np.testing.assert_allclose(got, (grad, spread, grad / spread), rtol=1e-12)
    assert mean_certificate(ts, np.zeros_like(logs)) == (0.0, 0.0, 0.0)
    assert all(type(v) is float for v in got)


def test_every_field_of_the_mean_says_what_it_documents(x, res):
    n = res.options.n_steps
    assert res.converged and res.stop_reason == "converged" and 1 <= res.n_iter
    assert res.tol == 1e-6 and res.certificate <= res.tol
    np.testing.assert_array_equal(res.init, procrustes_mean(x))
    assert res.tangent.base is not None and np.array_equal(res.tangent.base, res.mean)
    # the geodesics from the mean, recomputed from scratch by the geodesic solver
    for i, y in enumerate(x):
        geo = shapelib.geodesic(res.mean, y, sigma2=SIGMA2, n_steps=n, tol=1e-10, max_iter=2000)
        np.testing.assert_allclose(res.paths[i][0], res.mean, atol=1e-12)
        np.testing.assert_allclose(res.paths[i][-1], y, atol=1e-12)
        np.testing.assert_allclose(res.logs[i], n * (res.paths[i][1] - res.paths[i][0]), atol=1e-12)
        np.testing.assert_allclose(res.logs[i], n * (geo.path[1] - geo.path[0]), atol=1e-4)
        assert res.energies[i] == pytest.approx(geo.energy, rel=1e-5)
    assert res.variance == pytest.approx(np.mean(res.energies), rel=1e-14)
    assert res.log_converged.dtype == bool and res.log_converged.shape == (len(x),) and res.log_converged.all()
    # the certificate from the metric tensor at the mean, written out
    g = tangent_space(res.mean, sigma2=SIGMA2).metric_tensor
    flat = res.logs.reshape(len(x), -1)
    grad = np.sqrt(flat.mean(axis=0) @ g @ flat.mean(axis=0))
    spread = np.sqrt(np.mean(np.einsum("ni,ij,nj->n", flat, g, flat)))
    assert res.grad_norm == pytest.approx(grad, rel=1e-9, abs=1e-15) and res.spread == pytest.approx(spread, rel=1e-9)
    assert res.certificate == pytest.approx(grad / spread, rel=1e-9, abs=1e-15)
    # the share of Σ‖log‖²_g outside the retained subspace: from the eigenvectors of g
    lam, vec = np.linalg.eigh(g)
    c = flat @ vec
    dropped = lam < res.options.rcond * lam.max()
    assert res.discarded_fraction == pytest.approx(np.sum(lam[dropped] * c[:, dropped] ** 2)
                                                   / np.sum(lam * c ** 2), abs=1e-12)


def test_a_rank_deficient_tangent_space_discards_a_share_of_the_logs(x):
    """With rcond above the smallest eigenvalue of g, the logs have a share outside the retained subspace."""
    res = frechet_mean(x, tol=1e-3, rcond=0.2, max_iter=2, warn=False, **OPTS)
    g = tangent_space(res.mean, sigma2=SIGMA2).metric_tensor
    lam, vec = np.linalg.eigh(g)
    c = res.logs.reshape(len(x), -1) @ vec
    dropped = lam < 0.2 * lam.max()
    assert dropped.any() and res.tangent.rank == int((~dropped).sum())
    expected = np.sum(lam[dropped] * c[:, dropped] ** 2) / np.sum(lam * c ** 2)
    assert expected > 1e-6 and res.discarded_fraction == pytest.approx(expected, rel=1e-6)


def test_the_history_records_each_iteration(x, res, monkeypatch):
    log = res.log
    assert len(log) == res.n_iter + 1
    last = log[-1]
    assert (last["variance"], last["grad_norm"], last["certificate"]) == (res.variance, res.grad_norm, res.certificate)
    assert all("step" in h and h["step"] > 0 for h in log[:-1]) and "step" not in last
    assert [h["seconds"] for h in log] == sorted(h["seconds"] for h in log) and log[0]["seconds"] >= 0
    assert log[0]["path_iterations"] > 0 and all(type(h["path_iterations"]) is int for h in log)
    assert log[0]["backtracks"] == 0
    # the log maps counted by the population_logs calls that really ran
    calls = []
    real = frechet_module.population_logs

    def counted(m, shapes, **kw):
        calls.append(len(shapes))
        return real(m, shapes, **kw)

    monkeypatch.setattr(frechet_module, "population_logs", counted)
    again = frechet_mean(x, tol=1e-6, **OPTS)
    assert again.n_log_maps == sum(calls) == sum(h["log_maps"] for h in again.log)
    assert again.log[0]["log_maps"] == len(x)
    np.testing.assert_allclose(again.mean, res.mean, atol=1e-12)


def test_the_first_step_is_the_projected_mean_log(x):
    """One Karcher iteration from the Procrustes mean: ``m1 = exp_m0(P mean log)`` (no backtrack: it lowers
    the certificate), the exp map recomputed as the geodesic shooting of shapelib.exp_map."""
    one = frechet_mean(x, tol=1e-12, max_iter=1, warn=False, **OPTS)
    zero = frechet_mean(x, tol=1e-12, max_iter=0, warn=False, **OPTS)
    assert zero.n_iter == 0 and one.n_iter == 1 and not one.converged and one.stop_reason == "max_iter"
    np.testing.assert_array_equal(zero.mean, procrustes_mean(x))
    assert one.log[0]["backtracks"] == 0 and one.certificate < zero.certificate
    step = zero.tangent.project(zero.logs.mean(axis=0))
    assert one.log[0]["step"] == pytest.approx(float(zero.tangent.norm(step)), rel=1e-9)
    from shapelib.solver.logexp import exp_path

    np.testing.assert_allclose(one.mean, exp_path(zero.mean, step, options=zero.options)[0][-1], atol=1e-12)


def test_a_step_that_does_not_lower_the_certificate_is_halved(x):
    """karcher_iteration from a start far off the mean with a large step: whatever the backtracks, the step
    taken is the projected mean log halved ``backtracks`` times."""
    opts = geodesic_options("alpha", sigma2=SIGMA2, n_steps=4)
    m0 = procrustes_mean(x)
    for max_backtracks in (0, 2):
        r = karcher_iteration(x, m0, options=opts, tol=1e-12, max_iter=3, warn=False, max_backtracks=max_backtracks)
        for h, h_next in zip(r.log[:-1], r.log[1:]):
            assert 0 <= h_next["backtracks"] <= max_backtracks


def test_not_converged_warns_at_the_caller_and_warn_false_is_silent(x):
    warned = r"certificate ‖mean log‖/spread = .* > tol 1e-12 after 1 Karcher"
    with pytest.warns(shapelib.GeodesicWarning, match=warned) as record:
        frechet_mean(x, tol=1e-12, max_iter=1, **OPTS)
    if not UNDER_MUTMUT:  # mutmut's trampoline adds a frame of its own
        assert record[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        frechet_mean(x, tol=1e-12, max_iter=1, warn=False, **OPTS)


def test_the_summary_states_the_result(x, res):
    text = res.summary()
    assert text.startswith(f"Fréchet mean (alpha, σ² = 1, {len(x)} shapes): variance {res.variance:.6g}")
    assert f"converged True in {res.n_iter} iterations" in text and f"{res.certificate:.2e}" in text
    assert f"retained subspace {res.tangent.rank} of 12 directions" in text and "not converged" not in text
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.GeodesicWarning)
        rough = frechet_mean(x, tol=1e-12, max_iter=0, log_max_iter=1, **OPTS)
    bad = int((~rough.log_converged).sum())
    assert bad > 0 and rough.summary().endswith(f"; {bad} path solves not converged")


def test_the_options_reach_the_geodesics(x):
    o = geodesic_options("fisher_rao", sigma2=0.3, n_steps=5, log_tol=1e-7, log_max_iter=17, rcond=1e-5,
                         grid_spacing=0.4, grid_margin=2.5)
    assert (o.metric, o.sigma2, o.n_steps, o.tol, o.max_iter, o.rcond, o.grid_spacing, o.grid_margin, o.backend) == \
        ("fisher_rao", 0.3, 5, 1e-7, 17, 1e-5, 0.4, 2.5, "cpu")
    d = geodesic_options("alpha", sigma2=0.3)
    assert (d.n_steps, d.rcond) == (DEFAULT_LOG_STEPS, DEFAULT_RCOND)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.GeodesicWarning)
        r = frechet_mean(x, metric="alpha", sigma2=SIGMA2, n_steps=3, log_tol=1e-5, log_max_iter=50, rcond=1e-6,
                         max_iter=0, n_jobs=1)
    assert (r.options.n_steps, r.options.tol, r.options.max_iter, r.options.rcond) == (3, 1e-5, 50, 1e-6)
    fr = frechet_mean(x, metric="fisher_rao", sigma2=SIGMA2, n_steps=3, grid_spacing=0.4, grid_margin=2.5, max_iter=0,
                      warn=False, n_jobs=1).options
    assert (fr.metric, fr.grid_spacing, fr.grid_margin) == ("fisher_rao", 0.4, 2.5)
    assert len(r.paths[0]) == 4
    init = x[1]
    r = frechet_mean(x, init=init, max_iter=0, warn=False, **OPTS)
    np.testing.assert_array_equal(r.init, init)
    np.testing.assert_array_equal(r.mean, init)


def test_the_default_tolerance_is_met(x):
    """With the defaults the iteration runs until the certificate is 1e-3 or less (from a start above it)."""
    start = frechet_mean(x, max_iter=0, warn=False, **OPTS)
    assert start.certificate > 1e-3
    res = frechet_mean(x, **OPTS)
    assert res.converged and res.n_iter >= 1 and res.certificate <= 1e-3 and res.tol == 1e-3


def test_mean_of_copies_is_that_shape_with_no_iteration(x):
    res = frechet_mean(np.repeat(x[:1], 3, axis=0), **OPTS)
    assert res.converged and res.n_iter == 0 and res.variance == 0 and res.certificate == 0
    np.testing.assert_array_equal(res.mean, x[0])


@pytest.mark.parametrize("kw, match", [
    ({"tol": 0.0}, "^tol "), ({"tol": -1.0}, "^tol "),
    ({"max_iter": -1}, "^max_iter "), ({"max_iter": 1.5}, "^max_iter "),
])
def test_bad_options_name_the_parameter(x, kw, match):
    with pytest.raises(ValueError, match=match):
        frechet_mean(x, **{**OPTS, **kw})


def test_bad_shapes_name_the_parameter(x):
    with pytest.raises(ValueError, match="^init must have shape"):
        frechet_mean(x, init=x[0, :4], **OPTS)
    with pytest.raises(ValueError, match="shapes"):
        frechet_mean(x[0], **OPTS)
    with pytest.raises(ValueError, match="shapes"):
        frechet_mean(np.zeros((3, 4, 4)), **OPTS)


def test_the_population_checks_are_skipped_inside_a_checked_set(x):
    """A population out of pose is warned (once, at the caller), except inside set_checked (a statistic
    calling another has warned already)."""
    from shapelib._validate import set_checked

    turned = x.copy()
    turned[0] = x[0] @ _rot(0.4)
    with pytest.warns(shapelib.PoseWarning) as record:
        frechet_mean(turned, max_iter=0, warn=False, **OPTS)
    assert sum(issubclass(w.category, shapelib.PoseWarning) for w in record) == 1
    if not UNDER_MUTMUT:
        assert record[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error", shapelib.PoseWarning)
        with set_checked():
            frechet_mean(turned, max_iter=0, warn=False, **OPTS)
    with pytest.warns(shapelib.ScaleWarning) as record:
        frechet_mean(x * 100, max_iter=0, warn=False, sigma2=SIGMA2, n_steps=4, n_jobs=1)
    if not UNDER_MUTMUT:
        assert record[0].filename == __file__


def test_a_given_executor_runs_every_log_map_in_tasks_of_chunk_size(x, res):
    ex = CountingExecutor()
    try:
        got = frechet_mean(x, tol=1e-6, executor=ex, chunk_size=2, sigma2=SIGMA2, n_steps=4)
    finally:
        ex.pool.shutdown()
    np.testing.assert_allclose(got.mean, res.mean, atol=1e-10)
    assert got.n_iter == res.n_iter and sum(ex.tasks) == got.n_log_maps
    # every round of the 5 log maps in tasks of 2, 2 and 1
    assert len(ex.tasks) == 3 * got.n_log_maps // len(x) and set(ex.tasks) == {1, 2} and ex.tasks.count(1) * len(x) == \
        got.n_log_maps
    assert "mode" not in got.log[-1]   # the caller's executor: no engine mode to record


def test_where_the_log_maps_ran_is_recorded(x, res):
    assert (res.log[-1]["mode"], res.log[-1]["n_workers"]) == ("in-process", 1)
    auto = frechet_mean(x, tol=1e-6, sigma2=SIGMA2, n_steps=4)   # n_jobs=None: one log map timed, then decided
    assert auto.log[-1]["mode"] == "in-process"
    np.testing.assert_allclose(auto.mean, res.mean, atol=1e-12)


@pytest.mark.parametrize("kw", [{"n_jobs": 2}, {"client": object()}, {"scheduler": "tcp://127.0.0.1:1"}])
def test_an_executor_with_an_engine_keyword_is_refused(x, kw):
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as ex:
        with pytest.raises(ValueError, match="^give executor, or n_jobs / client / scheduler, not both"):
            frechet_mean(x, sigma2=SIGMA2, n_steps=4, executor=ex, **kw)


def test_the_device_reaches_the_backend_check(x):
    with pytest.raises(ValueError, match='^device="gpu" needs backend="jax"'):
        frechet_mean(x, sigma2=SIGMA2, n_steps=4, n_jobs=1, device="gpu")
    with pytest.raises(ValueError, match='^device="gpu" needs backend="jax"'):
        geodesic_options("alpha", sigma2=SIGMA2, device="gpu")
    assert geodesic_options("alpha", sigma2=SIGMA2, device="cpu").device == "cpu"
    r = frechet_mean(x, sigma2=SIGMA2, n_steps=4, n_jobs=1, device="cpu", max_iter=0, warn=False)
    assert r.options.device == "cpu"


def test_the_statistics_share_the_path_solves_defaults(x):
    """geodesic_options' defaults (what tangent PCA at a given mean uses) are frechet_mean's."""
    fm = frechet_mean(x, sigma2=SIGMA2, n_steps=4, n_jobs=1, max_iter=0, warn=False).options
    o = geodesic_options("alpha", sigma2=SIGMA2, n_steps=4)
    assert (o.tol, o.max_iter) == (fm.tol, fm.max_iter) == (1e-6, 200)


def test_at_the_rounding_floor_a_step_that_does_not_lower_the_certificate_is_halved_up_to_four_times(x):
    """tol = 1e-15 is below what rounding lets the certificate reach: the iteration runs to its default
    30 iterations, and there steps stop lowering the certificate and are halved, four times at most
    (whether a halved step at the floor ever lowers the certificate is rounding's choice and differs
    between machines). Far above the floor the full step lowers it. g is of full rank here (the
    projection is the identity), so each step's metric norm is the mean log's, ``grad_norm``, halved
    once per backtrack (recorded with the next iteration)."""
    r = frechet_mean(x, tol=1e-15, warn=False, **OPTS)
    assert r.n_iter == 30 and not r.converged and r.converged is False and len(r.log) == 31
    assert r.tangent.rank == 12
    halvings = [h["backtracks"] for h in r.log[1:]]
    assert max(halvings) == 4 and all(0 <= b <= 4 for b in halvings)
    assert halvings[:4] == [0, 0, 0, 0] and r.log[4]["certificate"] > 1e-9  # steps far above the floor
    for h, b in zip(r.log[:-1], halvings):
        assert h["step"] == pytest.approx(h["grad_norm"] * 0.5 ** b, rel=1e-6)
    assert all(type(h["log_maps"]) is int and h["log_maps"] == len(x) * (b + 1) for h, b in zip(r.log[1:], halvings))
    assert r.n_log_maps == len(x) * (1 + sum(b + 1 for b in halvings))


def test_warm_started_paths_need_no_iteration(x, res):
    """karcher_iteration from the mean with its own paths as the first warm starts: the path solves start
    at their solutions (the geodesics' first-order conditions hold there already)."""
    cold = karcher_iteration(x, res.mean, options=res.options, tol=1e-3, max_iter=0)
    warm = karcher_iteration(x, res.mean, options=res.options, tol=1e-3, max_iter=0, inits=res.paths)
    assert cold.log[0]["path_iterations"] > 0 and warm.log[0]["path_iterations"] == 0
    np.testing.assert_allclose(warm.logs, res.logs, atol=1e-9)


def test_karcher_iteration_warns_by_default(x, res):
    with pytest.warns(shapelib.GeodesicWarning, match="after 0 Karcher iterations"):
        karcher_iteration(x, procrustes_mean(x), options=res.options, tol=1e-12, max_iter=0)


def test_the_seconds_are_measured_from_the_start(x):
    import time

    t0 = time.perf_counter()
    r = frechet_mean(x, tol=1e-6, **OPTS)
    wall = time.perf_counter() - t0
    assert all(0 <= h["seconds"] <= wall for h in r.log)


def test_the_procrustes_mean_has_the_shape_of_the_rotations_only_gpa_mean(x):
    """A population that is not of similar copies: the mean's shape is the GPA mean of the unit-size
    shapes rotated onto it (no per-shape scale), computed here independently."""
    rng = np.random.default_rng(2)
    y = x * rng.uniform(0.6, 1.6, len(x))[:, None, None]   # sizes differ
    pre = np.stack([s - s.mean(axis=0) for s in y])
    pre /= np.linalg.norm(pre, axis=(1, 2))[:, None, None]
    mu = pre[0].copy()
    for _ in range(200):
        pre = np.stack([p @ _kabsch(p, mu) for p in pre])
        new = pre.mean(axis=0)
        new /= np.linalg.norm(new)
        if np.linalg.norm(new - mu) < 1e-14:
            break
        mu = new
    m = procrustes_mean(y)
    mc = m - m.mean(axis=0)
    mc /= np.linalg.norm(mc)
    np.testing.assert_allclose(mu @ _kabsch(mu, mc), mc, atol=1e-8)
    assert np.linalg.norm(m - m.mean(axis=0)) == pytest.approx(
        np.mean([np.linalg.norm(s - s.mean(axis=0)) for s in y]), rel=1e-12)


def test_the_summary_of_a_mean_whose_path_solves_converged_ends_with_the_discarded_share(res):
    assert res.summary().endswith(f"{res.discarded_fraction:.1e} of the variance outside it")


@pytest.mark.parametrize("call, match", [
    (lambda x: frechet_mean(x, sigma2=SIGMA2, init=np.zeros((6, 2, 1)), n_jobs=1), "^init must be a 2-D array"),
    (lambda x: frechet_mean(x, sigma2=SIGMA2, init=x[0, :4], n_jobs=1),
     r"^init must have shape \(6, 2\); got \(4, 2\)"),
    (lambda x: frechet_mean(x[0], sigma2=SIGMA2, n_jobs=1), r"^shapes must have shape \(N, K, d\)"),
    (lambda x: frechet_mean(np.zeros((3, 4, 4)), sigma2=SIGMA2, n_jobs=1), "^shapes: landmarks must have d = 2 or 3"),
    (lambda x: procrustes_mean(x[0]), r"^shapes must have shape \(N, K, d\)"),
])
def test_bad_input_names_the_parameter(x, call, match):
    with pytest.raises(ValueError, match=match):
        call(x)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_the_pose_warning_names_the_metric(x, metric):
    turned = x.copy()
    turned[0] = x[0] @ _rot(0.4)
    with pytest.warns(shapelib.PoseWarning, match=f"^{metric} depends on the pose"):
        frechet_mean(turned, metric=metric, max_iter=0, warn=False, **OPTS)
