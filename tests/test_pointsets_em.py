"""σ² from the data: equal-weight EM on points sampled from a known mixture, and the leave-one-out
σ² of one component per point (first-order condition, scale equivariance, bootstrap spread)."""

import warnings

import numpy as np
import pytest

import shapelib as sl
from shapelib.pointsets import fit_mixture
from shapelib.pointsets import em as em_module
from shapelib.pointsets.em import EMWarning, _loglik, _loo_terms, _sq

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions
#: go through a trampoline, one stack frame more than a user's call
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(em_module))

CENTRES = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0], [3.0, 3.0]])


def sample(seed, n=800, s2=0.2, d=2):
    rng = np.random.default_rng(seed)
    c = CENTRES if d == 2 else np.column_stack([CENTRES, np.arange(4.0)])
    return c[rng.integers(len(c), size=n)] + rng.normal(scale=np.sqrt(s2), size=(n, d)), c


@pytest.mark.parametrize("d", [2, 3])
def test_em_recovers_sigma2_within_its_standard_error_and_the_means(d):
    z = []
    for seed in range(12):
        x, c = sample(seed, d=d)
        fit = fit_mixture(x, n_components=4, seed=seed)
        assert fit.converged and fit.stop_reason == "tolerance" and fit.method == "em"
        z.append((fit.sigma2 - 0.2) / fit.standard_error)
        found = fit.means[np.argsort(fit.means[:, :2] @ [1.0, 10.0])]
        truth = c[np.argsort(c[:, :2] @ [1.0, 10.0])]
        assert np.abs(found - truth).max() < 0.15  # 4.7 standard errors of a mean of 200 points
    z = np.array(z)
    # standardised errors: no bias and the spread the standard error claims (12 draws)
    assert abs(z.mean()) < 1.0 and 0.5 < z.std() < 1.6 and np.abs(z).max() < 3.5


def test_em_increases_the_likelihood_and_reports_it():
    x, _ = sample(1)
    fit = fit_mixture(x, n_components=4)
    assert fit.log_likelihood == pytest.approx(_loglik(x, fit.means, fit.sigma2)[0], rel=1e-12)
    for eps in (1e-3, -1e-3):  # a maximum in σ² and in the means
        assert _loglik(x, fit.means, fit.sigma2 * (1 + eps))[0] < fit.log_likelihood
        assert _loglik(x, fit.means + eps, fit.sigma2)[0] < fit.log_likelihood
    assert fit.lower < fit.sigma2 < fit.upper
    assert "EM, 4 equal-weight components" in fit.summary()


def test_leave_one_out_sigma2_is_a_maximum_scales_with_the_points_and_its_se_matches_the_bootstrap():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(120, 2))
    fit = fit_mixture(x)
    assert fit.method == "leave_one_out" and fit.converged
    ll = lambda s2: _dense_loo_loglik(x, np.log(s2))
    assert ll(fit.sigma2) > max(ll(fit.sigma2 * 1.01), ll(fit.sigma2 / 1.01))
    assert fit_mixture(2.5 * x).sigma2 == pytest.approx(6.25 * fit.sigma2, rel=1e-6)
    boot = [fit_mixture(x[rng.integers(120, size=120)] + 1e-9 * rng.normal(size=(120, 2))).sigma2 for _ in range(40)]
    assert 0.5 < np.std(boot) / fit.standard_error < 2.0


def _dense_loo_loglik(x, t):
    """ℓ_LOO at σ² = exp(t) from every Gaussian density (scipy), the diagonal left out."""
    from scipy.stats import multivariate_normal

    n, d = x.shape
    dens = np.array([multivariate_normal(mean=xj, cov=np.exp(t) * np.eye(d)).pdf(x) for xj in x])
    np.fill_diagonal(dens, 0.0)
    return float(np.sum(np.log(dens.sum(axis=0) / (n - 1))))


@pytest.mark.parametrize("d", [2, 3])
def test_leave_one_out_terms_are_the_likelihood_and_its_derivatives_in_log_sigma2(d):
    """The one-pass terms of the leave-one-out fit against a dense computation of ℓ_LOO and its
    central differences in t = log σ²."""
    rng = np.random.default_rng(11)
    x = rng.normal(size=(40, d))
    ell = lambda t: _dense_loo_loglik(x, t)  # noqa: E731
    t, h = np.log(0.3), 1e-4
    ll, r, s, hess = _loo_terms(_sq(x, x), np.exp(t), d)
    assert ll == pytest.approx(ell(t), rel=1e-12)
    assert s.sum() == pytest.approx((ell(t + h) - ell(t - h)) / (2 * h), rel=1e-6)
    assert hess == pytest.approx((ell(t + h) - 2 * ell(t) + ell(t - h)) / h ** 2, rel=1e-4)
    np.testing.assert_allclose(r.sum(axis=1), 1.0, rtol=1e-14)
    assert np.all(np.diag(r) == 0.0)


def test_leave_one_out_sigma2_is_stationary_and_scale_equivariant_over_six_decades():
    """σ̂² of c·x is c²σ̂² of x, and at σ̂² the score in log σ² vanishes (Newton converges
    quadratically: the stopping test leaves a relative error far below its tolerance)."""
    rng = np.random.default_rng(12)
    x = rng.normal(size=(60, 2))
    base = fit_mixture(x).sigma2
    for c in (1e-3, 1.0, 1e3):
        fit = fit_mixture(c * x)
        assert fit.converged and fit.sigma2 == pytest.approx(c * c * base, rel=1e-9)
        _, _, s, hess = _loo_terms(_sq(c * x, c * x), fit.sigma2, 2)
        assert hess < 0 and abs(s.sum() / hess) < 1e-8  # the Newton step left, in log σ²


@pytest.mark.parametrize("case", ["normal", "two_clusters_and_a_far_point", "curve"])
def test_leave_one_out_newton_reaches_the_dense_maximum_in_a_few_iterations(case):
    """σ̂² against a bounded scalar search of the dense ℓ_LOO (scipy) in log σ², and Newton's
    quadratic convergence: a handful of iterations to tol = 1e-10 (the EM fixed point alone, the
    safeguard, converges linearly and needs far more). On the two clusters with a far point the first
    Newton step overshoots and the safeguard's EM step is taken."""
    from scipy.optimize import minimize_scalar

    rng = np.random.default_rng(1)
    base = rng.normal(size=(50, 2))
    x = {"normal": base,
         "two_clusters_and_a_far_point": np.vstack([0.01 * base, 0.01 * base + [5.0, 0.0], [[300.0, 300.0]]]),
         "curve": np.column_stack([np.arange(30.0), np.sin(np.arange(30.0))])}[case]
    fit = fit_mixture(x)
    t0 = np.log(fit.sigma2)
    best = minimize_scalar(lambda t: -_dense_loo_loglik(x, t), bounds=(t0 - 1.0, t0 + 1.0), method="bounded",
                           options={"xatol": 1e-9})
    assert fit.converged and fit.n_iter <= 8
    assert fit.sigma2 == pytest.approx(np.exp(best.x), rel=1e-6)
    assert fit.log_likelihood == pytest.approx(_dense_loo_loglik(x, t0), rel=1e-12)


def test_leave_one_out_max_iter_is_the_iteration_budget():
    rng = np.random.default_rng(13)
    x = rng.normal(size=(50, 2))
    n_iter = fit_mixture(x).n_iter
    assert n_iter >= 2
    done = fit_mixture(x, max_iter=n_iter)
    assert done.converged and done.n_iter == n_iter and done.stop_reason == "tolerance"
    with pytest.warns(EMWarning, match=f"after {n_iter - 1} iterations") as rec:
        short = fit_mixture(x, max_iter=n_iter - 1)
    if not UNDER_MUTMUT:  # mutmut's trampoline adds a frame of its own
        assert rec[0].filename == __file__  # the warning points at the caller's line
    assert not short.converged and short.n_iter == n_iter - 1 and short.stop_reason == "max_iter"


def test_leave_one_out_of_far_apart_pairs_has_its_closed_form():
    """Pairs of points, the pairs 100 apart: each point's leave-one-out density is its mate's
    Gaussian alone, ℓ_i = −δ_i²/(2σ²) − log(2πσ²) − log(n − 1) in 2-D with δ_i the pair's gap. So
    σ̂² = mean(δ_i²)/2 and, in t = log σ², the score s_i = δ_i²/(2σ²) − 1, the curvature −n and
    the sandwich standard error σ̂² √(Σ s_i²)/n (the curvature alone would say σ̂²/√n)."""
    gaps = np.array([0.05, 0.1, 0.2, 0.5, 1.0, 1.5, 2.0])
    centres = 100.0 * np.column_stack([np.arange(7.0), np.arange(7.0) % 2])
    x = np.concatenate([centres, centres + gaps[:, None] * [0.6, 0.8]])
    delta2 = np.tile(gaps ** 2, 2)
    n = len(x)
    fit = fit_mixture(x, tol=1e-13)
    s2 = np.mean(delta2) / 2
    assert fit.sigma2 == pytest.approx(s2, rel=1e-9)
    ll = np.sum(-delta2 / (2 * s2) - np.log(2 * np.pi * s2) - np.log(n - 1))
    assert fit.log_likelihood == pytest.approx(ll, rel=1e-9)
    score = delta2 / (2 * s2) - 1
    assert fit.standard_error == pytest.approx(s2 * np.sqrt(np.sum(score ** 2)) / n, rel=1e-6)
    assert abs(fit.standard_error - s2 / np.sqrt(n)) > 0.2 * fit.standard_error  # the two differ here


def test_leave_one_out_likelihood_and_sandwich_error_against_scipy_densities():
    """On a small irregular set: ℓ_LOO summed from scipy's Gaussian densities; its maximiser found
    by scipy; the sandwich error from finite differences of the per-point terms in log σ²."""
    from scipy.optimize import minimize_scalar
    from scipy.stats import multivariate_normal

    rng = np.random.default_rng(1)
    c = rng.uniform(0, 20, size=(6, 2))
    x = np.concatenate([c, c + np.array([0.05, 0.1, 0.2, 1.0, 1.5, 2.0])[:, None] * [1.0, 0.0]])
    n, d = x.shape

    def per_point(t):  # ℓ_i at σ² = e^t (the density is symmetric in x_i and x_j)
        return np.array([np.log(np.mean(multivariate_normal.pdf(np.delete(x, i, axis=0), mean=x[i],
                                                                cov=np.exp(t) * np.eye(d)))) for i in range(n)])

    fit = fit_mixture(x, tol=1e-13)
    t = np.log(fit.sigma2)
    assert fit.log_likelihood == pytest.approx(per_point(t).sum(), rel=1e-10)
    best = minimize_scalar(lambda u: -per_point(u).sum(), bracket=(t - 1, t + 1), tol=1e-10)
    assert fit.sigma2 == pytest.approx(np.exp(best.x), rel=1e-6)
    h = 1e-4
    score = (per_point(t + h) - per_point(t - h)) / (2 * h)
    curvature = (per_point(t + 10 * h).sum() - 2 * per_point(t).sum() + per_point(t - 10 * h).sum()) / (10 * h) ** 2
    assert fit.standard_error == pytest.approx(fit.sigma2 * np.sqrt(np.sum(score ** 2)) / abs(curvature), rel=1e-5)
    assert fit.standard_error > 1.2 * fit.sigma2 / np.sqrt(abs(curvature))  # not the curvature-only error


def test_em_rejects_bad_input():
    with pytest.raises(ValueError, match="n_components must be at most the number of points 5"):
        fit_mixture(np.arange(10.0).reshape(5, 2) ** 2, n_components=6)
    with pytest.raises(sl.InputError, match="points: point 1 repeats point 0"):
        fit_mixture([[0, 0], [0, 0], [1, 1]])


def _three_clusters(n=90, seed=0):
    rng = np.random.default_rng(seed)
    centres = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]])
    return centres[np.arange(n) % 3] + rng.normal(scale=0.4, size=(n, 2))


@pytest.mark.parametrize("n_components", [3, None])
def test_a_fit_cut_short_says_so_warns_at_the_caller_and_has_no_error_bar(n_components):
    """One iteration is not convergence: stop reason max_iter, converged False, one iteration, an
    EMWarning at the caller's line (not with warn=False); the EM fit then has no standard error."""
    x = _three_clusters()
    with pytest.warns(EMWarning, match=r"^fit_mixture: EM stopped without converging \(max_iter\) after 1 iterations$") \
            as caught:
        fit = fit_mixture(x, n_components=n_components, max_iter=1)
    assert not caught[0].filename.endswith(("/em.py", "\\em.py"))  # the caller's line, not fit_mixture's
    assert (fit.converged, fit.stop_reason, fit.n_iter) == (False, "max_iter", 1)
    if n_components is not None:
        assert np.isnan(fit.standard_error)
    assert fit.summary().endswith("; 1 iterations; NOT converged (max_iter)")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quiet = fit_mixture(x, n_components=n_components, max_iter=1, warn=False)
        done = fit_mixture(x, n_components=n_components)
    assert quiet.sigma2 == fit.sigma2
    assert done.converged and done.stop_reason == "tolerance" and 1 < done.n_iter < 2000
    assert done.summary().endswith(f"; {done.n_iter} iterations; converged (tolerance)")


def test_summaries_name_the_method_and_the_interval():
    """σ² ± se, the 95 % interval σ² exp(∓1.96 se/σ²), the method, the likelihood."""
    x = _three_clusters()
    em = fit_mixture(x, n_components=3)
    lo, hi = em.sigma2 * np.exp(-1.96 * em.standard_error / em.sigma2), em.sigma2 * np.exp(1.96 * em.standard_error / em.sigma2)
    assert em.summary().split("\n")[0] == (f"sigma2 = {em.sigma2:.6g} +/- {em.standard_error:.3g} (95% {lo:.4g} .. "
                                           f"{hi:.4g}); EM, 3 equal-weight components")
    assert em.summary().split("\n")[1].startswith(f"log-likelihood {em.log_likelihood:.6g}; ")
    loo = fit_mixture(x)
    assert loo.summary().split("\n")[0].endswith("; leave-one-out likelihood, one component per point")
    assert loo.method == "leave_one_out" and em.method == "em" and loo.n_components == len(x)


def test_fit_mixture_names_each_bad_option():
    x = _three_clusters(9)
    for kw, name in [({"tol": -1.0}, "tol"), ({"max_iter": 0}, "max_iter"), ({"n_components": 0}, "n_components"),
                     ({"n_components": 2, "n_init": 0}, "n_init")]:
        with pytest.raises(ValueError, match=rf"^{name}\b"):
            fit_mixture(x, **kw)
    with pytest.raises(ValueError, match=r"^n_components must be at most the number of points 9; got 10$"):
        fit_mixture(x, n_components=10)
    with pytest.raises(ValueError, match=r"^points\b"):
        fit_mixture(np.zeros(3))
    assert fit_mixture(x, n_components=9).method == "leave_one_out"  # one component per point


@pytest.mark.parametrize("n_components, s2", [(None, 1e-18), (6, 2.5e-19)])
def test_pairs_a_hair_apart_are_degenerate_with_their_closed_form(n_components, s2):
    """Six pairs of points δ = (1e-9, 1e-9) apart among points spread ~1: one component per point puts
    each point's partner at |δ|² = 2e-18 (σ² = |δ|²/d), one per pair sits at its midpoint (|δ/2|²/d);
    both are far below 1e-14 of the spread, so the fit stops as degenerate, not converged."""
    x = np.repeat(np.random.default_rng(0).normal(size=(6, 2)), 2, axis=0)
    x[1::2] += 1e-9
    with pytest.warns(EMWarning, match=r"\(degenerate\) after 1 iterations"):
        fit = fit_mixture(x, n_components=n_components)
    assert (fit.stop_reason, fit.converged, fit.n_iter) == ("degenerate", False, 1)
    assert fit.sigma2 == pytest.approx(s2, rel=1e-6, abs=0)  # abs=0: approx would accept any value within 1e-12


def test_em_likelihood_and_standard_error_of_far_apart_clusters():
    """Three clusters 100 σ apart: the reported log-likelihood is Σ log((1/3) Σ_j N(x_i; μ_j, σ²I)) by
    scipy's normal densities, and the observed-information error of σ² is that of one Gaussian,
    σ² √(2/(n d)) (the means' block decouples; the overlap of the clusters is e⁻¹²⁵⁰)."""
    from scipy.special import logsumexp
    from scipy.stats import multivariate_normal

    rng = np.random.default_rng(5)
    centres = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0]])
    x = centres[np.arange(300) % 3] + rng.normal(size=(300, 2))
    fit = fit_mixture(x, n_components=3)
    dens = np.stack([multivariate_normal(m, fit.sigma2 * np.eye(2)).logpdf(x) for m in fit.means], axis=1)
    assert fit.log_likelihood == pytest.approx(float(np.sum(logsumexp(dens, axis=1) - np.log(3))), rel=1e-10)
    assert fit.standard_error == pytest.approx(fit.sigma2 * np.sqrt(2 / (300 * 2)), rel=1e-4)


def test_em_standard_error_of_overlapping_clusters_is_the_inverse_hessian_of_the_likelihood():
    """Clusters that overlap (centres 1.5 apart, σ ≈ 0.7) couple the means with σ² in the information:
    the standard error is √((−∇²ℓ)⁻¹) in (μ, log σ²) for log σ², times σ², here with the Hessian from
    second differences of ℓ itself (not of the analytic score the fit differentiates)."""
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 0.0], [1.5, 0.0], [0.0, 1.5]])
    x = centres[np.arange(90) % 3] + rng.normal(scale=0.7, size=(90, 2))
    fit = fit_mixture(x, n_components=3, n_init=1)
    k, d = fit.means.shape
    theta = np.concatenate([fit.means.ravel(), [np.log(fit.sigma2)]])
    ell = lambda t: _loglik(x, t[:-1].reshape(k, d), np.exp(t[-1]))[0]  # noqa: E731
    m, h = len(theta), 1e-4
    hess = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            ei, ej = h * np.eye(m)[i], h * np.eye(m)[j]
            hess[i, j] = (ell(theta + ei + ej) - ell(theta + ei - ej) - ell(theta - ei + ej)
                          + ell(theta - ei - ej)) / (4 * h * h)
    assert fit.standard_error == pytest.approx(fit.sigma2 * np.sqrt(np.linalg.inv(-hess)[-1, -1]), rel=1e-5)


def test_em_standard_error_is_nan_when_a_component_holds_no_point():
    """A fourth mean 10⁶ away takes no responsibility: the likelihood does not depend on it, the
    information is singular and σ² has no error bar (NaN, not an exception)."""
    x = _three_clusters()
    fit = fit_mixture(x, n_components=3)
    assert np.isfinite(fit.standard_error)
    assert np.isnan(em_module._em_standard_error(x, np.vstack([fit.means, [[1e6, 1e6]]]), fit.sigma2))


def test_em_max_iter_is_the_iteration_budget():
    """With one restart, as many iterations as the converged fit took suffice and one fewer does not;
    the short fit reports exactly its budget."""
    x = _three_clusters()
    n_iter = fit_mixture(x, n_components=3, n_init=1).n_iter
    assert n_iter >= 3
    done = fit_mixture(x, n_components=3, n_init=1, max_iter=n_iter)
    assert done.converged and done.n_iter == n_iter and done.stop_reason == "tolerance"
    short = fit_mixture(x, n_components=3, n_init=1, max_iter=n_iter - 1, warn=False)
    assert not short.converged and short.n_iter == n_iter - 1 and short.stop_reason == "max_iter"


def test_leave_one_out_degenerate_pairs_report_their_closed_form_likelihood_and_error():
    """Six pairs a hair (δ = (1e-9, 1e-9)) apart: at the degenerate σ² = |δ|²/2 each point's leave-one-out
    density is its partner's Gaussian alone, ℓ_i = −|δ|²/(2σ²) − log(2πσ²) − log(n − 1) = −1 − log(2πσ²)
    − log 11, and each score s_i = |δ|²/(2σ²) − 1 vanishes, so the sandwich error is 0 (to the fit's tolerance)."""
    x = np.repeat(np.random.default_rng(0).normal(size=(6, 2)), 2, axis=0)
    x[1::2] += 1e-9
    fit = fit_mixture(x, warn=False)
    assert fit.stop_reason == "degenerate"
    s2 = fit.sigma2
    assert fit.log_likelihood == pytest.approx(12 * (-np.sum((x[1] - x[0]) ** 2) / (2 * s2) - np.log(2 * np.pi * s2)
                                                     - np.log(11)), rel=1e-6)
    assert fit.standard_error <= 1e-4 * s2
