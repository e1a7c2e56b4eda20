"""Morphological disparity: the Procrustes variance of each group and a permutation test of the
differences between groups, as geomorph's ``morphol.disparity``.

Procrustes variance
    Of a group ``g`` of ``n_g`` specimens with Procrustes coordinates ``y_i`` (rows of
    :func:`~shapelib.statistics.linear_model.procrustes_coordinates`)::

        PV_g = (1/n_g) Σ_{i∈g} |y_i − c_i|²,

    the trace of the group's covariance matrix with divisor ``n_g`` (Zelditch et al. 2012), where ``c_i`` is the
    mean of specimen ``i``'s own group (``about="group"``: how varied each group is about its own
    mean shape) or the grand mean (``about="grand"``: geomorph's ``coords ~ 1``).

Test
    The squared residual lengths ``d_i = |y_i − c_i|²`` are permuted among the specimens (the
    residual randomisation of Collyer et al. (2015) for the model ``d ~ group``: under the null
    hypothesis of equal disparity the residuals are exchangeable); each permutation gives the
    groups' means of ``d``, ``PV*``, and the p-value of a pair of groups is::

        p_ab = (1 + #{|PV*_a − PV*_b| ≥ |PV_a − PV_b|}) / (1 + n_permutations).

The references are those of :func:`morphological_disparity`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import as_shapes, check_positive_int
from .group import MIN_PERMUTATIONS

__all__ = ["DisparityResult", "morphological_disparity"]

#: what the residuals are taken about
ABOUT = ("group", "grand")


@dataclass
class DisparityResult:
    """Result of :func:`morphological_disparity`.

    Attributes
    ----------
    groups : ndarray (G,)
        The group labels, sorted.
    sizes : ndarray (G,)
        Specimens per group.
    value : ndarray (G,)
        Procrustes variance of each group, ``PV_g`` [1]_ (in squared Procrustes units).
    differences : ndarray (G, G)
        ``|PV_a − PV_b|``.
    p_values : ndarray (G, G)
        Permutation p-value of each difference (1 on the diagonal); not adjusted for the
        ``G(G − 1)/2`` comparisons (:func:`shapelib.holm_adjust` does that).
    about : str
        ``"group"`` or ``"grand"``: the mean the residuals are taken from.
    n_permutations : int
    residuals2 : ndarray (N,)
        Each specimen's squared residual length ``d_i``, in the order given.

    See Also
    --------
    morphological_disparity : What returns it.

    References
    ----------
    .. [1] M. L. Zelditch, D. L. Swiderski and H. D. Sheets, *Geometric Morphometrics for Biologists*,
       2nd ed., Academic Press, 2012 (the Procrustes variance).

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> base = np.array([[0, 0], [2, 0], [2, 1], [0, 1.0]])
    >>> shapes = np.stack([base + rng.normal(scale=s, size=(4, 2)) for s in [0.02] * 10 + [0.1] * 10])
    >>> res = sl.morphological_disparity(shapes, ["a"] * 10 + ["b"] * 10, n_permutations=199)
    >>> bool(res.value[1] > res.value[0]), bool(res.p_values[0, 1] < 0.05)
    (True, True)
    """

    groups: np.ndarray
    sizes: np.ndarray
    value: np.ndarray
    differences: np.ndarray
    p_values: np.ndarray
    about: str
    n_permutations: int
    residuals2: np.ndarray = field(repr=False)

    def summary(self) -> str:
        """The groups' Procrustes variances and each pair's difference with its p-value."""
        about = "its group's mean" if self.about == "group" else "the grand mean"
        lines = [f"morphological disparity: Procrustes variance about {about}, "
                 f"{self.n_permutations} permutations of the squared residuals (p not adjusted)"]
        lines += [f"  {g!s:>12}  n = {n:<4d} PV = {v:.4g}" for g, n, v in zip(self.groups, self.sizes, self.value)]
        for a in range(len(self.groups)):
            for b in range(a + 1, len(self.groups)):
                lines.append(f"  {self.groups[a]!s} vs {self.groups[b]!s}: |ΔPV| = {self.differences[a, b]:.4g}, "
                             f"p = {self.p_values[a, b]:.4g}")
        return "\n".join(lines)


def _coordinates(shapes, aligned):
    arr = np.asarray(shapes)
    if arr.ndim == 2:  # rows of coordinates, taken as aligned
        y = np.asarray(arr, dtype=np.float64)
        if not np.all(np.isfinite(y)):
            bad = np.argwhere(~np.isfinite(y))[0]
            raise ValueError(f"shapes: coordinate {bad[1]} of specimen {bad[0]} is not finite")
        return y
    x = as_shapes(shapes, name="shapes", min_shapes=2)
    if aligned:
        return x.reshape(len(x), -1)
    from .linear_model import procrustes_coordinates

    return procrustes_coordinates(x)


def _group_index(groups, n):
    labels = np.asarray(groups)
    if labels.ndim != 1 or len(labels) != n:
        raise ValueError(f"groups: expected one label per specimen ({n}), got shape {labels.shape}")
    names, index = np.unique(labels, return_inverse=True)
    sizes = np.bincount(index, minlength=len(names))
    if len(names) < 2:
        raise ValueError("groups: need at least two groups to compare")
    small = np.flatnonzero(sizes < 2)
    if small.size:
        raise ValueError(f"groups: group {names[small[0]].item()!r} has {sizes[small[0]]} specimen; each needs at least 2")
    return names, index, sizes


def group_means(values, index, sizes):
    """Mean of ``values`` (..., N) over each group's specimens: (..., G)."""
    onehot = np.zeros((len(index), len(sizes)))
    onehot[np.arange(len(index)), index] = 1.0
    return (values @ onehot) / sizes


def morphological_disparity(shapes, groups, *, about: str = "group", aligned: bool = False,
                            n_permutations: int = 999, seed: int | None = 0) -> DisparityResult:
    """Procrustes variance of each group and permutation tests of their pairwise differences.

    ``PV_g = (1/n_g) Σ_{i∈g} |y_i − c_i|²`` of the Procrustes coordinates ``y_i`` about each
    group's mean (or the grand mean), the Procrustes variance of [1]_, and ``p_ab = (1 + #{|PV*_a − PV*_b| ≥ |PV_a − PV_b|}) /
    (1 + n_permutations)`` with the squared residual lengths permuted among the specimens (the
    residual randomisation of [2]_; module docstring), as geomorph's ``morphol.disparity(coords ~ group, groups = ~group)`` (or
    ``coords ~ 1`` for ``about="grand"``).

    Parameters
    ----------
    shapes : array_like (N, K, d) or (N, p)
        Landmark configurations, aligned here by generalized Procrustes analysis at unit size
        (:func:`~shapelib.statistics.linear_model.procrustes_coordinates`) unless ``aligned``; or
        rows of coordinates already aligned (e.g. Procrustes or tangent coordinates), used as they are.
    groups : array_like (N,)
        A label per specimen; at least two groups of at least two specimens.
    about : {"group", "grand"}
        The mean the residuals are taken from.
    aligned : bool
        (N, K, d) shapes already aligned: flattened, not aligned again.
    n_permutations : int
        At least 19; the smallest attainable p is ``1 / (1 + n_permutations)``.
    seed : int or None

    Returns
    -------
    DisparityResult

    See Also
    --------
    shapelib.shape_lm : Differences in mean shape.
    shapelib.holm_adjust : Adjusting the pairwise p-values.

    References
    ----------
    .. [1] M. L. Zelditch, D. L. Swiderski and H. D. Sheets, *Geometric Morphometrics for Biologists*,
       2nd ed., Academic Press, 2012.
    .. [2] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for
       phenotypes described by high-dimensional data", *Heredity* 115, 357–365, 2015.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> y = np.random.default_rng(1).normal(size=(12, 6)) * np.repeat([1.0, 2.0, 1.0], 4)[:, None]
    >>> res = sl.morphological_disparity(y, np.repeat(["a", "b", "c"], 4), n_permutations=99)
    >>> res.p_values.shape, bool(np.allclose(res.differences, res.differences.T))
    ((3, 3), True)
    """
    if about not in ABOUT:
        raise ValueError(f"about must be one of {ABOUT}; got {about!r}")
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    if n_permutations < MIN_PERMUTATIONS:
        raise ValueError(f"n_permutations must be at least {MIN_PERMUTATIONS}; got {n_permutations}")
    y = _coordinates(shapes, aligned)
    names, index, sizes = _group_index(groups, len(y))
    if about == "group":
        centres = (group_means(y.T, index, sizes)).T[index]
    else:
        centres = y.mean(axis=0)
    d = np.sum((y - centres) ** 2, axis=1)
    pv = group_means(d, index, sizes)
    diff = np.abs(pv[:, None] - pv[None, :])
    rng = np.random.default_rng(seed)
    perms = np.stack([rng.permutation(len(d)) for _ in range(n_permutations)])
    pv_null = group_means(d[perms], index, sizes)  # (n_permutations, G)
    null = np.abs(pv_null[:, :, None] - pv_null[:, None, :])
    # a relative tolerance: a permutation that only reorders equal sums is "as large"
    exceed = np.sum(null >= diff * (1 - 1e-12), axis=0)
    p = (1.0 + exceed) / (1.0 + n_permutations)
    np.fill_diagonal(p, 1.0)
    return DisparityResult(groups=names, sizes=sizes, value=pv, differences=diff, p_values=p, about=about,
                           n_permutations=n_permutations, residuals2=d)
