"""Modularity: the covariance ratio CR of landmarks (or variables) split into hypothesised modules,
with a test against random assignments of the landmarks to modules of the same sizes, as geomorph's
``modularity.test``.

Covariance ratio
    The specimens' variables (centred) have the covariance matrix ``S``; with the variables split
    into modules, ``S_ab`` is the block of the variables of module ``a`` against those of module
    ``b``, and ``S*_aa`` is module ``a``'s own block with its diagonal (the variances) set to zero.
    The covariance ratio of two modules is (Adams 2016)::

        CR_ab = sqrt( tr(S_ab S_ba) / sqrt( tr(S*_aa S*_aa) tr(S*_bb S*_bb) ) ),

    the covariation between the modules relative to that within them: 0 when the modules do not
    covary at all; when every pair of variables has the same covariance, the ratio of the numbers of
    pairs, ``sqrt(p_a p_b / sqrt(p_a (p_a − 1) p_b (p_b − 1)))`` for modules of ``p_a`` and ``p_b``
    variables (close to 1 for large modules). With more than two modules, CR is the mean of the
    pairwise ``CR_ab``. The divisor of ``S`` cancels.

Test
    The landmarks (each with all its coordinates) are assigned to the modules at random, keeping
    the modules' sizes; each assignment gives ``CR*``, and since a small CR means modularity, the
    p-value is::

        p = (1 + #{CR* ≤ CR}) / (1 + n_permutations).

    The effect size ``z`` is CR's standard deviate in that permutation distribution,
    ``(CR − mean CR*) / sd CR*`` (Adams and Collyer 2019) (here without geomorph's Box–Cox step): negative for a
    modular signal, more negative for a stronger one.

Orientation
    The diagonals dropped from ``S*_aa`` are the variances of the x, y (and z) coordinates, so for
    landmarks CR depends on the orientation of the coordinate axes. Landmark data are therefore
    first rotated to the principal axes of their mean configuration (as geomorph's ``gpagen``
    orients its output), which makes CR a function of the shapes alone. geomorph's
    ``modularity.test`` by default (``opt.rot``) searches instead for the rotation whose CR equals
    CR's average over a quarter turn; that search is not done here.

The references are those of :func:`modularity_test`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import check_positive_int
from .group import MIN_PERMUTATIONS

__all__ = ["ModularityResult", "modularity_test"]


@dataclass
class ModularityResult:
    """Result of :func:`modularity_test`.

    Attributes
    ----------
    value : float
        The covariance ratio CR [1]_ (the mean of the pairwise ``CR_ab`` with more than two
        modules).
    p_value : float
        Its permutation p-value: the share of random assignments of the landmarks to the modules
        whose CR is as small or smaller (the data counted among them).
    z : float
        CR's standard deviate in the permutation distribution (the effect size [2]_), negative when
        the modules covary less than random sets of landmarks; 0 when every assignment gives the
        same CR (to rounding).
    pairwise : ndarray (G, G)
        ``CR_ab`` of each pair of modules, symmetric; NaN on the diagonal.
    modules : ndarray (G,)
        The module labels, sorted; the rows and columns of ``pairwise`` follow them.
    sizes : ndarray (G,)
        Landmarks (or variables) in each module.
    landmarks : bool
        Whether the partition was of landmarks (permuted with all their coordinates) or of
        variables.
    n_specimens : int
    n_permutations : int
    null : ndarray (n_permutations,)
        ``CR*`` of the random assignments: ∞ for one with a module whose variables do not covary
        among themselves at all (left out of ``z``).

    See Also
    --------
    modularity_test : What returns it.
    two_block_pls : The strength of the covariation between two blocks (integration).

    References
    ----------
    .. [1] D. C. Adams, "Evaluating modularity in morphometric data: challenges with the RV
       coefficient and a new test measure", *Methods in Ecology and Evolution* 7(5), 565–572, 2016.
    .. [2] D. C. Adams and M. L. Collyer, "Comparing the strength of modular signal, and evaluating
       alternative modular hypotheses, using covariance ratio effect sizes with morphometric data",
       *Evolution* 73(12), 2352–2367, 2019.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> a, b = rng.normal(size=(2, 40, 1))  # one factor for each set of six variables
    >>> x = np.hstack([a + 0.5 * rng.normal(size=(40, 6)), b + 0.5 * rng.normal(size=(40, 6))])
    >>> res = sl.modularity_test(x, np.repeat(["a", "b"], 6), n_permutations=99)
    >>> bool(res.value < 0.5), res.p_value, bool(res.z < -2)
    (True, 0.01, True)
    """

    value: float
    p_value: float
    z: float
    pairwise: np.ndarray
    modules: np.ndarray
    sizes: np.ndarray
    landmarks: bool = True
    n_specimens: int = 0
    n_permutations: int = 0
    null: np.ndarray = field(default=None, repr=False)

    def summary(self) -> str:
        """CR with its p-value and effect size, and the pairwise CRs with more than two modules."""
        unit = "landmarks" if self.landmarks else "variables"
        sizes = ", ".join(f"{m}: {s}" for m, s in zip(self.modules, self.sizes))
        text = (f"modularity test ({self.n_specimens} specimens; {len(self.modules)} modules of {unit}, {sizes}): "
                f"CR = {self.value:.4g}, p = {self.p_value:.4g} ({self.n_permutations} random assignments of the "
                f"{unit} to modules of these sizes), z = {self.z:.3g}")
        if len(self.modules) > 2:
            pairs = [f"{self.modules[a]}–{self.modules[b]} {self.pairwise[a, b]:.4g}"
                     for a in range(len(self.modules)) for b in range(a + 1, len(self.modules))]
            text += "; pairwise CR: " + ", ".join(pairs)
        return text


def _data(shapes, partition, principal_axes):
    """Centred variables (N, p), the module of each landmark or variable, and the coordinates per
    landmark (1 for variables)."""
    arr = np.asarray(shapes, dtype=np.float64)
    labels = np.asarray(partition)
    if labels.ndim != 1:
        raise ValueError(f"partition: expected one label per landmark or variable; got shape {labels.shape}")
    if arr.ndim == 3:
        d = arr.shape[2]
        if arr.shape[1] != len(labels):
            raise ValueError(f"partition: {len(labels)} labels for {arr.shape[1]} landmarks")
    elif arr.ndim == 2 and len(labels) and arr.shape[1] == len(labels):
        d = 1
    elif arr.ndim == 2 and len(labels) and arr.shape[1] % len(labels) == 0 and arr.shape[1] // len(labels) in (2, 3):
        d = arr.shape[1] // len(labels)  # rows of landmark coordinates, x1, y1, x2, ...
        arr = arr.reshape(len(arr), len(labels), d)
    else:
        raise ValueError(f"partition: {len(labels)} labels do not fit shapes of shape {arr.shape}: give (N, K, d) "
                         "landmarks with K labels, or (N, p) variables with p labels (or p / d for rows of "
                         "landmark coordinates)")
    if arr.shape[0] < 3:
        raise ValueError(f"shapes: at least 3 specimens are needed; got shape {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr.reshape(len(arr), -1)))
    if bad.size:
        raise ValueError(f"shapes: variable {bad[0][1]} of specimen {bad[0][0]} is not finite")
    if d > 1 and principal_axes:
        mean = arr.mean(axis=0)
        _, _, vt = np.linalg.svd(mean - mean.mean(axis=0))
        arr = arr @ vt.T
    x = arr.reshape(len(arr), -1)
    modules, codes = np.unique(labels, return_inverse=True)
    if len(modules) < 2:
        raise ValueError(f"partition: at least 2 modules are needed; got {len(modules)}")
    sizes = np.bincount(codes)
    if d == 1 and sizes.min() < 2:
        raise ValueError(f"partition: module {modules[np.argmin(sizes)].item()!r} has one variable; each module "
                         "needs at least 2 (CR compares covariances within the modules)")
    return x - x.mean(axis=0), modules, codes, sizes, d


def _pair_table(q, codes, g):
    """``T_ab = Σ_{i∈a, j∈b} q_ij``: the squared covariances summed over each pair of modules."""
    m = np.zeros((len(codes), g))
    m[np.arange(len(codes)), codes] = 1.0
    t = m.T @ q @ m
    return (t + t.T) / 2  # symmetric to the last digit


def _ratios(t):
    """The (G, G) pairwise CR of a table ``T`` (diagonal NaN) and their mean."""
    within = np.sqrt(np.diag(t))
    with np.errstate(divide="ignore", invalid="ignore"):
        cr = np.sqrt(t / np.outer(within, within))
    np.fill_diagonal(cr, np.nan)
    return cr, float(np.mean(cr[np.triu_indices(len(t), 1)]))


def modularity_test(shapes, partition, *, n_permutations: int = 999, seed: int | None = 0,
                    principal_axes: bool = True) -> ModularityResult:
    """Test a hypothesis of modules in a configuration of landmarks by the covariance ratio CR.

    CR [1]_ (module docstring) compares the covariances between the modules with those within them;
    it is compared with the CR of random assignments of the landmarks to modules of the same sizes
    (a small CR: modularity), and its standard deviate in that distribution is the effect size
    ``z`` [2]_, as geomorph's ``modularity.test``.

    Parameters
    ----------
    shapes : array_like (N, K, d), or (N, p)
        Aligned landmarks (:func:`shapelib.procrustes_coordinates` aligns them: align the whole
        configuration once, then test its partition), or rows of variables. Rows of landmark
        coordinates ``x₁, y₁, x₂, …`` (N, K·d), as :func:`shapelib.procrustes_coordinates` returns
        them, are read as landmarks when ``partition`` has K labels.
    partition : sequence (K,) or (p,)
        The module of each landmark (or variable): any labels, at least two distinct ones. A
        landmark moves with all its coordinates in the permutations; a module of variables needs at
        least two of them.
    n_permutations : int
        Random assignments; at least 19.
    seed : int or None
    principal_axes : bool
        Rotate landmarks to the principal axes of their mean configuration first (the default), so
        that CR does not depend on the orientation the alignment left them in; False uses the
        coordinates as given. Ignored for variables.

    Returns
    -------
    ModularityResult

    Raises
    ------
    ValueError
        If the partition does not fit the data or has one module, a module of variables has one
        variable, a module's variables do not covary among themselves at all, the data are not
        finite, or there are fewer than 3 specimens.

    See Also
    --------
    shapelib.procrustes_coordinates : The aligned coordinates to pass.
    shapelib.two_block_pls : How strongly two blocks covary (integration), with its own test.

    Notes
    -----
    CR of landmark data depends on the orientation of the axes (the variances dropped from the
    within-module blocks are those of the coordinates), hence ``principal_axes``. geomorph's default
    ``opt.rot`` chooses another orientation, the one whose CR is CR's average over a quarter turn,
    so its values can differ slightly from these; with ``opt.rot = FALSE`` on ``gpagen``'s
    coordinates (oriented on their principal axes) they are the same statistic.

    References
    ----------
    .. [1] D. C. Adams, "Evaluating modularity in morphometric data: challenges with the RV
       coefficient and a new test measure", *Methods in Ecology and Evolution* 7(5), 565–572, 2016.
    .. [2] D. C. Adams and M. L. Collyer, "Comparing the strength of modular signal, and evaluating
       alternative modular hypotheses, using covariance ratio effect sizes with morphometric data",
       *Evolution* 73(12), 2352–2367, 2019.

    Examples
    --------
    Two parts of a configuration that vary independently of each other:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(1)
    >>> base = np.array([[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [2, 1], [1, 1], [0, 1.0]])
    >>> left = base[:, 0] < 1.5
    >>> f, g = rng.normal(size=(2, 40, 1, 1))
    >>> shapes = (base + 0.04 * np.where(left[:, None], f, g) * base[:, ::-1]
    ...           + 0.01 * rng.normal(size=(40, 8, 2)))
    >>> y = sl.procrustes_coordinates(shapes)
    >>> res = sl.modularity_test(y, np.where(left, "left", "right"), n_permutations=199)
    >>> res.p_value < 0.05
    True
    """
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    if n_permutations < MIN_PERMUTATIONS:
        raise ValueError(f"n_permutations must be at least {MIN_PERMUTATIONS}; got {n_permutations}")
    x, modules, codes, sizes, d = _data(shapes, partition, principal_axes)
    g = len(modules)
    c = x.T @ x
    np.fill_diagonal(c, 0.0)
    q = c**2
    if d > 1:  # one row and column per landmark: its coordinates' squared covariances summed
        q = q.reshape(len(codes), d, len(codes), d).sum(axis=(1, 3))
    t = _pair_table(q, codes, g)
    empty = np.flatnonzero(np.diag(t) <= 0)
    if empty.size:
        raise ValueError(f"partition: the variables of module {modules[empty[0]].item()!r} do not covary among "
                         "themselves; CR is not defined")
    pairwise, value = _ratios(t)
    rng = np.random.default_rng(seed)
    null = np.array([_ratios(_pair_table(q, codes[rng.permutation(len(codes))], g))[1]
                     for _ in range(n_permutations)])
    p = (1.0 + np.sum(null <= value * (1 + 1e-12))) / (1.0 + n_permutations)
    # an assignment with a module whose variables do not covary among themselves has CR* = ∞ (NaN if the
    # modules do not covary either): never as small as CR, and left out of the effect size
    finite = np.where(np.isfinite(null), null, np.nan)
    sd = np.nanstd(finite, ddof=1)
    z = float((value - np.nanmean(finite)) / sd) if sd > 1e-12 * max(value, 1.0) else 0.0
    return ModularityResult(value=value, p_value=float(p), z=z, pairwise=pairwise, modules=modules, sizes=sizes,
                            landmarks=d > 1, n_specimens=len(x), n_permutations=n_permutations, null=null)
