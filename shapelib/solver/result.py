"""What a path solve returns: :class:`GeodesicResult`, its :class:`StopReason` and the warning
raised when the solver stops early.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

__all__ = ["GeodesicResult", "GeodesicWarning", "StopReason", "BracketStopReason"]


class StopReason(str, enum.Enum):
    r"""Why the path solver stopped (``GeodesicResult.stop_reason``).

    A ``str`` enum: ``result.log["stopped_by"] == "newton_decrement"`` and
    ``result.stop_reason is StopReason.NEWTON_DECREMENT`` say the same. The certified stop is the
    Newton decrement of the discrete path energy :math:`E_n` (eq. 8 of [1]_) on its exact Hessian
    :math:`H` with gradient :math:`g`,

    .. math::

        \tfrac12\, g^\top H^{-1} g < \text{tol} \cdot E_n,

    which estimates the energy still to be gained [2]_.

    Attributes
    ----------
    TRIVIAL : str
        ``"trivial"``: nothing to solve, one time step or identical ends (converged).
    NEWTON_DECREMENT : str
        ``"newton_decrement"``: a certified local minimum (converged).
    ENERGY_WINDOW : str
        ``"energy_window"``: the relative energy decrease over ``window`` iterations fell below
        ``tol`` (converged).
    NO_DECREASE : str
        ``"no_decrease"``: no damped step decreases the energy at machine precision (converged).
    TARGET_ENERGY : str
        ``"target_energy"``: the energy reached the caller's ``target_energy`` (the bracket's stop;
        converged).
    MAX_ITER : str
        ``"max_iter"``: ``max_iter`` iterations without another stop (not converged).
    UNDERFLOW : str
        ``"underflow"``: σ so small that the landmarks' Gaussians do not interact (not converged;
        see ``log["reason"]``).
    converged : bool
        Whether a result stopped for this reason counts as converged (property).

    See Also
    --------
    shapelib.GeodesicResult : Where it is reported.
    shapelib.BracketStopReason : The bracket's stop reasons.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., Springer, 2006.

    Examples
    --------
    >>> import shapelib as sl
    >>> sl.StopReason("newton_decrement") is sl.StopReason.NEWTON_DECREMENT
    True
    >>> sl.StopReason.MAX_ITER.converged, str(sl.StopReason.ENERGY_WINDOW)
    (False, 'energy_window')
    """

    #: nothing to solve: one time step, or identical ends (converged)
    TRIVIAL = "trivial"
    #: the Newton decrement on the exact, positive-definite Hessian is below ``tol · E``: a
    #: certified local minimum (converged)
    NEWTON_DECREMENT = "newton_decrement"
    #: the relative energy decrease over ``window`` iterations fell below ``tol`` (converged)
    ENERGY_WINDOW = "energy_window"
    #: no damped step decreases the energy at machine precision: a local minimum (converged)
    NO_DECREASE = "no_decrease"
    #: the energy reached the caller's ``target_energy`` (the bracket's stop; converged)
    TARGET_ENERGY = "target_energy"
    #: ``max_iter`` iterations without another stop (not converged)
    MAX_ITER = "max_iter"
    #: σ so small that the landmarks' Gaussians do not interact (not converged; see ``log["reason"]``)
    UNDERFLOW = "underflow"

    @property
    def converged(self) -> bool:
        """Whether a result stopped for this reason counts as converged."""
        return self not in (StopReason.MAX_ITER, StopReason.UNDERFLOW)

    def __str__(self) -> str:
        return self.value


class BracketStopReason(str, enum.Enum):
    r"""Why :func:`shapelib.distance_bracket` stopped refining (``DistanceBracket.stop_reason``).

    The bracket converges when its relative gap meets the tolerance,

    .. math::

        \frac{\text{upper}}{\text{lower}} - 1 \le \text{rtol},

    ``lower`` the closed-form bound and ``upper`` the length of a computed path under the metric of
    eq. (6) or (22) of [1]_.

    Attributes
    ----------
    RTOL : str
        ``"rtol"``: the relative gap is at most ``rtol`` (converged).
    STALLED : str
        ``"stalled"``: the gap stopped shrinking by the required fraction per doubling of
        ``n_steps``, or converges geometrically to a limit above ``rtol``; the bracket is reported
        as it is (not converged).
    MAX_N_STEPS : str
        ``"max_n_steps"``: ``max_n_steps`` reached with the gap above ``rtol`` (not converged).
    TRIVIAL : str
        ``"trivial"``: ``u == v`` (converged).
    converged : bool
        Whether a bracket stopped for this reason counts as converged (property).

    See Also
    --------
    shapelib.DistanceBracket : Where it is reported.
    shapelib.StopReason : The path solver's stop reasons.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import shapelib as sl
    >>> sl.BracketStopReason.RTOL.converged, sl.BracketStopReason.STALLED.converged
    (True, False)
    """

    #: the relative gap ``upper / lower − 1`` is at most ``rtol`` (converged)
    RTOL = "rtol"
    #: the gap stopped shrinking by the required fraction per doubling of ``n_steps``, or converges
    #: geometrically to a limit above ``rtol``; the bracket is reported as it is (not converged)
    STALLED = "stalled"
    #: ``max_n_steps`` reached with the gap above ``rtol`` (not converged)
    MAX_N_STEPS = "max_n_steps"
    #: ``u == v`` (converged)
    TRIVIAL = "trivial"

    @property
    def converged(self) -> bool:
        """Whether a bracket stopped for this reason counts as converged."""
        return self in (BracketStopReason.RTOL, BracketStopReason.TRIVIAL)

    def __str__(self) -> str:
        return self.value


class GeodesicWarning(RuntimeWarning):
    """The geodesic solver stopped before meeting its tolerance.

    A :class:`RuntimeWarning`: the result is still returned, with ``converged`` false and
    ``stop_reason`` saying why (``max_iter``, ``underflow``). Its length is still the length of an
    actual path, so ``lower_bound ≤ d(u, v) ≤ length`` holds [1]_; only the path is not (yet)
    the geodesic.

    Parameters
    ----------
    *args : str
        The message, as for any warning (:func:`warnings.warn` passes its text when given this
        category).

    See Also
    --------
    shapelib.geodesic : What raises it (``warn=False`` silences it).
    shapelib.StopReason : The reasons.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = np.array([[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]])
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     r = sl.geodesic(u, v, sigma2=0.5, n_steps=4, max_iter=0)
    >>> r.converged, any(issubclass(w.category, sl.GeodesicWarning) for w in caught)
    (False, True)
    """


@dataclass
class GeodesicResult:
    r"""A computed geodesic and its certificate.

    The path minimises the discrete path energy of eq. (8) of [1]_ over piecewise-linear paths;
    its length is an upper bound and the closed-form bound a lower bound on the geodesic distance:

    .. math::

        \ell(u, v) \le d(u, v) \le L = \int_0^1 \sqrt{\dot\theta^\top g(\theta)\,
        \dot\theta}\, dt, \qquad L^2 \le E_n,

    with :math:`\ell` the ``lower_bound``, :math:`L` the ``length`` and :math:`E_n` the ``energy``.

    Attributes
    ----------
    path : ndarray, shape (n_steps + 1, K, d)
        Landmarks at times ``t = 0, 1/n, …, 1``; ``path[0]`` and ``path[-1]`` are the inputs.
        The intermediate shapes are the intrinsic deformation (Figs. 4–8).
    length : float
        Riemannian length ``∫ √(θ̇ᵀ g θ̇) dt`` of the piecewise-linear path (an upper bound on
        the geodesic distance).
    energy : float
        Path energy (eq. 8) of the piecewise-linear path, 3-point Gauss–Legendre per segment
        (≥ length² ≥ lower_bound²; ≈ length² for a converged, constant-speed geodesic).
    lower_bound : float
        Closed-form (α) or great-circle (Fisher–Rao) lower bound on the geodesic distance.
    converged : bool
        Whether the solver met its tolerance (:class:`StopReason`).
    n_iter : int
        Levenberg–Marquardt iterations.
    grad_norm : float or None
        Euclidean norm of the energy gradient at the solution; None when the solve stopped on
        ``target_energy`` (the start or the last step met it), where the gradient at the final
        path is not evaluated.
    rel_energy_change : float
        Relative energy decrease of the last accepted step.
    max_step_over_sigma : float
        Largest landmark displacement between consecutive path points, in units of σ (of the
        kernel width for landmark diffeomorphisms).
    metric : str
        The metric's name.
    sigma2 : float or None
        σ² of eq. (5) (None for metrics without one).
    log : dict
        Energy per iteration, damping, timings, the metric's settings; ``hessian`` ("exact"
        or "model"), ``stopped_by`` (a :class:`StopReason` value, also :attr:`stop_reason`;
        "underflow" comes with a ``reason``) and the
        last ``newton_decrement`` (exact Hessian only, None where it was not positive definite,
        or not computed because the damped decrement, a lower bound on it, was already above
        ``tol · E``).
    stop_reason : StopReason
        Why the solver stopped (property).
    n_steps : int
        Number of path segments (property).
    times : ndarray, shape (n_steps + 1,)
        The times of the path points (property).
    velocities : ndarray, shape (n_steps, K, d)
        Landmark velocities on each segment (property).

    See Also
    --------
    shapelib.geodesic : What returns it.
    shapelib.DistanceBracket : A certified bracket to a requested width.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = np.array([[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, v, scaling=False)
    >>> r = sl.geodesic(u, v, sigma2=0.5, n_steps=4)
    >>> r.path.shape, r.converged, bool(r.lower_bound <= r.length <= np.sqrt(r.energy) + 1e-12)
    ((5, 4, 2), True, True)
    >>> r.shape_at(0.5).shape
    (4, 2)
    """

    path: np.ndarray
    length: float
    energy: float
    lower_bound: float
    converged: bool
    n_iter: int
    grad_norm: float | None
    rel_energy_change: float
    max_step_over_sigma: float
    metric: str
    sigma2: float | None
    log: dict = field(default_factory=dict, repr=False)

    @property
    def stop_reason(self) -> "StopReason":
        """Why the solver stopped (:class:`StopReason`)."""
        return StopReason(self.log["stopped_by"])

    @property
    def value(self) -> float:
        """The distance computed: :attr:`length` (the results' common name, as in
        :func:`shapelib.distances.pair_record`)."""
        return self.length

    @property
    def lower(self) -> float:
        """Certified lower end of the distance: :attr:`lower_bound`."""
        return self.lower_bound

    @property
    def upper(self) -> float:
        """Certified upper end of the distance: :attr:`length` (the length of an actual path)."""
        return self.length

    @property
    def n_steps(self) -> int:
        """Number of path segments ``n`` (``n + 1`` path points)."""
        return len(self.path) - 1

    @property
    def times(self) -> np.ndarray:
        """The times ``t = 0, 1/n, …, 1`` of the path points."""
        return np.linspace(0.0, 1.0, len(self.path))

    @property
    def velocities(self) -> np.ndarray:
        """Landmark velocities on each segment, shape (n_steps, K, d)."""
        return self.n_steps * np.diff(self.path, axis=0)

    def summary(self) -> str:
        """One line: metric, length with its certified lower bound, convergence."""
        return (f"{self.metric}: length {self.length:.6g} (lower bound {self.lower_bound:.6g}), "
                f"converged {self.converged} in {self.n_iter} iterations ({self.log.get('stopped_by', '?')})")

    def shape_at(self, t: float) -> np.ndarray:
        """Landmarks at time ``t ∈ [0, 1]`` (linear between path points); ``ValueError`` outside [0, 1]."""
        if not 0.0 <= t <= 1.0:
            raise ValueError(f"t must lie in [0, 1]; got {t!r}")
        s = t * self.n_steps
        i = min(int(np.floor(s)), self.n_steps - 1)
        return self.path[i] + (s - i) * (self.path[i + 1] - self.path[i])

