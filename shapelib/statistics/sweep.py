"""Statistics across a sweep of distance matrices (e.g. one per σ², :func:`shapelib.bound_matrix_sweep`),
with a test that survives the sweep.

Looking at a statistic over many σ² values and reporting the best one is a multiple test: the
smallest of twenty permutation p-values is not a p-value (under no effect at all it falls below
0.05 far more often than one time in twenty). :func:`permanova_sweep` and :func:`knn_sweep`
compute the statistic at every σ² **with the same permutations**, and add Westfall & Young's
(1993) min-P test over the whole sweep: each permutation's statistic at each σ² becomes its own
permutation p-value (its rank among the observed and permuted values at that σ²), and the
observed smallest p over the sweep is compared with the smallest p over the sweep of every
permutation. That family-wise p-value is valid whichever σ² turns out best, and it is never below
the plain p-value at the best σ² (``tests/test_sweep.py``). Its resolution is coarser than a
single test's: each of the S values has a permutation on top, so the smallest attainable
family-wise p is about S / (1 + permutations) — use at least 50 S permutations (999 for 20 values).

Pure functions of a stack of ``(N, N)`` distance matrices and labels; they know nothing about shapes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .distance_based import TIE_RTOL, KnnResult, PermanovaResult, knn_loo_accuracy, permanova

__all__ = ["SweepTest", "permanova_sweep", "knn_sweep", "min_p_adjusted"]


@dataclass
class SweepTest:
    """One statistic across a sweep, with its family-wise permutation test.

    Attributes
    ----------
    statistic : ndarray, shape (S,)
        Observed statistic at each value of the sweep.
    p_values : ndarray, shape (S,)
        Plain permutation p-value at each value (each valid for that value alone).
    best : int
        Index of the value with the smallest p (ties: the largest statistic).
    p_family : float
        Westfall–Young min-P p-value of the whole sweep: how often the best of the sweep is at
        least this good when the labels carry no information. Report this, not ``p_values[best]``.
    name : str
        What the statistic is, for :meth:`summary`.
    n_permutations : int
        Permutations, the same at every value.
    results : list
        The result of each value's test (:class:`PermanovaResult` or :class:`KnnResult`).

    See Also
    --------
    permanova_sweep, knn_sweep : What return it.
    min_p_adjusted : The family-wise p-value.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> rng = np.random.default_rng(0)
    >>> group = np.repeat(["a", "b"], 6)
    >>> points = rng.normal(size=(12, 2))
    >>> # three matrices: the groups drawn 0, 1 and 3 units apart
    >>> sweep = [squareform(pdist(points + shift * (group == "b")[:, None])) for shift in (0.0, 1.0, 3.0)]
    >>> from shapelib.statistics import permanova_sweep
    >>> test = permanova_sweep(sweep, {"group": group}, term="group", n_permutations=99)
    >>> test.statistic.round(2), test.best, test.p_family
    (array([ 1.46,  3.43, 33.36]), 2, 0.02)
    >>> print(test.summary())
    PERMANOVA pseudo-F of group: best at sweep value 2 (33.36, plain p = 0.01); over the whole sweep of 3 values p = 0.02 (Westfall-Young min-P, 99 permutations)
    """

    statistic: np.ndarray
    p_values: np.ndarray
    best: int
    p_family: float
    name: str
    n_permutations: int
    results: list = field(default_factory=list, repr=False)

    def summary(self) -> str:
        b = self.best
        return (f"{self.name}: best at sweep value {b} ({self.statistic[b]:.4g}, plain p = {self.p_values[b]:.3g}); "
                f"over the whole sweep of {len(self.statistic)} values p = {self.p_family:.3g} "
                f"(Westfall-Young min-P, {self.n_permutations} permutations)")


def min_p_adjusted(observed, null, *, rtol: float = 0.0):
    r"""Plain and family-wise (min-P) p-values of a statistic observed at S values of a sweep.

    With the observed row :math:`t_{0s}` and the permuted rows :math:`t_{ks}`,
    :math:`k = 1 … P`, each row's p-value at value :math:`s` among all :math:`1 + P` rows, and
    Westfall & Young's (1993) min-P adjustment over the sweep, are

    .. math::

        p_{ks} = \frac{\#\{k' : t_{k's} \ge t_{ks}\}}{1 + P}, \qquad
        p_\text{family} = \frac{\#\{k : \min_s p_{ks} \le \min_s p_{0s}\}}{1 + P}.

    Parameters
    ----------
    observed : array_like, shape (S,)
        The statistic at each value (larger is stronger).
    null : array_like, shape (P, S)
        The statistic under P permutations, the same permutation in a row for every value.
    rtol : float
        A permuted value within ``rtol · |value|`` below another counts as at least as large
        (ties in recomputed statistics).

    Returns
    -------
    p : ndarray, shape (S,)
        ``(1 + #{null ≥ observed}) / (1 + P)`` per value.
    p_family : float
        ``#{k : min_s p_ks ≤ min_s p_s} / (1 + P)`` over the observed (k = 0) and permuted rows,
        where ``p_ks`` is the p-value of row k's statistic at value s among all ``1 + P`` rows.

    See Also
    --------
    permanova_sweep, knn_sweep : The sweeps it adjusts.

    Examples
    --------
    The smallest plain p of three values is not a p-value for the sweep; the family-wise one
    is larger:

    >>> import numpy as np
    >>> from shapelib.statistics import min_p_adjusted
    >>> null = np.random.default_rng(0).normal(size=(99, 3))   # 99 permutations, 3 values
    >>> p, p_family = min_p_adjusted([0.5, 2.5, 1.0], null)
    >>> p, p_family
    (array([0.3 , 0.02, 0.15]), 0.06)
    """
    obs = np.asarray(observed, dtype=np.float64)
    nul = np.asarray(null, dtype=np.float64)
    if obs.ndim != 1 or nul.ndim != 2 or nul.shape[1] != obs.shape[0] or nul.shape[0] < 1:
        raise ValueError(f"observed must be (S,) and null (P, S) with P >= 1; got {obs.shape} and {nul.shape}")
    rows = np.vstack([obs, nul])  # (1 + P, S)
    n = len(rows)
    # p of each row at each value: share of all rows at least as large (within rtol)
    p_all = np.empty_like(rows)
    for s in range(rows.shape[1]):
        col = rows[:, s]
        srt = np.sort(col)
        thresh = col - rtol * np.abs(col)
        p_all[:, s] = (n - np.searchsorted(srt, thresh, side="left")) / n
    p = (1.0 + np.count_nonzero(nul >= (obs - rtol * np.abs(obs))[None, :], axis=0)) / n
    mins = p_all.min(axis=1)
    p_family = float(np.count_nonzero(mins <= mins[0] * (1 + 1e-12)) / n)
    return p, p_family


def _best(p, stat):
    order = np.lexsort((-stat, p))
    return int(order[0])


def permanova_sweep(distances, covariates, *, term: str, n_permutations: int = 999, seed: int | None = 0,
                    **kw) -> SweepTest:
    """PERMANOVA (:func:`shapelib.statistics.distance_based.permanova`) at every matrix of a sweep.

    Parameters
    ----------
    distances : sequence of array_like, each (N, N)
        One distance matrix per value of the sweep (e.g. per σ²), rows in the same order.
    covariates : pandas.DataFrame or dict
        The model, as for :func:`permanova` (every term in the model at every value).
    term : str
        The term whose pseudo-F is followed across the sweep.
    n_permutations, seed
        As :func:`permanova`; the same seed gives every matrix the same permutations, which the
        family-wise test needs.
    **kw
        Other options of :func:`permanova` (``by``, ``permute``).

    Returns
    -------
    SweepTest
        Statistic: the term's pseudo-F; ``results``: the :class:`PermanovaResult` of each matrix.

    See Also
    --------
    min_p_adjusted : The family-wise p-value over the sweep.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> rng = np.random.default_rng(0)
    >>> group = np.repeat(["a", "b"], 6)
    >>> points = rng.normal(size=(12, 2))
    >>> # three matrices: the groups drawn 0, 1 and 3 units apart
    >>> sweep = [squareform(pdist(points + shift * (group == "b")[:, None])) for shift in (0.0, 1.0, 3.0)]
    >>> from shapelib.statistics import permanova_sweep
    >>> test = permanova_sweep(sweep, {"group": group}, term="group", n_permutations=99)
    >>> test.p_values, test.best, test.p_family
    (array([0.21, 0.1 , 0.01]), 2, 0.02)
    """
    cov = pd.DataFrame(covariates)
    if term not in cov.columns:
        raise ValueError(f"term {term!r} is not a column of covariates {list(cov.columns)}")
    results: list[PermanovaResult] = [permanova(d, cov, n_permutations=n_permutations, seed=seed, **kw)
                                      for d in distances]
    if not results:
        raise ValueError("distances: the sweep is empty")
    stat = np.array([r.table.loc[term, "pseudo_F"] for r in results])
    null = np.column_stack([r.null[term] for r in results])
    p, p_family = min_p_adjusted(stat, null, rtol=TIE_RTOL)
    return SweepTest(stat, p, _best(p, stat), p_family, f"PERMANOVA pseudo-F of {term}", int(n_permutations), results)


def knn_sweep(distances, labels, *, n_neighbors: int = 5, n_permutations: int = 999, seed: int | None = 0) -> SweepTest:
    """Leave-one-out k-NN accuracy (:func:`shapelib.statistics.distance_based.knn_loo_accuracy`) at
    every matrix of a sweep, the same label permutations for all, with the family-wise test.

    Parameters
    ----------
    distances : sequence of array_like, each (N, N)
        One distance matrix per value of the sweep (e.g. per σ²), rows in the same order.
    labels : array_like, shape (N,)
        Class of each object.
    n_neighbors : int
        ``k``, as :func:`knn_loo_accuracy`.
    n_permutations : int
        Label permutations, the same for every matrix.
    seed : int or None
        As :func:`knn_loo_accuracy`; the same seed gives every matrix the same permutations,
        which the family-wise test needs.

    Returns
    -------
    SweepTest
        Statistic: the accuracy; ``results``: the :class:`KnnResult` of each matrix.

    See Also
    --------
    min_p_adjusted : The family-wise p-value over the sweep.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> rng = np.random.default_rng(0)
    >>> group = np.repeat(["a", "b"], 6)
    >>> points = rng.normal(size=(12, 2))
    >>> # three matrices: the groups drawn 0, 1 and 3 units apart
    >>> sweep = [squareform(pdist(points + shift * (group == "b")[:, None])) for shift in (0.0, 1.0, 3.0)]
    >>> from shapelib.statistics import knn_sweep
    >>> test = knn_sweep(sweep, group, n_neighbors=3, n_permutations=99)
    >>> test.statistic.round(3), test.p_values, test.p_family
    (array([0.333, 0.667, 1.   ]), array([0.71, 0.13, 0.01]), 0.02)
    """
    results: list[KnnResult] = [knn_loo_accuracy(d, labels, n_neighbors=n_neighbors, n_permutations=n_permutations,
                                                 seed=seed) for d in distances]
    if not results:
        raise ValueError("distances: the sweep is empty")
    stat = np.array([r.accuracy for r in results])
    null = np.column_stack([r.null for r in results])
    p, p_family = min_p_adjusted(stat, null)
    return SweepTest(stat, p, _best(p, stat), p_family, f"{n_neighbors}-NN leave-one-out accuracy",
                     int(n_permutations), results)
