"""One entry point for every shape distance in the study: :func:`distance`, :func:`pair_record`
(the matrix of a whole population: :func:`shapelib.pairwise_distances`).

``metric`` names and what they compute (keyword options in brackets):

``"alpha"``, ``"fisher_rao"``
    Geodesic length under the α-order (eq. 22) or Fisher–Rao (eq. 6) metric, from
    :func:`shapelib.geodesic` [``sigma2`` (required), ``n_steps``, ``tol``, ``max_iter``, ...];
    with ``rtol=x``, the upper end of the certified bracket of
    :func:`shapelib.solver.bracket.distance_bracket` [``sigma2``, ``n_steps``, ``max_n_steps``, ...].
``"alpha_bound"``
    Closed-form lower bound ``‖p_u − p_v‖`` on the α geodesic distance (the L² distance of the
    eq. 5 densities, :func:`shapelib.geometry.gmm.l2_distance`) [``sigma2``].
``"fisher_rao_bound"``
    Great-circle lower bound ``2 arccos ∫√(p_u p_v)`` on the Fisher–Rao geodesic distance
    (:func:`shapelib.solver.geodesic.fisher_rao_lower_bound`) [``sigma2``, ``grid_spacing``, ``grid_margin``].
``"diffeomorphism"``
    Landmark-diffeomorphism (Camion–Younes) geodesic length, :mod:`shapelib.comparison.diffeomorphism`
    [``lam`` (default 10), ``kernel_width``, ``n_steps``, ...].
``"procrustes"``
    Procrustes distance [``kind`` = "angle" (default), "full", "partial"].
``"hausdorff"``
    Symmetrised Hausdorff distance of the landmark sets.
``"tps"``
    Thin-plate spline bending energy of the map taking ``u`` onto ``v`` (not symmetric) [``kernel``].
``"wendland"``
    Wendland ψ₃,₁ spline bending energy [``support``, ``affine``] (not symmetric).

Every per-pair computation of the library (the pairwise engine :mod:`shapelib.pairwise`, the CLI,
the notebooks) goes through :func:`pair_record`. Paper-specific conventions (alignment, scale,
squared values) belong to the study notebooks.
"""

from __future__ import annotations

import inspect
import math
import time

from ._validate import as_shape_pair

__all__ = ["distance", "pair_record", "path_result", "check_metric_params",
           "METRICS", "SYMMETRIC", "PATH_METRICS", "RECORD_FIELDS"]


PATH_METRICS = ("alpha", "fisher_rao", "diffeomorphism")
#: path metrics whose distance can be certified to a relative tolerance (``rtol=``)
BRACKET_METRICS = ("alpha", "fisher_rao")
#: keys of :func:`pair_record`'s dict, in order
RECORD_FIELDS = ("value", "lower", "upper", "energy", "converged", "n_iter", "seconds")


def path_result(u, v, *, metric: str, **params):
    """The full :class:`~shapelib.solver.geodesic.GeodesicResult` of a path metric (``"alpha"``,
    ``"fisher_rao"``: :func:`shapelib.geodesic`; ``"diffeomorphism"``:
    :func:`shapelib.landmark_diffeomorphism`) — what :func:`distance` reduces to its length."""
    if metric not in PATH_METRICS:
        raise ValueError(f"{metric!r} is not a path metric; choose one of {PATH_METRICS}")
    if metric == "diffeomorphism":
        return _function(metric)(u, v, **params)
    if "sigma2" not in params:
        raise ValueError(f"metric {metric!r} needs sigma2=...")
    return _function(metric)(u, v, metric=metric, **params)


def _alpha_bound(u, v, *, sigma2):
    from .solver.geodesic import alpha_lower_bound

    return alpha_lower_bound(u, v, sigma2=sigma2)


def _function(metric: str):
    """The library function that computes ``metric`` (imported on first use): the one place that
    names it; :data:`METRICS`, :func:`path_result` and the parameter check all go through here."""
    if metric in ("alpha", "fisher_rao"):
        from .solver.geodesic import geodesic

        return geodesic
    if metric == "diffeomorphism":
        from .comparison.diffeomorphism import landmark_diffeomorphism

        return landmark_diffeomorphism
    if metric == "alpha_bound":
        return _alpha_bound
    if metric == "fisher_rao_bound":
        from .solver.geodesic import fisher_rao_lower_bound

        return fisher_rao_lower_bound
    from .geometry.procrustes import procrustes_distance
    from .comparison.hausdorff import hausdorff_distance
    from .comparison.splines import tps_bending_energy, wendland_bending_energy

    return {"procrustes": procrustes_distance, "hausdorff": hausdorff_distance,
            "tps": tps_bending_energy, "wendland": wendland_bending_energy}[metric]


def _compute(metric: str):
    """``(u, v, **params) -> float`` for ``metric``: a path metric's geodesic length, else its function."""
    if metric in PATH_METRICS:
        return lambda u, v, **kw: path_result(u, v, metric=metric, **kw).length
    return lambda u, v, **kw: _function(metric)(u, v, **kw)


METRICS = {m: _compute(m) for m in ("alpha", "fisher_rao", "diffeomorphism", "alpha_bound", "fisher_rao_bound",
                                    "procrustes", "hausdorff", "tps", "wendland")}
#: metrics with d(u, v) = d(v, u); the others are computed for both orders in pairwise_distances
SYMMETRIC = {"alpha", "fisher_rao", "diffeomorphism", "alpha_bound", "fisher_rao_bound", "procrustes",
             "hausdorff"}


def target_function(metric: str, rtol):
    """The library function whose keyword options ``metric`` (with ``rtol``) accepts."""
    if rtol is not None:
        from .solver.bracket import distance_bracket

        return distance_bracket
    return _function(metric)


def check_metric_params(metric: str, params: dict, *, rtol=None) -> None:
    """Raise ``ValueError`` naming an unknown ``metric``, an option it does not take, a missing
    required option (``sigma2``) or an ``rtol`` it cannot honour.

    The options allowed are the keyword options of the function that computes the metric (see the
    module docstring), so this check can never drift from the functions themselves.
    """
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose one of {sorted(METRICS)}")
    if rtol is not None:
        if metric not in BRACKET_METRICS:
            raise ValueError(f"rtol applies to the certified metrics {BRACKET_METRICS}, not {metric!r}")
        if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not (math.isfinite(rtol) and rtol > 0):
            raise ValueError(f"rtol must be a finite number > 0; got {rtol!r}")
    sig = inspect.signature(target_function(metric, rtol))
    fixed = {"u", "v", "metric", "rtol"}
    if any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
        return
    allowed = [name for name in sig.parameters if name not in fixed]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(f"metric {metric!r} has no parameter(s) {unknown}; it takes {allowed}")
    missing = [name for name, p in sig.parameters.items()
               if name not in fixed and p.default is p.empty and name not in params]
    if missing:
        raise ValueError(f"metric {metric!r} needs {', '.join(f'{m}=...' for m in missing)}")


def distance(u, v, *, metric: str, rtol: float | None = None, **params) -> float:
    """Distance between two landmark shapes under ``metric`` (see the module docstring).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes with landmarks in correspondence.
    metric : str
        One of :data:`METRICS`.
    rtol : float, optional
        ``"alpha"``, ``"fisher_rao"`` only. ``None``: the length of the geodesic computed by
        :func:`shapelib.geodesic` (eqs. 8–12). A number: the upper end of the certified bracket
        ``lower ≤ d ≤ upper`` with ``upper / lower − 1 ≤ rtol`` (:func:`shapelib.solver.bracket.distance_bracket`).
    **params
        Options of that metric (e.g. ``sigma2`` for the information metrics).
    """
    if rtol is None:
        check_metric_params(metric, params)
        u, v = as_shape_pair(u, v)
        return float(METRICS[metric](u, v, **params))
    return pair_record(u, v, metric=metric, rtol=rtol, **params)["value"]


def pair_record(u, v, *, metric: str, rtol: float | None = None, **params) -> dict:
    """Distance of one pair with its diagnostics — the one per-pair function of the library.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
    metric : str
        One of :data:`METRICS`.
    rtol : float, optional
        As in :func:`distance` (path metrics ``"alpha"``, ``"fisher_rao"`` only).
    **params
        Options of that metric.

    Returns
    -------
    dict
        ``value`` (the distance :func:`distance` returns), ``lower`` and ``upper`` (certified bounds:
        the closed-form bound of eqs. 5/6 and the computed path's length for the information
        metrics; ``lower = upper = value`` for the non-path metrics), ``energy`` (path energy,
        eq. 8; NaN for non-path metrics, which have none), ``converged`` (bool; the geodesic
        solver's certificate, or ``upper / lower − 1 ≤ rtol``; True for non-path metrics),
        ``n_iter`` (solver iterations, 0 for non-path metrics), ``seconds`` (wall time).
    """
    check_metric_params(metric, params, rtol=rtol)
    u, v = as_shape_pair(u, v)
    t0 = time.perf_counter()
    if rtol is not None:
        from .solver.bracket import distance_bracket

        b = distance_bracket(u, v, metric=metric, rtol=rtol, **params)
        rec = (b.upper, b.lower, b.upper, b.energy, b.converged, b.n_iter)
    elif metric in PATH_METRICS:
        r = path_result(u, v, metric=metric, **params)
        rec = (r.length, r.lower_bound, r.length, r.energy, r.converged, r.n_iter)
    else:
        d = float(METRICS[metric](u, v, **params))
        rec = (d, d, d, math.nan, True, 0)
    seconds = time.perf_counter() - t0
    value, lower, upper, energy, converged, n_iter = rec
    return {"value": float(value), "lower": float(lower), "upper": float(upper), "energy": float(energy),
            "converged": bool(converged), "n_iter": int(n_iter), "seconds": float(seconds)}


#: metrics whose value changes when one shape of a pair is rotated or moved (the others — Procrustes,
#: and the bending energies, whose matrices annihilate the affine part — do not): the pairwise engine
#: checks the shapes' pose for them (:func:`shapelib.geometry.procrustes.check_pose`), the CLI aligns
POSE_DEPENDENT = ("alpha", "fisher_rao", "alpha_bound", "fisher_rao_bound", "diffeomorphism", "hausdorff")


def pose_dependent(metric: str, params: dict) -> bool:
    """Whether ``metric`` with ``params`` depends on the pose of the shapes (:data:`POSE_DEPENDENT`;
    ``"wendland"`` too with ``affine=False``, whose energy then includes the affine part)."""
    return metric in POSE_DEPENDENT or (metric == "wendland" and params.get("affine", True) is False)
