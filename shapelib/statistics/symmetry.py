"""Bilateral symmetry: the Procrustes ANOVA of symmetry and asymmetry of Klingenberg and McIntyre
(1998) and Klingenberg, Barluenga and Meyer (2002), as geomorph's ``bilat.symmetry``.

Object symmetry
    A structure symmetric about a midline (a skull, a face). Each specimen ``x`` has a mirror image
    ``x' = P x M``: its first coordinate negated (``M``) and the landmarks of each pair in
    ``land_pairs`` swapped (``P``; landmarks on the midline are in no pair). The ``N`` specimens and
    their ``N`` mirror images are superimposed together by one generalized Procrustes analysis at unit
    centroid size; the two copies of a specimen are its two "sides".

Matching symmetry
    Paired structures (left and right wings): one configuration per side of each individual, the
    configurations of one side reflected before the superimposition (by the user, or here with
    ``mirror_side``).

Components
    With ``y_is`` the mean aligned configuration of individual ``i`` on side ``s ∈ {1, 2}``::

        symmetric_i  = (y_i1 + y_i2) / 2,
        asymmetric_i = (y_i1 − y_i2) / 2,

    half the difference between the sides, so that ``y_i1 = symmetric_i + asymmetric_i`` and
    ``y_i2 = symmetric_i − asymmetric_i``. The directional asymmetry is the mean of the asymmetric
    components and the fluctuating asymmetry of ``i`` its deviation from that mean.

Procrustes ANOVA
    The rows ``y`` (one per configuration or mirror image, flattened) are fitted by the nested
    linear models ``1 ⊂ ind ⊂ ind + side ⊂ ind + side + ind:side``; each term's sum of squares is the
    squared Frobenius norm of the change of the fitted values when it enters (sequential, type I,
    sums of squares)::

        SS_term = ‖ŷ_(with term) − ŷ_(before term)‖²,   SS_total = Σ ‖y − ȳ‖²,

    which for balanced data are the classical two-way sums of squares. Without replicates the
    individual × side interaction (fluctuating asymmetry) is the residual; with replicates it is a
    term and the residual, the variation among replicates of one side of one individual, is
    measurement error. ``F`` of ``ind`` and ``side`` divides their mean squares by that of
    ``ind:side``; ``F`` of ``ind:side`` divides by the measurement error's.

Test
    Residual randomisation (RRPP, as geomorph's default ``RRPP = TRUE``): for a term, the residuals
    of the model before it are permuted among the rows and added back to that model's fitted values,
    the term's sum of squares and its ``F`` are recomputed, and::

        p = (1 + #{F* ≥ F}) / (1 + n_permutations).

The references are those of :func:`bilateral_symmetry`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import as_shapes, check_positive_int
from .group import MIN_PERMUTATIONS

__all__ = ["SymmetryResult", "bilateral_symmetry"]

#: the names of the rows of the ANOVA table, as geomorph's
ROWS_REPLICATES = ("ind", "side", "ind:side", "ind:side:replicate", "Total")
ROWS_SINGLE = ("ind", "side", "ind:side", "Total")
#: the two copies of an object-symmetric specimen
OBJECT_SIDES = ("original", "mirror")
#: mean squares below this are rounding noise of the unit-size Procrustes coordinates (identical
#: configurations give ~1e-31): an F with such a denominator is NaN
MS_FLOOR = 1e-24


@dataclass
class SymmetryResult:
    """Result of :func:`bilateral_symmetry`.

    Attributes
    ----------
    kind : str
        ``"object"`` or ``"matching"``.
    rows : tuple of str
        The rows of the ANOVA table: ``ind``, ``side``, ``ind:side`` (fluctuating asymmetry), with
        replicates ``ind:side:replicate`` (measurement error), and ``Total``.
    df, ss, ms : ndarray
        Degrees of freedom, sums of squares (squared Procrustes units) and mean squares of each row;
        the terms' sums of squares add up to the total.
    value : ndarray
        ``F`` of each term tested: ``ind`` and ``side`` over ``ind:side``, ``ind:side`` over the
        measurement error [1]_; NaN on the rows not tested (the residual, the total) and where the
        denominator is zero (below 1e-24, rounding noise).
    p_value : ndarray
        The permutation p-value of each ``F`` (RRPP [2]_), NaN where ``value`` is.
    individuals : ndarray (n,)
        The individuals' labels, sorted.
    sides : tuple
        The two sides' labels: ``("original", "mirror")`` for object symmetry.
    symmetric : ndarray (n, K, d)
        Each individual's symmetric component, the mean of its two sides' mean configurations.
    asymmetric : ndarray (n, K, d)
        Each individual's asymmetric component: half its first side's mean configuration minus its
        second's (a deviation, not a configuration).
    directional : ndarray (K, d)
        The directional asymmetry, the mean of ``asymmetric``.
    fluctuating : ndarray (n, K, d)
        ``asymmetric − directional``.
    consensus : ndarray (K, d)
        The mean shape, the mean of ``symmetric``: symmetric itself for object symmetry.
    aligned : ndarray (M, K, d)
        The superimposed configurations (for object symmetry the specimens then their mirror
        images), with ``ind_index`` and ``side_index`` (M,) their individual and side.
    n_permutations : int
    null : ndarray (n_permutations, T)
        ``F*`` of the ``T`` tested terms in each permutation.

    See Also
    --------
    bilateral_symmetry : What returns it.
    shapelib.shape_lm : Procrustes ANOVA of other designs.

    References
    ----------
    .. [1] C. P. Klingenberg, M. Barluenga and A. Meyer, "Shape analysis of symmetric structures:
       quantifying variation among individuals and asymmetry", *Evolution* 56(10), 1909–1920, 2002.
    .. [2] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for
       phenotypes described by high-dimensional data", *Heredity* 115, 357–365, 2015.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> base = np.array([[-1, 0], [1, 0], [-1.5, 2], [1.5, 2], [0, 3.0]])
    >>> shapes = base + rng.normal(scale=0.03, size=(12, 5, 2))
    >>> res = sl.bilateral_symmetry(shapes, land_pairs=[[0, 1], [2, 3]], n_permutations=99)
    >>> res.rows, bool(np.isclose(res.ss[:-1].sum(), res.ss[-1]))
    (('ind', 'side', 'ind:side', 'Total'), True)
    """

    kind: str
    rows: tuple
    df: np.ndarray
    ss: np.ndarray
    ms: np.ndarray
    value: np.ndarray
    p_value: np.ndarray
    individuals: np.ndarray
    sides: tuple
    symmetric: np.ndarray = field(repr=False)
    asymmetric: np.ndarray = field(repr=False)
    directional: np.ndarray = field(repr=False)
    fluctuating: np.ndarray = field(repr=False)
    consensus: np.ndarray = field(repr=False)
    aligned: np.ndarray = field(repr=False)
    ind_index: np.ndarray = field(repr=False)
    side_index: np.ndarray = field(repr=False)
    n_permutations: int = 0
    null: np.ndarray = field(default=None, repr=False)

    def summary(self) -> str:
        """The ANOVA table with the symmetry's kind and the permutation scheme."""
        lines = [f"bilateral symmetry ({self.kind} symmetry, {len(self.individuals)} individuals): "
                 f"Procrustes ANOVA, sequential sums of squares, RRPP with {self.n_permutations} permutations",
                 f"  {'':>20} {'Df':>5} {'SS':>11} {'MS':>11} {'F':>9} {'p':>7}"]
        for k, row in enumerate(self.rows):
            ms = "" if row == "Total" else f"{self.ms[k]:.5g}"
            f = "" if np.isnan(self.value[k]) else f"{self.value[k]:.4g}"
            p = "" if np.isnan(self.p_value[k]) else f"{self.p_value[k]:.4g}"
            lines.append(f"  {row:>20} {self.df[k]:>5d} {self.ss[k]:>11.5g} {ms:>11} {f:>9} {p:>7}")
        return "\n".join(lines)


def _pairs(land_pairs, n_landmarks):
    try:
        pairs = np.asarray(land_pairs)
        pairs = pairs.reshape(-1, 2) if pairs.size == 0 else pairs
    except (TypeError, ValueError) as exc:
        raise ValueError(f"land_pairs must be a (P, 2) array of landmark indices: {exc}") from None
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"land_pairs must be a (P, 2) array of landmark indices; got shape {pairs.shape}")
    if pairs.size and not np.issubdtype(pairs.dtype, np.integer):
        raise ValueError(f"land_pairs must hold integer landmark indices; got dtype {pairs.dtype}")
    pairs = pairs.astype(np.int64)
    if pairs.size and (pairs.min() < 0 or pairs.max() >= n_landmarks):
        raise ValueError(f"land_pairs: indices must lie in [0, {n_landmarks}); got {pairs.min()}..{pairs.max()}")
    flat = pairs.ravel()
    if len(np.unique(flat)) != len(flat):
        raise ValueError("land_pairs: a landmark appears twice (each is in at most one pair, never paired "
                         "with itself)")
    return pairs


def _mirror(x, pairs):
    """Mirror images: the first coordinate negated, the landmarks of each pair swapped."""
    y = x.copy()
    y[:, pairs[:, 0]] = x[:, pairs[:, 1]]
    y[:, pairs[:, 1]] = x[:, pairs[:, 0]]
    y[..., 0] *= -1.0
    return y


def _labels(values, n, name):
    labels = np.asarray(values)
    if labels.ndim != 1 or len(labels) != n:
        raise ValueError(f"{name}: expected one label per specimen ({n}), got shape {labels.shape}")
    return np.unique(labels, return_inverse=True)


def _basis(design):
    """Orthonormal basis (M, r) of the column space of ``design``."""
    u, s, _ = np.linalg.svd(design, full_matrices=False)
    return u[:, s > s[0] * max(design.shape) * 1e-12]


def _ratio(num, den):
    """num / den, NaN where the denominator is rounding noise (below ``MS_FLOOR``)."""
    return np.where(den > MS_FLOOR, num / np.maximum(den, MS_FLOOR), np.nan)


def _design(rows, ind_index, side_index, n_ind, replicates):
    """Nested designs: 1, + ind, + side, (+ ind:side with replicates); their orthonormal bases."""
    one = np.ones((rows, 1))
    ind = np.eye(n_ind)[ind_index]
    side = (side_index == 1).astype(float)[:, None]
    designs = [one, np.hstack([one, ind]), np.hstack([one, ind, side])]
    if replicates:
        designs.append(np.eye(2 * n_ind)[2 * ind_index + side_index])
    return [_basis(d) for d in designs]


def _anova(y, bases, replicates, n_permutations, rng):
    """Sequential SS of the terms, their F and RRPP p-values (module docstring)."""
    fitted = [q @ (q.T @ y) for q in bases]
    n_terms = len(bases) - 1
    ranks = [q.shape[1] for q in bases]
    df_terms = np.diff(ranks)
    df_res = len(y) - ranks[-1]
    ss_terms = np.array([np.sum((fitted[k + 1] - fitted[k]) ** 2) for k in range(n_terms)])
    ss_res = np.sum((y - fitted[-1]) ** 2)
    ss_total = np.sum((y - fitted[0]) ** 2)

    def f_values(ss, rss):
        ms = ss / df_terms
        ms_res = rss / df_res
        if replicates:  # ind and side over ind:side, ind:side over the measurement error
            return _ratio(ms, np.array([ms[2], ms[2], ms_res[2]]))
        return _ratio(ms, ms_res)

    f_obs = f_values(ss_terms, np.full(n_terms, ss_res))
    null = np.empty((n_permutations, n_terms))
    residuals = [y - fitted[k] for k in range(n_terms)]
    for b in range(n_permutations):
        perm = rng.permutation(len(y))
        ss_b, rss_b = np.empty(n_terms), np.empty(n_terms)
        for k in range(n_terms):
            y_b = fitted[k] + residuals[k][perm]
            hi, lo = bases[k + 1] @ (bases[k + 1].T @ y_b), bases[k] @ (bases[k].T @ y_b)
            ss_b[k] = np.sum((hi - lo) ** 2)
            full = bases[-1] @ (bases[-1].T @ y_b)
            rss_b[k] = np.sum((y_b - full) ** 2)
        null[b] = f_values(ss_b, rss_b)
    # a relative tolerance: a permutation that only reorders equal sums is "as large"
    exceed = np.sum(null >= f_obs * (1 - 1e-12), axis=0)
    p = np.where(np.isnan(f_obs), np.nan, (1.0 + exceed) / (1.0 + n_permutations))
    return ss_terms, df_terms, ss_res, df_res, ss_total, f_obs, p, null


def bilateral_symmetry(shapes, *, land_pairs=None, side=None, ind=None, replicate=None, mirror_side=None,
                       n_permutations: int = 999, seed: int | None = 0) -> SymmetryResult:
    """Procrustes ANOVA of symmetry and asymmetry: variation among individuals, directional and
    fluctuating asymmetry and measurement error, as geomorph's ``bilat.symmetry``.

    Object symmetry (``land_pairs``) or matching symmetry (``side``) [1]_ [2]_. The configurations
    (with object symmetry each specimen and its mirror image) are superimposed by generalized
    Procrustes analysis at unit centroid size and the sums of squares of ``ind``, ``side`` and
    ``ind:side`` (and, with replicates, of measurement error) taken in turn (sequential sums of
    squares, module docstring); each ``F`` is tested by residual randomisation [3]_.

    Parameters
    ----------
    shapes : array_like (N, K, d)
        Landmark configurations, in any position, orientation and size.
    land_pairs : array_like (P, 2) of int, optional
        Object symmetry: the pairs of landmark indices that swap under reflection (landmarks on the
        midline are in no pair). Each specimen's mirror image has its first coordinate negated and
        the landmarks of each pair swapped.
    side : array_like (N,), optional
        Matching symmetry: the side of each configuration, two labels.
    ind : array_like (N,), optional
        The individual of each configuration: every individual on both sides, with matching symmetry
        (required there). With object symmetry each specimen is its own individual unless
        ``replicate`` is given.
    replicate : array_like (N,), optional
        Replicate labels (repeated digitisations of one individual, one side): the variation among
        them becomes the measurement-error term. Without it each individual has one configuration
        per side.
    mirror_side : optional
        Matching symmetry: the label of the side whose configurations are reflected (first
        coordinate negated) here; by default they are taken as reflected already, as geomorph does.
    n_permutations : int
        At least 19; the smallest attainable p is ``1 / (1 + n_permutations)``.
    seed : int or None

    Returns
    -------
    SymmetryResult

    See Also
    --------
    shapelib.shape_lm : Procrustes ANOVA of other designs.
    shapelib.procrustes_coordinates : The superimposition.

    Notes
    -----
    The asymmetric component is half the difference between the sides (each side is the symmetric
    component plus or minus it); geomorph's ``asymm.shape`` of object symmetry is the consensus plus
    this component. In each permutation the rows are permuted once, and that permutation is applied
    to the residuals of every term's reduced model; ``F*`` of ``ind`` and ``side`` divides by the
    ``ind:side`` mean square of the same permutation, as geomorph does with replicates. The degrees
    of freedom count configurations, not coordinates, as geomorph's: they scale the mean squares but
    not the p-values. Sums of squares are sequential (``ind`` first), equal to the classical ones of
    a balanced design. They are those of the doubled data set (each specimen and its mirror image),
    as geomorph's; Klingenberg et al. [2]_ and MorphoJ halve them for object symmetry and count
    degrees of freedom in shape coordinates (Goodall's F): each F then changes by a constant factor,
    the same in every permutation, and no p-value changes.

    References
    ----------
    .. [1] C. P. Klingenberg and G. S. McIntyre, "Geometric morphometrics of developmental instability:
       analyzing patterns of fluctuating asymmetry with Procrustes methods", *Evolution* 52(5),
       1363–1375, 1998.
    .. [2] C. P. Klingenberg, M. Barluenga and A. Meyer, "Shape analysis of symmetric structures:
       quantifying variation among individuals and asymmetry", *Evolution* 56(10), 1909–1920, 2002.
    .. [3] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for
       phenotypes described by high-dimensional data", *Heredity* 115, 357–365, 2015.

    Examples
    --------
    A directional asymmetry (the right eye higher in every specimen) is in the ``side`` term:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(1)
    >>> face = np.array([[-1, 1], [1, 1], [0, 0], [-0.6, -1], [0.6, -1.0]])
    >>> shapes = face + rng.normal(scale=0.02, size=(15, 5, 2))
    >>> shapes[:, 1, 1] += 0.1
    >>> res = sl.bilateral_symmetry(shapes, land_pairs=[[0, 1], [3, 4]], n_permutations=99)
    >>> float(res.p_value[1]), bool(res.value[1] > 10)
    (0.01, True)
    """
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    if n_permutations < MIN_PERMUTATIONS:
        raise ValueError(f"n_permutations must be at least {MIN_PERMUTATIONS}; got {n_permutations}")
    if (land_pairs is None) == (side is None):
        raise ValueError("give land_pairs (object symmetry) or side (matching symmetry), one of the two")
    x = as_shapes(shapes, name="shapes", min_shapes=2)
    n = len(x)
    if land_pairs is not None:
        kind = "object"
        if mirror_side is not None:
            raise ValueError("mirror_side is for matching symmetry (side=...); object symmetry mirrors every specimen")
        pairs = _pairs(land_pairs, x.shape[1])
        if ind is None:
            if replicate is not None:
                raise ValueError("ind: give each replicate's individual")
            ind = np.arange(n)
        names, ind_index = _labels(ind, n, "ind")
        sides = OBJECT_SIDES
        x = np.concatenate([x, _mirror(x, pairs)])
        ind_index = np.concatenate([ind_index, ind_index])
        side_index = np.repeat([0, 1], n)
    else:
        kind = "matching"
        if ind is None:
            raise ValueError("ind: matching symmetry needs the individual of each configuration")
        names, ind_index = _labels(ind, n, "ind")
        side_names, side_index = _labels(side, n, "side")
        if len(side_names) != 2:
            raise ValueError(f"side: expected two sides; got {len(side_names)}: {side_names.tolist()}")
        sides = tuple(side_names.tolist())
        if mirror_side is not None:
            if mirror_side not in sides:
                raise ValueError(f"mirror_side: {mirror_side!r} is not a side; the sides are {list(sides)}")
            x = x.copy()
            x[side_index == sides.index(mirror_side), :, 0] *= -1.0
    n_ind = len(names)
    counts = np.zeros((n_ind, 2), dtype=int)
    np.add.at(counts, (ind_index, side_index), 1)
    if np.any(counts == 0):
        i = int(np.argwhere(counts == 0)[0, 0])
        raise ValueError(f"ind: individual {names[i].item()!r} is not on both sides")
    if replicate is None:
        if np.any(counts > 1):
            i = int(np.argwhere(counts > 1)[0, 0])
            raise ValueError(f"replicate: individual {names[i].item()!r} has several configurations on one side; "
                             "label them with replicate=...")
        if n_ind < 2:
            raise ValueError("ind: need at least two individuals")
    else:
        rep = np.asarray(replicate)
        if rep.ndim != 1 or len(rep) != n:
            raise ValueError(f"replicate: expected one label per specimen ({n}), got shape {rep.shape}")
        if not np.any(counts > 1):
            raise ValueError("replicate: no side of any individual has two replicates (no measurement error to "
                             "estimate)")
        if n_ind < 2:
            raise ValueError("ind: need at least two individuals")
    from ..geometry.procrustes import generalized_procrustes

    aligned, _ = generalized_procrustes(x, scaling=False)
    y = aligned.reshape(len(aligned), -1)
    replicates = replicate is not None
    bases = _design(len(y), ind_index, side_index, n_ind, replicates)
    rng = np.random.default_rng(seed)
    ss_t, df_t, ss_r, df_r, ss_total, f_obs, p, null = _anova(y, bases, replicates, n_permutations, rng)
    rows = ROWS_REPLICATES if replicates else ROWS_SINGLE
    df = np.array([*df_t, df_r, len(y) - 1], dtype=int)
    ss = np.array([*ss_t, ss_r, ss_total])
    ms = ss / np.maximum(df, 1)
    value = np.full(len(rows), np.nan)
    p_value = np.full(len(rows), np.nan)
    value[:len(f_obs)], p_value[:len(p)] = f_obs, p
    # each individual's mean configuration on each side
    cells = np.zeros((n_ind, 2) + aligned.shape[1:])
    np.add.at(cells, (ind_index, side_index), aligned)
    cells /= counts[:, :, None, None]
    symmetric = cells.mean(axis=1)
    asymmetric = (cells[:, 0] - cells[:, 1]) / 2.0
    directional = asymmetric.mean(axis=0)
    return SymmetryResult(kind=kind, rows=rows, df=df, ss=ss, ms=ms, value=value, p_value=p_value,
                          individuals=names, sides=sides, symmetric=symmetric, asymmetric=asymmetric,
                          directional=directional, fluctuating=asymmetric - directional,
                          consensus=symmetric.mean(axis=0), aligned=aligned, ind_index=ind_index,
                          side_index=side_index, n_permutations=n_permutations, null=null)
