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

from .._validate import deprecated_alias, keeps_old_calls
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
    n_permutations : int
    """

    statistic: np.ndarray
    p_values: np.ndarray
    best: int
    p_family: float
    name: str
    n_permutations: int
    results: list = field(default_factory=list, repr=False)

    permutations = deprecated_alias("permutations", "n_permutations", owner="SweepTest")

    def summary(self) -> str:
        b = self.best
        return (f"{self.name}: best at sweep value {b} ({self.statistic[b]:.4g}, plain p = {self.p_values[b]:.3g}); "
                f"over the whole sweep of {len(self.statistic)} values p = {self.p_family:.3g} "
                f"(Westfall-Young min-P, {self.n_permutations} permutations)")


def min_p_adjusted(observed, null, *, rtol: float = 0.0):
    """Plain and family-wise (min-P) p-values of a statistic observed at S values of a sweep.

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


@keeps_old_calls(renamed={"permutations": "n_permutations"})
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


@keeps_old_calls(renamed={"permutations": "n_permutations"})
def knn_sweep(distances, labels, *, n_neighbors: int = 5, n_permutations: int = 999, seed: int | None = 0) -> SweepTest:
    """Leave-one-out k-NN accuracy (:func:`shapelib.statistics.distance_based.knn_loo_accuracy`) at
    every matrix of a sweep, the same label permutations for all, with the family-wise test.

    Returns
    -------
    SweepTest
        Statistic: the accuracy; ``results``: the :class:`KnnResult` of each matrix.
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
