"""One entry point for every shape distance in the study: :func:`distance`, :func:`pair_record`
(the matrix of a whole population: :func:`shapelib.pairwise_distances`), over one registry of
metrics (:func:`metric_info`, :func:`register_metric`).

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
``"registration"``
    Point sets of any sizes, no correspondence: the misfit left after the non-rigid registration
    of each set onto the other (:func:`shapelib.pointsets.registration_distance.registration_distance`;
    registered with the others here) [``combine``, ``reflection``,
    ``lam``, ``sigma2_metric``, ``max_iter``, ``tol``, ``energy_weight``]; through :func:`shapelib.pairwise_distances`
    also ``shortlist=k``.

Each metric is one :class:`MetricInfo` record (its function, whether it is symmetric, a path
metric, certifiable to ``rtol``, the function whose keyword options it takes, its lower-bound
metric, its batched block function, whether it depends on pose, a one-line description);
:func:`register_metric` adds one, after which every entry point (the pairwise engine and its Dask
workers, the CLI's ``--metric``) accepts its name. The engine reads everything it needs from the
record: it has no list of metric names of its own.

Validation happens once, at the public door: :func:`distance` and :func:`pair_record` check the
options and the two shapes, then call the record's unchecked :meth:`MetricInfo.record`; the pairwise
engine checks the options and the whole set of shapes once per run (and once per block on a Dask
worker), then calls :meth:`MetricInfo.record` for every pair. Paper-specific conventions (alignment,
scale, squared values) belong to the study notebooks.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import time
from collections.abc import Callable, Mapping, Sequence, Set
from dataclasses import dataclass

import numpy as np
from functools import lru_cache, partial

from ._validate import InputError, as_shape_pair, check_positive, literal
from .comparison.diffeomorphism import landmark_diffeomorphism
from .comparison.hausdorff import hausdorff_distance
from .comparison.splines import tps_bending_energy, wendland_bending_energy
from .geometry.bound_matrices import alpha_bound_block, fisher_rao_bound_block
from .geometry.procrustes import procrustes_distance, procrustes_distance_unchecked
from .pointsets.registration_distance import registration_distance
from .solver.bracket import distance_bracket
from .solver.geodesic import alpha_lower_bound, fisher_rao_lower_bound, geodesic

__all__ = ["distance", "pair_record", "path_result", "check_metric_params",
           "MetricInfo", "metric_info", "register_metric", "pose_dependent",
           "METRICS", "SYMMETRIC", "PATH_METRICS", "BRACKET_METRICS", "POSE_DEPENDENT", "RECORD_FIELDS"]

#: keys of :func:`pair_record`'s dict, in order
RECORD_FIELDS = ("value", "lower", "upper", "energy", "converged", "n_iter", "seconds")
#: keyword names a metric's function may have that are not metric options
_FIXED = frozenset({"u", "v", "metric", "rtol"})


@dataclass(frozen=True)
class MetricInfo:
    r"""One metric of the registry (what :func:`shapelib.register_metric` records).

    Cf. the ``MetricInfo`` records of :mod:`scipy.spatial.distance`. For the information metrics of
    [1]_ the record ties the geodesic length to its closed-form lower bound,

    .. math::

        \ell(u, v) \le d(u, v),

    with :math:`\ell` the metric named by ``lower_bound``, e.g.
    ``metric_info("alpha").lower_bound == "alpha_bound"``.

    Attributes
    ----------
    name : str
        What ``metric=`` is given as.
    function : callable
        ``function(u, v, **params)``: the distance (a float), or for a path metric the path's
        result (with ``length``, ``lower_bound``, ``energy``, ``converged``, ``n_iter``, as
        :class:`~shapelib.GeodesicResult`). Sent to Dask workers with each task, pickled
        by reference: a module-level function (or a :func:`functools.partial` of one) in a module
        the workers can import.
    symmetric : bool
        ``d(u, v) = d(v, u)``: the pairwise engine computes each unordered pair once.
    path : bool
        A path metric (``function`` returns the geodesic; :func:`~shapelib.distances.path_result`).
    bracket : callable or None
        ``bracket(u, v, *, rtol, **params)`` returning a certified bracket (``lower``, ``upper``,
        ``energy``, ``converged``, ``n_iter``, as :class:`~shapelib.DistanceBracket`): the
        metric can be certified to a relative tolerance (``rtol=``). None: it cannot.
    accepts : callable
        The function whose keyword options (its signature) are the metric's options; default
        ``function``. A ``**kwargs`` in its signature turns the option check off.
    lower_bound : str or None
        Name of the registered metric that bounds this one from below, if any.
    description : str
        One line, shown by ``shapelib distances --help``.
    block : callable or None
        ``block(rows, cols=None, *, n_threads=None, **params)``: the metric between every shape of
        ``rows`` (R, K, d) and every shape of ``cols`` (C, K, d) as one ``(R, C)`` array in one
        batched call (``cols=None``: ``rows`` with itself), as :mod:`scipy.spatial.distance`'s
        ``MetricInfo`` carries a ``pdist_func``. The pairwise engine computes a block of pairs with
        it (without ``rtol``); a ``ValueError`` it raises sends the block pair by pair. None: pair by
        pair always.
    pose_dependent : bool or callable
        Whether the value changes when one shape of a pair is rotated or moved; a callable
        ``pose_dependent(params) -> bool`` when that depends on the options (``"wendland"`` with
        ``affine=False``). The engine checks the pose of the shapes once for such a metric, the CLI
        aligns them.
    core : callable or None
        ``core(u, v, **params)``: ``function`` without its input checks, for shapes that are
        already float64 ``(K, d)`` arrays (checked once for a whole set); default ``function``.
    quadrature : bool
        The metric integrates on a grid of step ``grid_spacing · σ`` (the Fisher–Rao metrics): a σ
        that leaves the grid nothing to resolve is an error before any work, once for a whole set.
    point_sets : bool
        The metric compares point sets of any sizes without correspondence (``"registration"``):
        the pairwise engine takes a list of ``(n_i, d)`` arrays and calls ``core`` (or
        ``function``) on each pair of them.

    See Also
    --------
    shapelib.metric_info : The record of a name.
    shapelib.register_metric : Add a record.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import shapelib as sl
    >>> info = sl.metric_info("alpha")
    >>> info.path, info.symmetric, info.lower_bound, info.bracket is not None
    (True, True, 'alpha_bound', True)
    >>> sl.metric_info("tps").symmetric
    False
    """

    name: str
    function: Callable
    symmetric: bool = True
    path: bool = False
    bracket: Callable | None = None
    accepts: Callable | None = None
    lower_bound: str | None = None
    description: str = ""
    block: Callable | None = None
    pose_dependent: bool | Callable = False
    core: Callable | None = None
    quadrature: bool = False
    point_sets: bool = False

    def options_of(self, rtol=None) -> Callable:
        """The function whose keyword options the metric takes (the bracket's with ``rtol``)."""
        if rtol is not None and self.bracket is not None:
            return self.bracket
        return self.accepts if self.accepts is not None else self.function

    def compute(self, u, v, **params) -> float:
        """The distance of ``u`` and ``v`` (a path metric's geodesic length), unchecked."""
        out = (self.core or self.function)(u, v, **params)
        return float(out.length if self.path else out)

    def depends_on_pose(self, params: dict | None = None) -> bool:
        """Whether the metric with options ``params`` depends on the pose of the shapes."""
        pose = self.pose_dependent
        return bool(pose(dict(params or {})) if callable(pose) else pose)

    def record(self, u, v, *, rtol=None, **params) -> dict:
        """:func:`pair_record` without its checks: ``u``, ``v`` float64 ``(K, d)`` arrays and
        ``params`` (and ``rtol``) already checked (:func:`check_metric_params`)."""
        t0 = time.perf_counter()
        if rtol is not None:
            b = self.bracket(u, v, rtol=rtol, **params)
            rec = (b.upper, b.lower, b.upper, b.energy, b.converged, b.n_iter)
        elif self.path:
            r = (self.core or self.function)(u, v, **params)
            rec = (r.length, r.lower_bound, r.length, r.energy, r.converged, r.n_iter)
        else:
            d = float((self.core or self.function)(u, v, **params))
            rec = (d, d, d, math.nan, True, 0)
        seconds = time.perf_counter() - t0
        value, lower, upper, energy, converged, n_iter = rec
        return {"value": float(value), "lower": float(lower), "upper": float(upper), "energy": float(energy),
                "converged": bool(converged), "n_iter": int(n_iter), "seconds": float(seconds)}


_REGISTRY: dict[str, MetricInfo] = {}


def register_metric(name: str, function: Callable, *, symmetric: bool = True, path: bool = False,
                    bracket: Callable | None = None, accepts: Callable | None = None,
                    lower_bound: str | None = None, description: str = "", block: Callable | None = None,
                    pose_dependent: bool | Callable = False, core: Callable | None = None,
                    quadrature: bool = False, point_sets: bool = False, replace: bool = False) -> MetricInfo:
    r"""Add a metric to the registry.

    Afterwards :func:`shapelib.distance`, :func:`shapelib.pair_record`,
    :func:`shapelib.pairwise_distances` and ``shapelib distances --metric`` accept ``name``. A
    registered metric sits beside the information metrics of [1]_ (eqs. 6 and 22) and the
    comparisons of its Table I: any function

    .. math::

        d : \mathbb{R}^{K \times d} \times \mathbb{R}^{K \times d} \to [0, \infty).

    For the pairwise engine on Dask the function travels with each task, pickled by reference, so
    define it at module level in a module the workers can import (the LocalCluster's workers
    inherit this process's ``sys.path``; for ``dask worker`` processes put the module on their
    ``PYTHONPATH``).

    Parameters
    ----------
    name : str
        What ``metric=`` will be given as (an identifier-like string).
    function : callable
        ``function(u, v, **params)``: the distance, or a path metric's result.
    symmetric : bool, default True
        ``d(u, v) = d(v, u)``.
    path : bool, default False
        ``function`` returns a geodesic result.
    bracket : callable, optional
        A certified bracket (``rtol=``).
    accepts : callable, optional
        The function whose keyword options are the metric's options (default ``function``).
    lower_bound : str, optional
        A registered metric bounding this one from below.
    description : str
        One line for ``shapelib distances --help``.
    point_sets : bool, default False
        The metric compares point sets of any sizes (:attr:`MetricInfo.point_sets`).
    replace : bool, default False
        Replace a metric of that name; without it a taken name is a ``ValueError``.

    Returns
    -------
    MetricInfo
        The record stored.

    Raises
    ------
    ValueError
        For a name that is not an identifier, a taken name without ``replace``, a function,
        bracket or accepts that is not callable, or an unknown ``lower_bound``.

    See Also
    --------
    shapelib.MetricInfo : The fields.
    shapelib.metric_info : Look a record up.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> def chebyshev(u, v):
    ...     return float(np.max(np.abs(np.asarray(u) - np.asarray(v))))
    >>> info = sl.register_metric("chebyshev", chebyshev, description="largest coordinate difference",
    ...                           replace=True)
    >>> sl.distance([[0, 0], [1, 0]], [[0, 0], [1, 2]], metric="chebyshev")
    2.0
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"metric name must be an identifier-like string; got {name!r}")
    if name in _REGISTRY and not replace:
        raise ValueError(f"metric {name!r} is already registered; pass replace=True to replace it")
    for what, f in (("function", function), ("bracket", bracket), ("accepts", accepts), ("block", block),
                    ("core", core)):
        if f is not None and not callable(f):
            raise ValueError(f"metric {name!r}: {what} must be callable; got {f!r}")
    if function is None:
        raise ValueError(f"metric {name!r}: function must be callable; got None")
    if lower_bound is not None and lower_bound not in _REGISTRY and lower_bound != name:
        raise ValueError(f"metric {name!r}: lower_bound {lower_bound!r} is not a registered metric")
    if not callable(pose_dependent) and not isinstance(pose_dependent, (bool, np.bool_)):
        raise ValueError(f"metric {name!r}: pose_dependent must be a bool or callable; got {pose_dependent!r}")
    info = MetricInfo(name=name, function=function, symmetric=bool(symmetric), path=bool(path), bracket=bracket,
                      accepts=accepts, lower_bound=lower_bound, description=" ".join(str(description).split()),
                      block=block, pose_dependent=pose_dependent if callable(pose_dependent) else bool(pose_dependent),
                      core=core, quadrature=bool(quadrature), point_sets=bool(point_sets))
    _REGISTRY[name] = info
    return info


def metric_info(metric) -> MetricInfo:
    r"""The :class:`~shapelib.MetricInfo` of a metric.

    ``metric`` is a name, or a record (returned as is). The records of the information metrics of
    [1]_ name their lower bounds (``"alpha_bound"``, ``"fisher_rao_bound"``):

    .. math::

        \|p_u - p_v\| \le d_\alpha(u, v), \qquad 2 \arccos \int \sqrt{p_u\, p_v}\, dx \le d_{FR}(u, v).

    Parameters
    ----------
    metric : str or MetricInfo
        The metric.

    Returns
    -------
    MetricInfo
        Its record.

    Raises
    ------
    ValueError
        Naming an unknown metric and listing the registered ones.

    See Also
    --------
    shapelib.register_metric : Add a metric.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import shapelib as sl
    >>> sl.metric_info("fisher_rao").lower_bound
    'fisher_rao_bound'
    >>> sl.metric_info(sl.metric_info("procrustes")).name
    'procrustes'
    """
    if isinstance(metric, MetricInfo):
        return metric
    try:
        return _REGISTRY[metric]
    except (KeyError, TypeError):
        raise ValueError(f"unknown metric {metric!r}; choose one of {sorted(_REGISTRY)}") from None


# -- live, read-only views of the registry (the names these tables always had) ------------------


class _Names(Sequence):
    """Names of the registered metrics with a property, in registration order (a live tuple)."""

    def __init__(self, keep):
        self._keep = keep

    def _names(self) -> tuple:
        return tuple(n for n, m in _REGISTRY.items() if self._keep(m))

    def __getitem__(self, i):
        return self._names()[i]

    def __len__(self):
        return len(self._names())

    def __contains__(self, name):
        return name in self._names()

    def __eq__(self, other):
        return self._names() == tuple(other) if isinstance(other, (tuple, list, Sequence)) else NotImplemented

    __hash__ = None

    def __repr__(self):
        return repr(self._names())


class _NameSet(Set):
    """The same as a live set."""

    def __init__(self, keep):
        self._names = _Names(keep)

    def __contains__(self, name):
        return name in self._names

    def __iter__(self):
        return iter(self._names._names())

    def __len__(self):
        return len(self._names)

    def __repr__(self):
        return repr(set(self._names._names()))


class _Functions(Mapping):
    """``name -> (u, v, **params) -> float`` for every registered metric (a live dict)."""

    def __getitem__(self, name):
        return _REGISTRY[name].compute

    def __iter__(self):
        return iter(list(_REGISTRY))

    def __len__(self):
        return len(_REGISTRY)

    def __repr__(self):
        return f"<shapelib metrics {list(_REGISTRY)}>"


#: ``name -> (u, v, **params) -> float`` (every registered metric; unchecked)
METRICS = _Functions()
#: metrics with d(u, v) = d(v, u); the others are computed for both orders in pairwise_distances
SYMMETRIC = _NameSet(lambda m: m.symmetric)
#: path metrics (:func:`path_result`)
PATH_METRICS = _Names(lambda m: m.path)
#: path metrics whose distance can be certified to a relative tolerance (``rtol=``)
BRACKET_METRICS = _Names(lambda m: m.bracket is not None)
#: metrics whose value changes when one shape of a pair is rotated or moved, whatever their options
#: (the others — Procrustes, and the bending energies, whose matrices annihilate the affine part — do
#: not; ``"wendland"`` does with ``affine=False``: :func:`pose_dependent`). The pairwise engine checks
#: the shapes' pose for them (:func:`shapelib.geometry.procrustes.check_pose`), the CLI aligns them.
POSE_DEPENDENT = _Names(lambda m: m.pose_dependent is True)


#: name -> function of the metrics shapelib registers itself (see :func:`is_builtin`)
_BUILTIN = {}


def is_builtin(info) -> bool:
    """Whether the record ``info`` is shapelib's own metric of that name, not a replacement
    registered with ``register_metric(..., replace=True)``.
    """
    return _BUILTIN.get(info.name) is info.function


def _wendland_pose(params) -> bool:
    """``"wendland"`` depends on pose only with ``affine=False`` (its energy then includes the affine part)."""
    return params.get("affine", True) is False



for _name, _fn, _kw in (
        ("alpha", partial(geodesic, metric="alpha"),
         dict(path=True, bracket=partial(distance_bracket, metric="alpha"), pose_dependent=True,
              description="α-order geodesic length (eqs. 8, 22); needs sigma2; certifiable to a relative tolerance (rtol)")),
        ("fisher_rao", partial(geodesic, metric="fisher_rao"),
         dict(path=True, bracket=partial(distance_bracket, metric="fisher_rao"), pose_dependent=True, quadrature=True,
              description="Fisher–Rao geodesic length (eqs. 6, 8); needs sigma2; certifiable to a relative tolerance (rtol)")),
        ("diffeomorphism", landmark_diffeomorphism,
         dict(path=True, pose_dependent=True,
              description="landmark-diffeomorphism (Camion–Younes) geodesic length (eq. 3)")),
        ("alpha_bound", alpha_lower_bound,
         dict(block=alpha_bound_block, pose_dependent=True,
              description="closed-form lower bound ‖p_u − p_v‖ on alpha (eq. 5)")),
        ("fisher_rao_bound", fisher_rao_lower_bound,
         dict(block=fisher_rao_bound_block, pose_dependent=True, quadrature=True,
              description="great-circle lower bound 2 arccos ∫√(p_u p_v) on fisher_rao")),
        ("procrustes", procrustes_distance,
         dict(core=procrustes_distance_unchecked, description="Procrustes distance (kind: angle, full, partial)")),
        ("hausdorff", hausdorff_distance,
         dict(pose_dependent=True, description="symmetrised Hausdorff distance of the landmark sets")),
        ("tps", tps_bending_energy,
         dict(symmetric=False, description="thin-plate spline bending energy of the map u -> v (not symmetric)")),
        ("wendland", wendland_bending_energy,
         dict(symmetric=False, pose_dependent=_wendland_pose,
              description="Wendland ψ3,1 spline bending energy of the map u -> v (not symmetric)")),
        ("registration", registration_distance,
         dict(point_sets=True,
              description="point sets of any sizes: the EM σ² left after non-rigid registration, both sets at "
                          "unit RMS radius, times exp(κ E/m) for the deformation's energy E, both directions "
                          "(mean); shortlist=k: only each query's k nearest by the rigid bound")),
):
    register_metric(_name, _fn, **_kw)
    _BUILTIN[_name] = _fn
for _name in ("alpha", "fisher_rao"):  # their bounds are registered after them
    _REGISTRY[_name] = dataclasses.replace(_REGISTRY[_name], lower_bound=f"{_name}_bound")
del _name, _fn, _kw


def path_result(u, v, *, metric: str, **params):
    r"""The full geodesic result of a path metric, which :func:`shapelib.distance` reduces to its length.

    ``"alpha"``, ``"fisher_rao"``: :func:`shapelib.geodesic` (eqs. 8–12 of [1]_);
    ``"diffeomorphism"``: :func:`shapelib.landmark_diffeomorphism` (eq. 3). The distance is the
    path's length,

    .. math::

        d(u, v) \le \text{length} = \int_0^1 \sqrt{\dot\theta^\top g(\theta)\, \dot\theta}\, dt.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence.
    metric : str, keyword-only
        A path metric (:data:`~shapelib.distances.PATH_METRICS`).
    **params
        Options of that metric.

    Returns
    -------
    GeodesicResult
        The path, its length, energy, bound and convergence.

    Raises
    ------
    ValueError
        For a metric that is not a path metric, or options it does not take.

    See Also
    --------
    shapelib.distance : The length alone.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.distances import path_result
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> r = path_result(u, v, metric="alpha", sigma2=0.5, n_steps=4)
    >>> r.path.shape, r.converged
    ((5, 4, 2), True)
    """
    info = metric_info(metric)
    if not info.path:
        raise ValueError(f"{info.name!r} is not a path metric; choose one of {PATH_METRICS}")
    check_metric_params(info, params)
    return info.function(u, v, **params)


def target_function(metric, rtol):
    """The library function whose keyword options ``metric`` (with ``rtol``) accepts."""
    return metric_info(metric).options_of(rtol)


@lru_cache(maxsize=256)
def _options(function) -> tuple:
    """``(takes **kwargs, option names, required option names)`` of a metric's function, read from
    its signature once (``inspect.signature`` costs tens of µs: more than a cheap pair)."""
    sig = inspect.signature(function)
    if any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
        return True, (), ()
    allowed = tuple(name for name in sig.parameters if name not in _FIXED)
    required = tuple(name for name, p in sig.parameters.items()
                     if name not in _FIXED and p.default is p.empty and p.kind is not p.VAR_POSITIONAL)
    return False, allowed, required


def check_metric_params(metric, params: dict, *, rtol=None) -> None:
    r"""Check a metric's options against the function that computes it.

    Raises ``ValueError`` naming an unknown ``metric``, an option it does not take, a missing
    required option (``sigma2``, an :class:`~shapelib.InputError`) or an ``rtol`` it cannot honour.
    The options allowed are the keyword options of the function that computes the metric
    (:attr:`MetricInfo.accepts`; see the module docstring), so this check can never drift from the
    functions themselves. ``rtol`` must satisfy

    .. math::

        0 < \text{rtol} < \infty

    for the certified metrics of [1]_ (eqs. 6 and 22) only.

    Parameters
    ----------
    metric : str or MetricInfo
        The metric.
    params : dict
        The options given.
    rtol : float, optional
        The relative tolerance asked for.

    Returns
    -------
    None

    Raises
    ------
    ValueError
        As above (:class:`~shapelib.InputError` for a missing option).

    See Also
    --------
    shapelib.distance : Checks its options with it.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.distances import check_metric_params
    >>> check_metric_params("procrustes", {"kind": "full"}) is None
    True
    >>> try:
    ...     check_metric_params("alpha", {})
    ... except ValueError as exc:
    ...     print(exc)
    metric 'alpha' needs sigma2=...
    """
    info = metric_info(metric)
    metric = info.name
    if rtol is not None:
        if info.bracket is None:
            raise ValueError(f"rtol applies to the certified metrics {BRACKET_METRICS}, not {metric!r}")
        check_positive(rtol, name="rtol")
    any_option, allowed, required = _options(info.options_of(rtol))
    if any_option:
        return
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(f"metric {metric!r} has no parameter(s) {unknown}; it takes {list(allowed)}")
    missing = [name for name in required if name not in params]
    if missing:
        words = ", ".join("{sigma2}" if m == "sigma2" else f"{literal(m)}=..." for m in missing)
        raise InputError(f"metric {literal(repr(metric))} needs {words}", {"metric": metric, "parameters": tuple(missing)})


def distance(u, v, *, metric: str, rtol: float | None = None, **params) -> float:
    r"""Distance between two landmark shapes under ``metric`` (see the module docstring).

    For ``"alpha"`` and ``"fisher_rao"`` the geodesic length under the metric of eq. (22) or (6) of
    [1]_; with ``rtol`` the upper end of a certified bracket,

    .. math::

        \text{lower} \le d(u, v) \le \text{upper}, \qquad \frac{\text{upper}}{\text{lower}} - 1 \le \text{rtol};

    for the other metrics their closed form (Table I's comparisons).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes with landmarks in correspondence.
    metric : str
        One of :data:`~shapelib.distances.METRICS`.
    rtol : float, optional
        ``"alpha"``, ``"fisher_rao"`` only. ``None``: the length of the geodesic computed by
        :func:`shapelib.geodesic` (eqs. 8–12). A number: the upper end of the certified bracket
        ``lower ≤ d ≤ upper`` with ``upper / lower − 1 ≤ rtol`` (:func:`shapelib.distance_bracket`).
    **params
        Options of that metric (e.g. ``sigma2`` for the information metrics).

    Returns
    -------
    float
        The distance.

    Raises
    ------
    ValueError
        For an unknown metric, an option it does not take, a missing required option (an
        :class:`~shapelib.InputError`), an ``rtol`` it cannot honour, or bad shapes.

    See Also
    --------
    shapelib.pair_record : The same with its bounds and diagnostics.
    shapelib.pairwise_distances : The matrix of a population.

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
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> round(sl.distance(u, v, metric="procrustes"), 4)
    0.1097
    >>> round(sl.distance(u, v, metric="alpha", sigma2=0.5, rtol=1e-3), 4)
    0.0464
    """
    if rtol is None:
        info = metric_info(metric)
        check_metric_params(info, params)
        u, v = as_shape_pair(u, v)
        return info.compute(u, v, **params)
    return pair_record(u, v, metric=metric, rtol=rtol, **params)["value"]


def pair_record(u, v, *, metric: str, rtol: float | None = None, **params) -> dict:
    r"""Distance of one pair with its diagnostics — the one per-pair function of the library.

    For the information metrics of [1]_ the record certifies the value:

    .. math::

        \text{lower} \le d(u, v) \le \text{upper} = \text{value}, \qquad
        \text{upper}^2 \le \text{energy},

    ``lower`` the closed-form bound (eqs. 5, 6, 22) and ``energy`` the path energy of eq. (8).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes with landmarks in correspondence.
    metric : str or MetricInfo
        A registered metric (:data:`~shapelib.distances.METRICS`).
    rtol : float, optional
        As in :func:`shapelib.distance` (path metrics ``"alpha"``, ``"fisher_rao"`` only).
    **params
        Options of that metric.

    Returns
    -------
    dict
        ``value`` (the distance :func:`shapelib.distance` returns), ``lower`` and ``upper``
        (certified bounds: the closed-form bound of eqs. 5/6 and the computed path's length for the
        information metrics; ``lower = upper = value`` for the non-path metrics), ``energy`` (path
        energy, eq. 8; NaN for non-path metrics, which have none), ``converged`` (bool; the geodesic
        solver's certificate, or ``upper / lower − 1 ≤ rtol``; True for non-path metrics),
        ``n_iter`` (solver iterations, 0 for non-path metrics), ``seconds`` (wall time).

    Raises
    ------
    ValueError
        As :func:`shapelib.distance`.

    See Also
    --------
    shapelib.distance : The value alone.
    shapelib.pairwise_distances : Records of every pair of a population.

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
    >>> v = sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False)
    >>> rec = sl.pair_record(u, v, metric="alpha", sigma2=0.5, rtol=1e-2)
    >>> sorted(rec)
    ['converged', 'energy', 'lower', 'n_iter', 'seconds', 'upper', 'value']
    >>> rec["converged"], bool(rec["lower"] <= rec["value"] <= (1 + 1e-2) * rec["lower"])
    (True, True)
    """
    info = metric_info(metric)
    check_metric_params(info, params, rtol=rtol)
    u, v = as_shape_pair(u, v)
    return info.record(u, v, rtol=rtol, **params)


def pose_dependent(metric, params: dict | None = None) -> bool:
    """Whether ``metric`` with options ``params`` depends on the pose of the shapes.

    The record's ``pose_dependent`` (:data:`POSE_DEPENDENT`; ``"wendland"`` with ``affine=False``
    too, whose energy then includes the affine part): a value that changes when one shape of a
    pair is rotated or moved; the information metrics of [1]_ depend on pose, Procrustes does not.

    Parameters
    ----------
    metric : str or MetricInfo
        A registered metric's name or record.
    params : dict, optional
        The metric's keyword options.

    Returns
    -------
    bool

    See Also
    --------
    shapelib.geometry.procrustes.check_pose : the check the engine runs once for such a metric.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> pose_dependent("hausdorff"), pose_dependent("procrustes")
    (True, False)
    >>> pose_dependent("wendland", {"affine": False})
    True
    """
    return metric_info(metric).depends_on_pose(params)
