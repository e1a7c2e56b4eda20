"""Geodesic regression of shapes on a scalar covariate (Fletcher 2013), under the α-order or
Fisher–Rao metric.

The model is a geodesic ``γ(t) = exp_p((t − t_ref) v)`` in shape space, fitted by least squares,

    L(γ) = Σ_i d²(y_i, γ(t_i)),

with Fletcher's coefficient of determination ``R² = 1 − Σ d²(y_i, γ(t_i)) / Σ d²(y_i, ȳ)``
(``ȳ`` the Fréchet mean, :mod:`shapelib.statistics.frechet`).

Parametrisation and gradient
    The geodesic is represented by its points at the ends of the covariate range,
    ``A = γ(t_min)`` and ``B = γ(t_max)``, and computed between them as a discrete geodesic of
    ``path_steps`` segments (:func:`shapelib.solver.minimise.minimise_path`); predictions inside
    the range are read off it (linear between its points), outside it by the exponential map from
    the nearer end. A boundary-value problem needs no ``g⁻¹`` and is as well posed as a distance.
    The loss is the sum of the residual geodesics' energies (the discrete ``d²``). Its gradient in
    ``(A, B)`` is exact for the discrete problem:

    * ``∂L/∂ŷ_i`` is the derivative of the residual path energy at its start (envelope theorem;
      a covector, ≈ ``−2 g(ŷ_i) log_ŷ_i(y_i)``);
    * those covectors are spread onto the regression path's points and carried to its ends
      through the path's optimality (implicit function theorem: one solve with the
      block-tridiagonal Hessian of the path energy, slightly shifted to be positive definite).

    Steps are Levenberg–Marquardt steps on the Gauss–Newton model ``Σ_i ‖ε_i − J_i δ‖²_{g(ŷ_i)}``
    (``J_i`` the Jacobian of ``ŷ_i`` in ``(A, B)``, from the same implicit-function solve), with the
    damping raised until ``L`` decreases; the start is the least-squares line through the landmark
    coordinates (exact in the small-σ limit). The ends move only in the directions whose metric
    eigenvalue exceeds ``step_rcond`` (default 1e-3) of the largest: in the weaker ones the
    Gauss–Newton curvature ``g`` falls far below the loss's true curvature (the residuals are as
    long as the shapes' spread), and steps there were rejected one after another (measured on 24
    ADHD-200 contours: 20 iterations and 162 s without reaching the certificate, against 2
    iterations and 2.3 s). Those directions hold ~2e-4 of the corpus callosum's variance.

Stop
    A first-order certificate like the mean's: the metric norm of the preconditioned gradient at
    either end, relative to ``√(Σ d²(y_i, ŷ_i))·√N`` (for a flat metric: the norm of the residuals'
    weighted sum relative to their spread), below ``tol``; or ``L`` below ``1e-14`` of the
    total sum of squares (noiseless data).
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._validate import (as_shapes, check_dimension, check_nonnegative_int, check_positive, check_positive_int,
                         set_checked)
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING
from ..solver.energy import path_energy
from ..solver.linalg import block_cholesky, block_solve, one_blas_thread
from ..solver.logexp import (DEFAULT_LOG_STEPS, DEFAULT_RCOND, GeodesicOptions, TangentSpace, segment_derivatives,
                             exp_path, tangent_space)
from ..solver.minimise import minimise_path
from ..solver.result import GeodesicWarning
from ._run import where_logs_run
from .frechet import FrechetMeanResult, check_population, frechet_mean, geodesic_options, procrustes_mean
from .population_logs import population_logs, shifted_paths

__all__ = ["GeodesicRegressionResult", "geodesic_regression", "DEFAULT_PATH_STEPS"]

#: segments of the regression geodesic between the ends of the covariate range
DEFAULT_PATH_STEPS = 8
#: the ends of the regression geodesic move in the directions whose metric eigenvalue exceeds this
#: fraction of the largest (see the module docstring)
DEFAULT_STEP_RCOND = 1e-3


@dataclass
class GeodesicRegressionResult:
    """A fitted geodesic ``γ(t)`` and its fit.

    Attributes
    ----------
    path : ndarray (path_steps + 1, K, d)
        The discrete geodesic from ``γ(t_min)`` to ``γ(t_max)``.
    t_range : (float, float)
        ``(t_min, t_max)`` of the data.
    t_ref : float
        Where the intercept is given (default the mean of ``t``).
    intercept : ndarray (K, d)
        ``γ(t_ref)``.
    velocity : ndarray (K, d)
        ``dγ/dt`` at ``t_ref`` (per unit of ``t``); for ``t_ref`` outside ``t_range``, at the nearer
        end of the range (the velocity the exponential map continues the geodesic with).
    fitted : ndarray (N, K, d)
        ``γ(t_i)``.
    residuals : ndarray (N, K, d)
        ``log_{γ(t_i)}(y_i)``.
    residual_energies : ndarray (N,)
        ``d²(y_i, γ(t_i))`` (discrete path energies).
    ss_residual, ss_total : float
        ``Σ d²(y_i, γ(t_i))`` and ``Σ d²(y_i, ȳ)``.
    r2 : float
        Fletcher's ``1 − ss_residual / ss_total``.
    certificate : float
        Relative first-order certificate (module docstring).
    converged : bool
    n_iter : int
    mean : FrechetMeanResult
        The Fréchet mean of the data (``ȳ`` of ``ss_total``).
    log : list of dict
        Per iteration: the certificate, the energies, the step.
    stop_reason : str
        ``"converged"`` or ``"max_iter"`` (a property).

    See Also
    --------
    geodesic_regression : What returns it.

    Examples
    --------
    Ellipses that widen with a covariate lie on a geodesic, which the fit recovers:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> s = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> age = np.linspace(0.0, 1.0, 6)
    >>> x = np.stack([np.c_[(1.5 + 0.5 * a) * np.cos(s), np.sin(s)] for a in age])
    >>> fit = sl.geodesic_regression(x, age, sigma2=0.5, n_jobs=1)
    >>> fit.converged, fit.stop_reason, fit.path.shape, fit.t_range, fit.t_ref
    (True, 'converged', (9, 8, 2), (0.0, 1.0), 0.5)
    >>> fit.fitted.shape, bool(fit.r2 > 0.99), bool(np.isclose(fit.r2, 1 - fit.ss_residual / fit.ss_total))
    ((6, 8, 2), True, True)
    """

    path: np.ndarray
    t_range: tuple
    t_ref: float
    intercept: np.ndarray
    velocity: np.ndarray
    fitted: np.ndarray
    residuals: np.ndarray
    residual_energies: np.ndarray
    ss_residual: float
    ss_total: float
    r2: float
    certificate: float
    converged: bool
    n_iter: int
    mean: FrechetMeanResult
    options: GeodesicOptions
    tol: float
    log: list = field(default_factory=list, repr=False)

    @property
    def stop_reason(self) -> str:
        """Why the iteration stopped: ``"converged"`` (certificate ≤ tol) or ``"max_iter"``."""
        return "converged" if self.converged else "max_iter"

    @property
    def speed(self) -> float:
        """Metric norm of ``velocity`` at the intercept (distance per unit of ``t``)."""
        return float(tangent_space(self.intercept, options=self.options).norm(self.velocity))

    def predict(self, t) -> np.ndarray:
        """``γ(t)`` for a scalar or array of covariate values: (K, d) or (len(t), K, d)."""
        ts = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if not np.all(np.isfinite(ts)):
            raise ValueError("t must be finite")
        out = np.stack([_point_on(self.path, self.t_range, s, self.options) for s in ts])
        return out[0] if np.ndim(t) == 0 else out

    def summary(self) -> str:
        return (f"geodesic regression ({self.options.metric}, σ² = {self.options.sigma2:g}) of {len(self.fitted)} "
                f"shapes on t ∈ [{self.t_range[0]:g}, {self.t_range[1]:g}]: R² = {self.r2:.4f} "
                f"(Σd² residual {self.ss_residual:.4g} of {self.ss_total:.4g}), speed {self.speed:.4g} per unit t; "
                f"certificate {self.certificate:.1e} (tol {self.tol:.0e}), converged {self.converged} in "
                f"{self.n_iter} iterations")


def _interp(path, t_range, t):
    """Point at ``t`` of the piecewise-linear path over ``t_range`` (inside it) and the segment
    index and weight."""
    m = len(path) - 1
    lo, hi = t_range
    s = 0.0 if hi == lo else (t - lo) / (hi - lo) * m
    j = int(min(max(math.floor(s), 0), m - 1))
    w = s - j
    return (1 - w) * path[j] + w * path[j + 1], j, w


def _point_on(path, t_range, t, options):
    lo, hi = t_range
    m = len(path) - 1
    if lo <= t <= hi:
        return _interp(path, t_range, t)[0]
    # outside the range: the exponential map from the nearer end, with the end segment's velocity
    if t > hi:
        start, vel, span = path[-1], path[-1] - path[-2], (t - hi)
    else:
        start, vel, span = path[0], path[0] - path[1], (lo - t)
    factor = span / ((hi - lo) / m)
    return exp_path(start, factor * vel, options=options)[0][-1]


def _ols_ends(y, t, lo, hi):
    """Least-squares line through the landmark coordinates, evaluated at ``lo`` and ``hi``."""
    tc = t - t.mean()
    denom = float(tc @ tc)
    slope = np.einsum("n,nkd->kd", tc, y) / denom if denom > 0 else np.zeros(y.shape[1:])
    mid = y.mean(axis=0)
    return mid + slope * (lo - t.mean()), mid + slope * (hi - t.mean())


def _start_covector(model, path, n):
    """``∂E/∂θ₀`` of a discrete path energy (the first segment's derivative in its start)."""
    ctx = model.prepare(path[:2])
    da, _, _ = segment_derivatives(model, path[0], path[1], n, ctx, hessian=False)
    return da


@dataclass
class _State:
    a: np.ndarray
    b: np.ndarray
    path: np.ndarray
    fitted: np.ndarray
    logs: list
    loss: float
    idx: np.ndarray
    w: np.ndarray


def geodesic_regression(shapes, t, *, metric: str = "alpha", sigma2, t_ref: float | None = None,
                        mean: FrechetMeanResult | None = None, tol: float = 1e-3, max_iter: int = 20,
                        path_steps: int = DEFAULT_PATH_STEPS, n_steps: int = DEFAULT_LOG_STEPS,
                        log_tol: float = 1e-6, log_max_iter: int = 200, rcond: float = DEFAULT_RCOND,
                        grid_spacing: float = DEFAULT_SPACING, grid_margin: float = DEFAULT_MARGIN, step_rcond: float = DEFAULT_STEP_RCOND,
                        executor=None, chunk_size: int | None = None, warn: bool = True, n_jobs: int | None = None,
                        client=None, scheduler=None) -> GeodesicRegressionResult:
    """The geodesic ``γ(t) = exp_p((t − t_ref) v)`` that best fits ``shapes`` against ``t``.

    Minimises the sum of squared geodesic residuals ``Σ d²(γ(t_i), x_i)`` over the geodesic's two
    ends by Gauss–Newton, with ``R² = 1 − Σ d²(γ(t_i), x_i) / Σ d²(x̄, x_i)`` against the Fréchet
    mean ``x̄`` (module docstring).

    Parameters
    ----------
    shapes : array_like (N, K, d)
        Landmarks in correspondence and in a common frame, d = 2 or 3.
    t : array_like (N,)
        The covariate (e.g. age), not all equal.
    metric, sigma2
        The metric (eq. 22 or eq. 6).
    t_ref : float, optional
        Where ``intercept`` and ``velocity`` are reported (default the mean of ``t``); outside the
        range of ``t`` the velocity is the one at the nearer end of the range.
    mean : FrechetMeanResult, optional
        The Fréchet mean of ``shapes`` for ``R²`` (computed when not given).
    tol, max_iter
        Stop: relative first-order certificate (module docstring), Gauss–Newton iterations.
    path_steps : int
        Segments of the regression geodesic over ``[t_min, t_max]``.
    n_steps, log_tol, log_max_iter, rcond, grid_spacing, grid_margin
        The residual geodesics and the retained subspace (as :func:`~shapelib.statistics.frechet.frechet_mean`).
    step_rcond : float
        The ends of the geodesic move in the directions whose metric eigenvalue exceeds this share
        of the largest (module docstring); in (0, 1).
    executor, chunk_size
        Where the residual log maps run (:mod:`shapelib.statistics.population_logs`).
    n_jobs, client, scheduler
        Or on the engine, as for :func:`shapelib.frechet_mean` (``log[-1]`` says where).

    Returns
    -------
    GeodesicRegressionResult

    See Also
    --------
    shapelib.frechet_mean

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> s = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> age = np.linspace(0.0, 1.0, 6)
    >>> x = np.stack([np.c_[(1.5 + 0.5 * a) * np.cos(s), np.sin(s)] for a in age])
    >>> fit = sl.geodesic_regression(x, age, sigma2=0.5, n_jobs=1)
    >>> bool(fit.r2 > 0.99)
    True
    """
    y = as_shapes(shapes, name="shapes")
    check_dimension(y, name="shapes")
    tt = np.asarray(t, dtype=np.float64)
    if tt.shape != (len(y),):
        raise ValueError(f"t must have one value per shape ({len(y)}); got shape {tt.shape}")
    if not np.all(np.isfinite(tt)):
        raise ValueError(f"t contains non-finite values (first at shape {int(np.flatnonzero(~np.isfinite(tt))[0])})")
    lo, hi = float(tt.min()), float(tt.max())
    if hi == lo:
        raise ValueError(f"t is constant ({lo!r}): there is nothing to regress on")
    step_rcond = check_positive(step_rcond, name="step_rcond")
    if step_rcond >= 1:
        raise ValueError(f"step_rcond must be below 1 (a share of the largest eigenvalue); got {step_rcond!r}")
    opts = geodesic_options(metric, sigma2=sigma2, n_steps=n_steps, log_tol=log_tol, log_max_iter=log_max_iter, rcond=rcond,
                            grid_spacing=grid_spacing, grid_margin=grid_margin)
    tol = check_positive(tol, name="tol")
    max_iter = check_nonnegative_int(max_iter, name="max_iter")
    m_steps = check_positive_int(path_steps, name="path_steps")
    t_ref = float(tt.mean()) if t_ref is None else float(t_ref)
    check_population(y, metric=metric, sigma2=opts.sigma2, stacklevel=3)
    start = {}  # the Procrustes mean, once: the timed log map's base and the Fréchet mean's start

    def base():
        start.setdefault("init", procrustes_mean(y))
        return start["init"]

    rounds = 6.0 if mean is None else 4.0  # the mean's rounds and Gauss–Newton's
    with set_checked(), where_logs_run(y, opts, base=base, rounds=rounds, executor=executor, n_jobs=n_jobs,
                                       client=client, scheduler=scheduler, chunk_size=chunk_size) as where:
        res = _fit(y, tt, lo, hi, t_ref, mean, opts, tol=tol, max_iter=max_iter, m_steps=m_steps,
                   step_rcond=step_rcond, executor=where.executor, chunk_size=where.chunk_size, warn=warn,
                   mean_kw={**where.passed_on, **start})
    where.record(res.log)
    return res


def _fit(y, tt, lo, hi, t_ref, mean, opts, *, tol, max_iter, m_steps, step_rcond, executor, chunk_size, warn,
         mean_kw):
    metric, sigma2, n_steps = opts.metric, opts.sigma2, opts.n_steps
    log_tol, log_max_iter, rcond = opts.tol, opts.max_iter, opts.rcond
    grid_spacing, grid_margin = opts.grid_spacing, opts.grid_margin
    if mean is None:
        mean = frechet_mean(y, metric=metric, sigma2=sigma2, n_steps=n_steps, log_tol=log_tol, log_max_iter=log_max_iter,
                            rcond=rcond, grid_spacing=grid_spacing, grid_margin=grid_margin, warn=warn, **mean_kw)
    elif not isinstance(mean, FrechetMeanResult) or mean.logs.shape != y.shape:
        raise ValueError("mean must be the FrechetMeanResult of these shapes")
    ss_total = float(np.sum(mean.energies))
    model = opts.model()
    n = opts.n_steps
    t0 = time.perf_counter()

    def evaluate(a, b, prev: _State | None):
        init = None if prev is None else _moved_path(prev, a, b)
        with one_blas_thread():
            geo = minimise_path(model, a, b, n_steps=m_steps, tol=1e-10, max_iter=500, window=5, init=init, warn=False,
                                length_scale=math.sqrt(opts.sigma2), sigma2=opts.sigma2, hessian="exact",
                                lower_bound=0.0)
        path = geo.path
        pts = [_interp(path, (lo, hi), s) for s in tt]
        fitted = np.stack([p[0] for p in pts])
        inits = None if prev is None else shifted_paths(prev.logs, prev.fitted, fitted)
        logs = population_logs(fitted, y, options=opts, inits=inits, executor=executor, chunk_size=chunk_size)
        loss = float(sum(r.energy for r in logs))
        return _State(a, b, path, fitted, logs, loss, np.array([p[1] for p in pts]), np.array([p[2] for p in pts]))

    state = evaluate(*_ols_ends(y, tt, lo, hi), None)
    history, converged, it, cert, lam = [], False, 0, np.inf, 1e-6
    while True:
        grad, jac, ts_a, ts_b = _gradient(model, state, opts, m_steps, n)
        # Gauss–Newton on the retained subspaces at A and B: N = Σ J_iᵀ g(ŷ_i) J_i
        basis = _block_basis(ts_a, ts_b, step_rcond)
        g_fit = model.tensors(state.fitted, model.prepare(state.fitted))
        jr = jac @ basis  # (N, q, r)
        normal = np.einsum("nir,nis->rs", jr, g_fit @ jr)
        rhs = -0.5 * basis.T @ grad
        step_gn = np.linalg.lstsq(normal, rhs, rcond=1e-12)[0]
        # relative first-order certificate: the share of the residuals a move of the geodesic explains
        explained = max(float(rhs @ step_gn), 0.0)
        cert = math.sqrt(explained / state.loss) if state.loss > 0 else 0.0
        history.append({"loss": state.loss, "certificate": cert, "seconds": time.perf_counter() - t0,
                        "path_iterations": int(sum(r.n_iter for r in state.logs)), "damping": lam})
        if cert <= tol or state.loss <= 1e-14 * ss_total:
            converged = True
            break
        if it >= max_iter:
            break
        it += 1
        level = float(np.trace(normal)) / len(normal)
        accepted = False
        for back in range(8):
            delta = basis @ np.linalg.solve(normal + lam * level * np.eye(len(normal)), rhs)
            q = state.a.size
            trial = evaluate(state.a + delta[:q].reshape(state.a.shape), state.b + delta[q:].reshape(state.b.shape),
                             state)
            if trial.loss < state.loss:
                accepted = True
                lam = max(lam / 10, 1e-9)
                break
            lam *= 10
        history[-1]["backtracks"] = back
        if not accepted:  # no decrease: the loss is at its floor
            break
        state = trial
    if not converged and warn:
        warnings.warn(f"geodesic regression: certificate {cert:.2e} > tol {tol:.0e} after {it} iterations",
                      GeodesicWarning, stacklevel=3)
    intercept, j, _ = _interp(state.path, (lo, hi), t_ref) if lo <= t_ref <= hi else (
        _point_on(state.path, (lo, hi), t_ref, opts), None, None)
    if j is None:
        j = 0 if t_ref < lo else m_steps - 1
    velocity = (state.path[j + 1] - state.path[j]) * m_steps / (hi - lo)
    ss_res = state.loss
    return GeodesicRegressionResult(
        path=state.path, t_range=(lo, hi), t_ref=t_ref, intercept=intercept, velocity=velocity, fitted=state.fitted,
        residuals=np.stack([r.vector for r in state.logs]), residual_energies=np.array([r.energy for r in state.logs]),
        ss_residual=ss_res, ss_total=ss_total, r2=1.0 - ss_res / ss_total if ss_total > 0 else float("nan"),
        certificate=cert, converged=converged, n_iter=it, mean=mean, options=opts, tol=tol, log=history)


def _moved_path(prev: _State, a, b):
    m = len(prev.path) - 1
    s = (np.arange(m + 1) / m)[:, None, None]
    return prev.path + (1 - s) * (a - prev.a) + s * (b - prev.b)


def _block_basis(ts_a: TangentSpace, ts_b: TangentSpace, rcond: float) -> np.ndarray:
    """Columns spanning the directions at A (first q coordinates) and B (last q) whose metric
    eigenvalue exceeds ``rcond`` of the largest."""
    q = ts_a.basis.shape[0]
    ra = int(np.count_nonzero(ts_a.eigenvalues > rcond * ts_a.eigenvalues[0]))
    rb = int(np.count_nonzero(ts_b.eigenvalues > rcond * ts_b.eigenvalues[0]))
    basis = np.zeros((2 * q, ra + rb))
    basis[:q, :ra] = ts_a.eigenvectors[:, :ra]
    basis[q:, ra:] = ts_b.eigenvectors[:, :rb]
    return basis


def _solve_columns(factors, rhs):
    """``H⁻¹ R`` for a block right-hand side R (m, q, c), column by column."""
    return np.stack([block_solve(factors, rhs[:, :, c]) for c in range(rhs.shape[2])], axis=2)


def _gradient(model, state: _State, opts, m_steps, n):
    """Exact gradient of the loss in the ends ``(A, B)`` of the regression geodesic, stacked (2 q,),
    and the Jacobians of the fitted points in ``(A, B)``, (N, q, 2 q) (module docstring)."""
    k, d = state.a.shape
    q = k * d
    # ∂L/∂ŷ_i: derivative of each residual path's energy in its start
    cov = np.stack([_start_covector(model, r.path, n) for r in state.logs]).reshape(len(state.logs), q)
    path = state.path
    # Jacobians of the path points in (A, B): ends are the identity, interior points by the
    # implicit function theorem on ∇_Θ E = 0
    pts_jac = np.zeros((m_steps + 1, q, 2 * q))
    pts_jac[0, :, :q] = np.eye(q)
    pts_jac[-1, :, q:] = np.eye(q)
    if m_steps > 1:
        with one_blas_thread():
            _, _, (hd, ho) = path_energy(model, path, hessian="exact")
            scale = float(np.mean(np.einsum("tii->t", hd))) / hd.shape[1]
            shift = 1e-10 * scale
            while True:
                try:
                    factors = block_cholesky(hd, ho, shift)
                    break
                except np.linalg.LinAlgError:
                    shift *= 10
            ctx = model.prepare(path)
            _, _, mix0 = segment_derivatives(model, path[0], path[1], m_steps, ctx, hessian=True)
            _, _, mix1 = segment_derivatives(model, path[-2], path[-1], m_steps, ctx, hessian=True)
            cross = np.zeros((m_steps - 1, q, 2 * q))
            cross[0, :, :q] = mix0.T  # ∂²E/∂θ₁∂A
            cross[-1, :, q:] = mix1  # ∂²E/∂θ_{M−1}∂B
            pts_jac[1:-1] = -_solve_columns(factors, cross)
    idx, w = state.idx, state.w
    jac = (1 - w)[:, None, None] * pts_jac[idx] + w[:, None, None] * pts_jac[idx + 1]
    grad = np.einsum("nq,nqr->r", cov, jac)
    return grad, jac, tangent_space(state.a, options=opts), tangent_space(state.b, options=opts)
