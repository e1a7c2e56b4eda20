"""σ² (and the means of a compact mixture) estimated from the points by maximum likelihood.

The mixture of eq. (5), equal weights and one isotropic σ² shared by the K components,

    p(x | μ, σ²) = (1/K) Σ_k N(x; μ_k, σ² I),     ℓ(μ, σ²) = Σ_i log p(x_i | μ, σ²).

``K < n`` components: EM. With responsibilities ``r_ik = N(x_i; μ_k, σ²I) / Σ_l N(x_i; μ_l, σ²I)``
(E-step), the M-step is ``μ_k = Σ_i r_ik x_i / Σ_i r_ik`` and ``σ² = Σ_ik r_ik |x_i − μ_k|² / (n d)``
(equal weights stay equal; they do not enter either update). Each iteration increases ℓ;
the fit starts from k-means++ seeds (several restarts, best ℓ kept).

One component per point (``K = n``, the landmark representation): the maximum-likelihood σ² is
degenerate. Each point is the mean of its own component, so ``ℓ(σ²) ≥ Σ_i log N(x_i; x_i, σ²I) / n
= −(n d / 2) log(2πσ²) − n log n → +∞`` as ``σ² → 0``: the likelihood is unbounded and its
"maximum" is σ² = 0. The leave-one-out likelihood removes each point's own component,

    ℓ_LOO(σ²) = Σ_i log [ (1/(n−1)) Σ_{j≠i} N(x_i; x_j, σ²I) ],

which is bounded and has an interior maximum (the likelihood cross-validation bandwidth of a
kernel density estimate). It is maximised by Newton steps in log σ² (analytic first and second
derivatives), falling back on the EM fixed point with ``r_ii = 0``,
``σ² = Σ_i Σ_{j≠i} r_ij |x_i − x_j|² / (n d)``, wherever a Newton step would not increase it.

Standard errors. EM (``K < n``): the observed information ``−∇²ℓ`` in ``(μ, log σ²)`` at the
maximum (central differences of the analytic score), inverted, by the delta method for σ².
Leave-one-out: ``ℓ_LOO`` is not a likelihood, so its curvature alone understates the spread; the
sandwich ``Var(log σ²) = Σ_i s_i² / (ℓ_LOO'')²`` with ``s_i`` the per-point scores is reported.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from .._validate import check_positive, check_positive_int
from .checks import as_point_set

__all__ = ["fit_mixture", "MixtureFit", "EMWarning"]


class EMWarning(RuntimeWarning):
    """EM stopped before meeting its tolerance.

    A :class:`RuntimeWarning`: :func:`fit_mixture` still returns the last estimate, with
    ``converged`` false and ``stop_reason`` ``"max_iter"``.

    Parameters
    ----------
    *args : str
        The message, as for any warning (:func:`warnings.warn` passes its text when given this
        category).

    See Also
    --------
    fit_mixture : What warns (``warn=False`` silences it).

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from shapelib.pointsets import fit_mixture, EMWarning
    >>> rng = np.random.default_rng(0)
    >>> x = np.concatenate([rng.normal(size=(20, 2)), rng.normal(size=(20, 2)) + 4])
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     fit = fit_mixture(x, n_components=2, max_iter=1)
    >>> fit.converged, fit.stop_reason, any(issubclass(w.category, EMWarning) for w in caught)
    (False, 'max_iter', True)
    """


@dataclass
class MixtureFit:
    """A mixture fitted by :func:`fit_mixture`.

    Attributes
    ----------
    means : ndarray, shape (K, d)
        Component means (the points themselves for ``method="leave_one_out"``).
    sigma2 : float
        The estimate of σ² (also ``value``).
    standard_error : float
        Its standard error (module docstring); ``lower``, ``upper``: a 95 % interval, symmetric
        in log σ².
    log_likelihood : float
        ℓ (EM) or ℓ_LOO (leave-one-out) at the estimate.
    n_iter, converged, stop_reason
        EM iterations, and why it stopped: ``"tolerance"`` (converged), ``"max_iter"``,
        ``"degenerate"`` (σ² collapsed onto coincident points; not converged).
    method : {"em", "leave_one_out"}

    See Also
    --------
    fit_mixture : The fit.
    shapelib.pointsets.registration.register : σ² and outliers by EM during registration.

    Notes
    -----
    σ² is the shared variance of the mixture of eq. (5) of [1]_; with ``K < n`` components it is estimated by
    EM [2]_.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] A. P. Dempster, N. M. Laird and D. B. Rubin, "Maximum likelihood from incomplete data via the EM
       algorithm", *Journal of the Royal Statistical Society, Series B* 39(1), 1–38, 1977.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.pointsets import fit_mixture
    >>> x = np.random.default_rng(1).normal(size=(30, 2))
    >>> fit = fit_mixture(x)  # one component per point: the leave-one-out likelihood
    >>> fit.method, fit.n_components, fit.converged
    ('leave_one_out', 30, True)
    >>> bool(fit.lower < fit.value < fit.upper)
    True
    """

    means: np.ndarray
    sigma2: float
    standard_error: float
    log_likelihood: float
    n_iter: int
    converged: bool
    stop_reason: str
    method: str

    @property
    def value(self) -> float:
        return self.sigma2

    @property
    def lower(self) -> float:
        return float(self.sigma2 * np.exp(-1.96 * self.standard_error / self.sigma2))

    @property
    def upper(self) -> float:
        return float(self.sigma2 * np.exp(1.96 * self.standard_error / self.sigma2))

    @property
    def n_components(self) -> int:
        return len(self.means)

    def summary(self) -> str:
        how = "leave-one-out likelihood, one component per point" if self.method == "leave_one_out" else \
            f"EM, {self.n_components} equal-weight components"
        return (f"sigma2 = {self.sigma2:.6g} +/- {self.standard_error:.3g} (95% {self.lower:.4g} .. {self.upper:.4g}); "
                f"{how}\nlog-likelihood {self.log_likelihood:.6g}; {self.n_iter} iterations; "
                f"{'converged' if self.converged else 'NOT converged'} ({self.stop_reason})")


def _sq(x, y):
    d = x[:, None, :] - y[None, :, :]
    return np.einsum("ikd,ikd->ik", d, d)


def _loglik(x, mu, s2):
    """ℓ of the equal-weight mixture, responsibilities (n, K) and the squared distances."""
    n, d = x.shape
    sq = _sq(x, mu)
    logn = -sq / (2 * s2) - 0.5 * d * np.log(2 * np.pi * s2)
    lse = logsumexp(logn, axis=1)
    return float(lse.sum() - n * np.log(len(mu))), np.exp(logn - lse[:, None]), sq


def _kmeanspp(x, k, rng):
    idx = [int(rng.integers(len(x)))]
    d2 = _sq(x, x[idx]).min(axis=1)
    for _ in range(1, k):
        p = d2 / d2.sum() if d2.sum() > 0 else None
        idx.append(int(rng.choice(len(x), p=p)))
        d2 = np.minimum(d2, _sq(x, x[idx[-1:]])[:, 0])
    return x[idx].copy()


def _em(x, mu, s2, tol, max_iter, floor):
    n, d = x.shape
    ll, r, sq = _loglik(x, mu, s2)
    for it in range(1, max_iter + 1):
        nk = r.sum(axis=0)
        ok = nk > 1e-300
        mu = mu.copy()
        mu[ok] = (r[:, ok].T @ x) / nk[ok, None]
        s2 = float(np.sum(r * _sq(x, mu)) / (n * d))
        if s2 <= floor:
            return mu, s2, ll, it, False, "degenerate"
        new, r, sq = _loglik(x, mu, s2)
        if abs(new - ll) <= tol * abs(new):
            return mu, s2, new, it, True, "tolerance"
        ll = new
    return mu, s2, ll, max_iter, False, "max_iter"


def _score(x, theta, k):
    """Analytic score of ℓ w.r.t. (μ (K d), log σ²)."""
    n, d = x.shape
    mu, s2 = theta[:-1].reshape(k, d), np.exp(theta[-1])
    _, r, sq = _loglik(x, mu, s2)
    gmu = (r.T @ x - r.sum(axis=0)[:, None] * mu) / s2
    gls = float(np.sum(r * (sq / (2 * s2) - d / 2)))
    return np.concatenate([gmu.ravel(), [gls]])


def _em_standard_error(x, mu, s2):
    k, d = mu.shape
    theta = np.concatenate([mu.ravel(), [np.log(s2)]])
    h = 1e-5 * np.maximum(1.0, np.abs(theta))
    info = np.empty((len(theta), len(theta)))
    for j in range(len(theta)):
        e = np.zeros_like(theta)
        e[j] = h[j]
        info[:, j] = -(_score(x, theta + e, k) - _score(x, theta - e, k)) / (2 * h[j])
    info = 0.5 * (info + info.T)
    try:
        var_log = float(np.linalg.inv(info)[-1, -1])
    except np.linalg.LinAlgError:
        return float("nan")
    return float(s2 * np.sqrt(max(var_log, 0.0)))


def _loo_terms(sq, s2, d):
    """Everything the leave-one-out fit needs at σ², in one pass over the (n, n) squared distances
    ``sq`` (zero diagonal): ``(ℓ_LOO, r, s, h)`` with the responsibilities ``r_ij ∝ N(x_i; x_j, σ²I)``
    (``j ≠ i``), the per-point scores in log σ², ``s_i = Σ_j r_ij a_ij − d/2`` with
    ``a_ij = |x_i − x_j|²/2σ²`` (``∂ log N_ij / ∂ log σ² = a_ij − d/2``), and ℓ_LOO's second
    derivative in log σ², ``h = Σ_i [Var_r(a)_i − E_r(a)_i]``. Each row's sum is scaled by its
    largest term (log-sum-exp)."""
    n = len(sq)
    a = sq / (2 * s2)
    np.fill_diagonal(a, np.inf)  # j = i left out
    amin = a.min(axis=1)
    e = np.exp(amin[:, None] - a)
    tot = e.sum(axis=1)
    r = e / tot[:, None]
    np.fill_diagonal(a, 0.0)
    ra = r * a
    ea = ra.sum(axis=1)
    hess = float(np.sum(np.sum(ra * a, axis=1) - ea ** 2 - ea))
    ll = float(np.sum(np.log(tot) - amin) - n * (0.5 * d * np.log(2 * np.pi * s2) + np.log(n - 1)))
    return ll, r, ea - d / 2, hess


def _loo_em_step(r, sq, d):
    """EM's update of σ² for ℓ_LOO, ``σ² = Σ_ij r_ij |x_i − x_j|² / (n d)``, from the responsibilities
    ``r`` at the current σ² and the squared distances ``sq``: it never decreases ℓ_LOO."""
    return float(np.sum(r * sq) / (len(r) * d))


def _loo(x, tol, max_iter, floor):
    """Maximise ℓ_LOO over log σ²: Newton steps where ℓ_LOO is concave there, the EM fixed point
    (which never decreases ℓ_LOO) otherwise. Returns σ², ℓ_LOO, the scores and the second derivative
    at σ², the iterations, whether it converged and why it stopped."""
    n, d = x.shape
    sq = _sq(x, x)
    np.fill_diagonal(sq, np.inf)
    s2 = float(np.mean(sq.min(axis=1)) / d)  # nearest-neighbour start
    np.fill_diagonal(sq, 0.0)
    ll, r, si, hess = _loo_terms(sq, s2, d)
    for it in range(1, max_iter + 1):
        g = float(si.sum())
        if hess < 0:
            step = -g / hess
            s2_new = s2 * float(np.exp(np.clip(step, -2.0, 2.0)))
        else:
            s2_new = _loo_em_step(r, sq, d)
        new = _loo_terms(sq, s2_new, d)
        if new[0] < ll:  # Newton overshot: the EM step instead
            s2_new = _loo_em_step(r, sq, d)
            new = _loo_terms(sq, s2_new, d)
        if s2_new <= floor:
            return s2_new, new[0], new[2], new[3], it, False, "degenerate"
        done = abs(s2_new - s2) <= tol * s2
        s2 = s2_new
        ll, r, si, hess = new
        if done:
            return s2, ll, si, hess, it, True, "tolerance"
    return s2, ll, si, hess, max_iter, False, "max_iter"


def fit_mixture(points, *, n_components: int | None = None, tol: float = 1e-10, max_iter: int = 2000,
                n_init: int = 3, seed: int = 0, warn: bool = True) -> MixtureFit:
    """Estimate σ² of eq. (5) (and, for ``K < n`` components, their means) from a point set.

    ``n_components`` None (one component per point): σ² maximising the leave-one-out likelihood
    ``ℓ_LOO(σ²) = Σ_i log[(1/(n−1)) Σ_{j≠i} N(x_i; x_j, σ²I)]`` (the plain likelihood is
    unbounded, module docstring). ``K < n``: equal-weight EM for ``(μ_1..μ_K, σ²)`` maximising
    ``ℓ = Σ_i log[(1/K) Σ_k N(x_i; μ_k, σ²I)]``.

    Parameters
    ----------
    points : array_like, shape (n, d)
        The point set (d = 2 or 3).
    n_components : int, optional
        K, at most n. Default: one component per point (leave-one-out).
    tol : float
        EM stops when ℓ (``K < n``) or σ² (leave-one-out) changes by less than ``tol`` (relative).
    max_iter : int
        EM iterations (per restart).
    n_init : int
        k-means++ restarts for ``K < n`` (the best ℓ is kept).
    seed : int
        Seed of the k-means++ starts.
    warn : bool
        Warn (:class:`EMWarning`) when EM stops without converging.

    Returns
    -------
    MixtureFit
        ``sigma2`` (= ``value``), ``standard_error``, ``lower``/``upper``, ``means``,
        ``log_likelihood``, ``n_iter``, ``converged``, ``stop_reason``, ``summary()``.

    See Also
    --------
    shapelib.geometry.sigma2.scatter_sigma2 : σ² of landmark shapes from their scatter.
    shapelib.pointsets.registration.register : Uses σ² estimated by EM with an outlier component.

    Notes
    -----
    The mixture is eq. (5) of [1]_; for ``K < n`` components its means and σ² are maximum-likelihood estimates
    by EM [2]_.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] A. P. Dempster, N. M. Laird and D. B. Rubin, "Maximum likelihood from incomplete data via the EM
       algorithm", *Journal of the Royal Statistical Society, Series B* 39(1), 1–38, 1977.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.pointsets import fit_mixture
    >>> rng = np.random.default_rng(0)
    >>> centres = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]])
    >>> x = centres[rng.integers(3, size=600)] + rng.normal(scale=0.4, size=(600, 2))  # σ² = 0.16
    >>> fit = fit_mixture(x, n_components=3)
    >>> bool(abs(fit.sigma2 - 0.16) < 3 * fit.standard_error), fit.converged
    (True, True)
    """
    x = as_point_set(points, name="points")
    n, d = x.shape
    tol = check_positive(tol, name="tol")
    max_iter = check_positive_int(max_iter, name="max_iter")
    floor = 1e-14 * float(np.mean(np.sum((x - x.mean(0)) ** 2, axis=1)))
    if n_components is None or n_components == n:
        s2, ll, si, hess, it, ok, why = _loo(x, tol, max_iter, floor)
        se = float(s2 * np.sqrt(np.sum(si * si)) / abs(hess)) if hess != 0 else float("nan")
        fit = MixtureFit(x.copy(), s2, se, ll, it, ok, why, "leave_one_out")
    else:
        k = check_positive_int(n_components, name="n_components")
        if k > n:
            raise ValueError(f"n_components must be at most the number of points {n}; got {k}")
        rng = np.random.default_rng(seed)
        best = None
        for _ in range(check_positive_int(n_init, name="n_init")):
            mu = _kmeanspp(x, k, rng)
            s2 = max(float(np.mean(_sq(x, mu).min(axis=1)) / d), 1e3 * floor)
            res = _em(x, mu, s2, tol, max_iter, floor)
            if best is None or res[2] > best[2]:
                best = res
        mu, s2, ll, it, ok, why = best
        se = _em_standard_error(x, mu, s2) if ok else float("nan")
        fit = MixtureFit(mu, s2, se, ll, it, ok, why, "em")
    if warn and not fit.converged:
        warnings.warn(f"fit_mixture: EM stopped without converging ({fit.stop_reason}) after {fit.n_iter} iterations",
                      EMWarning, stacklevel=2)
    return fit
