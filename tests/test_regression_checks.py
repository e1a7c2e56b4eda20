"""Geodesic regression's parts checked against independent values. In the small-σ limit (landmarks
far apart against σ: the metric is constant, geodesics are straight lines, each fit takes a few
hundredths of a second) the fit is least-squares linear regression of the coordinates, so the
start, the prediction outside the covariate range (the exponential map), the intercept and velocity
at any ``t_ref`` and R² have closed forms. On a curved population (8 shapes of 6 landmarks, short
geodesics): the gradient in the geodesic's ends against a central difference of the loss recomputed
with :func:`shapelib.geodesic`, the speed against the metric tensor written out, the given mean, the
history, the stop and its warning."""

import warnings
from fractions import Fraction

import numpy as np
import pytest

import shapelib
from shapelib.statistics import regression as regression_module
from shapelib.statistics.regression import geodesic_regression

# the curved population is aligned, the ends moved off it to check derivatives are not quite: a pose
# the check finds "not aligned" at its 0.1 % tolerance
pytestmark = pytest.mark.filterwarnings("ignore::shapelib.PoseWarning")

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions go
#: through a trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(regression_module))
FLAT_S2 = 0.09  # landmarks 5 apart: overlaps ~exp(-50), the α-metric is constant


@pytest.fixture(scope="module")
def flat():
    """Shapes on a noisy line in the coordinates, the covariate on [8, 20], and the least-squares
    line ``a + (t − t̄) b`` through them."""
    rng = np.random.default_rng(3)
    base = 5.0 * np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 1.7]])
    slope = 0.2 * rng.normal(size=base.shape)
    t = np.array([8.0, 9.0, 11.0, 12.5, 14.0, 15.0, 17.0, 19.0, 20.0])
    y = base + (t - 14)[:, None, None] * slope / 6 + 0.05 * rng.normal(size=(len(t), *base.shape))
    tc = t - t.mean()
    b = np.einsum("n,nkd->kd", tc, y) / (tc @ tc)
    a = y.mean(axis=0)
    return y, t, a, b


def _fit_flat(y, t, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.ScaleWarning)  # the shapes are large against σ on purpose
        warnings.simplefilter("ignore", shapelib.PoseWarning)
        return geodesic_regression(y, t, sigma2=FLAT_S2, n_jobs=1, **kw)


@pytest.fixture  # a few hundredths of a second; per test, so that mutmut counts the fit towards each test that reads it
def flat_fit(flat):
    y, t, _, _ = flat
    return _fit_flat(y, t, tol=1e-9)


def test_the_start_is_the_least_squares_line_which_the_flat_limit_accepts_at_once(flat):
    """The Gauss–Newton start is the least-squares line of the coordinates, the answer in the flat
    limit: with no iteration allowed the fit is already converged on it."""
    y, t, a, b = flat
    res = _fit_flat(y, t, tol=1e-6, max_iter=0)
    assert res.converged and res.n_iter == 0 and len(res.log) == 1
    assert np.allclose(res.intercept, a, atol=1e-8) and np.allclose(res.velocity, b, atol=1e-8)
    assert np.allclose(res.path[0], a + (t.min() - t.mean()) * b, atol=1e-8)
    assert np.allclose(res.path[-1], a + (t.max() - t.mean()) * b, atol=1e-8)
    # a covariate of small spread (Σ(t − t̄)² < 1) as well
    small = _fit_flat(y, t / 100, tol=1e-6, max_iter=0)
    assert small.converged and np.allclose(small.velocity, 100 * b, atol=1e-6)


def test_prediction_outside_the_range_continues_the_line(flat, flat_fit):
    """Outside [t_min, t_max] the prediction is the exponential map from the nearer end: in the flat
    limit the least-squares line, on both sides, near and far."""
    y, t, a, b = flat
    for s in (4.0, 7.5, 20.5, 27.0):
        assert np.allclose(flat_fit.predict(s), a + (s - t.mean()) * b, atol=1e-6), s
    many = flat_fit.predict([5.0, 10.0, 23.0])
    assert many.shape == (3, *y.shape[1:])
    assert np.allclose(many, a + (np.array([5.0, 10.0, 23.0]) - t.mean())[:, None, None] * b, atol=1e-6)


def test_predict_takes_any_real_scalar_and_refuses_a_non_finite_one(flat, flat_fit):
    y, t, a, b = flat
    one = flat_fit.predict(10.0)
    assert one.shape == y.shape[1:]  # a scalar gives one shape
    assert flat_fit.predict([10.0]).shape == (1, *y.shape[1:])
    assert np.array_equal(flat_fit.predict(10), one)
    assert np.allclose(flat_fit.predict(Fraction(21, 2)), flat_fit.predict(10.5), atol=0, rtol=0)
    assert np.allclose(flat_fit.predict(t.min()), flat_fit.path[0], atol=0, rtol=0)
    assert np.allclose(flat_fit.predict(t.max()), flat_fit.path[-1], atol=0, rtol=0)
    for bad in (np.nan, [10.0, np.inf]):
        with pytest.raises(ValueError, match="^t must be finite$"):
            flat_fit.predict(bad)


@pytest.mark.parametrize("t_ref", [2.0, 8.0, 13.3, 20.0, 26.0])
def test_intercept_and_velocity_at_any_reference(flat, t_ref):
    """``γ(t_ref)`` and ``dγ/dt``: the least-squares line's value and slope, inside the covariate
    range or outside it."""
    y, t, a, b = flat
    res = _fit_flat(y, t, tol=1e-9, t_ref=t_ref)
    assert res.t_ref == t_ref and res.t_range == (8.0, 20.0)
    assert np.allclose(res.intercept, a + (t_ref - t.mean()) * b, atol=1e-6)
    assert np.allclose(res.velocity, b, atol=1e-7)


def test_r2_and_the_sums_of_squares_in_the_flat_limit(flat, flat_fit):
    """``d²`` is ``c‖·‖²`` with the constant metric ``c = 1/(8πσ⁴K²)`` of a mixture of ``K``
    far-apart landmarks: the sums of squares are the least-squares ones times ``c``."""
    y, t, a, b = flat
    c = 1 / (8 * np.pi * FLAT_S2**2 * y.shape[1] ** 2)
    resid = y - a - (t - t.mean())[:, None, None] * b
    assert flat_fit.ss_residual == pytest.approx(c * np.sum(resid**2), rel=1e-6)
    assert np.allclose(flat_fit.residual_energies, c * np.sum(resid**2, axis=(1, 2)), rtol=1e-6)
    assert flat_fit.ss_total == pytest.approx(c * np.sum((y - a) ** 2), rel=1e-6)
    assert flat_fit.r2 == pytest.approx(1 - np.sum(resid**2) / np.sum((y - a) ** 2), abs=1e-7)
    assert np.allclose(flat_fit.residuals, resid, atol=1e-6)
    assert np.allclose(flat_fit.fitted, y - resid, atol=1e-7)
    assert flat_fit.speed == pytest.approx(np.sqrt(c) * np.linalg.norm(b), rel=1e-7)


def test_the_summary_states_the_fit(flat_fit):
    text = flat_fit.summary()
    assert text.startswith("geodesic regression (alpha, σ² = 0.09) of 9 shapes on t ∈ [8, 20]: ")
    assert f"R² = {flat_fit.r2:.4f} " in text
    assert f"(Σd² residual {flat_fit.ss_residual:.4g} of {flat_fit.ss_total:.4g})" in text
    assert f"speed {flat_fit.speed:.4g} per unit t" in text
    assert f"certificate {flat_fit.certificate:.1e} (tol 1e-09), converged True in {flat_fit.n_iter} iterations" in text


# --- a curved population -------------------------------------------------------------------------

S2 = 1.0
OPTS = {"sigma2": S2, "n_steps": 4, "n_jobs": 1}


@pytest.fixture(scope="module")
def curved():
    """8 ellipses of 6 landmarks stretched with the covariate, with noise, in pose."""
    from tests.conftest import ellipse

    rng = np.random.default_rng(11)
    base = ellipse(6)
    mode = np.column_stack([0.15 * base[:, 0], -0.1 * base[:, 1]])
    t = np.sort(rng.uniform(0.0, 4.0, 8))
    x = np.stack([base + (s - 2.0) * mode + 0.1 * rng.normal(size=base.shape) for s in t])
    return shapelib.pose_align(x)[0], t


def _loss_and_fitted(a, b, y, t, m):
    """The regression loss at ends ``(a, b)``, computed afresh with :func:`shapelib.geodesic`: the
    ``m``-segment geodesic between the ends, its points at ``t`` (linear between its nodes), and the
    sum of the residual geodesics' energies."""
    path = shapelib.geodesic(a, b, sigma2=S2, n_steps=m, tol=1e-12).path if m > 1 else np.stack([a, b])
    s = (t - t.min()) / (t.max() - t.min()) * m
    j = np.minimum(np.floor(s).astype(int), m - 1)
    fitted = (1 - (s - j))[:, None, None] * path[j] + (s - j)[:, None, None] * path[j + 1]
    loss = sum(shapelib.geodesic(f, x, sigma2=S2, n_steps=4, tol=1e-12).energy for f, x in zip(fitted, y))
    return loss, fitted


@pytest.mark.parametrize("m", [1, 2, 3])
def test_the_gradient_and_jacobians_are_derivatives_of_the_loss(curved, m):
    """``∂L/∂(A, B)`` and ``∂ŷ_i/∂(A, B)`` (envelope and implicit-function theorems) against
    central differences of the loss and of the fitted points along random directions, at ends off
    the optimum."""
    from shapelib.statistics.frechet import geodesic_options
    from shapelib.statistics.population_logs import population_logs

    y, t = curved
    rng = np.random.default_rng(m)
    a = y[0] + 0.05 * rng.normal(size=y[0].shape)
    b = y[-1] + 0.05 * rng.normal(size=y[0].shape)
    opts = geodesic_options("alpha", sigma2=S2, n_steps=4, log_tol=1e-12, log_max_iter=500)
    model = opts.model()
    path = shapelib.geodesic(a, b, sigma2=S2, n_steps=m, tol=1e-12).path if m > 1 else np.stack([a, b])
    s = (t - t.min()) / (t.max() - t.min()) * m
    idx = np.minimum(np.floor(s).astype(int), m - 1)
    w = s - idx
    fitted = (1 - w)[:, None, None] * path[idx] + w[:, None, None] * path[idx + 1]
    logs = population_logs(fitted, y, options=opts)
    state = regression_module._State(a, b, path, fitted, logs, float(sum(r.energy for r in logs)), idx, w)
    grad, jac, _, _ = regression_module._gradient(model, state, opts, m, 4)
    assert grad.shape == (2 * a.size,) and jac.shape == (len(y), a.size, 2 * a.size)
    h = 1e-3  # a 4-point difference: O(h⁴) error, and the geodesics' own tolerance divided by h only
    for _ in range(2):
        step = rng.normal(size=2 * a.size)
        da, db = step[:a.size].reshape(a.shape), step[a.size:].reshape(b.shape)
        (l1, f1), (l2, f2), (l3, f3), (l4, f4) = (_loss_and_fitted(a + c * h * da, b + c * h * db, y, t, m)
                                                  for c in (1, -1, 2, -2))
        assert grad @ step == pytest.approx((8 * (l1 - l2) - (l3 - l4)) / (12 * h), rel=1e-6)
        fd = (8 * (f1 - f2) - (f3 - f4)) / (12 * h)
        assert np.allclose(jac @ step, fd.reshape(len(y), -1), rtol=0, atol=1e-5 * np.abs(fd).max())


def test_the_fit_is_stationary_and_records_its_options(curved):
    """At the fit (default ``tol``), a central difference of the loss along any move of the ends is
    small against the loss; the options it was given are the ones it reports."""
    y, t = curved
    res = geodesic_regression(y, t, sigma2=S2, n_steps=5, log_tol=1e-9, log_max_iter=300, rcond=1e-8,
                              grid_spacing=0.3, grid_margin=5.0, path_steps=3, n_jobs=1)
    o = res.options
    assert (o.metric, o.sigma2, o.n_steps, o.tol, o.max_iter, o.rcond, o.grid_spacing, o.grid_margin) == (
        "alpha", S2, 5, 1e-9, 300, 1e-8, 0.3, 5.0)
    assert res.mean.options == o  # the Fréchet mean of R² with the same options
    assert res.tol == 1e-3 and res.converged and res.certificate <= 1e-3 and len(res.path) == 4
    rng = np.random.default_rng(0)
    eps = 1e-4
    for _ in range(2):
        da, db = rng.normal(size=(2, *y[0].shape))
        lp = _loss_and_fitted(res.path[0] + eps * da, res.path[-1] + eps * db, y, t, 3)[0]
        lm = _loss_and_fitted(res.path[0] - eps * da, res.path[-1] - eps * db, y, t, 3)[0]
        assert abs(lp - lm) / (2 * eps) < 2e-3 * res.ss_residual  # ~2e-4 measured
    # the speed is the metric norm of the velocity: the α tensor written out
    g = shapelib.alpha_metric(res.intercept, sigma2=S2)
    assert res.speed == pytest.approx(np.sqrt(res.velocity.ravel() @ g @ res.velocity.ravel()), rel=1e-10)


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_the_fit_is_a_geodesic_and_r2_is_against_the_frechet_mean_of_its_metric(curved, metric):
    """The fitted path is the discrete geodesic between its ends (solved again with
    :func:`shapelib.geodesic`), and ``ss_total`` the squared distances (recomputed) from the
    Fréchet mean of the same metric and options (4 of the shapes: Fisher–Rao's integrals are slower)."""
    y, t = curved
    y, t = y[::2], t[::2]
    res = geodesic_regression(y, t, metric=metric, sigma2=S2, n_steps=3, log_tol=1e-9, path_steps=2, tol=1e-3,
                              n_jobs=1)
    assert res.mean.options == res.options and res.options.metric == metric
    again = shapelib.geodesic(res.path[0], res.path[-1], metric=metric, sigma2=S2, n_steps=2, tol=1e-12)
    assert np.abs(again.path - res.path).max() < 1e-9
    energies = [shapelib.geodesic(res.mean.mean, x, metric=metric, sigma2=S2, n_steps=3, tol=1e-12).energy for x in y]
    assert res.ss_total == pytest.approx(sum(energies), rel=1e-7)
    fitted = [shapelib.geodesic(f, x, metric=metric, sigma2=S2, n_steps=3, tol=1e-12).energy
              for f, x in zip(res.fitted, y)]
    assert np.allclose(res.residual_energies, fitted, rtol=1e-7)
    assert res.r2 == pytest.approx(1 - sum(fitted) / sum(energies), abs=1e-7)


def test_a_given_mean_is_used_and_a_wrong_one_refused(curved):
    y, t = curved
    mean = shapelib.frechet_mean(y, tol=1e-8, **OPTS)
    res = geodesic_regression(y, t, mean=mean, tol=1e-4, path_steps=3, **OPTS)
    assert res.mean is mean and res.ss_total == pytest.approx(float(np.sum(mean.energies)), rel=1e-14)
    assert res.r2 == pytest.approx(1 - res.ss_residual / float(np.sum(mean.energies)), rel=1e-14)
    other = shapelib.frechet_mean(y[:-1], tol=1e-4, **OPTS)
    for bad in (other, mean.mean):
        with pytest.raises(ValueError, match="^mean must be the FrechetMeanResult of these shapes$"):
            geodesic_regression(y, t, mean=bad, **OPTS)


def test_a_given_executor_runs_every_log_map_in_tasks_of_chunk_size(curved):
    """The residual log maps of every evaluation of the loss (the start and each trial step) go to
    the executor in tasks of ``chunk_size`` shapes; without a given mean, the mean's log maps too."""
    from tests.conftest import CountingExecutor

    y, t = curved
    mean = shapelib.frechet_mean(y, tol=1e-6, **OPTS)
    counts = []
    for given in (mean, None):
        ex = CountingExecutor()
        try:
            res = geodesic_regression(y, t, sigma2=S2, n_steps=4, mean=given, tol=1e-4, path_steps=3, executor=ex,
                                      chunk_size=3)
        finally:
            ex.pool.shutdown()
        assert len(ex.tasks) % 3 == 0 and ex.tasks == [3, 3, 2] * (len(ex.tasks) // 3)  # 8 shapes a round
        counts.append(sum(ex.tasks))
        if given is not None:  # one round of N log maps per evaluation: the start and every trial
            trials = sum(h["backtracks"] + 1 for h in res.log if "backtracks" in h)
            assert counts[0] == len(y) * (1 + trials)
    assert counts[1] > counts[0]  # the mean's log maps ran there too


def test_not_converging_warns_from_the_callers_line_unless_told_not_to(curved):
    y, t = curved
    with pytest.warns(shapelib.GeodesicWarning, match=r"geodesic regression: certificate .* > tol 1e-12 after 0 "
                                                      r"iterations") as record:
        res = geodesic_regression(y, t, tol=1e-12, max_iter=0, path_steps=2, **OPTS)
    if not UNDER_MUTMUT:  # mutmut's trampoline adds frames of its own
        assert record[0].filename == __file__
    assert not res.converged and res.stop_reason == "max_iter" and res.n_iter == 0 and len(res.log) == 1
    assert res.certificate == res.log[0]["certificate"] > 1e-12
    with warnings.catch_warnings():
        warnings.simplefilter("error", shapelib.GeodesicWarning)
        quiet = geodesic_regression(y, t, tol=1e-12, max_iter=0, path_steps=2, warn=False, **OPTS)
    assert not quiet.converged


def test_the_history_records_a_decreasing_loss(curved):
    import time

    y, t = curved
    start = time.perf_counter()
    res = geodesic_regression(y, t, tol=1e-6, path_steps=2, **OPTS)
    elapsed = time.perf_counter() - start
    assert res.converged and len(res.log) == res.n_iter + 1 >= 2
    losses = [h["loss"] for h in res.log]
    assert all(b < a for a, b in zip(losses, losses[1:])) and losses[-1] == res.ss_residual
    assert res.log[-1]["certificate"] == res.certificate <= 1e-6 < res.log[0]["certificate"]
    assert res.log[0]["path_iterations"] > 0  # later rounds start from the last paths, often already solved
    # the damping falls after a step accepted at once
    assert all(b["damping"] < a["damping"] or b["damping"] == a["damping"] == res.log[-1]["damping"]
               for a, b in zip(res.log, res.log[1:]) if a["backtracks"] == 0)
    assert all("backtracks" in h for h in res.log[:-1]) and "backtracks" not in res.log[-1]
    seconds = [h["seconds"] for h in res.log]
    assert seconds == sorted(seconds) and seconds[0] >= 0 and seconds[-1] <= elapsed  # since the fit began
    assert res.log[-1]["mode"] == "in-process"


def test_the_engine_route_keeps_the_work_in_process_for_a_small_population(flat, flat_fit):
    """``n_jobs=None``: the log maps are timed at the Procrustes mean and, this population being
    small, stay in this process; the fit is the one of ``n_jobs=1``."""
    y, t, _, _ = flat
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.ScaleWarning)
        res = geodesic_regression(y, t, sigma2=FLAT_S2, tol=1e-9)
    assert res.log[-1]["mode"] == "in-process" and res.log[-1]["n_workers"] == 1
    assert np.allclose(res.path, flat_fit.path, atol=1e-9) and res.r2 == pytest.approx(flat_fit.r2, rel=1e-9)


def test_a_one_segment_geodesic(flat, curved):
    """``path_steps=1``: the fit is the straight segment between its ends (no interior points)."""
    y, t, a, b = flat
    res = _fit_flat(y, t, tol=1e-9, path_steps=1)
    assert res.path.shape == (2, *y.shape[1:])
    assert np.allclose(res.intercept, a, atol=1e-7) and np.allclose(res.velocity, b, atol=1e-7)
    y, t = curved
    res = geodesic_regression(y, t, tol=1e-4, path_steps=1, **OPTS)
    assert res.converged and 0 < res.r2 < 1


def test_the_covariate_may_be_any_real_numbers(flat, flat_fit):
    y, t, _, _ = flat
    exact = [Fraction(s).limit_denominator(10) for s in t]
    res = _fit_flat(y, exact, tol=1e-9)
    assert res.t_range == (8.0, 20.0) and np.allclose(res.path, flat_fit.path, atol=1e-12)


def test_bad_input_is_refused_naming_the_parameter(flat):
    y, t, _, _ = flat
    with pytest.raises(ValueError, match=r"first at shape 3\)"):
        geodesic_regression(y, np.where(np.arange(len(t)) == 3, np.inf, t), sigma2=FLAT_S2, n_jobs=1)
    with pytest.raises(ValueError, match="^shapes must have shape"):
        geodesic_regression(y[:, :, 0], t, sigma2=FLAT_S2, n_jobs=1)
    with pytest.raises(ValueError, match="^shapes: landmarks must have d = 2 or 3"):
        geodesic_regression(np.concatenate([y, y[..., :1], y[..., :1]], axis=2), t, sigma2=FLAT_S2, n_jobs=1)
    for name, value, match in (("tol", 0.0, "^tol must be"), ("max_iter", -1, "^max_iter must be"),
                               ("path_steps", 0, "^path_steps must be"), ("step_rcond", 0.0, "^step_rcond must be"),
                               ("step_rcond", float("nan"), "^step_rcond must be"),
                               ("step_rcond", 1.0, "^step_rcond must be below 1")):
        with pytest.raises(ValueError, match=match):
            geodesic_regression(y, t, sigma2=FLAT_S2, n_jobs=1, **{name: value})


def test_the_warm_start_moves_the_ends_of_the_previous_path():
    """The next path solve starts from the previous path with its ends moved to the new ones and
    the move tapered linearly in between: the ends land exactly, a common move translates it."""
    rng = np.random.default_rng(0)
    path = rng.normal(size=(5, 3, 2))
    prev = regression_module._State(path[0], path[-1], path, None, [], 0.0, None, None)
    a, b = path[0] + rng.normal(size=(3, 2)), path[-1] + rng.normal(size=(3, 2))
    out = regression_module._moved_path(prev, a, b)
    assert np.allclose(out[0], a, atol=1e-15) and np.allclose(out[-1], b, atol=1e-15)
    assert np.allclose(np.diff(out - path, 2, axis=0), 0.0, atol=1e-14)  # linear in the node index
    move = rng.normal(size=(3, 2))
    assert np.allclose(regression_module._moved_path(prev, path[0] + move, path[-1] + move), path + move, atol=1e-15)


def test_the_velocity_at_either_end_is_the_log_map_along_the_fit(curved):
    """At ``t_ref = t_min`` the velocity is ``log_{γ(t_min)} γ(t_max) / (t_max − t_min)`` and at
    ``t_max`` minus the log map back, both on a fresh ``path_steps``-segment geodesic between the
    fit's ends (on a curved fit the two differ)."""
    y, t = curved
    lo, hi = t.min(), t.max()
    first = geodesic_regression(y, t, t_ref=lo, tol=1e-4, path_steps=3, **OPTS)
    last = geodesic_regression(y, t, t_ref=hi, tol=1e-4, path_steps=3, mean=first.mean, **OPTS)
    a, b = first.path[0], first.path[-1]
    assert np.allclose(first.intercept, a, atol=0) and np.allclose(last.intercept, b, atol=1e-9)
    forward = shapelib.log_map(a, b, sigma2=S2, n_steps=3, tol=1e-12) / (hi - lo)
    backward = -shapelib.log_map(b, a, sigma2=S2, n_steps=3, tol=1e-12) / (hi - lo)
    assert np.abs(forward - backward).max() > 1e-3
    assert np.allclose(first.velocity, forward, atol=1e-6) and np.allclose(last.velocity, backward, atol=1e-6)
    # outside the range: the velocity at the nearer end (documented), the intercept on the exponential map
    before = geodesic_regression(y, t, t_ref=lo - 1.0, tol=1e-4, path_steps=3, mean=first.mean, **OPTS)
    after = geodesic_regression(y, t, t_ref=hi + 1.0, tol=1e-4, path_steps=3, mean=first.mean, **OPTS)
    assert np.allclose(before.velocity, forward, atol=1e-6) and np.allclose(after.velocity, backward, atol=1e-6)
    assert np.array_equal(before.intercept, before.predict(lo - 1.0))
    assert np.array_equal(after.intercept, after.predict(hi + 1.0))


def test_an_unreachable_tolerance_stops_at_the_loss_floor(flat):
    """With ``tol`` below what rounding allows, the iteration stops when no damping lowers the
    loss (its floor), before ``max_iter``, not converged, at the least-squares line."""
    y, t, a, b = flat
    with pytest.warns(shapelib.GeodesicWarning, match="certificate"):
        res = _fit_flat(y, t, tol=1e-300, max_iter=40)
    assert not res.converged and res.n_iter < 40 and res.log[-1]["backtracks"] == 7
    assert np.allclose(res.intercept, a, atol=1e-7) and np.allclose(res.velocity, b, atol=1e-7)


def test_the_defaults_are_the_frechet_means(flat, flat_fit):
    """The residual geodesics' options default to those of :func:`shapelib.frechet_mean`; the stop
    to ``tol = 1e-3``."""
    from shapelib.statistics.frechet import geodesic_options

    y, t, _, _ = flat
    assert flat_fit.options == geodesic_options("alpha", sigma2=FLAT_S2)
    res = _fit_flat(y, t)
    assert res.tol == 1e-3 and res.options == flat_fit.options


def test_the_retained_subspace_does_not_move_the_fit(curved):
    """``rcond`` sets the subspace the mean's tangent space keeps (here one of 12 directions is
    dropped); the ends move in their own (``step_rcond``), so the fitted geodesic is the same."""
    y, t = curved
    full = geodesic_regression(y, t, tol=1e-6, path_steps=2, **OPTS)
    cut = geodesic_regression(y, t, tol=1e-6, path_steps=2, rcond=0.1, **OPTS)
    assert cut.mean.discarded_fraction > 0 and cut.options.rcond == 0.1
    assert np.allclose(cut.path, full.path, atol=1e-9)


def test_shapes_out_of_pose_warn_once_from_the_callers_line(curved):
    y, t = curved
    turned = y.copy()
    c, s = np.cos(0.3), np.sin(0.3)
    turned[2] = turned[2] @ np.array([[c, -s], [s, c]])
    with pytest.warns(shapelib.PoseWarning, match="^fisher_rao depends on the pose") as record:
        geodesic_regression(turned[:4], t[:4], metric="fisher_rao", max_iter=0, warn=False, sigma2=S2, n_steps=2,
                            path_steps=1, n_jobs=1)
    assert sum(issubclass(w.category, shapelib.PoseWarning) for w in record) == 1
    if not UNDER_MUTMUT:  # mutmut's trampoline adds frames of its own
        assert record[0].filename == __file__


def test_identical_shapes_give_a_standing_geodesic_and_no_r2():
    """Shapes that do not vary: the geodesic stands still at the shape, with zero loss (certificate
    0: nothing left to explain) and zero total sum of squares, so R² is undefined (nan)."""
    from tests.conftest import ellipse

    y = np.stack([ellipse(5)] * 4)
    res = geodesic_regression(y, [0.0, 1.0, 2.0, 3.0], tol=1e-6, path_steps=2, **OPTS)
    assert res.converged and res.n_iter == 0 and res.certificate == 0.0
    assert res.ss_residual == 0.0 and res.ss_total == 0.0 and np.isnan(res.r2)
    assert np.allclose(res.path, y[0], atol=1e-12) and np.allclose(res.velocity, 0.0, atol=1e-12)
