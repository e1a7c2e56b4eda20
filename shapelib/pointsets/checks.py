"""Input checks for point sets: shapes without landmarks.

A point set is an ``(n, d)`` array of any number ``n ≥ 2`` of points in ``d = 2`` or ``3``
dimensions, in no particular order and with no correspondence to the points of another set.
Landmark code paths keep their own checks (``shapelib._validate.as_shape``); point-set
paths get these, each failure one :class:`~shapelib.InputError` (a ``ValueError``) that names
the set and the offending point.
"""

from __future__ import annotations

import numpy as np

from .._validate import InputError, check_dimension, literal

__all__ = ["as_point_set", "as_point_sets", "POINT_SET_DIMS"]

#: dimensions a point set may have
POINT_SET_DIMS = (2, 3)


def as_point_set(x, *, name: str = "points", min_points: int = 2) -> np.ndarray:
    """Return ``x`` as a float64 ``(n, d)`` point set, or raise one clear error.

    Checks, in this order: numeric, two axes ``(n, d)``, not empty, ``d`` = 2 or 3, at least
    ``min_points`` points, every coordinate finite, no point repeated (a repeated point is a
    component counted twice in the point set's mixture density, almost always a reading error).

    Parameters
    ----------
    x : array_like, shape (n, d)
        The points, one per row, in any order.
    name : str
        What the error messages call the set (an argument, a file, a specimen).
    min_points : int
        Smallest admissible ``n`` (default 2: a single point has no shape).

    Returns
    -------
    ndarray, shape (n, d)
        The points as float64 (a new array).

    Raises
    ------
    InputError
        With ``facts["points"]``: the indices (from 0) of the offending points, where there are.

    See Also
    --------
    as_point_sets : A collection of point sets of one dimension.
    shapelib.pointsets.density.density_distance : Density distances between point sets.

    Notes
    -----
    A point set stands for the equal-weight isotropic mixture of eq. (5) of [1]_ with one component per point,
    so the points need no order and no correspondence with another set.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.pointsets import as_point_set
    >>> as_point_set([[0, 0], [1, 0], [0, 1]]).shape
    (3, 2)
    >>> try:
    ...     as_point_set([[0, 0], [1, 0], [0, 0]], name="outline")
    ... except ValueError as exc:
    ...     print(exc)
    outline: point 2 repeats point 0 at (0, 0); remove duplicated points (e.g. numpy.unique(points, axis=0))
    """
    label = literal(name)
    try:
        arr = np.array(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{label} must be a numeric (n, d) array of points: {literal(exc)}") from None
    if arr.ndim != 2:
        raise InputError(f"{label} must be a 2-D array of points with shape (n, d); got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise InputError(f"{label} is empty: a point set needs at least {min_points} points")
    check_dimension(arr, name=name, allowed=POINT_SET_DIMS)
    if arr.shape[0] < min_points:
        raise InputError(f"{label} has {arr.shape[0]} point(s); a point set needs at least {min_points}")
    bad = ~np.isfinite(arr)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputError(f"{label}: point {i} has a non-finite coordinate {j} ({float(arr[i, j])}); "
                         f"{int(bad.any(axis=1).sum())} point(s) in all are not finite", {"points": (int(i),)})
    _check_duplicates(arr, label)
    return arr


def _check_duplicates(arr: np.ndarray, label: str) -> None:
    order = np.lexsort(arr.T[::-1])
    srt = arr[order]
    same = np.all(srt[1:] == srt[:-1], axis=1)
    if same.any():
        k = int(np.argmax(same))
        i, j = sorted((int(order[k]), int(order[k + 1])))
        where = ", ".join(f"{v:g}" for v in arr[i])
        raise InputError(f"{label}: point {j} repeats point {i} at ({literal(where)}); remove duplicated points "
                         f"(e.g. numpy.unique(points, axis=0))", {"points": (i, j)})


def as_point_sets(sets, *, name: str = "point sets", min_points: int = 2) -> list[np.ndarray]:
    """Return a collection of point sets as a list of float64 ``(n_i, d)`` arrays of one ``d``.

    The sets may have different numbers of points. Each is checked by :func:`as_point_set`
    (named ``name[i]``); a set whose dimension differs from the first set's is named.

    Parameters
    ----------
    sets : sequence of array_like
        The point sets (a 3-D array ``(N, n, d)`` is read as N sets of n points).
    name : str
        What the error messages call the collection.
    min_points : int
        Smallest admissible number of points per set.

    Returns
    -------
    list of ndarray

    See Also
    --------
    as_point_set : One point set.
    shapelib.pointsets.invariant.invariant_distance_matrix : Distances between every pair of sets.

    Notes
    -----
    Each set stands for the equal-weight isotropic mixture of eq. (5) of [1]_ with one component per point;
    the sets may differ in size.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.pointsets import as_point_sets
    >>> [s.shape for s in as_point_sets([[[0, 0], [1, 0]], [[0, 0], [1, 1], [2, 0]]])]
    [(2, 2), (3, 2)]
    """
    if isinstance(sets, np.ndarray) and sets.ndim != 3:
        raise InputError(f"{literal(name)} must be a list of (n, d) point sets or an (N, n, d) array; got shape {sets.shape}")
    try:
        items = list(sets)
    except TypeError:
        raise InputError(f"{literal(name)} must be a list of (n, d) point sets; got {type(sets).__name__}") from None
    if not items:
        raise InputError(f"{literal(name)} is empty: give at least one point set")
    out = [as_point_set(s, name=f"{name}[{i}]", min_points=min_points) for i, s in enumerate(items)]
    d0 = out[0].shape[1]
    for i, s in enumerate(out):
        if s.shape[1] != d0:
            raise InputError(f"{literal(name)}[{i}] has d = {s.shape[1]} coordinates per point but {literal(name)}[0] "
                             f"has d = {d0}: all point sets of a collection must have the same dimension",
                             {"sets": (0, i)})
    return out


def check_same_dimension(a: np.ndarray, b: np.ndarray, names=("source", "target")) -> None:
    """Raise :class:`InputError` unless two checked point sets have the same ``d``."""
    if a.shape[1] != b.shape[1]:
        raise InputError(f"{literal(names[0])} has d = {a.shape[1]} coordinates per point and {literal(names[1])} "
                         f"d = {b.shape[1]}: both point sets must have the same dimension")
