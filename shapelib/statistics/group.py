"""A difference in mean shape between two groups: permutation test, the two Fréchet means and the
geodesic between them.

Test statistic
    At the pooled Fréchet mean ``m`` (:mod:`shapelib.statistics.frechet`) every shape has its log
    map ``v_i``; the statistic is the metric distance between the groups' mean log maps,

        T = ‖v̄_A − v̄_B‖_{g(m)},

    the first-order (tangent-space) approximation of the distance between the two groups'
    Fréchet means. It is computed from the Gram matrix ``G_ij = v_iᵀ g(m) v_j`` (no truncation:
    sliding components weigh nothing), so a relabelling costs ``O(N²)`` arithmetic and no path
    solve. The pooled mean and its log maps do not depend on the labels, so under the null
    hypothesis of exchangeable labels the permutation test is exact: the p-value is
    ``(1 + #{T_π ≥ T}) / (1 + n_permutations)`` over random relabellings ``π`` (Phipson & Smyth
    2010); use ``n_permutations ≥ 999`` for a p-value you report.

What is reported besides
    The groups' own Fréchet means (Karcher iterations started at the pooled mean, warm-started
    from the pooled log maps), the intrinsic distance between them (the length of the geodesic,
    :func:`shapelib.geodesic`) and that geodesic — the deformation from one mean to the other, for
    pictures (:mod:`shapelib.plotting`, :func:`shapelib.extrinsic_warp`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validate import as_shapes, check_dimension, check_positive_int, set_checked
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING
from ..solver.geodesic import geodesic
from ..solver.logexp import DEFAULT_LOG_STEPS, DEFAULT_RCOND
from ..solver.result import GeodesicResult
from ._run import MEAN_ROUNDS, where_logs_run
from .frechet import (FrechetMeanResult, check_population, frechet_mean, geodesic_options, karcher_iteration,
                      procrustes_mean)

__all__ = ["MeanDifferenceResult", "mean_difference_test", "permutation_statistics", "MIN_PERMUTATIONS"]

#: a group smaller than this draws a warning (its mean is barely estimated, its permutations few)
SMALL_GROUP = 3

#: fewest permutations accepted (the smallest attainable p-value is 1 / (1 + n_permutations))
MIN_PERMUTATIONS = 19


@dataclass
class MeanDifferenceResult:
    """Result of :func:`mean_difference_test`.

    Attributes
    ----------
    labels : tuple
        The two group labels, in the order of the difference (``A``, ``B``).
    sizes : tuple of int
    statistic : float
        ``T = ‖v̄_A − v̄_B‖_{g(m)}`` at the pooled mean.
    p_value : float
        ``(1 + #{T_π ≥ T}) / (1 + n_permutations)``.
    n_permutations : int
    null : ndarray (n_permutations,)
        The permuted statistics.
    difference : ndarray (K, d)
        ``v̄_B − v̄_A``: the mean difference as a tangent vector at the pooled mean.
    pooled : FrechetMeanResult
    means : tuple of FrechetMeanResult, or None
        The groups' Fréchet means (``group_means=True``).
    distance : float or None
        Intrinsic distance between the two means: the length of :attr:`geodesic` (an upper bound
        on the geodesic distance; ``geodesic.lower_bound`` is a lower one).
    geodesic : GeodesicResult or None
        From the mean of ``A`` to the mean of ``B``.

    See Also
    --------
    mean_difference_test : What returns it.

    Examples
    --------
    Two groups of ellipses of different widths:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> s = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> rng = np.random.default_rng(1)
    >>> x = np.stack([np.c_[(2.0 + 0.3 * (i % 2)) * np.cos(s), np.sin(s)] + 0.02 * rng.normal(size=(8, 2))
    ...               for i in range(12)])
    >>> x = sl.pose_align(x)[0]
    >>> test = sl.mean_difference_test(x, np.arange(12) % 2, sigma2=0.5, n_permutations=199, group_means=False,
    ...                                n_jobs=1)
    >>> test.labels, test.sizes, test.null.shape, test.difference.shape
    ((0, 1), (6, 6), (199,), (8, 2))
    >>> print(test.summary())
    0 (n = 6) vs 1 (n = 6), alpha: tangent distance between the group means 0.04038, permutation p = 0.01 (199 permutations)
    """

    labels: tuple
    sizes: tuple
    statistic: float
    p_value: float
    n_permutations: int
    null: np.ndarray
    difference: np.ndarray
    pooled: FrechetMeanResult
    means: tuple | None = None
    distance: float | None = None
    geodesic: GeodesicResult | None = None

    def summary(self) -> str:
        a, b = self.labels
        s = (f"{a} (n = {self.sizes[0]}) vs {b} (n = {self.sizes[1]}), {self.pooled.options.metric}: tangent distance "
             f"between the group means {self.statistic:.4g}, permutation p = {self.p_value:.4g} "
             f"({self.n_permutations} permutations)")
        if not self.pooled.converged:
            s += (f" [the pooled mean did not converge in {self.pooled.n_iter} iterations: the tangent distance is "
                  "measured at its last iterate]")
        if self.distance is not None:
            s += f"; geodesic distance between the Fréchet means {self.distance:.4g}"
            late = [f"{lab} (after {m.n_iter} iterations)" for lab, m in zip(self.labels, self.means or ())
                    if not m.converged]
            if late:
                s += (f" [not converged: the Fréchet mean of {' and '.join(late)}; the distance is between the last "
                      "iterates, not the means]")
            elif self.geodesic is not None and not self.geodesic.converged:
                s += (f" [the geodesic between the means did not converge: the distance is the length of the path it "
                      f"had, an upper bound; lower bound {self.geodesic.lower_bound:.4g}]")
        return s

    @property
    def converged(self) -> bool:
        """Whether the pooled mean, the group means and the geodesic between them all converged."""
        parts = [self.pooled.converged, *(m.converged for m in self.means or ())]
        if self.geodesic is not None:
            parts.append(self.geodesic.converged)
        return bool(all(parts))


def _sorted_labels(values) -> list:
    """``values`` in their natural order (9 before 10), or as text where they do not compare."""
    try:
        return sorted(values)
    except TypeError:
        return sorted(values, key=str)


def permutation_statistics(gram, labels, n_permutations, rng):
    """``‖v̄_A − v̄_B‖`` for the observed labels (bool array, True = B) and ``n_permutations``
    random relabellings, from the Gram matrix of the log maps."""
    n = len(labels)
    nb = int(labels.sum())
    na = n - nb

    def stat(lab):
        w = np.where(lab, 1.0 / nb, -1.0 / na)
        return np.sqrt(np.maximum(np.einsum("...i,ij,...j->...", w, gram, w), 0.0))

    observed = float(stat(labels))
    perms = np.stack([rng.permutation(labels) for _ in range(n_permutations)]) if n_permutations else np.zeros((0, n))
    return observed, stat(perms)


def mean_difference_test(shapes, groups, *, metric: str = "alpha", sigma2, order=None, n_permutations: int = 999,
                         seed=0, pooled: FrechetMeanResult | None = None, group_means: bool = True,
                         geodesic_steps: int = 16, tol: float = 1e-3, n_steps: int = DEFAULT_LOG_STEPS,
                         rcond: float = DEFAULT_RCOND, grid_spacing: float = DEFAULT_SPACING,
                         grid_margin: float = DEFAULT_MARGIN, executor=None, chunk_size: int | None = None,
                         n_jobs: int | None = None, client=None, scheduler=None,
                         **mean_options) -> MeanDifferenceResult:
    """Test whether two groups differ in mean shape; their Fréchet means and the geodesic between them.

    The statistic is the metric norm ``T = ‖v̄_A − v̄_B‖_g`` of the difference of the groups' mean
    log maps at the pooled Fréchet mean; its p-value ``(1 + #{T_π ≥ T}) / (1 + n_permutations)``
    over random relabellings (module docstring).

    Parameters
    ----------
    shapes : array_like (N, K, d)
    groups : array_like (N,)
        Two distinct labels.
    metric, sigma2
        The metric (eq. 22 or eq. 6).
    order : sequence of the two labels, optional
        ``(A, B)``: the difference and the geodesic go from ``A`` to ``B`` (default: the labels sorted;
        as text where they do not compare, e.g. a number and a string).
    n_permutations : int
        Random relabellings (≥ 999 for a reported p-value).
    seed : int or numpy Generator
    pooled : FrechetMeanResult, optional
        The Fréchet mean of all the shapes (computed when not given).
    group_means : bool
        Also compute the groups' Fréchet means, the distance between them and their geodesic.
    geodesic_steps : int
        Segments of the geodesic between the group means.
    tol, n_steps, rcond, grid_spacing, grid_margin, executor, chunk_size, **mean_options
        As in :func:`~shapelib.statistics.frechet.frechet_mean`.
    n_jobs, client, scheduler
        Where the log maps run, as for :func:`shapelib.frechet_mean`.

    Returns
    -------
    MeanDifferenceResult

    See Also
    --------
    shapelib.frechet_mean, shapelib.statistics.permanova

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> s = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> rng = np.random.default_rng(1)
    >>> x = np.stack([np.c_[(2.0 + 0.3 * (i % 2)) * np.cos(s), np.sin(s)] + 0.02 * rng.normal(size=(8, 2))
    ...               for i in range(12)])
    >>> x = sl.pose_align(x)[0]
    >>> test = sl.mean_difference_test(x, np.arange(12) % 2, sigma2=0.5, n_permutations=199, group_means=False,
    ...                                n_jobs=1)
    >>> bool(test.p_value < 0.05)
    True
    """
    x = as_shapes(shapes, name="shapes")
    check_dimension(x, name="shapes")
    g = np.asarray(groups)
    if g.shape != (len(x),):
        raise ValueError(f"groups must have one label per shape ({len(x)}); got shape {g.shape}")
    labels = tuple(order) if order is not None else tuple(_sorted_labels(set(g.tolist())))
    if len(labels) != 2 or set(labels) != set(g.tolist()):
        found = _sorted_labels(set(g.tolist()))
        raise ValueError(f"groups must hold exactly two labels{' (those of order)' if order is not None else ''}; "
                         f"found {len(found)}: {found[:6]}")
    is_b = g == labels[1]
    sizes = (int((~is_b).sum()), int(is_b.sum()))
    if min(sizes) < 1:
        raise ValueError(f"both groups need shapes; sizes {dict(zip(labels, sizes))}")
    if min(sizes) < SMALL_GROUP:
        import math
        import warnings

        small = labels[int(np.argmin(sizes))]
        warnings.warn(f"group {small!r} has {min(sizes)} shape(s) against {max(sizes)}: its mean is barely estimated "
                      f"and the permutation test has only {math.comb(sum(sizes), min(sizes))} distinct relabellings "
                      f"(smallest possible p {1 / math.comb(sum(sizes), min(sizes)):.3g})", UserWarning, stacklevel=2)
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    if n_permutations < MIN_PERMUTATIONS:
        raise ValueError(f"n_permutations must be at least {MIN_PERMUTATIONS}; got {n_permutations}")
    opts_kw = dict(metric=metric, sigma2=sigma2, n_steps=n_steps, rcond=rcond, grid_spacing=grid_spacing,
                   grid_margin=grid_margin)
    check_population(x, metric=metric, sigma2=sigma2, stacklevel=3)
    start = {}  # the Procrustes mean, once: the timed log map's base and the pooled mean's start

    def base():
        if pooled is not None:
            return pooled.mean
        if mean_options.get("init") is not None:  # the user's start
            return np.asarray(mean_options["init"], dtype=np.float64)
        start.setdefault("init", procrustes_mean(x))
        return start["init"]

    options = pooled.options if isinstance(pooled, FrechetMeanResult) else geodesic_options(
        **opts_kw, **{k: mean_options[k] for k in ("log_tol", "log_max_iter") if k in mean_options})
    rounds = (0.0 if pooled is not None else MEAN_ROUNDS) + (MEAN_ROUNDS if group_means else 0.0)
    with set_checked(), where_logs_run(x, options, base=base, rounds=rounds, executor=executor, n_jobs=n_jobs,
                                       client=client, scheduler=scheduler, chunk_size=chunk_size) as where:
        # warned once for the whole population
        return _test(x, is_b, labels, sizes, n_permutations, seed, pooled, group_means, geodesic_steps, tol,
                     {**opts_kw, **where.passed_on, **start}, where.executor, where.chunk_size, mean_options)


def _test(x, is_b, labels, sizes, n_permutations, seed, pooled, group_means, geodesic_steps, tol, opts_kw, executor,
          chunk_size, mean_options):
    if pooled is None:
        pooled = frechet_mean(x, tol=tol, **opts_kw, **mean_options)
    elif not isinstance(pooled, FrechetMeanResult) or pooled.logs.shape != x.shape:
        raise ValueError("pooled must be the FrechetMeanResult of these shapes")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    gram = pooled.tangent.gram(pooled.logs)
    observed, null = permutation_statistics(gram, is_b, n_permutations, rng)
    p = (1 + int(np.count_nonzero(null >= observed * (1 - 1e-12)))) / (1 + n_permutations)
    diff = pooled.logs[is_b].mean(axis=0) - pooled.logs[~is_b].mean(axis=0)
    res = MeanDifferenceResult(labels=labels, sizes=sizes, statistic=observed, p_value=p, n_permutations=n_permutations,
                               null=null, difference=diff, pooled=pooled)
    if group_means:
        means = []
        for sel in (~is_b, is_b):
            paths = [r for r, s in zip(pooled.paths, sel) if s]
            means.append(karcher_iteration(x[sel], pooled.mean, options=pooled.options, tol=tol,
                                           max_iter=mean_options.get("max_iter", 30), executor=executor,
                                           chunk_size=chunk_size, inits=paths))
        geo = geodesic(means[0].mean, means[1].mean, metric=pooled.options.metric, sigma2=pooled.options.sigma2,
                       n_steps=geodesic_steps, tol=1e-8, grid_spacing=pooled.options.grid_spacing,
                       grid_margin=pooled.options.grid_margin)
        res.means, res.distance, res.geodesic = tuple(means), float(geo.length), geo
    return res
