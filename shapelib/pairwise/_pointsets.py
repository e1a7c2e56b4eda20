"""Point sets of different sizes through the engine: density distances modulo the similarity group.

``pairwise_distances(point_sets, metric="alpha_bound" | "fisher_rao_bound", modulo="similarity",
sigma2=...)`` takes a list of ``(n_i, 2)`` arrays. Each set is normalised once here, on the client
(centred on its mean, unit RMS radius: :func:`shapelib.pointsets.invariant.normalise_points`), and
its polar spectrum computed once (:func:`shapelib.pointsets.invariant.polar_spectra`), on one grid
covering all of them, so every block — whichever its size, in this process or on a Dask worker —
searches the rotations on the same grid and a pair's value does not depend on the block it fell
in; each task receives its sets with their spectra. A block is one call of
:func:`shapelib.pointsets.invariant.distances_from_spectra` (batched FFT angle search, then the α
value in closed form at the pose found).

A metric whose record says ``point_sets`` (``pairwise_distances(point_sets, metric="registration")``)
takes the sets as they are (checked once here, :func:`prepare_pairs`) and computes each pair with
its function (:func:`shapelib.pairwise._blocks.pair_block`). With ``shortlist=k`` the rigid bound
modulo similarity is computed first and only the pairs where one set is among the other's ``k``
nearest by it are computed; the blocks receive each set with its shortlist
(:func:`items_of`), mark the other pairs ``+inf``, and the driver fills them from the rigid bound
shifted above every computed value (:func:`fill_off_shortlist`).
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from .._validate import check_sigma2
from ..pointsets.checks import as_point_sets
from ..pointsets.invariant import (INVARIANT_METRICS, PolarSpectra, distances_from_spectra, normalise_points,
                                   polar_spectra, spectrum_kind)

#: the groups a point-set matrix can be taken modulo
MODULI = ("similarity",)
#: the options of a point-set metric (besides ``modulo``)
OPTIONS = ("sigma2", "reflection", "exact")


def prepare(shapes, metric: str, modulo: str, params: dict):
    """Check and normalise the point sets once and compute each one's polar spectrum.

    Returns ``(items, block_params, recorded, fingerprint)``: one ``(normalised set, spectrum)``
    item per set (what the blocks receive), the options every block gets, the options the
    store records (``modulo``, ``sigma2``, ``reflection``) and ``(sha256, sizes)`` of the sets.
    """
    if modulo not in MODULI:
        raise ValueError(f"modulo must be one of {MODULI}; got {modulo!r}")
    if metric not in INVARIANT_METRICS:
        raise ValueError(f"point sets modulo {modulo!r} are compared by {INVARIANT_METRICS}; got metric {metric!r}")
    unknown = sorted(set(params) - set(OPTIONS))
    if unknown:
        raise ValueError(f"metric {metric!r} modulo {modulo!r} has no parameter(s) {unknown}; it takes {list(OPTIONS)}")
    if "sigma2" not in params:
        raise ValueError(f"metric {metric!r} needs sigma2=... (in units of each set's RMS radius, e.g. 0.01)")
    s2 = check_sigma2(params["sigma2"])
    sets = as_point_sets(shapes, name="point sets")
    if sets[0].shape[1] != 2:
        raise ValueError(f"point sets modulo {modulo!r}: planar sets only ((n, 2) arrays); got d = {sets[0].shape[1]}")
    normalised = [normalise_points(x, name=f"point set {i}")[0] for i, x in enumerate(sets)]
    max_radius = max(float(np.sqrt(np.max(np.sum(x * x, axis=1)))) for x in normalised)
    t0 = time.perf_counter()
    spectra = polar_spectra(normalised, sigma2=s2, kind=spectrum_kind(metric), max_radius=max_radius)
    seconds = time.perf_counter() - t0
    items = [(x, spectra.coefficients[i]) for i, x in enumerate(normalised)]
    grid = {"weights": spectra.weights, "radii": spectra.radii, "n_angles": spectra.n_angles, "kind": spectra.kind}
    recorded = {"modulo": modulo, "sigma2": s2, "reflection": bool(params.get("reflection", True)),
                "exact": bool(params.get("exact", False))}
    block_params = {**recorded, "grid": grid, "spectra_seconds": seconds}
    h = hashlib.sha256()
    for x in sets:
        h.update(repr(x.shape).encode())
        h.update(np.ascontiguousarray(x).tobytes())
    return items, block_params, recorded, (h.hexdigest(), [len(x) for x in sets])


def _spectra(items, params) -> PolarSpectra:
    g = params["grid"]
    return PolarSpectra(np.stack([c for _, c in items]), g["weights"], g["radii"], g["n_angles"], g["kind"],
                        params["sigma2"])


def point_set_block(xi, xj, *, diagonal: bool, metric: str, params: dict) -> np.ndarray:
    """The distances of one block of ``(normalised set, spectrum)`` items (``xj`` ignored on a
    diagonal block: the symmetric matrix of ``xi``)."""
    xs = [x for x, _ in xi]
    if diagonal:
        return distances_from_spectra(xs, _spectra(xi, params), metric=metric, reflection=params["reflection"],
                                      exact=params["exact"])
    return distances_from_spectra(xs, _spectra(xi, params), [y for y, _ in xj], _spectra(xj, params),
                                  metric=metric, reflection=params["reflection"], exact=params["exact"])


def time_one_pair(items, metric: str, params: dict) -> float:
    """Seconds per pair within a block of up to 64 sets (twice; the faster: the first pays one-off costs)."""
    m = min(len(items), 64)
    best = np.inf
    for _ in range(2):
        t0 = time.perf_counter()
        point_set_block(items[:m], items[:m], diagonal=True, metric=metric, params=params)
        best = min(best, time.perf_counter() - t0)
    return best / max(1, m * (m - 1) // 2)


# -- point-set metrics without correspondence (``MetricInfo.point_sets``: ``"registration"``) -----------

#: the options of such a metric that the engine takes itself (the rigid shortlist), not the pair function
SHORTLIST_OPTIONS = ("shortlist", "shortlist_metric", "shortlist_sigma2")


def prepare_pairs(shapes, info, params: dict):
    """Check the sets and the options of a point-set metric once (``info.point_sets``).

    Returns ``(sets, pair_params, shortlist, fingerprint)``: the float64 sets, the options each
    pair's function gets, the shortlist options (``None`` without ``shortlist``) and
    ``(sha256, sizes)``.
    """
    from ..distances import check_metric_params

    params = dict(params)
    short = {key: params.pop(key) for key in SHORTLIST_OPTIONS if key in params}
    check_metric_params(info, params)
    sets = as_point_sets(shapes, name="point sets")
    if len(sets) < 2:
        raise ValueError(f"point sets: at least 2 to compare; got {len(sets)}")
    shortlist = None
    if short.get("shortlist") is not None:
        k = short["shortlist"]
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k < len(sets):
            raise ValueError(f"shortlist must be an integer between 1 and N − 1 = {len(sets) - 1}; got {k!r}")
        metric = short.get("shortlist_metric", "fisher_rao_bound")
        if metric not in INVARIANT_METRICS:
            raise ValueError(f"shortlist_metric must be one of {INVARIANT_METRICS}; got {metric!r}")
        shortlist = {"shortlist": int(k), "shortlist_metric": metric,
                     "shortlist_sigma2": check_sigma2(short.get("shortlist_sigma2", 0.01))}
    elif set(short) - {"shortlist"}:
        raise ValueError(f"{sorted(set(short) - {'shortlist'})} apply only with shortlist=k")
    h = hashlib.sha256()
    for x in sets:
        h.update(repr(x.shape).encode())
        h.update(np.ascontiguousarray(x).tobytes())
    return sets, params, shortlist, (h.hexdigest(), [len(x) for x in sets])


def shortlist_neighbours(rigid: np.ndarray, k: int) -> np.ndarray:
    """Each row's ``k`` nearest other columns of the rigid matrix, ties by index: ``(N, k)`` ints."""
    d = np.array(rigid, dtype=np.float64)
    np.fill_diagonal(d, np.inf)
    return np.argsort(d, axis=1, kind="stable")[:, :k]


def shortlist_mask(neighbours: np.ndarray) -> np.ndarray:
    """The pairs to register: ``j`` among ``i``'s shortlist or ``i`` among ``j``'s (symmetric)."""
    n = len(neighbours)
    mask = np.zeros((n, n), dtype=bool)
    mask[np.repeat(np.arange(n), neighbours.shape[1]), neighbours.ravel()] = True
    return mask | mask.T


def items_of(sets, neighbours=None) -> list:
    """What the blocks receive: ``(set, its index, its shortlist or None)`` for each set."""
    return [(x, i, None if neighbours is None else frozenset(int(j) for j in neighbours[i]))
            for i, x in enumerate(sets)]


def fill_off_shortlist(matrix: np.ndarray, rigid: np.ndarray) -> tuple[np.ndarray, float]:
    """The pairs off the shortlist (``+inf``) from the rigid bound, shifted above every registered
    value: ``D_ij = M + ε + rigid_ij`` with ``M`` the largest registered value, so that each row ranks
    its registered pairs first, the others after them in the rigid bound's order. Returns the matrix
    and the shift ``M + ε``."""
    off = np.isinf(matrix)
    finite = matrix[~off & ~np.eye(len(matrix), dtype=bool)]
    top = float(finite.max()) if finite.size else 0.0
    shift = top + 1e-9 * max(top, 1.0)
    out = matrix.copy()
    out[off] = shift + rigid[off]
    return out, shift
