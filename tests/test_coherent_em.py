"""The registration EM's compiled pieces against dense, independent computations."""

import numpy as np
import pytest

from shapelib.pointsets._coherent_em import (PLAIN_ITER, EMState, Kernel, _column, _em_map, _estep, _exp_neg,
                                             _extrapolate, _m_step, _sse, initial_sigma2, objective, outlier_term,
                                             posteriors, run_em, sq_dist)

#: no known correspondences (the compiled loops' empty label array)
NO_LABELS = np.zeros(0, dtype=np.int64)


@pytest.fixture
def sets():
    rng = np.random.default_rng(3)
    theta = rng.normal(size=(23, 2))
    y = np.vstack([theta[:17] + 0.05 * rng.normal(size=(17, 2)), rng.uniform(-3, 3, size=(6, 2))])
    return theta, y


def test_the_vectorised_exponential_is_within_one_ulp_of_numpy():
    # every argument the E-step gives it (0 to PRUNE + 1) and the log-likelihood's (to 700), densely,
    # with the points where the range reduction's k changes (multiples of ln 2) and their neighbours
    ln2 = np.log(2.0)
    a = np.concatenate([np.linspace(0.0, 38.0, 200_001), np.linspace(38.0, 700.0, 20_001),
                        np.arange(1, 1010) * ln2 / 1.0, np.arange(1, 1010) * ln2 / 2.0])
    a = np.concatenate([a, np.nextafter(a, 0.0), np.nextafter(a, np.inf)])
    a = a[(a >= 0) & (a <= 700)]
    out = np.empty_like(a)
    _exp_neg(a, out)
    ref = np.exp(-a)
    assert np.max(np.abs(out - ref) / np.spacing(ref)) <= 1.0
    assert out[a == 0.0][0] == 1.0


@pytest.mark.parametrize("s2", [2.0, 0.05, 1e-3, 1e-5])
@pytest.mark.parametrize("w", [0.0, 0.2])
def test_the_estep_sums_equal_the_dense_posteriors(sets, s2, w):
    theta, y = sets
    volume = 36.0
    p = posteriors(theta, y, s2, w, volume)  # the (n, m) matrix, exponentials of every pair
    c = outlier_term(len(theta), 2, s2, w, volume)
    p1, pt1, py, sse, lse = _estep(theta, y, s2, c, True, NO_LABELS)
    # the log-normalisers: log(Σ_i exp(−|y_j − θ_i|²/2σ²) + c), summed over j, by scipy from the distances
    from scipy.special import logsumexp
    logs = -sq_dist(theta, y) / (2 * s2)
    if c > 0:
        logs = np.vstack([logs, np.full(len(y), np.log(c))])
    assert lse == pytest.approx(float(logsumexp(logs, axis=0).sum()), rel=1e-12, abs=1e-9)
    np.testing.assert_allclose(p1, p.sum(axis=1), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(pt1, p.sum(axis=0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(py, p @ y, rtol=1e-12, atol=1e-14)
    assert sse == pytest.approx(float(np.sum(p * sq_dist(theta, y))), rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("s2", [2.0, 1e-3])
def test_the_estep_sums_equal_the_dense_posteriors_in_3d(s2):
    rng = np.random.default_rng(4)
    theta = rng.normal(size=(19, 3))
    y = np.vstack([theta[:15] + 0.05 * rng.normal(size=(15, 3)), rng.uniform(-3, 3, size=(5, 3))])
    c = outlier_term(len(theta), 3, s2, 0.2, 216.0)
    p = posteriors(theta, y, s2, 0.2, 216.0)
    p1, pt1, py, sse, _ = _estep(theta, y, s2, c, True, NO_LABELS)
    np.testing.assert_allclose(p1, p.sum(axis=1), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(pt1, p.sum(axis=0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(py, p @ y, rtol=1e-12, atol=1e-14)
    assert sse == pytest.approx(float(np.sum(p * sq_dist(theta, y))), rel=1e-12, abs=1e-14)


def test_a_point_far_from_every_mean_takes_no_posterior_without_an_outlier_term(sets):
    theta, _ = sets
    y = np.array([[1e3, 1e3], theta[0]])
    p1, pt1, _, _, _ = _estep(theta, y, 1e-2, 0.0, True, NO_LABELS)
    assert pt1[0] == 0.0 and pt1[1] == pytest.approx(1.0)
    assert p1.sum() == pytest.approx(1.0)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("n", [1, 3, 4, 5, 98])
def test_a_column_is_the_squared_distances_and_their_exact_minimum(d, n):
    # the minimum is taken over the bit patterns as integers: it must be the float minimum exactly,
    # for every length (the compiled loop's vector body and its remainder), with ties and with a
    # target point on a source point (distance +0)
    rng = np.random.default_rng(n + d)
    theta = rng.normal(size=(n, d))
    theta[n // 2] = theta[-1] if n > 1 else theta[0]  # a tie
    y = np.vstack([rng.normal(size=(6, d)), theta[n // 3]])  # the last lies on a source point
    dist = np.empty(n)
    for j in range(len(y)):
        low = _column(np.ascontiguousarray(theta.T), y, j, dist)
        np.testing.assert_allclose(dist, np.sum((theta - y[j]) ** 2, axis=1), rtol=1e-14, atol=0.0)
        assert low == dist.min()
    assert low == 0.0 and not np.signbit(low)


@pytest.mark.parametrize("rank", [None, 6])
def test_the_m_step_solves_its_linear_system_and_gives_g_w(rank):
    # (diag(P1) G + λσ² I) W = B with G = Q diag(ev) Qᵀ (all eigenvalues, or the largest few), against
    # numpy's dense solve; some P1 zero (source points that took no posterior); G W = Q z is the kernel
    # applied to W; the σ² update's sum Σ P_ij |y_j − θ_i|² from P1, Pᵀ1, P y equals the dense sum
    rng = np.random.default_rng(4)
    n, d, m = 17, 2, 13
    u = rng.normal(size=(n, d))
    k = Kernel.of(np.exp(-sq_dist(u, u) / 2.0))
    if rank is not None:
        k = Kernel(q=np.ascontiguousarray(k.q[:, -rank:]), ev=k.ev[-rank:].copy())
    g = k.q @ np.diag(k.ev) @ k.q.T
    p1 = rng.uniform(0.0, 2.0, size=n)
    p1[[2, 9]] = 0.0
    b = rng.normal(size=(n, d))
    lam_s2 = 0.07
    q = np.ascontiguousarray(k.q)
    coef, gw = _m_step(q, np.ascontiguousarray(q.T), k.ev, np.zeros((0, 0)), p1, b, lam_s2)
    want = np.linalg.solve(p1[:, None] * g + lam_s2 * np.eye(n), b)
    np.testing.assert_allclose(gw, g @ want, rtol=1e-10, atol=1e-12)
    if rank is None:  # with every eigenvalue, W itself is the solution
        np.testing.assert_allclose(coef, want, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(p1[:, None] * gw + lam_s2 * coef, b, rtol=1e-10, atol=1e-12)
    p = rng.uniform(size=(n, m))
    y = rng.normal(size=(m, d))
    theta = u + gw
    dense = np.sum(p * np.sum((y[None] - theta[:, None]) ** 2, axis=2))
    got = _sse(p.sum(axis=0), np.sum(y * y, axis=1), p @ y, p.sum(axis=1), u, gw)
    assert got == pytest.approx(dense, rel=1e-12)


@pytest.mark.parametrize("fixed", [False, True])
def test_the_compiled_woodbury_em_equals_the_dense_solve(sets, fixed):
    theta, y = sets
    u = theta * 1.1 + 0.05
    g = np.exp(-sq_dist(u, u) / (4 * 0.05))  # well conditioned: every eigenvalue kept
    common = dict(lam=2.0, volume=36.0, max_iter=7, tol=0.0, fixed_s2=0.3 if fixed else None, s2_floor=1e-12)
    fact = run_em(EMState(u=u, kernel=Kernel.of(g), coef=np.zeros_like(u), s2=0.3, w=0.1), y, **common)
    dense = run_em(EMState(u=u, kernel=Kernel(full=np.kron(g, np.eye(2))), coef=np.zeros_like(u), s2=0.3, w=0.1),
                   y, **common)
    assert fact.kernel.ev.size == len(u)
    assert fact.it == dense.it == 7
    np.testing.assert_allclose(fact.theta, dense.theta, rtol=1e-9, atol=1e-11)
    assert fact.s2 == pytest.approx(dense.s2, rel=1e-9)


def test_the_compiled_em_stops_at_its_tolerance_like_the_loop(sets):
    theta, y = sets
    u = theta + 0.1
    g = np.exp(-sq_dist(u, u) / (4 * 0.05))
    # a floor as register sets it (the Woodbury form loses accuracy as λσ² goes to 0)
    opts = dict(lam=2.0, volume=36.0, max_iter=500, tol=1e-6, fixed_s2=None, s2_floor=1e-4)
    fact = run_em(EMState(u=u, kernel=Kernel.of(g), coef=np.zeros_like(u), s2=1.0, w=0.1), y, **opts)
    dense = run_em(EMState(u=u, kernel=Kernel(full=np.kron(g, np.eye(2))), coef=np.zeros_like(u), s2=1.0, w=0.1),
                   y, **opts)
    assert fact.ok and dense.ok and fact.why == "tolerance"
    assert fact.it == dense.it < 500
    np.testing.assert_allclose(fact.theta, dense.theta, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("w", [0.0, 0.3])
@pytest.mark.parametrize("s2", [1.0, 1e-4])
def test_the_objective_is_the_negative_log_posterior(sets, w, s2):
    """F against scipy's log-density of the mixture plus the uniform component, summed directly."""
    from scipy.special import logsumexp
    from scipy.stats import multivariate_normal

    from shapelib.pointsets._coherent_em import objective

    theta, y = sets
    u = theta - 0.05
    g = np.exp(-sq_dist(u, u) / (4 * 0.5))
    kernel = Kernel.of(g)
    st = EMState(u=u, kernel=kernel, coef=np.zeros_like(u) + 0.01, s2=s2, w=w)
    volume = 36.0
    comp = np.array([multivariate_normal(mean=t, cov=s2 * np.eye(2)).logpdf(y) for t in st.theta])  # (n, m)
    terms = [logsumexp(comp, axis=0) + np.log((1 - w) / len(u))]
    if w > 0:
        terms.append(np.full(len(y), np.log(w / volume)))
    ll = logsumexp(np.stack(terms), axis=0).sum()
    energy = np.sum(st.coef * (g @ st.coef))
    assert objective(st, y, lam=2.0, volume=volume) == pytest.approx(-ll + 0.5 * 2.0 * energy, rel=1e-10)


def _problem():
    """A bent outline with noise, half of it resampled: plain EM needs about 200 iterations."""
    rng = np.random.default_rng(5)
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    u = np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])
    y = u + np.column_stack([0.05 * np.sin(2 * u[:, 1]), 0.25 * u[:, 0] ** 2]) + 0.03 * rng.normal(size=u.shape)
    y = y[rng.permutation(60)[:50]]
    kernel = Kernel.of(np.exp(-sq_dist(u, u) / (4 * 0.5)))
    return u, y, kernel, dict(lam=2.0, volume=float(np.prod(np.ptp(y, axis=0))), s2_floor=1e-6)


def test_the_em_map_gives_the_objective_at_its_input():
    """F from the E-step's normalisers against the objective (itself checked against scipy above)."""
    u, y, kernel, o = _problem()
    st = EMState(u=u, kernel=kernel, coef=0.02 * np.cos(u), s2=0.07, w=0.1)
    n, d = u.shape
    # the arrays contiguous, as run_em passes them: the loop's compiled specialisation, not another one
    q = np.ascontiguousarray(kernel.q)
    out = _em_map(u, q, np.ascontiguousarray(q.T), kernel.ev, np.zeros((0, 0)), y, np.sum(y * y, axis=1),
                  st.coef, kernel.apply(st.coef), st.s2,
                  outlier_term(n, d, 1.0, st.w, o["volume"]), o["lam"], False, o["s2_floor"], np.log(0.9 / n), NO_LABELS)
    assert out[3] == pytest.approx(objective(st, y, lam=o["lam"], volume=o["volume"]), rel=1e-12)
    # and the iteration it gives is one plain EM iteration, with G W of the new W
    one = run_em(EMState(u=u, kernel=kernel, coef=st.coef.copy(), s2=st.s2, w=0.1), y, max_iter=1, tol=0.0, **o)
    np.testing.assert_allclose(out[0], one.coef, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(out[1], kernel.apply(out[0]), rtol=1e-10, atol=1e-13)
    assert out[2] == pytest.approx(one.s2, rel=1e-12)


def test_the_extrapolation_recovers_the_limit_of_a_geometric_sequence():
    """SQUAREM's S3 step is exact for x_k = x* + ρ^k e (its α is −1/(1 − ρ)), and α = −1 gives x2."""
    rng = np.random.default_rng(0)
    star, e = rng.normal(size=(7, 2)), rng.normal(size=(7, 2))
    ls, le = np.log(0.3), 0.8
    for rho in (0.5, 0.9, 0.99):
        xs = [(star + rho**k * e, np.exp(ls + rho**k * le)) for k in range(3)]
        c, s2, alpha = _extrapolate(*xs[0], *xs[1], *xs[2], 1e-12)
        assert alpha == pytest.approx(-1 / (1 - rho), rel=1e-9)
        np.testing.assert_allclose(c, star, atol=1e-9)
        assert np.log(s2) == pytest.approx(ls, abs=1e-9)
    # a sequence that does not contract (‖r‖ ≤ ‖v‖): the step is held at α = −1, which is x2
    xs = [(star + (-1.5) ** k * e, np.exp(ls + (-1.5) ** k * le)) for k in range(3)]
    c, s2, alpha = _extrapolate(*xs[0], *xs[1], *xs[2], 1e-12)
    assert alpha == -1.0
    np.testing.assert_allclose(c, xs[2][0], atol=1e-12)
    assert s2 == pytest.approx(xs[2][1], rel=1e-12)


def test_the_accelerated_em_reaches_the_fixed_point_of_plain_em_in_fewer_iterations():
    u, y, kernel, o = _problem()
    fits = {}
    for acc in (False, True):
        st = EMState(u=u, kernel=kernel, coef=np.zeros_like(u), s2=1.0, w=0.1)
        fits[acc] = run_em(st, y, max_iter=20000, tol=1e-11, accelerate=acc, **o)
    plain, fast = fits[False], fits[True]
    assert plain.ok and fast.ok
    np.testing.assert_allclose(fast.theta, plain.theta, atol=1e-6)
    assert fast.s2 == pytest.approx(plain.s2, rel=1e-6)
    assert fast.it < 0.6 * plain.it
    # the first PLAIN_ITER iterations are plain EM: the same iterate either way
    a = run_em(EMState(u=u, kernel=kernel, coef=np.zeros_like(u), s2=1.0, w=0.1), y, max_iter=PLAIN_ITER, tol=0.0,
               **o)
    b = run_em(EMState(u=u, kernel=kernel, coef=np.zeros_like(u), s2=1.0, w=0.1), y, max_iter=PLAIN_ITER, tol=0.0,
               accelerate=False, **o)
    np.testing.assert_array_equal(a.coef, b.coef)


def test_a_cycle_never_ends_above_one_em_iteration():
    """The safeguard: a cycle (three iterations past PLAIN_ITER, one call) ends at an F no higher than one
    plain EM iteration from its start reaches, and EM never increases F; so F over the calls never increases.
    Accelerated from σ² = 1 (as if past PLAIN_ITER), where extrapolations overshoot and are refused."""
    u, y, kernel, o = _problem()
    st = EMState(u=u, kernel=kernel, coef=np.zeros_like(u), s2=1.0, w=0.6, it=PLAIN_ITER)
    f = [objective(st, y, lam=o["lam"], volume=o["volume"])]
    for _ in range(15):
        one = EMState(u=u, kernel=kernel, coef=st.coef.copy(), s2=st.s2, w=0.6)
        run_em(one, y, max_iter=1, tol=0.0, accelerate=False, **o)
        run_em(st, y, max_iter=3, tol=0.0, **o)
        f.append(objective(st, y, lam=o["lam"], volume=o["volume"]))
        assert f[-1] <= objective(one, y, lam=o["lam"], volume=o["volume"]) + 1e-9 * abs(f[-1])
    assert np.all(np.diff(f) <= 1e-9 * np.abs(f[:-1]))
    assert st.it == PLAIN_ITER + 45


def test_the_start_sigma2_is_the_mean_squared_distance_over_the_dimension(sets):
    theta, y = sets
    u = 2.0 * theta + [0.3, -1.2]  # off-centre: the cross term counts
    dense = np.mean(np.sum((y[None, :, :] - u[:, None, :]) ** 2, axis=2)) / 2
    assert initial_sigma2(u, y) == pytest.approx(dense, rel=1e-13)
    assert initial_sigma2(y, y) == pytest.approx(np.mean(np.sum((y[None] - y[:, None]) ** 2, axis=2)) / 2, rel=1e-13)


def test_a_truncated_kernel_keeps_the_eigenpairs_above_rtol_of_the_largest():
    rng = np.random.default_rng(6)
    q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    top = 0.2  # below 1: the threshold is rtol times the largest eigenvalue, not rtol
    at = 1e-3 * top  # exactly the threshold: dropped (strictly above is kept)
    ev = np.array([1e-9, 1e-6, at, 5e-4, 0.05, top])
    k = Kernel(q=q, ev=ev)
    t = k.truncated(1e-3)
    np.testing.assert_array_equal(t.ev, ev[3:])
    np.testing.assert_array_equal(t.q, q[:, 3:])
    assert t.q.flags.c_contiguous
    # coefficients in its range give the same G W under the full kernel (its eigenvectors a subset)
    coef = rng.normal(size=(6, 2))
    np.testing.assert_allclose(k.apply(t.in_range(coef)), t.apply(coef), rtol=1e-12, atol=1e-15)
    # nothing to drop, no eigenpair at all, or a dense kernel: the kernel itself
    assert k.truncated(1e-12) is k
    empty = Kernel(q=np.zeros((3, 0)), ev=np.zeros(0))
    assert empty.truncated(1e-3) is empty
    dense = Kernel(full=np.eye(4))
    assert dense.truncated(1e-3) is dense
