"""Phenotypic trajectory analysis: how groups change along a sequence of levels (times, environments),
compared by the size, direction and shape of their paths, as RRPP's and geomorph's
``trajectory.analysis``.

Trajectories
    The specimens fall into the cells of a ``groups`` × ``points`` design, with at least one specimen
    in every cell. The trajectory of group ``g`` is the sequence of its cell means in the order of the
    levels, ``m_g1, …, m_gT`` (rows of shape variables of length ``p``).

Attributes
    Of one trajectory, and of a pair of trajectories ``a`` and ``b``::

        L_g      = Σ_{t=1}^{T−1} |m_g,t+1 − m_gt|               (magnitude: the path length)
        MD_ab    = |L_a − L_b|                                 (magnitude difference)
        θ_ab     = arccos(|u_a · u_b|)  in degrees, 0–90       (direction, direction="axis")
        θ_ab     = arccos(u_a · u_b)    in degrees, 0–180      (direction, direction="path")
        D_ab     = min_{R ∈ O(p)} ‖A − B R‖                    (shape)

    ``u_g`` is the first right singular vector of the trajectory's centred points (its first
    principal axis); its sign is arbitrary, so ``direction="axis"`` takes the acute angle between the
    two axes, and ``direction="path"`` first turns each axis to point from the trajectory's first
    point towards its last (``u_g · (m_gT − m_g1) ≥ 0``). ``A`` and ``B`` are the two trajectories'
    points (T, p) centred on their mean and scaled to unit Frobenius norm; ``D_ab`` is the partial
    Procrustes distance of an ordinary Procrustes superimposition of ``B`` on ``A`` by an orthogonal
    ``p × p`` matrix, computed as::

        D_ab = ‖A − B U Vᵀ‖,   Bᵀ A = U Σ Vᵀ,

    the rotation of Gower (1975), ``D_ab² = 2 − 2 Σ σ``. It is 0 when the two sequences of points
    differ by a translation, a scaling and a rotation only.

Test
    Residual randomisation (RRPP, Collyer et al. 2015) under the model without the interaction: the
    residuals ``e`` of the least-squares fit ``ŷ`` of ``y ~ groups + points`` are permuted among the
    specimens, ``y* = ŷ + e_π``, the cell means and the attributes recomputed, and for every pair and
    attribute::

        p = (1 + #{s* ≥ s}) / (1 + n_permutations),

    the observed statistic counted among the permuted ones (to within rounding);
    ``z = (s − mean(s*)) / sd(s*)``, with the standard deviation of divisor ``n_permutations − 1``.

The references are those of :func:`trajectory_analysis`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import check_positive_int
from .disparity import _coordinates
from .group import MIN_PERMUTATIONS

__all__ = ["TrajectoryResult", "trajectory_analysis"]

#: how the sign of a trajectory's first principal axis is fixed
DIRECTIONS = ("axis", "path")
#: differences of the statistics below this (times the longest path for the magnitudes; in degrees for the
#: angles; at unit size for the shapes) are rounding: ties in the p-values, no spread for the effect sizes
ROUNDING = 1e-9


@dataclass
class TrajectoryResult:
    """Result of :func:`trajectory_analysis`.

    Attributes
    ----------
    groups : ndarray (G,)
        The group labels (one trajectory each), sorted.
    levels : ndarray (T,)
        The levels of ``points`` in the order of the trajectories' points.
    trajectories : ndarray (G, T, p)
        The cell means: the points of each trajectory.
    sizes : ndarray (G, T)
        Specimens per cell.
    magnitudes : ndarray (G,)
        Each trajectory's path length [1]_.
    magnitude_differences : ndarray (G, G)
        ``|L_a − L_b|``.
    angles : ndarray (G, G)
        Angle between the first principal axes of the trajectories, in degrees [1]_.
    shape_distances : ndarray (G, G)
        Procrustes distance between the trajectories' points at unit size [2]_.
    magnitude_p_values, angle_p_values, shape_p_values : ndarray (G, G)
        Permutation p-values (1 on the diagonal), not adjusted for the ``G(G − 1)/2`` comparisons
        (:func:`shapelib.holm_adjust` does that).
    magnitude_z, angle_z, shape_z : ndarray (G, G)
        The statistics' standard deviates in their permutation distributions (effect sizes); 0 on the
        diagonal and where every permutation gives the same value.
    direction : str
        ``"axis"`` (angles 0–90°) or ``"path"`` (0–180°).
    n_permutations : int

    See Also
    --------
    trajectory_analysis : What returns it.

    References
    ----------
    .. [1] D. C. Adams and M. L. Collyer, "A general framework for the analysis of phenotypic
       trajectories in evolutionary studies", *Evolution* 63(5), 1143–1154, 2009.
    .. [2] M. L. Collyer and D. C. Adams, "Phenotypic trajectory analysis: comparison of shape
       change patterns in evolution and ecology", *Hystrix* 24(1), 75–83, 2013.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> steps = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    >>> means = np.concatenate([steps, 2 * steps + [0, 1, 0]])
    >>> y = np.repeat(means, 4, axis=0) + np.random.default_rng(0).normal(scale=0.05, size=(24, 3))
    >>> res = sl.trajectory_analysis(y, np.repeat(["a", "b"], 12), np.tile(np.repeat([1, 2, 3], 4), 2),
    ...                              n_permutations=99)
    >>> bool(res.magnitudes[1] > res.magnitudes[0]), float(res.magnitude_p_values[0, 1])
    (True, 0.01)
    """

    groups: np.ndarray
    levels: np.ndarray
    trajectories: np.ndarray = field(repr=False)
    sizes: np.ndarray = field(repr=False)
    magnitudes: np.ndarray = None
    magnitude_differences: np.ndarray = None
    angles: np.ndarray = None
    shape_distances: np.ndarray = None
    magnitude_p_values: np.ndarray = None
    angle_p_values: np.ndarray = None
    shape_p_values: np.ndarray = None
    magnitude_z: np.ndarray = field(default=None, repr=False)
    angle_z: np.ndarray = field(default=None, repr=False)
    shape_z: np.ndarray = field(default=None, repr=False)
    direction: str = "axis"
    n_permutations: int = 0

    def summary(self) -> str:
        """Each trajectory's path length and each pair's three attributes with their p-values."""
        g, t, p = self.trajectories.shape
        lines = [f"trajectory analysis: {g} trajectories of {t} points in {p} variables, "
                 f"{self.n_permutations} RRPP permutations (p not adjusted); angles in degrees, "
                 f"{'0-90' if self.direction == 'axis' else '0-180'}"]
        lines += [f"  {name!s:>12}  path length = {length:.4g}" for name, length in zip(self.groups, self.magnitudes)]
        for a in range(g):
            for b in range(a + 1, g):
                lines.append(f"  {self.groups[a]!s} vs {self.groups[b]!s}: |ΔL| = "
                             f"{self.magnitude_differences[a, b]:.4g} (p = {self.magnitude_p_values[a, b]:.4g}), "
                             f"angle = {self.angles[a, b]:.4g} (p = {self.angle_p_values[a, b]:.4g}), "
                             f"shape = {self.shape_distances[a, b]:.4g} (p = {self.shape_p_values[a, b]:.4g})")
        return "\n".join(lines)


def _factor(labels, n, name):
    arr = np.asarray(labels)
    if arr.ndim != 1 or len(arr) != n:
        raise ValueError(f"{name}: expected one label per specimen ({n}), got shape {arr.shape}")
    return arr


def _design(groups, points, levels, n):
    groups = _factor(groups, n, "groups")
    points = _factor(points, n, "points")
    names, g_index = np.unique(groups, return_inverse=True)
    if len(names) < 2:
        raise ValueError("groups: need at least two trajectories to compare")
    present = np.unique(points)
    if levels is None:
        levels = present
    else:
        levels = np.asarray(levels)
        if levels.ndim != 1 or len(np.unique(levels)) != len(levels):
            raise ValueError(f"levels: expected distinct labels, got {levels.tolist()!r}")
        if set(levels.tolist()) != set(present.tolist()):
            raise ValueError(f"levels: {levels.tolist()!r} are not the levels of points, {present.tolist()!r}")
    if len(levels) < 2:
        raise ValueError("points: need at least two levels (points of a trajectory)")
    t_index = np.empty(n, dtype=np.intp)
    for t, level in enumerate(levels):
        t_index[points == level] = t
    sizes = np.zeros((len(names), len(levels)), dtype=np.intp)
    np.add.at(sizes, (g_index, t_index), 1)
    empty = np.argwhere(sizes == 0)
    if empty.size:
        g, t = empty[0]
        raise ValueError(f"points: group {names[g].item()!r} has no specimen at level {levels[t].item()!r}; "
                         "every group needs a specimen at every level")
    return names, np.asarray(levels), g_index, t_index, sizes


def _attributes(means, direction):
    """Path lengths (G,) and the pairwise magnitude differences, angles and shape distances (G, G)."""
    steps = np.linalg.norm(np.diff(means, axis=1), axis=2)
    lengths = steps.sum(axis=1)
    centred = means - means.mean(axis=1, keepdims=True)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axes = vt[:, 0, :]  # (G, p)
    if direction == "path":
        sign = np.sign(np.einsum("gp,gp->g", axes, means[:, -1] - means[:, 0]))
        axes = axes * np.where(sign < 0, -1.0, 1.0)[:, None]
    # from the chord between the unit axes, 2 arcsin(|u_a − u_b| / 2): accurate near 0° (arccos is not)
    chord = np.linalg.norm(axes[:, None, :] - axes[None, :, :], axis=2)
    if direction == "axis":
        chord = np.minimum(chord, np.linalg.norm(axes[:, None, :] + axes[None, :, :], axis=2))
    angles = np.degrees(2.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0)))
    unit = centred / np.linalg.norm(centred, axis=(1, 2), keepdims=True)
    n_groups, n_levels, p = means.shape
    first, second = np.triu_indices(n_groups, k=1)
    pairs = np.concatenate([unit[first], unit[second]], axis=1)  # (P, 2T, p)
    if p > 2 * n_levels:  # the pair's points in a basis of the space they span: (P, 2T, 2T)
        pairs = np.swapaxes(np.linalg.qr(np.swapaxes(pairs, 1, 2), mode="r"), 1, 2)
    a, b = pairs[:, :n_levels], pairs[:, n_levels:]
    # b's best orthogonal superimposition on a: b U Vᵀ, with bᵀa = U Σ Vᵀ; the difference itself
    # is measured (2 − 2 Σσ would lose half the digits to cancellation)
    u, _, vt = np.linalg.svd(np.swapaxes(b, 1, 2) @ a)
    distances = np.linalg.norm(a - b @ u @ vt, axis=(1, 2))
    if n_levels == 2:  # two segments have the same shape: 0, not rounding noise that would rank permutations
        distances[:] = 0.0
    shapes = np.zeros((n_groups, n_groups))
    shapes[first, second] = shapes[second, first] = distances
    np.fill_diagonal(angles, 0.0)
    return lengths, np.abs(lengths[:, None] - lengths[None, :]), angles, shapes


def trajectory_analysis(shapes, groups, points, *, levels=None, direction: str = "axis", aligned: bool = False,
                        n_permutations: int = 999, seed: int | None = 0) -> TrajectoryResult:
    """Phenotypic trajectories of groups across levels, compared in magnitude, direction and shape.

    The trajectory of each group is the sequence of its cell means across the levels of ``points``;
    each pair of trajectories is compared by the difference of their path lengths, the angle between
    their first principal axes and the Procrustes distance between their points at unit size [1]_
    [2]_ [4]_ (module docstring), and each comparison is tested by residual randomisation under the model
    without the groups × points interaction [3]_, as RRPP's ``trajectory.analysis(fit, groups =
    groups, traj.pts = points)`` for ``fit = lm.rrpp(y ~ groups * points)``.

    Parameters
    ----------
    shapes : array_like (N, K, d) or (N, p)
        Landmark configurations, aligned here by generalized Procrustes analysis at unit size
        (:func:`~shapelib.statistics.linear_model.procrustes_coordinates`) unless ``aligned``; or
        rows of variables (Procrustes or tangent coordinates, measurements), used as they are.
    groups : array_like (N,)
        The trajectory of each specimen; at least two groups.
    points : array_like (N,)
        The level of each specimen (a time, an environment); at least two levels, and at least one
        specimen of every group at every level.
    levels : sequence, optional
        The levels in the order of the trajectories' points; by default sorted. Must hold each level
        of ``points`` once.
    direction : {"axis", "path"}
        ``"axis"``: the acute angle between the first principal axes, 0–90°, whatever their signs;
        ``"path"``: each axis turned to point from the first level's mean towards the last's, so
        that opposite trajectories are 180° apart.
    aligned : bool
        (N, K, d) shapes already aligned: flattened, not aligned again.
    n_permutations : int
        At least 19; the smallest attainable p is ``1 / (1 + n_permutations)``.
    seed : int or None

    Returns
    -------
    TrajectoryResult

    See Also
    --------
    shapelib.shape_lm : The test of the groups × points interaction as a whole.
    shapelib.morphological_disparity : Differences in variation between groups.
    shapelib.holm_adjust : Adjusting the pairwise p-values.

    Notes
    -----
    RRPP takes the angle as the arc cosine of the dot product of the first principal axes as the
    singular value decomposition returns them, whose signs are arbitrary: its angle is ``θ`` or
    ``180° − θ``. ``direction="axis"`` gives ``min(θ, 180° − θ)``; ``direction="path"`` fixes the
    signs by the trajectories' own sense (where the axis is perpendicular to the line from the first
    point to the last, as for a closed loop, that sense is undefined and the sign is the SVD's).
    RRPP superimposes every trajectory at unit size on their mean and measures the distances between
    the superimposed ones; here each pair is superimposed on each other (a distance that does not
    depend on the other trajectories). The two can differ a little; both are 0 for trajectories of
    the same shape. With two levels every trajectory is a segment and every shape distance is 0. The
    orthogonal matrix may include a reflection, which changes nothing when ``p`` exceeds ``T − 1``
    (a reflection of the points is then also a rotation).

    References
    ----------
    .. [1] D. C. Adams and M. L. Collyer, "A general framework for the analysis of phenotypic
       trajectories in evolutionary studies", *Evolution* 63(5), 1143–1154, 2009.
    .. [2] M. L. Collyer and D. C. Adams, "Phenotypic trajectory analysis: comparison of shape
       change patterns in evolution and ecology", *Hystrix* 24(1), 75–83, 2013.
    .. [3] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for
       phenotypes described by high-dimensional data", *Heredity* 115, 357–365, 2015.
    .. [4] J. C. Gower, "Generalized Procrustes analysis", *Psychometrika* 40(1), 33–51, 1975.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(2)
    >>> groups, points = np.repeat(["a", "b"], 15), np.tile(np.repeat([0, 1, 2], 5), 2)
    >>> y = rng.normal(scale=0.03, size=(30, 4))
    >>> y[:, 0] += points                 # both groups move along the first variable...
    >>> y[groups == "b", 1] += points[groups == "b"]   # ...b also along the second
    >>> res = sl.trajectory_analysis(y, groups, points, n_permutations=199)
    >>> bool(abs(res.angles[0, 1] - 45) < 3), bool(res.angle_p_values[0, 1] < 0.05)
    (True, True)
    """
    if direction not in DIRECTIONS:
        raise ValueError(f"direction must be one of {DIRECTIONS}; got {direction!r}")
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    if n_permutations < MIN_PERMUTATIONS:
        raise ValueError(f"n_permutations must be at least {MIN_PERMUTATIONS}; got {n_permutations}")
    y = _coordinates(shapes, aligned)
    n = len(y)
    names, levels, g_index, t_index, sizes = _design(groups, points, levels, n)
    n_groups, n_levels = sizes.shape
    cell = g_index * n_levels + t_index
    averaging = np.zeros((n_groups * n_levels, n))
    averaging[cell, np.arange(n)] = 1.0
    averaging /= averaging.sum(axis=1, keepdims=True)
    # the reduced model ~ groups + points: intercept and treatment contrasts of both factors
    design = np.column_stack([np.ones(n), (g_index[:, None] == np.arange(1, n_groups)).astype(float),
                              (t_index[:, None] == np.arange(1, n_levels)).astype(float)])
    fitted = design @ np.linalg.lstsq(design, y, rcond=None)[0]
    residuals = y - fitted
    shape = (n_groups, n_levels, y.shape[1])
    means = (averaging @ y).reshape(shape)
    observed = _attributes(means, direction)[1:]
    fitted_means = averaging @ fitted
    rng = np.random.default_rng(seed)
    null = np.empty((n_permutations, 3, n_groups, n_groups))
    for i in range(n_permutations):
        means_i = (fitted_means + averaging @ residuals[rng.permutation(n)]).reshape(shape)
        null[i] = _attributes(means_i, direction)[1:]
    stats = np.stack(observed)
    lengths = _attributes(means, direction)[0]
    # rounding: a permutation that leaves the trajectories as they are (residuals of exactly additive data,
    # or moved within their cells) gives the observed statistic to within these, and counts as "as large"
    tol = np.array([ROUNDING * lengths.max(), ROUNDING, ROUNDING])[:, None, None]
    exceed = np.sum(null >= stats - tol, axis=0)
    p = (1.0 + exceed) / (1.0 + n_permutations)
    spread = null.std(axis=0, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(spread > tol, (stats - null.mean(axis=0)) / spread, 0.0)
    for k in range(3):
        np.fill_diagonal(p[k], 1.0)
        np.fill_diagonal(z[k], 0.0)
    return TrajectoryResult(groups=names, levels=levels, trajectories=means, sizes=sizes,
                            magnitudes=lengths, magnitude_differences=observed[0],
                            angles=observed[1], shape_distances=observed[2], magnitude_p_values=p[0],
                            angle_p_values=p[1], shape_p_values=p[2], magnitude_z=z[0], angle_z=z[1], shape_z=z[2],
                            direction=direction, n_permutations=n_permutations)
