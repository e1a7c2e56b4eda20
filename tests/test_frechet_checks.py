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
from tests.conftest import ellipse_population

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
    """The rotation R (det +1) minimising ‖a R − b‖ for centred a, b (numpy's SVD, independently of the library)."""
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
    with pytest.warns(shapelib.GeodesicWarning, match=r"certificate ‖mean log‖/spread = .* > tol 1e-12 after 1 Karcher") \
            as record:
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
    ({"tol": 0.0}, "^tol "), ({"tol": -1.0}, "^tol "), ({"max_iter": -1}, "^max_iter "), ({"max_iter": 1.5}, "^max_iter "),
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
