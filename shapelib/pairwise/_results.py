"""The engine's results: :class:`PairwiseResult`, :class:`PairError`, :class:`BlockProgress`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import InputError
from ..distances import SYMMETRIC

class PairError(ValueError):
    """A pair's input was rejected by its metric: which pair and why.

    ``i``, ``j`` are the row and column of the matrix, i.e. ``shapes[i]`` is the metric's ``u``
    and ``shapes[j]`` its ``v``; ``reason`` is the metric's own message (which speaks of ``u``
    and ``v`` and counts landmarks from 0); ``landmarks``: the landmark indices it names (from 0),
    empty if none. Raised in-process and, unchanged, through Dask.

    Parameters
    ----------
    i, j : int
        The pair's row and column of the matrix.
    reason : str or Exception
        The metric's rejection; an :class:`~shapelib.InputError` also gives the landmarks.
    landmarks : sequence of int, optional
        Landmark indices (from 0) the reason names; default: those of an
        :class:`~shapelib.InputError` reason, else none.

    Attributes
    ----------
    i, j : int
        As given.
    reason : str
        The metric's message.
    landmarks : tuple of int
        The landmarks it names.

    See Also
    --------
    compute_pairwise : Raises it, before or during the run.

    Examples
    --------
    >>> from shapelib.pairwise import PairError
    >>> exc = PairError(2, 5, ValueError("u and v have different numbers of landmarks"))
    >>> print(exc)
    pair (shapes[2], shapes[5]) as (u, v): u and v have different numbers of landmarks
    >>> isinstance(exc, ValueError), exc.i, exc.j, exc.landmarks
    (True, 2, 5, ())
    """

    def __init__(self, i, j, reason, landmarks=()):
        if not landmarks and isinstance(reason, InputError):
            landmarks = reason.facts.get("landmarks", ())
        landmarks = tuple(int(k) for k in landmarks)
        super().__init__(int(i), int(j), str(reason), landmarks)  # args: what pickling (Dask) rebuilds it from
        self.i, self.j, self.reason, self.landmarks = int(i), int(j), str(reason), landmarks

    def __str__(self):
        return f"pair (shapes[{self.i}], shapes[{self.j}]) as (u, v): {self.reason}"


@dataclass
class PairwiseResult:
    """A distance matrix with the diagnostics of every pair.

    Attributes
    ----------
    matrix : ndarray, shape (N, N)
        Distances, zero diagonal; for asymmetric metrics ``[i, j]`` is the map from ``i`` onto ``j``.
        NaN where a partial store has no value yet (see ``computed``).
    lower, upper : ndarray, shape (N, N)
        Certified bounds ``lower ≤ d ≤ upper`` (= ``matrix`` for non-path metrics).
    energy : ndarray, shape (N, N)
        Path energy (eq. 8) of the computed path; NaN for non-path metrics.
    seconds : ndarray, shape (N, N)
        Wall time of each pair.
    converged : ndarray of bool, shape (N, N)
        In words per pair: :meth:`status` (converged / bracket wider than rtol / solver failed).
    n_iter : ndarray of int, shape (N, N)
        Solver iterations (0 for non-path metrics, −1 where not computed).
    metric : str
    params : dict
        Every parameter of the metric, defaults filled in (and ``rtol`` if given).
    store : str or None
        Path of the zarr store.
    computed : ndarray of bool, shape (N, N)
        Pairs whose values are present (all, for a finished run).
    log : dict
        Blocks in total / computed by this call / found done, block size, where it ran, wall
        seconds, ``stopped`` (True when a ``callback`` stopped the run), ``estimated_seconds``
        (pairs × timed seconds per pair ÷ workers, when a pair was timed).
    symmetric : bool or None
        Whether the metric is symmetric (pairs ``i < j`` only); None: looked up by name.
    """

    matrix: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    energy: np.ndarray
    seconds: np.ndarray
    converged: np.ndarray
    n_iter: np.ndarray
    metric: str
    params: dict
    store: str | None = None
    computed: np.ndarray | None = None
    log: dict = field(default_factory=dict, repr=False)
    symmetric: bool | None = None

    @property
    def complete(self) -> bool:
        """True when every pair is computed."""
        return bool(self.computed is None or self.computed.all())

    def _pairs(self):
        n = len(self.matrix)
        symmetric = self.metric in SYMMETRIC if self.symmetric is None else self.symmetric
        i, j = np.triu_indices(n, 1) if symmetric else np.nonzero(~np.eye(n, dtype=bool))
        keep = self.computed[i, j] if self.computed is not None else np.ones(len(i), bool)
        return i[keep], j[keep]

    def nonconverged_pairs(self) -> list[tuple[int, int]]:
        """Computed pairs ``(i, j)`` (``i < j`` for symmetric metrics) whose solver did not converge."""
        i, j = self._pairs()
        bad = ~self.converged[i, j]
        return [(int(a), int(b)) for a, b in zip(i[bad], j[bad])]

    def rel_gap(self, i=None, j=None) -> np.ndarray:
        """``upper / lower − 1`` of pairs ``(i, j)`` (default: every computed pair, as :meth:`to_frame`
        orders them): the relative width of each certified bracket (0 for non-path metrics, ``inf``
        where the bound is 0 but the path is not)."""
        if i is None:
            i, j = self._pairs()
        lo, up = self.lower[i, j], self.upper[i, j]
        with np.errstate(divide="ignore", invalid="ignore"):
            gap = np.where(lo > 0, up / lo - 1.0, np.where(up > 0, np.inf, 0.0))
        return np.maximum(gap, 0.0)

    def status(self, i=None, j=None) -> np.ndarray:
        """Per pair, in words: ``"converged"``; ``"bracket wider than rtol"`` (with ``rtol``: the
        distance is certified to lie in its bracket ``[lower, upper]``, whose relative width
        :meth:`rel_gap` is above ``rtol``, the value being its upper end); ``"solver failed"`` (no
        ``rtol``: the geodesic solver stopped before its tolerance, so ``value`` is the length of
        the path it had, still an upper bound on the distance)."""
        if i is None:
            i, j = self._pairs()
        bad = "bracket wider than rtol" if self.params.get("rtol") is not None else "solver failed"
        return np.where(self.converged[i, j], "converged", bad)

    @property
    def value(self) -> np.ndarray:
        """The distances: :attr:`matrix` (the results' common name for what was computed)."""
        return self.matrix

    @property
    def stop_reason(self) -> str:
        """``"complete"``, ``"stopped"`` (a ``callback`` stopped the run) or ``"partial"`` (a store
        read before its run finished)."""
        if self.complete:
            return "complete"
        return "stopped" if self.log.get("stopped") else "partial"

    def summary(self) -> str:
        """One line: the matrix, how many pairs are computed, and the pairs that did not converge
        in :meth:`status`'s words (with how wide the brackets are).

        Examples
        --------
        >>> import numpy as np
        >>> import shapelib as sl
        >>> x = np.random.default_rng(0).normal(size=(4, 5, 2))
        >>> r = sl.pairwise_distances(x, metric="procrustes", n_jobs=1, progress=False, return_result=True)
        >>> r.summary()
        '4 × 4 procrustes matrix: 6 of 6 pairs computed, all converged'
        """
        i, _ = self._pairs()
        n = len(self.matrix)
        total = n * (n - 1) // 2 if (self.metric in SYMMETRIC if self.symmetric is None else self.symmetric) else n * (n - 1)
        words = self._nonconverged()
        line = f"{n} × {n} {self.metric} matrix: {len(i)} of {total} pairs computed, " + (words or "all converged")
        short = (self.log or {}).get("shortlist")
        if short:
            line += (f"; registered only each query's {short['shortlist']} nearest by the rigid {short['shortlist_metric']} "
                     f"(σ² = {short['shortlist_sigma2']:g}): {short['pairs_registered']} pairs, the others are the rigid "
                     f"bound + {short['shift']:.4g}, ranked after them")
        return line

    def _nonconverged(self) -> str:
        """One line on the pairs that did not converge, in :meth:`status`'s words with how wide the
        brackets are; ``""`` if every computed pair converged."""
        i, j = self._pairs()
        bad = ~self.converged[i, j]
        if not bad.any():
            return ""
        n, total = int(bad.sum()), len(bad)
        first = [(int(a), int(b)) for a, b in zip(i[bad][:3], j[bad][:3])]
        rtol = self.params.get("rtol")
        if self.metric == "registration":
            return (f"{n} of {total} {self.metric} pairs: an EM stopped at max_iter before its tolerance (each value is "
                    f"the misfit it had), first {first}")
        if rtol is None:
            return (f"{n} of {total} {self.metric} pairs: solver failed (the geodesic solver stopped before its "
                    f"tolerance; each value is the length of the path it had, an upper bound), first {first}")
        gap = self.rel_gap(i[bad], j[bad])
        return (f"{n} of {total} {self.metric} pairs: the certified bracket is wider than rtol = {rtol:g} (relative "
                f"gap median {100 * float(np.median(gap)):.3g} %, max {100 * float(np.max(gap)):.3g} %): each distance "
                f"lies in its bracket [lower, upper] and the value is its upper end; not a solver failure")

    def to_frame(self):
        """One row per computed pair (``i < j`` for symmetric metrics) with all diagnostics,
        :meth:`status` and :meth:`rel_gap` included."""
        import pandas as pd

        i, j = self._pairs()
        return pd.DataFrame({"i": i, "j": j, "value": self.matrix[i, j], "lower": self.lower[i, j],
                             "upper": self.upper[i, j], "rel_gap": self.rel_gap(i, j), "energy": self.energy[i, j],
                             "converged": self.converged[i, j], "status": self.status(i, j),
                             "n_iter": self.n_iter[i, j], "seconds": self.seconds[i, j]})


@dataclass(frozen=True)
class BlockProgress:
    """What ``compute_pairwise(..., callback=)`` is called with after each block is written.

    Attributes
    ----------
    block : tuple of int
        Block indices ``(I, J)`` of the block just written.
    rows, cols : range
        Its rows and columns of the matrix.
    blocks_done, blocks_total : int
        Blocks in the store now (this run's and those found done) and in all.
    blocks_computed : int
        Blocks computed by this call so far.
    pairs_done, pairs_total : int
        The same counted in pairs (one per unordered pair for symmetric metrics).

    See Also
    --------
    compute_pairwise : Calls the callback.

    Examples
    --------
    Five shapes in blocks of two are six blocks; the callback stops the run after the second:

    >>> import numpy as np
    >>> from shapelib.pairwise import compute_pairwise
    >>> x = np.random.default_rng(0).normal(size=(5, 6, 2))
    >>> def stop_after_two(p):
    ...     print(p.block, p.rows, p.cols, f"{p.pairs_done}/{p.pairs_total} pairs")
    ...     return p.blocks_done == 2
    >>> r = compute_pairwise(x, metric="procrustes", n_jobs=1, block_size=2, progress=False,
    ...                      callback=stop_after_two)
    (0, 0) range(0, 2) range(0, 2) 1/10 pairs
    (0, 1) range(0, 2) range(2, 4) 5/10 pairs
    >>> r.complete, r.log["stopped"], int(r.computed.sum())
    (False, True, 12)
    """

    block: tuple
    rows: range
    cols: range
    blocks_done: int
    blocks_total: int
    blocks_computed: int
    pairs_done: int
    pairs_total: int
