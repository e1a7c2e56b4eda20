r"""The path solver: Levenberg–Marquardt (a trust-region Newton method) on the discrete path energy
of any :class:`~shapelib.PathMetric`, with a certified stop.

The pieces, each its own function:

* :func:`damped_newton_step` — the subproblem: solve :math:`(H + \lambda s I)\, x = -g` on the
  block-tridiagonal Hessian (:math:`s` its mean diagonal), doubling λ until the shifted matrix
  is positive definite;
* :func:`newton_certificate` — where the exact Hessian is positive definite, the Newton
  decrement :math:`\tfrac12 g^\top H^{-1} g` estimates the energy still to gain; below
  :math:`\text{tol} \cdot E` the path is a certified local minimum;
* :func:`accept_step` — the accept loop: a trial step is kept if it lowers the energy; the
  damping follows the ratio of actual to predicted decrease;
* the stop rules, each reported as a :class:`~shapelib.StopReason`.

:func:`minimise_path` runs them; :func:`shapelib.geodesic`, :func:`shapelib.distance_bracket` and
:func:`shapelib.landmark_diffeomorphism` call it.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from .._validate import check_nonnegative_int, check_positive, check_positive_int
from .energy import metric_length, path_energy
from .linalg import block_cholesky, block_solve, hess_vec, one_blas_thread
from .path_metric import PathMetric
from .result import GeodesicResult, GeodesicWarning, StopReason

__all__ = ["minimise_path", "damped_newton_step", "newton_certificate", "accept_step", "StepOutcome",
           "MAX_FACTORISATIONS"]

#: factorisations one iteration may try (shift doublings and rejected steps together)
MAX_FACTORISATIONS = 60


def damped_newton_step(hess, grad, lam: float, scale: float, *, budget: int = MAX_FACTORISATIONS):
    r"""Solve the damped subproblem ``(H + lam·scale·I) x = −grad`` on the block-tridiagonal ``H``.

    The Levenberg–Marquardt step [1]_ on the discrete path energy of eq. (8) of [2]_,

    .. math::

        (H + \lambda s I)\, x = -g,

    with ``lam`` doubled after each failed factorisation (:math:`H + \lambda s I` not positive
    definite).

    Parameters
    ----------
    hess : tuple (diag, upper)
        Blocks of ``H`` as :func:`shapelib.solver.energy.path_energy` returns them.
    grad : ndarray, shape (n - 1, q)
        The gradient at the interior points.
    lam, scale : float
        Damping and its scale (the mean diagonal entry of ``H``).
    budget : int
        Factorisations allowed; each failure (``H + shift`` not positive definite) doubles ``lam``.

    Returns
    -------
    step : ndarray (n - 1, q) or None
        None when every factorisation in the budget failed.
    lam : float
        The damping that succeeded (or the last tried).
    tries : int
        Failed factorisations.

    See Also
    --------
    shapelib.solver.linalg.block_cholesky : The factorisation.

    References
    ----------
    .. [1] J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., Springer, 2006.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.minimise import damped_newton_step
    >>> diag = np.array([[[2.0]], [[2.0]]])
    >>> upper = np.array([[[-1.0]]])
    >>> step, lam, tries = damped_newton_step((diag, upper), np.array([[1.0], [0.0]]), 0.0, 1.0)
    >>> step.ravel().round(6), tries
    (array([-0.666667, -0.333333]), 0)
    """
    hd, ho = hess
    tries = 0
    while tries < budget:
        try:
            return -block_solve(block_cholesky(hd, ho, lam * scale), grad), lam, tries
        except np.linalg.LinAlgError:  # Hessian + damping not positive definite
            lam = max(lam * 2, 1e-12)
            tries += 1
    return None, lam, tries


def newton_certificate(hess, grad, energy: float, tol: float, damped_step=None):
    r"""The undamped Newton step and decrement ``½ gᵀH⁻¹g``, where ``H`` is positive definite.

    .. math::

        \delta = \tfrac12\, g^\top H^{-1} g,

    the energy a Newton step on the quadratic model would still gain [1]_: the path solver of
    eq. (8) of [2]_ stops when :math:`\delta < \text{tol} \cdot E`. For :math:`H \succ 0` and
    :math:`\mu > 0`, :math:`g^\top H^{-1} g \ge g^\top (H + \mu I)^{-1} g`: when the decrement of
    ``damped_step`` already exceeds :math:`\text{tol} \cdot E` the certificate cannot pass, and the
    unshifted factorisation (which fails in most iterations of a non-convex solve) is skipped.

    Parameters
    ----------
    hess : tuple (diag, upper)
        Blocks of the exact Hessian.
    grad : ndarray, shape (n - 1, q)
        The gradient.
    energy : float
        The current energy :math:`E`.
    tol : float
        The certificate's relative tolerance.
    damped_step : ndarray, optional
        A step already solved with damping (for the shortcut above).

    Returns
    -------
    step : ndarray or None
        The Newton step.
    decrement : float or None
        None where ``H`` is not positive definite or the factorisation was skipped.

    See Also
    --------
    shapelib.StopReason : ``NEWTON_DECREMENT`` is this certificate.

    References
    ----------
    .. [1] J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., Springer, 2006.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.minimise import newton_certificate
    >>> diag, upper = np.array([[[2.0]], [[2.0]]]), np.array([[[-1.0]]])
    >>> step, dec = newton_certificate((diag, upper), np.array([[1.0], [0.0]]), 1.0, 1e-6)
    >>> round(dec, 6)
    0.333333
    """
    if damped_step is not None and -0.5 * float(np.sum(grad * damped_step)) >= tol * energy * (1 + 1e-6):
        return None, None
    hd, ho = hess
    try:
        newton = -block_solve(block_cholesky(hd, ho, 0.0), grad)
    except np.linalg.LinAlgError:
        return None, None
    return newton, -0.5 * float(np.sum(grad * newton))


@dataclass
class StepOutcome:
    r"""What :func:`~shapelib.solver.minimise.accept_step` did.

    The new path and energy if ``accepted``, the damping for the next iteration and the actual
    decrease of the path energy (eq. 8 of [1]_),

    .. math::

        \text{decrease} = E_n(\text{path}_{\text{old}}) - E_n(\text{path}_{\text{new}}) > 0
        \quad \text{when accepted}.

    Attributes
    ----------
    accepted : bool
        Whether a step lowered the energy.
    path : ndarray, shape (n + 1, K, d)
        The new path (the old one if not accepted).
    energy : float
        Its energy.
    decrease : float
        The actual energy decrease (0 if not accepted).
    lam : float
        The damping for the next iteration.

    See Also
    --------
    shapelib.solver.minimise.accept_step

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.minimise import StepOutcome
    >>> StepOutcome(False, np.zeros((2, 1, 2)), 1.0, 0.0, 1e-3).accepted
    False
    """

    accepted: bool
    path: np.ndarray
    energy: float
    decrease: float
    lam: float


def accept_step(model, path, energy, hess, grad, lam, scale, *, pending=None,
                budget: int = MAX_FACTORISATIONS) -> StepOutcome:
    r"""Levenberg–Marquardt accept loop: try damped steps until one lowers the energy.

    A step lowering the path energy of eq. (8) of [2]_ is accepted and the damping updated from the
    ratio of actual to predicted decrease [1]_,

    .. math::

        \rho = \frac{E(\theta) - E(\theta + x)}{-g^\top x - \tfrac12 x^\top H x}, \qquad
        \lambda \leftarrow \begin{cases} \lambda / 3 & \rho > 0.75 \\ \lambda & 0.25 \le \rho \le 0.75 \\
        4 \lambda & \rho < 0.25 \end{cases}

    a rejected step multiplies it by 10; a failed factorisation doubles it. ``budget`` attempts in
    all.

    Parameters
    ----------
    model : PathMetric
        The metric.
    path : ndarray, shape (n + 1, K, d)
        The current path.
    energy : float
        Its energy.
    hess : tuple (diag, upper)
        Blocks of the Hessian.
    grad : ndarray, shape (n - 1, q)
        The gradient.
    lam, scale : float
        Damping and its scale.
    pending : ndarray, optional
        A step already solved at ``lam`` (:func:`~shapelib.solver.minimise.damped_newton_step`).
    budget : int
        Attempts allowed.

    Returns
    -------
    StepOutcome
        The new path, its energy, the decrease and the next damping.

    See Also
    --------
    shapelib.solver.minimise.minimise_path : The loop around it.

    References
    ----------
    .. [1] J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., Springer, 2006.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.solver.energy import path_energy
    >>> from shapelib.solver.minimise import accept_step
    >>> model = sl.path_metric("alpha", 0.5)
    >>> path = np.array([[[0.0, 0.0]], [[0.8, 0.3]], [[1.0, 0.0]]])  # a bent path of one landmark
    >>> e, grad, hess = path_energy(model, path, hessian="exact")
    >>> out = accept_step(model, path, e, hess, grad.reshape(1, -1), 1e-3, 1.0)
    >>> out.accepted, bool(out.energy < e)
    (True, True)
    """
    hd, ho = hess
    n = len(path) - 1
    k, d = path.shape[1:]
    for _ in range(budget):
        if pending is not None:
            step, pending = pending, None
        else:
            try:
                step = -block_solve(block_cholesky(hd, ho, lam * scale), grad)
            except np.linalg.LinAlgError:  # Hessian + damping not positive definite
                lam = max(lam * 2, 1e-12)
                continue
        predicted = -float(np.sum(grad * step)) - 0.5 * float(np.sum(step * hess_vec(hd, ho, step)))
        trial = path.copy()
        trial[1:-1] += step.reshape(n - 1, k, d)
        e_trial = path_energy(model, trial, gradient=False)[0]
        actual = energy - e_trial
        if np.isfinite(e_trial) and actual > 0:
            rho = actual / predicted if predicted > 0 else 0.0
            lam = lam / 3 if rho > 0.75 else (lam * 4 if rho < 0.25 else lam)
            return StepOutcome(True, trial, e_trial, actual, max(lam, 1e-14))
        lam = max(lam * 10, 1e-12)
    return StepOutcome(False, path, energy, 0.0, lam)


def _energy_window_met(energies, window: int, tol: float) -> bool:
    """Stop rule: the relative energy decrease over the last ``window`` iterations is below ``tol``."""
    return len(energies) > window and (energies[-1 - window] - energies[-1]) < tol * energies[-1]


def minimise_path(model: PathMetric, u, v, *, n_steps, tol, max_iter, window, init, warn, length_scale,
                  sigma2=None, hessian=None, stacklevel=2, target_energy=None, lower_bound=None) -> GeodesicResult:
    r"""Minimise the piecewise-linear path energy of ``model`` between ``u`` and ``v``.

    The discrete energy of eq. (8) of [1]_ (:mod:`shapelib.solver.energy`),

    .. math::

        \min_{\theta_1, \dots, \theta_{n-1}} E_n(\theta_0 = u, \theta_1, \dots, \theta_{n-1}, \theta_n = v),

    by Levenberg–Marquardt steps [2]_ on the block-tridiagonal Hessian, stopped by the Newton
    decrement, the energy window, ``target_energy`` or ``max_iter`` (module docstring).

    Parameters
    ----------
    model : PathMetric
        The metric (:mod:`shapelib.solver.path_metric`); metrics with ``has_exact_hessian`` get
        exact Newton steps and the Newton-decrement certificate unless ``hessian="model"``.
    u, v : ndarray, shape (K, d)
        The fixed ends (validated by the caller).
    n_steps : int
        Time steps of the path.
    tol : float
        Convergence tolerance (as :func:`shapelib.geodesic`).
    max_iter : int
        Maximum Levenberg–Marquardt iterations.
    window : int
        Iterations over which the energy decrease is measured.
    init : array_like, shape (n_steps + 1, K, d), optional
        Initial path (default: the straight line).
    warn : bool
        Emit a :class:`~shapelib.GeodesicWarning` when it stops before converging.
    length_scale : float
        Unit of ``max_step_over_sigma`` (σ, or the kernel width of diffeomorphisms).
    sigma2 : float, optional
        σ² recorded in the result.
    hessian : {"exact", "model"}, optional
        Default: exact where the metric has it.
    stacklevel : int
        Of the :class:`~shapelib.GeodesicWarning`, counted from here.
    target_energy : float, optional
        Stop as soon as the energy is at or below it (``StopReason.TARGET_ENERGY``, counted
        as converged) — :func:`shapelib.distance_bracket` passes ``(lower · (1 + rtol))²``,
        since ``length ≤ √E``.
    lower_bound : float, optional
        ``model.lower_bound(u, v)`` when the caller has it already.

    Returns
    -------
    GeodesicResult
        With ``log["stopped_by"]`` a :class:`~shapelib.StopReason` value.

    Raises
    ------
    ValueError
        For a non-positive ``n_steps``, ``tol`` or ``window``, a negative ``max_iter``, an unknown
        ``hessian`` or an ``init`` of the wrong shape.

    Warns
    -----
    GeodesicWarning
        When it stops without converging and ``warn`` is true.

    See Also
    --------
    shapelib.geodesic : The checked entry point.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., Springer, 2006.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.solver.minimise import minimise_path
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> r = minimise_path(sl.path_metric("alpha", 0.5), u, 1.1 * u - 0.05, n_steps=4, tol=1e-6, max_iter=50,
    ...                   window=5, init=None, warn=True, length_scale=np.sqrt(0.5), sigma2=0.5)
    >>> r.converged, r.path.shape
    (True, (5, 4, 2))
    """
    n = check_positive_int(n_steps, name="n_steps")
    window = check_positive_int(window, name="window")
    max_iter = check_nonnegative_int(max_iter, name="max_iter")  # 0: evaluate the start only
    tol = check_positive(tol, name="tol")
    if hessian not in (None, "exact", "model"):
        raise ValueError(f"hessian must be 'exact' or 'model'; got {hessian!r}")
    k, d = u.shape
    if init is None:
        t = np.linspace(0.0, 1.0, n + 1)[:, None, None]
        path = (1 - t) * u + t * v
    else:
        path = np.array(init, dtype=np.float64)
        if path.shape != (n + 1, k, d):
            raise ValueError(f"init must have shape {(n + 1, k, d)}; got {path.shape}")
        if not np.all(np.isfinite(path)):
            raise ValueError("init contains non-finite values")
        path[0], path[-1] = u, v
    with one_blas_thread():  # many small dense blocks: see one_blas_thread
        t0 = time.perf_counter()
        energies, dampings = [], []
        converged = n == 1 or np.array_equal(u, v)
        rel_change = 0.0
        it = 0
        kind = "exact" if hessian in (None, "exact") and model.has_exact_hessian else "model"
        trivial = converged
        energy, grad, hess = None, None, None
        if target_energy is not None and not converged:  # the start may do
            energy = path_energy(model, path, gradient=False)[0]
            converged = energy <= target_energy
        if energy is None or not converged:
            energy, grad, hess = path_energy(model, path, gradient=not converged,
                                             hessian=None if converged else kind)
        energies.append(energy)
        if converged:
            stopped_by = StopReason.TARGET_ENERGY if target_energy is not None and not trivial else StopReason.TRIVIAL
        else:
            stopped_by = StopReason.MAX_ITER
        newton_decrement = None
        lam = 1e-3  # damping, relative to the mean diagonal of the Hessian
        while not converged and it < max_iter:
            hd, _ = hess
            g2 = grad.reshape(n - 1, -1)
            scale = float(np.mean(np.einsum("tii->t", hd))) / hd.shape[1]
            # the first damped factorisation of the accept loop, done first: it also tells
            # whether the certificate can pass (failed attempts count towards the loop's budget)
            pending, lam, tries = damped_newton_step(hess, g2, lam, scale)
            if kind == "exact":
                newton, newton_decrement = newton_certificate(hess, g2, energy, tol, pending)
                if newton_decrement is not None and newton_decrement < tol * energy:
                    trial = path.copy()
                    trial[1:-1] += newton.reshape(n - 1, k, d)
                    if path_energy(model, trial, gradient=False)[0] < energy:
                        path = trial
                        energy, grad, _ = path_energy(model, path)
                        energies.append(energy)
                    converged, stopped_by = True, StopReason.NEWTON_DECREMENT
                    break
            it += 1
            step = accept_step(model, path, energy, hess, g2, lam, scale, pending=pending,
                               budget=MAX_FACTORISATIONS - tries)
            lam = step.lam
            if not step.accepted:  # no decrease possible at machine precision: a (local) minimum
                converged, stopped_by = True, StopReason.NO_DECREASE
                break
            rel_change = step.decrease / energy
            path = step.path
            done = target_energy is not None and step.energy <= target_energy
            if done:  # the loop stops here: no gradient or Hessian at the new path
                energy, grad = step.energy, None
            else:
                energy, grad, hess = path_energy(model, path, hessian=kind)
            energies.append(energy)
            dampings.append(lam)
            if done:
                converged, stopped_by = True, StopReason.TARGET_ENERGY
            elif _energy_window_met(energies, window, tol):
                converged, stopped_by = True, StopReason.ENERGY_WINDOW
    if trivial:
        grad_norm = 0.0
    else:  # None: stopped on target_energy, where no gradient is evaluated
        grad_norm = float(np.linalg.norm(grad)) if grad is not None else None
    window_change = (energies[-1 - min(window, len(energies) - 1)] - energy) / energy if energy > 0 else 0.0
    if not converged and warn:
        warnings.warn(
            f"{model.name} geodesic did not converge in {it} iterations (relative energy change "
            f"over the last {window} iterations {window_change:.2e} > tol {tol:.1e}; gradient norm {grad_norm:.2e})",
            GeodesicWarning, stacklevel=stacklevel,
        )
    length = metric_length(model, path)
    steps = np.linalg.norm(np.diff(path, axis=0), axis=2)
    return GeodesicResult(
        path=path, length=length, energy=energy,
        lower_bound=model.lower_bound(u, v) if lower_bound is None else float(lower_bound), converged=bool(converged),
        n_iter=it, grad_norm=grad_norm, rel_energy_change=float(rel_change),
        max_step_over_sigma=float(steps.max() / length_scale), metric=model.name, sigma2=sigma2,
        log={"energy": energies, "damping": dampings, "hessian": kind, "stopped_by": stopped_by.value,
             "newton_decrement": newton_decrement,
             "seconds": time.perf_counter() - t0,
             "n_steps": n, "tol": tol, **model.settings()},
    )
