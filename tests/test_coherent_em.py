"""The registration EM's compiled pieces against dense, independent computations."""

import numpy as np
import pytest

from shapelib.pointsets._coherent_em import (EMState, Kernel, _estep, _exp_neg, outlier_term, posteriors, run_em,
                                             sq_dist)


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
    _exp_neg(a, out, np.empty(a.size, dtype=np.int64))
    ref = np.exp(-a)
    assert np.max(np.abs(out - ref) / np.spacing(ref)) <= 1.0
    assert out[a == 0.0][0] == 1.0


@pytest.mark.parametrize("s2", [2.0, 0.05, 1e-3, 1e-5])
@pytest.mark.parametrize("w", [0.0, 0.2])
def test_the_estep_sums_equal_the_dense_posteriors(sets, s2, w):
    theta, y = sets
    volume = 36.0
    p = posteriors(theta, y, s2, w, volume)  # the (n, m) matrix, exponentials of every pair
    p1, pt1, py, sse = _estep(theta, y, s2, outlier_term(len(theta), 2, s2, w, volume))
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
    p1, pt1, py, sse = _estep(theta, y, s2, c)
    np.testing.assert_allclose(p1, p.sum(axis=1), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(pt1, p.sum(axis=0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(py, p @ y, rtol=1e-12, atol=1e-14)
    assert sse == pytest.approx(float(np.sum(p * sq_dist(theta, y))), rel=1e-12, abs=1e-14)


def test_a_point_far_from_every_mean_takes_no_posterior_without_an_outlier_term(sets):
    theta, _ = sets
    y = np.array([[1e3, 1e3], theta[0]])
    p1, pt1, _, _ = _estep(theta, y, 1e-2, 0.0)
    assert pt1[0] == 0.0 and pt1[1] == pytest.approx(1.0)
    assert p1.sum() == pytest.approx(1.0)


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
