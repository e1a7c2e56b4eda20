r"""Procrustes analysis: ordinary and generalised alignment and the Procrustes distances.

References: Kendall (1984), Dryden & Mardia, *Statistical Shape Analysis* (paper refs. [4], [40]).

For centred configurations scaled to unit Frobenius norm (pre-shapes) ``X`` and ``Y``, let
:math:`s` be the singular values of :math:`X^\top Y` with the sign of the smallest one flipped
when the optimal orthogonal map would be a reflection (rotations only). With
:math:`S = \sum_i s_i` (:math:`0 \le S \le 1`):

.. math::

    \rho = \arccos S \quad \text{(Procrustes angle, the Riemannian shape-space distance)},

    d_F = \sqrt{1 - S^2} \quad \text{(full Procrustes distance)}, \qquad
    d_P = \sqrt{2 - 2S} \quad \text{(partial Procrustes distance)}.

``scipy.spatial.procrustes`` returns :math:`d_F^2` when reflections are allowed.
Table I's Procrustes column is ρ × 100 (``notebooks/table1_pairwise.py``).

Pose
----
The information metrics (eqs. 6, 22), their bounds, the landmark diffeomorphism and the
Hausdorff distance compare shapes where they lie: rotating or moving one shape changes them.
:func:`pose_align` aligns shapes by rotations and translations only (sizes kept, so σ² keeps its
meaning) and says how far each shape moved; :func:`check_pose` warns (:class:`PoseWarning`) when
that is more than :data:`POSE_TOL` of the shapes' size.
"""

from __future__ import annotations

import warnings

import numpy as np

from .._validate import as_shape, as_shape_pair, as_shapes, set_was_checked

__all__ = [
    "PoseWarning",
    "POSE_TOL",
    "POSE_PAIR_RATIO",
    "pose_align",
    "pose_change",
    "check_pose",
    "center",
    "centroid_size",
    "preshape",
    "optimal_rotation",
    "procrustes_align",
    "procrustes_distance",
    "generalized_procrustes",
]


def center(x) -> np.ndarray:
    r"""Translate the landmarks so that their centroid is at the origin.

    .. math::

        x_a \mapsto x_a - \bar x, \qquad \bar x = \frac{1}{K} \sum_{a=1}^K x_a

    Parameters
    ----------
    x : array_like, shape (K, d)
        Landmarks.

    Returns
    -------
    ndarray, shape (K, d)
        The centred landmarks.

    Raises
    ------
    ValueError
        If ``x`` is not a finite ``(K, d)`` array.

    See Also
    --------
    shapelib.preshape : Centre and scale to unit size.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    >>> from shapelib.geometry.procrustes import center
    >>> center([[0.0, 0.0], [2.0, 0.0], [1.0, 3.0]])
    array([[-1., -1.],
           [ 1., -1.],
           [ 0.,  2.]])

    This is the first step of every Procrustes quantity [1]_.
    """
    x = as_shape(x, name="x")
    return x - x.mean(axis=0)


def centroid_size(x) -> float:
    r"""Centroid size: the Frobenius norm of the centred configuration.

    .. math::

        S(x) = \Big(\sum_{a=1}^K |x_a - \bar x|^2\Big)^{1/2}

    the size measure of Procrustes analysis [1]_; the study brings shapes to centroid size 20
    (:func:`shapelib.to_centroid_size`).

    Parameters
    ----------
    x : array_like, shape (K, d)
        Landmarks.

    Returns
    -------
    float
        :math:`S(x) \ge 0`.

    Raises
    ------
    ValueError
        If ``x`` is not a finite ``(K, d)`` array.

    See Also
    --------
    shapelib.preshape : Scale to unit centroid size.
    shapelib.to_centroid_size : Bring a population to a common centroid size.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    >>> import shapelib as sl
    >>> sl.centroid_size([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0], [3.0, 4.0]])
    5.0
    """
    c = center(x)
    top = float(np.abs(c).max()) if c.size else 0.0
    return top * float(np.linalg.norm(c / top)) if top > 0 and np.isfinite(top) else float(np.linalg.norm(c))


def preshape(x) -> np.ndarray:
    r"""Centre and scale to unit centroid size (the pre-shape).

    .. math::

        z = \frac{x - \bar x}{\|x - \bar x\|_F}

    Kendall's pre-shape [1]_ [2]_: what is left of a configuration once location and scale are
    removed (rotation is removed by :func:`shapelib.procrustes_align`).

    Parameters
    ----------
    x : array_like, shape (K, d)
        Landmarks.

    Returns
    -------
    ndarray, shape (K, d)
        Centred, with unit Frobenius norm.

    Raises
    ------
    ValueError
        If all landmarks coincide (zero centroid size) or ``x`` is not a finite ``(K, d)`` array.

    See Also
    --------
    shapelib.centroid_size : The norm divided out.
    shapelib.procrustes_distance : Distances between pre-shapes, rotation removed.

    References
    ----------
    .. [1] D. G. Kendall, "Shape manifolds, Procrustean metrics, and complex projective spaces",
       *Bulletin of the London Mathematical Society* 16(2), 81–121, 1984.
    .. [2] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> z = sl.preshape([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0], [3.0, 4.0]])
    >>> bool(np.isclose(np.linalg.norm(z), 1.0)), bool(np.allclose(z.mean(axis=0), 0.0))
    (True, True)
    """
    return _preshape(as_shape(x, name="x"))


def _preshape(x: np.ndarray) -> np.ndarray:
    c = x - x.mean(axis=0)
    if not np.isfinite(c).all():
        raise ValueError(f"configuration of shape {c.shape} has coordinates too large to centre in double precision "
                         f"(largest {np.nanmax(np.abs(x)):.3g}): rescale them")
    top = float(np.abs(c).max()) if c.size else 0.0
    if top == 0:
        raise ValueError(f"configuration of shape {c.shape} has zero centroid size (all landmarks coincide)")
    u = c / top  # scaled first: the sum of squares of coordinates near 1e200 overflows
    return u / np.linalg.norm(u)


def optimal_rotation(x, y, *, reflection: bool = False):
    r"""Rotation ``R`` minimising ``‖x − y R‖`` for centred ``x`` and ``y``, and the summed singular values.

    The orthogonal Procrustes problem [1]_: with the singular value decomposition
    :math:`y^\top x = U \operatorname{diag}(s) V^\top`,

    .. math::

        R = \arg\min_{R^\top R = I,\ \det R = 1} \|x - yR\|_F = U V^\top,

    with the last column of :math:`U` and the smallest :math:`s` negated when :math:`U V^\top` would
    be a reflection and ``reflection`` is false.

    Parameters
    ----------
    x, y : ndarray, shape (K, d)
        Centred configurations, landmarks in correspondence (not checked: a core for callers that
        have validated their input).
    reflection : bool, default False
        Allow an improper orthogonal map.

    Returns
    -------
    R : ndarray, shape (d, d)
        The optimal orthogonal map, applied on the right of ``y``.
    trace : float
        :math:`\sum s`: the sum of singular values of :math:`y^\top x` (smallest one negated when a
        proper rotation is enforced and the unconstrained optimum is a reflection).

    See Also
    --------
    shapelib.procrustes_align : Translation, rotation and scale of one shape onto another.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.procrustes import optimal_rotation
    >>> x = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 2.0], [0.0, -2.0]])
    >>> c, s = np.cos(0.3), np.sin(0.3)
    >>> y = x @ np.array([[c, s], [-s, c]])
    >>> r, trace = optimal_rotation(x, y)
    >>> bool(np.allclose(y @ r, x)), round(trace, 6)
    (True, 10.0)
    """
    u, s, vt = np.linalg.svd(y.T @ x)
    if not reflection and np.linalg.det(u @ vt) < 0:
        u = u.copy()
        u[:, -1] *= -1
        s = s.copy()
        s[-1] *= -1
    return u @ vt, float(s.sum())


def procrustes_align(x, y, *, scaling: bool = True, reflection: bool = False) -> np.ndarray:
    r"""Ordinary Procrustes analysis: superimpose ``y`` onto ``x``.

    ``y`` is translated to ``x``'s centroid, rotated (and scaled if ``scaling``) to minimise the sum
    of squared landmark distances to ``x`` [1]_:

    .. math::

        \min_{\beta > 0,\ R \in SO(d),\ t} \|x - (\beta\, y R + \mathbf{1} t^\top)\|_F^2,
        \qquad \hat\beta = \frac{\sum s}{\|y - \bar y\|_F^2},

    with :math:`R` and :math:`\sum s` from :func:`~shapelib.geometry.procrustes.optimal_rotation`.

    Parameters
    ----------
    x, y : array_like, shape (K, d)
        Target and moving configurations, landmarks in correspondence.
    scaling : bool, default True
        Also fit an isotropic scale.
    reflection : bool, default False
        Allow an improper orthogonal map.

    Returns
    -------
    ndarray, shape (K, d)
        ``y`` aligned to ``x``.

    Raises
    ------
    ValueError
        If the shapes do not match in shape or are not finite, or (with ``scaling``) all landmarks
        of ``y`` coincide.

    See Also
    --------
    shapelib.pose_align : Rotations and translations only, for a whole set.
    shapelib.procrustes_distance : The distance that remains after this alignment.
    shapelib.generalized_procrustes : Alignment of a collection to its mean.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    A rotated, scaled and shifted copy is brought back exactly:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> x = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> c, s = np.cos(0.5), np.sin(0.5)
    >>> y = 3.0 * x @ np.array([[c, s], [-s, c]]) + [5.0, -1.0]
    >>> bool(np.allclose(sl.procrustes_align(x, y), x))
    True
    """
    x, y = as_shape_pair(x, y, names=("x", "y"))
    mx = x.mean(axis=0)
    xc, yc = x - mx, y - y.mean(axis=0)
    r, tr = optimal_rotation(xc, yc, reflection=reflection)
    beta = 1.0
    if scaling:
        ny = np.sum(yc**2)
        if ny == 0:
            raise ValueError("y has zero centroid size (all landmarks coincide); cannot scale it")
        beta = tr / ny
    return beta * (yc @ r) + mx


def procrustes_distance(u, v, *, kind: str = "angle") -> float:
    r"""Procrustes distance between two landmark configurations (rotations, no reflections).

    With :math:`S = \sum s` the summed singular values of the pre-shapes' cross-product
    (module docstring) [1]_ [2]_:

    .. math::

        \rho = \arccos S, \qquad d_F = \sqrt{1 - S^2}, \qquad d_P = \sqrt{2 - 2S}.

    Table I of [3]_ reports ρ × 100.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Configurations with landmarks in correspondence, K >= 2.
    kind : {"angle", "full", "partial"}, default "angle"
        ``"angle"``: ρ (Kendall's shape-space geodesic distance, in radians); ``"full"``:
        :math:`d_F`; ``"partial"``: :math:`d_P`.

    Returns
    -------
    float
        The distance; invariant to translation, rotation and scale of either shape.

    Raises
    ------
    ValueError
        For an unknown ``kind``, shapes that do not match or have fewer than two landmarks, or a
        shape whose landmarks all coincide.

    See Also
    --------
    shapelib.procrustes_align : The superimposition behind it.
    shapelib.distance : Every distance of the study through one entry point.

    References
    ----------
    .. [1] D. G. Kendall, "Shape manifolds, Procrustean metrics, and complex projective spaces",
       *Bulletin of the London Mathematical Society* 16(2), 81–121, 1984.
    .. [2] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.
    .. [3] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> rect = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> round(sl.procrustes_distance(square, 2.0 * square + 1.0), 6)
    0.0
    >>> round(sl.procrustes_distance(square, rect), 6)
    0.321751
    >>> round(sl.procrustes_distance(square, rect, kind="full"), 6)
    0.316228
    """
    u, v = as_shape_pair(u, v, min_landmarks=2)
    return procrustes_distance_unchecked(u, v, kind=kind)


def procrustes_distance_unchecked(u, v, *, kind: str = "angle") -> float:
    """:func:`procrustes_distance` of float64 ``(K, d)`` arrays ``u``, ``v`` already checked
    (:func:`shapelib._validate.as_shape_pair`): the core the pairwise engine calls for every pair
    of a set it has checked once."""
    if kind not in ("angle", "full", "partial"):
        raise ValueError(f"kind must be 'angle', 'full' or 'partial'; got {kind!r}")
    _, s = optimal_rotation(_preshape(u), _preshape(v))
    s = min(max(s, -1.0), 1.0)
    if kind == "angle":
        return float(np.arccos(s))
    if kind == "full":
        return float(np.sqrt(max(1.0 - s * s, 0.0)))
    return float(np.sqrt(max(2.0 - 2.0 * s, 0.0)))


def generalized_procrustes(shapes, *, scaling: bool = True, tol: float = 1e-12, max_iter: int = 1000):
    r"""Generalised Procrustes analysis (GPA) of a collection of shapes.

    Each shape is centred and scaled to unit centroid size, then rotated (rotations only) to the
    current mean, and the mean re-estimated and normalised, until the mean stops changing [1]_ [2]_.
    With ``scaling``, full GPA scale factors are fitted as well (Ten Berge 1977), keeping the total
    size fixed. The alignment minimises

    .. math::

        \sum_{i=1}^{N} \|\beta_i z_i R_i - \mu\|_F^2, \qquad \|\mu\|_F = 1,

    over rotations :math:`R_i` (and scales :math:`\beta_i` with :math:`\sum_i \beta_i^2 \|z_i\|^2 = N`
    when ``scaling``), :math:`z_i` the pre-shapes.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        Shapes in landmark correspondence, K >= 2.
    scaling : bool, default True
        Fit per-shape scales (full GPA) instead of leaving every shape at unit size.
    tol : float, default 1e-12
        Convergence tolerance on the change of the mean (Frobenius norm).
    max_iter : int, default 1000
        Iterations before giving up (with a ``RuntimeWarning``).

    Returns
    -------
    aligned : ndarray, shape (N, K, d)
        Aligned shapes, centred; with ``scaling=False`` each has unit centroid size.
    mean : ndarray, shape (K, d)
        Their mean, with unit centroid size.

    Raises
    ------
    ValueError
        If ``shapes`` is not a finite ``(N, K, d)`` array with K >= 2, or a shape has zero size.

    Warns
    -----
    RuntimeWarning
        When the mean has not converged within ``max_iter`` iterations.

    See Also
    --------
    shapelib.pose_align : GPA rotations at the shapes' own sizes.
    shapelib.to_centroid_size : GPA, then every shape at the study's centroid size.

    References
    ----------
    .. [1] J. C. Gower, "Generalized Procrustes analysis", *Psychometrika* 40(1), 33–51, 1975.
    .. [2] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    Rotated copies of one shape align onto a single configuration:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> base = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> rot = lambda a: np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    >>> shapes = np.stack([base @ rot(a) for a in (0.0, 0.4, 1.1)])
    >>> aligned, mean = sl.generalized_procrustes(shapes, scaling=False)
    >>> aligned.shape, bool(np.allclose(aligned, mean))
    ((3, 4, 2), True)
    """
    x = as_shapes(shapes, name="shapes", min_landmarks=2)
    aligned = np.stack([preshape(s) for s in x])
    mean = preshape(aligned[0])
    for it in range(max_iter):
        for i in range(len(aligned)):
            r, _ = optimal_rotation(mean, aligned[i])
            aligned[i] = aligned[i] @ r
        if scaling and len(aligned) > 1:
            # Ten Berge (1977): scales proportional to the leading eigenvector of the correlation.
            flat = aligned.reshape(len(aligned), -1)
            gram = flat @ flat.T
            norms = np.sqrt(np.diag(gram))
            corr = gram / np.outer(norms, norms)
            w, vecs = np.linalg.eigh(corr)
            phi = np.abs(vecs[:, -1])
            beta = np.sqrt(np.sum(norms**2) / norms**2) * phi
            aligned = aligned * beta[:, None, None]
        new_mean = aligned.mean(axis=0)
        new_mean /= np.linalg.norm(new_mean)
        delta = np.linalg.norm(new_mean - mean)
        mean = new_mean
        if delta < tol:
            break
    else:
        warnings.warn(f"generalized_procrustes did not converge in {max_iter} iterations", RuntimeWarning, stacklevel=2)
    return aligned, mean


# ---------------------------------------------------------------------------------------------
# Pose: are the shapes aligned?
# ---------------------------------------------------------------------------------------------

#: Shapes count as aligned when aligning them moves no shape by more than this fraction of its
#: centroid size (RMS over landmarks × √K; 1e-3 is a rotation of 0.06°).
POSE_TOL = 1e-3
#: Two shapes are not aligned when aligning them moves one by more than this fraction of the shape
#: difference that remains. Shapes taken from one aligned set stay far below it: at most 0.05 over
#: the pairs of the corpus callosum, Beijing and ADHD-200 shapes after generalised Procrustes.
POSE_PAIR_RATIO = 0.25


class PoseWarning(UserWarning):
    """A pose-dependent distance was asked of shapes that are not aligned.

    The information metrics (eqs. 6, 22 of [1]_), their closed-form bounds, landmark
    diffeomorphisms and the Hausdorff distance compare shapes where they lie; they warn with this
    category when rotating and translating the shapes would move them by more than
    :data:`~shapelib.geometry.procrustes.POSE_TOL` of their size
    (:func:`~shapelib.geometry.procrustes.check_pose`). Filter it with :mod:`warnings` like any
    :class:`UserWarning`.

    Parameters
    ----------
    *args : str
        The message, as for any warning (:func:`warnings.warn` passes its text when given this
        category).

    See Also
    --------
    shapelib.pose_align : The fix: align the shapes first.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import shapelib as sl
    >>> u = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> v = u @ np.array([[0.0, 1.0], [-1.0, 0.0]])  # u turned by 90 degrees
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = sl.distance(u, v, metric="alpha_bound", sigma2=0.5)
    >>> any(issubclass(w.category, sl.PoseWarning) for w in caught)
    True
    """


def pose_align(shapes):
    r"""Align shapes by rotations and translations only, each keeping its centroid size.

    Generalised Procrustes without scaling [1]_: each shape :math:`x_i` is rotated and translated to
    minimise :math:`\sum_i \|x_i R_i + \mathbf{1} t_i^\top - \mu\|_F^2` at its own size, then one
    rotation and translation of the whole set (which changes no pose-dependent distance) puts it back
    in the frame nearest the input. Sizes are kept, so σ² of eq. (5) keeps its meaning [2]_.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        Shapes in landmark correspondence, K >= 2.

    Returns
    -------
    aligned : ndarray, shape (N, K, d)
        The shapes after GPA rotations at their own centroid sizes, with a common centroid, in the
        frame nearest the input.
    moved : ndarray, shape (N,)
        :math:`\|x_i - \text{aligned}_i\|_F / S(x_i)`: 0 for shapes already aligned (0 also for a
        shape whose landmarks all coincide, which has no pose).

    Raises
    ------
    ValueError
        If ``shapes`` is not a finite ``(N, K, d)`` array with K >= 2.

    See Also
    --------
    shapelib.PoseWarning : Raised by the distances this alignment is for.
    shapelib.generalized_procrustes : GPA with unit or fitted sizes.
    shapelib.procrustes_align : One shape onto another.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> base = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> turned = base @ np.array([[0.0, 1.0], [-1.0, 0.0]]) + 3.0
    >>> aligned, moved = sl.pose_align(np.stack([base, turned]))
    >>> bool(np.allclose(aligned[0], aligned[1])), bool(moved[1] > 0.5)
    (True, True)
    >>> bool(np.isclose(sl.centroid_size(aligned[1]), sl.centroid_size(turned)))
    True
    """
    x = as_shapes(shapes, name="shapes", min_landmarks=2)
    centred = x - x.mean(axis=1, keepdims=True)
    sizes = np.linalg.norm(centred, axis=(1, 2))
    ok = sizes > 0
    aligned = x.copy()
    moved = np.zeros(len(x))
    if ok.sum() == 0:
        return aligned, moved
    if ok.sum() == 1:
        gpa = centred[ok] / sizes[ok, None, None]
    else:
        gpa, _ = generalized_procrustes(x[ok], scaling=False)
    back = gpa * sizes[ok, None, None]
    offset = x[ok].mean(axis=(0, 1))
    r, _ = optimal_rotation((x[ok] - offset).reshape(-1, x.shape[2]), back.reshape(-1, x.shape[2]))
    aligned[ok] = back @ r + offset
    moved[ok] = np.linalg.norm(x[ok] - aligned[ok], axis=(1, 2)) / sizes[ok]
    return aligned, moved


def pose_change(u, v) -> tuple[float, float]:
    r"""How much of the difference between ``u`` and ``v`` is pose: ``(moved, remaining)``.

    With :math:`v'` the rigid superimposition of ``v`` onto ``u``
    (:func:`~shapelib.procrustes_align` without scaling) and
    :math:`\bar S = (S(u) + S(v))/2` the mean centroid size,

    .. math::

        \text{moved} = \frac{\|v - v'\|_F}{\bar S}, \qquad
        \text{remaining} = \frac{\|u - v'\|_F}{\bar S}

    (0, 0 if both shapes have size 0) [1]_.

    Parameters
    ----------
    u, v : array_like, shape (K, d)
        Shapes in landmark correspondence, K >= 2.

    Returns
    -------
    moved : float
        How far the rigid alignment moves ``v``, in units of the mean centroid size.
    remaining : float
        The shape difference that the alignment leaves, in the same units.

    Raises
    ------
    ValueError
        If the shapes do not match in shape, are not finite, or have fewer than two landmarks.

    See Also
    --------
    shapelib.geometry.procrustes.check_pose : The warning built on it.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.procrustes import pose_change
    >>> u = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> moved, remaining = pose_change(u, u + [1.0, 0.0])
    >>> round(moved, 6), round(remaining, 6)
    (0.894427, 0.0)
    """
    u, v = as_shape_pair(u, v, min_landmarks=2)
    size = 0.5 * (centroid_size(u) + centroid_size(v))
    if size == 0:
        return 0.0, 0.0
    if np.linalg.norm(v - v.mean(axis=0)) == 0:  # a point has no rotation: only its position counts
        moved_v = v - v.mean(axis=0) + u.mean(axis=0)
    else:
        moved_v = procrustes_align(u, v, scaling=False)
    return float(np.linalg.norm(v - moved_v) / size), float(np.linalg.norm(u - moved_v) / size)


def check_pose(shapes, *, metric: str, tol: float = POSE_TOL, stacklevel: int = 3) -> float:
    r"""Warn when a pose-dependent metric is asked of shapes that are not aligned.

    Returns how far aligning would move them (a fraction of their size). Two shapes ``(2, K, d)``
    (one pair) are not aligned when rotating and translating ``v`` onto ``u`` moves it by more than
    ``tol`` and by more than :data:`~shapelib.geometry.procrustes.POSE_PAIR_RATIO` times the shape
    difference that remains (:func:`~shapelib.geometry.procrustes.pose_change`): a good part of what
    the distance measures is then their relative pose,

    .. math::

        \text{moved} > \text{tol} \quad \text{and} \quad
        \text{moved} > r \cdot \text{remaining}, \qquad r = 0.25.

    Two shapes taken from a larger aligned set are not aligned to each other exactly, but what
    aligning them changes is of second order in their shape difference, so they pass. More shapes:
    any shape that :func:`~shapelib.pose_align` moves by more than ``tol``.
    Skipped (returns NaN) inside ``shapelib._validate.set_checked``, where the pairwise engine has
    checked the set. The pose-dependent metrics are those of [1]_ (eqs. 6, 22), their bounds,
    landmark diffeomorphisms and the Hausdorff distance.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        The shapes a distance is asked of (N = 2: one pair).
    metric : str, keyword-only
        The metric's name, for the message.
    tol : float, default POSE_TOL
        Largest movement (fraction of the centroid size) that counts as aligned.
    stacklevel : int, default 3
        Counted from this function, as :func:`warnings.warn` counts it.

    Returns
    -------
    float
        The largest movement alignment would make (NaN when skipped, 0 for single landmarks).

    Raises
    ------
    ValueError
        If ``shapes`` is not a finite ``(N, K, d)`` array.

    Warns
    -----
    PoseWarning
        When the shapes are not aligned; the message says by how much and how to align them.

    See Also
    --------
    shapelib.pose_align : The fix.
    shapelib.PoseWarning : The warning category.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from shapelib.geometry.procrustes import check_pose
    >>> u = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("error")
    ...     moved = check_pose(np.stack([u, u]), metric="alpha")
    >>> bool(moved < 1e-12)
    True
    """
    if set_was_checked():
        return float("nan")
    x = as_shapes(shapes, name="shapes")
    if x.shape[1] < 2:
        return 0.0
    if len(x) == 2:
        moved, remaining = pose_change(x[0], x[1])
        if moved > tol and moved > POSE_PAIR_RATIO * remaining:
            warnings.warn(
                f"{metric} depends on the pose of the shapes, and u and v are not aligned: rotating and "
                f"translating v onto u moves it by {100 * moved:.3g} % of their size, against a shape "
                f"difference of {100 * remaining:.3g} % that remains, so the distance measures their relative "
                f"pose as well as their shapes. Align them first: v = shapelib.procrustes_align(u, v, "
                f"scaling=False), or shapelib.pose_align(shapes)[0] for a whole set.", PoseWarning,
                stacklevel=stacklevel)
        return moved
    _, moved = pose_align(x)
    worst = int(np.argmax(moved))
    if moved[worst] > tol:
        n_bad = int(np.sum(moved > tol))
        warnings.warn(
            f"{metric} depends on the pose of the shapes, and these are not aligned: aligning them "
            f"(rotations and translations) moves {n_bad} of {len(x)} shapes by more than {100 * tol:.2g} % of "
            f"their size, shapes[{worst}] by {100 * moved[worst]:.3g} %. Align them first: "
            f"shapelib.pose_align(shapes)[0] (sizes kept, so sigma2 keeps its meaning); the shapelib "
            f"command line does this by default.", PoseWarning, stacklevel=stacklevel)
    return float(moved[worst])
