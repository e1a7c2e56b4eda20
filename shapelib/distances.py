"""One entry point for every shape distance in the study: :func:`distance` and :func:`pairwise_distances`.

``metric`` names and what they compute (keyword options in brackets):

``"alpha"``, ``"fisher_rao"``
    Geodesic length under the α-order (eq. 22) or Fisher–Rao (eq. 6) metric, from
    :func:`shapelib.geodesic` [``sigma2`` (required), ``n_steps``, ``tol``, ``max_iter``, ...].
``"diffeomorphism"``
    Landmark-diffeomorphism (Camion–Younes) geodesic length, :mod:`shapelib.diffeomorphism`
    [``lam`` (default 10), ``kernel_width``, ``n_steps``, ...].
``"procrustes"``
    Procrustes distance [``kind`` = "angle" (default), "full", "partial"].
``"hausdorff"``
    Symmetrised Hausdorff distance of the landmark sets.
``"tps"``
    Thin-plate spline bending energy of the map taking ``u`` onto ``v`` (not symmetric).
``"wendland"``
    Wendland ψ₃,₁ spline bending energy [``support``, ``affine``] (not symmetric).

Paper-specific conventions (alignment, scale, squared values) belong to the study notebooks.
"""

from __future__ import annotations

import concurrent.futures as cf
import itertools
import os

import numpy as np

from ._validate import as_shape_pair, as_shapes

__all__ = ["distance", "pairwise_distances", "path_result", "METRICS", "SYMMETRIC", "PATH_METRICS"]


PATH_METRICS = ("alpha", "fisher_rao", "diffeomorphism")


def path_result(u, v, *, metric: str, **params):
    """The full :class:`~shapelib.geodesic.GeodesicResult` of a path metric (``"alpha"``,
    ``"fisher_rao"``: :func:`shapelib.geodesic`; ``"diffeomorphism"``:
    :func:`shapelib.landmark_diffeomorphism`) — what :func:`distance` reduces to its length."""
    if metric == "diffeomorphism":
        from .diffeomorphism import landmark_diffeomorphism

        return landmark_diffeomorphism(u, v, **params)
    if metric not in PATH_METRICS:
        raise ValueError(f"{metric!r} is not a path metric; choose one of {PATH_METRICS}")
    from .geodesic import geodesic

    if "sigma2" not in params:
        raise ValueError(f"metric {metric!r} needs sigma2=...")
    return geodesic(u, v, metric=metric, **params)


def _path_length(metric):
    return lambda u, v, **kw: path_result(u, v, metric=metric, **kw).length


def _procrustes(u, v, **kw):
    from .procrustes import procrustes_distance

    return procrustes_distance(u, v, **kw)


def _hausdorff(u, v, **kw):
    from .splines import hausdorff_distance

    return hausdorff_distance(u, v, **kw)


def _tps(u, v, **kw):
    from .splines import tps_bending_energy

    return tps_bending_energy(u, v, **kw)


def _wendland(u, v, **kw):
    from .splines import wendland_bending_energy

    return wendland_bending_energy(u, v, **kw)


METRICS = {
    "alpha": _path_length("alpha"),
    "fisher_rao": _path_length("fisher_rao"),
    "diffeomorphism": _path_length("diffeomorphism"),
    "procrustes": _procrustes,
    "hausdorff": _hausdorff,
    "tps": _tps,
    "wendland": _wendland,
}
#: metrics with d(u, v) = d(v, u); the others are computed for both orders in pairwise_distances
SYMMETRIC = {"alpha", "fisher_rao", "diffeomorphism", "procrustes", "hausdorff"}


def distance(u, v, *, metric: str, **params) -> float:
    """Distance between two landmark shapes under ``metric`` (see the module docstring).

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes with landmarks in correspondence.
    metric : str
        One of :data:`METRICS`.
    **params
        Options of that metric (e.g. ``sigma2`` for the information metrics).
    """
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose one of {sorted(METRICS)}")
    u, v = as_shape_pair(u, v)
    return float(METRICS[metric](u, v, **params))


def _one(args):
    i, j, u, v, metric, params = args
    return i, j, distance(u, v, metric=metric, **params)


def pairwise_distances(shapes, *, metric: str, n_jobs: int | None = 1, progress: bool = False, **params) -> np.ndarray:
    """Matrix of distances between every pair of ``shapes`` (N, K, d).

    Symmetric metrics are computed once per unordered pair; for the bending energies entry
    ``[i, j]`` is the energy of the map taking shape ``i`` onto shape ``j``.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
    metric : str
    n_jobs : int or None
        Worker processes (``None`` or ``-1``: all cores). Pairs are independent.
    progress : bool
        Show a progress bar (tqdm) if it is installed.
    **params
        Passed to :func:`distance`.

    Returns
    -------
    ndarray, shape (N, N)
        Zero diagonal.
    """
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose one of {sorted(METRICS)}")
    x = as_shapes(shapes, name="shapes")
    n = len(x)
    pairs = itertools.combinations(range(n), 2) if metric in SYMMETRIC else itertools.permutations(range(n), 2)
    tasks = [(i, j, x[i], x[j], metric, params) for i, j in pairs]
    out = np.zeros((n, n))
    workers = (os.cpu_count() or 1) if n_jobs in (None, -1) else int(n_jobs)
    bar = None
    if progress:
        try:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(tasks), desc=f"{metric} distances")
        except ImportError:
            pass
    if workers <= 1:
        results = map(_one, tasks)
    else:
        pool = cf.ProcessPoolExecutor(max_workers=workers)
        results = pool.map(_one, tasks, chunksize=1)
    try:
        for i, j, d in results:
            out[i, j] = d
            if metric in SYMMETRIC:
                out[j, i] = d
            if bar is not None:
                bar.update()
    finally:
        if workers > 1:
            pool.shutdown()
        if bar is not None:
            bar.close()
    return out
