"""Global integration: how the shape variation of a sample is spread over spatial scales, measured
by the slope of the log variances of its partial warps on the log of their bending energies
(Bookstein 2015), as geomorph's ``globalIntegration``.

Partial warps
    The thin-plate spline bending-energy matrix ``L_K`` (K, K) of the mean configuration ``M``
    (:func:`shapelib.bending_energy_matrix`) is symmetric and positive semi-definite, and its null
    space holds the affine functions of ``M`` (dimension d + 1). Its ``m = K − d − 1`` nonzero
    eigenvalues ``λ₁ < … < λ_m`` are the bending energies of the partial warps, its eigenvectors
    ``e_j`` (K,): ``e_j`` with a small ``λ_j`` bends the configuration gently, over its whole extent
    (a large spatial scale); with a large ``λ_j``, locally (a small scale).

Variances
    Each specimen's coordinates ``X_i`` (K, d) are projected on each partial warp,
    ``w_ij = X_iᵀ e_j`` (d,), and the variance of partial warp ``j`` is the variance of these
    projections over the specimens, summed over the d coordinates::

        v_j = Σ_c var_i(w_ijc).

The statistic
    The slope ``b`` of the least-squares line of ``log v_j`` on ``log λ_j`` (j = 1 … m). Under
    self-similarity (variation the same at every scale once the bending energy is accounted for)
    ``v_j ∝ 1 / λ_j``, ``b = −1``. A slope below −1 puts relatively more of the variation at the
    large scales (the shape *integrated*), one between −1 and 0 at the small scales
    (*disintegrated*); isotropic, independent noise at the landmarks gives the same variance on
    every partial warp, ``b ≈ 0``. The divisor of the variances and the scale of the bending
    energies (the size of ``M``, the constant of the kernel) only shift the line: the slope does
    not depend on them.

The references are those of :func:`global_integration`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import as_shapes, check_positive

__all__ = ["GlobalIntegrationResult", "global_integration"]

#: the words of the three readings of the slope, in the order integrated, self-similar, disintegrated
_READINGS = ("integrated", "self-similar", "disintegrated")


@dataclass
class GlobalIntegrationResult:
    """Result of :func:`global_integration`.

    Attributes
    ----------
    value : float
        The slope ``b`` of ``log v_j`` on ``log λ_j`` [1]_: −1 for self-similar variation, below −1
        for integrated, above −1 for disintegrated; about 0 for isotropic landmark noise.
    intercept : float
        The intercept of that line (it depends on the units of the coordinates and of the bending
        energies; the slope does not).
    bending_energies : ndarray (m,)
        The bending energies ``λ_j`` of the ``m = K − d − 1`` partial warps, increasing: from the
        largest spatial scale to the smallest.
    variances : ndarray (m,)
        ``v_j``: the variance of the specimens' projections on each partial warp, summed over the
        coordinates (divisor N − 1).
    partial_warps : ndarray (K, m)
        The partial warps ``e_j`` as columns: orthonormal eigenvectors of the bending-energy
        matrix of the mean, in the order of ``bending_energies`` (each defined up to its sign).
    mean : ndarray (K, d)
        The mean configuration whose bending-energy matrix gives the partial warps.
    n_specimens : int
    tolerance : float
        How close to −1 a slope is read as self-similar (:attr:`reading`).

    See Also
    --------
    global_integration : What returns it.
    shapelib.two_block_pls : The integration of two parts of a shape, by their covariation.

    References
    ----------
    .. [1] F. L. Bookstein, "Integration, disintegration, and self-similarity: characterizing the
       scales of shape variation in landmark data", *Evolutionary Biology* 42(4), 395–426, 2015.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> base = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [1, 1.2], [0, 1], [0.5, 0.5], [1.5, 0.5]])
    >>> res = sl.global_integration(base + 0.01 * rng.normal(size=(200, 8, 2)))
    >>> res.bending_energies.shape, res.reading
    ((5,), 'disintegrated')
    """

    value: float
    intercept: float
    bending_energies: np.ndarray
    variances: np.ndarray
    partial_warps: np.ndarray = field(repr=False)
    mean: np.ndarray = field(repr=False)
    n_specimens: int = 0
    tolerance: float = 0.1

    @property
    def reading(self) -> str:
        """``"integrated"`` when the slope is below ``−1 − tolerance``, ``"disintegrated"`` when it
        is above ``−1 + tolerance``, ``"self-similar"`` in between."""
        if self.value < -1.0 - self.tolerance:
            return _READINGS[0]
        if self.value > -1.0 + self.tolerance:
            return _READINGS[2]
        return _READINGS[1]

    def summary(self) -> str:
        """The slope and how it reads: integrated, self-similar or disintegrated."""
        side = {"integrated": "steeper than −1: relatively more variation at the large scales",
                "self-similar": f"within {self.tolerance:g} of −1: the same variation at every scale",
                "disintegrated": "shallower than −1: relatively more variation at the small scales"}[self.reading]
        return (f"global integration ({self.n_specimens} specimens, {len(self.bending_energies)} partial warps): "
                f"slope of log variance on log bending energy = {self.value:.4g}, {self.reading} ({side}; "
                "−1 is self-similarity, 0 isotropic landmark noise)")


def _shapes(shapes, procrustes):
    """The specimens (N, K, d) as float64, checked, aligned by GPA when ``procrustes``."""
    x = as_shapes(shapes, name="shapes")
    n, k, d = x.shape
    if n < 3:
        raise ValueError(f"shapes: at least 3 specimens are needed; got shape {x.shape}")
    if k < d + 3:
        raise ValueError(f"shapes: at least {d + 3} landmarks are needed in {d}-D (two partial warps, K − {d + 1}, "
                         f"for a slope); got shape {x.shape}")
    if procrustes:
        from ..geometry.procrustes import generalized_procrustes

        x, _ = generalized_procrustes(x, scaling=False)
    return x


def global_integration(shapes, *, procrustes: bool = True, tolerance: float = 0.1) -> GlobalIntegrationResult:
    r"""How a sample's shape variation is spread over spatial scales: the slope of the log
    variances of the partial warps on the log of their bending energies, as geomorph's
    ``globalIntegration`` [1]_.

    The partial warps ``e_j`` are the eigenvectors of the bending-energy matrix ``L_K`` of the
    mean configuration ``M`` with nonzero eigenvalues ``λ_j`` (their bending energies), and
    ``v_j`` is the variance over the specimens of their coordinates projected on ``e_j``, summed
    over the d coordinates (module docstring). The result is the least-squares slope

    .. math::

        b = \frac{\sum_j (\ell_j - \bar\ell)(\log v_j - \overline{\log v})}{\sum_j (\ell_j - \bar\ell)^2},
        \qquad \ell_j = \log \lambda_j, \quad v_j = \sum_{c=1}^{d} \operatorname{var}_i
        \big( (X_i^\top e_j)_c \big), \quad L_K e_j = \lambda_j e_j,

    over the ``m = K − d − 1`` partial warps. ``b = −1`` is self-similarity; below −1 the
    variation is integrated (concentrated at the large scales), above −1 disintegrated; isotropic
    noise at the landmarks gives ``b ≈ 0``.

    Parameters
    ----------
    shapes : array_like (N, K, d)
        Landmark configurations, d = 2 or 3, N ≥ 3 specimens and K ≥ d + 3 landmarks (two partial
        warps at least). A geomorph array ``p × k × n`` is ``numpy.moveaxis(A, 2, 0)``.
    procrustes : bool
        Align the specimens first by generalized Procrustes analysis at unit centroid size (the
        default), which makes the slope independent of each specimen's position, orientation and
        size; False takes them as already aligned (geomorph's input: ``gpagen``'s coordinates).
    tolerance : float
        How close to −1 a slope is read as self-similar in :attr:`GlobalIntegrationResult.reading`
        and the summary (positive; shapelib's convention: geomorph prints the slope alone). The
        slope itself does not depend on it.

    Returns
    -------
    GlobalIntegrationResult

    Raises
    ------
    ValueError
        If ``shapes`` is not a finite (N, K, d) array with d = 2 or 3, has fewer than 3 specimens or
        fewer than d + 3 landmarks, its mean configuration is nearly a single point (residuals
        rather than coordinates) or has no thin-plate spline (landmarks on one line, or one plane
        in 3-D, or coinciding), or the specimens do not vary along a partial warp; if
        ``tolerance`` is not positive.

    See Also
    --------
    shapelib.bending_energy_matrix : ``L_K``.
    shapelib.procrustes_coordinates : The alignment, as rows of coordinates.
    shapelib.two_block_pls : The integration of two parts of a shape.

    Notes
    -----
    This follows geomorph's ``globalIntegration`` (geomorph 4.0.8): the mean of the specimens as
    given, the partial warps of its bending-energy matrix, the projections of each coordinate,
    their variances (divisor N − 1) summed over the coordinates, and the least-squares slope of
    the logarithms over all the partial warps. It differs in these respects:

    * geomorph takes already aligned coordinates; here the specimens are aligned first unless
      ``procrustes=False``. shapelib's alignment leaves the coordinates on the shape sphere, where
      ``gpagen`` projects them onto the tangent space of the mean; that projection subtracts from
      each specimen a multiple of the mean configuration, whose projections on its own partial
      warps are zero, so the slope is the same.
    * The 2-D kernel of :func:`shapelib.bending_energy_matrix` is ``r² log r``, geomorph's
      ``r² log r²``: geomorph's bending energies are half of these, which moves the line, not its
      slope.
    * geomorph rounds the eigenvalues to seven significant digits of the largest (``zapsmall``)
      and keeps the positive ones; here the ``K − d − 1`` largest are kept unrounded, and a mean
      configuration without a thin-plate spline (landmarks on a line or plane, or coinciding) is
      an error.
    * :func:`shapelib.bending_energy_matrix` solves the spline at unit centroid size and rescales
      its energies to the mean's size (exactly: ``s⁻²`` in 2-D, ``s⁻¹`` in 3-D), which keeps them
      accurate whatever the units of the coordinates; geomorph solves at the size given (about 1
      after ``gpagen``).
    * Fewer than d + 3 landmarks (one partial warp: geomorph's slope is ``NA``) and specimens that
      do not vary along a partial warp (a logarithm of 0) are errors here.
    * geomorph plots the points, the line and a line of slope −1; here the points are returned
      (``bending_energies``, ``variances``) for a plot of one's own, and the slope is read as
      integrated, self-similar or disintegrated with ``tolerance``.

    References
    ----------
    .. [1] F. L. Bookstein, "Integration, disintegration, and self-similarity: characterizing the
       scales of shape variation in landmark data", *Evolutionary Biology* 42(4), 395–426, 2015.

    Examples
    --------
    Variation whose variance on each partial warp is ``λ⁻²``, steeper than self-similarity:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> mean = np.array([[0, 0], [1, 0], [2, 0.1], [2, 1], [1, 1.2], [0, 1], [0.6, 0.5], [1.5, 0.4]])
    >>> lam, e = np.linalg.eigh(sl.bending_energy_matrix(mean))
    >>> lam, e = lam[3:], e[:, 3:]                  # the 5 partial warps (3 zero eigenvalues: affine)
    >>> scores = rng.normal(size=(500, 5, 2)) * lam[:, None] ** -1.0 * 0.01
    >>> shapes = mean + np.einsum("km,nmc->nkc", e, scores)
    >>> res = sl.global_integration(shapes, procrustes=False)
    >>> round(res.value, 1), res.reading
    (-2.0, 'integrated')
    >>> print(res.summary())  # doctest: +ELLIPSIS
    global integration (500 specimens, 5 partial warps): slope ... = -2..., integrated (steeper than −1: ...)
    """
    from ..geometry.semilandmarks import bending_energy_matrix

    tolerance = check_positive(tolerance, name="tolerance")
    x = _shapes(shapes, procrustes)
    n, k, d = x.shape
    mean = x.mean(axis=0)
    centred = mean - mean.mean(axis=0)
    spread = np.linalg.svd(centred, compute_uv=False)  # a zero: the landmarks on one line (plane in 3-D)
    gaps = np.linalg.norm(mean[:, None] - mean[None], axis=-1)[np.triu_indices(k, 1)]
    # the mean's spread against the specimens' own (each coordinate's variance over the landmarks)
    if centred.var() <= 1e-16 * x.var(axis=1).mean():
        raise ValueError("shapes: the mean configuration is nearly a single point (below 1e-8 of the specimens' "
                         "size): pass landmark coordinates, not residuals from the mean")
    if spread[-1] <= 1e-8 * spread[0] or gaps.min() <= 1e-8 * spread[0]:
        raise ValueError("shapes: the mean configuration has no thin-plate spline: its landmarks lie on one line "
                         "(one plane in 3-D) or two of them coincide")
    size = np.sqrt(np.sum(centred**2))
    lk = bending_energy_matrix(mean)  # solved at unit centroid size, rescaled to the mean's
    lam, vec = np.linalg.eigh((lk + lk.T) / 2)
    m = k - d - 1
    # distinct landmarks not on one line (plane) have a thin-plate spline: m positive bending energies
    lam, vec = lam[-m:], vec[:, -m:]  # the affine null space (d + 1 zero eigenvalues) left out
    scores = np.einsum("km,nkc->nmc", vec, x)
    variances = scores.var(axis=0, ddof=1).sum(axis=1)
    flat = np.flatnonzero(variances <= 1e-24 * size**2)  # rounding of identical specimens, or none at all
    if flat.size:
        raise ValueError(f"shapes: the specimens do not vary along partial warp {flat[0]} (bending energy "
                         f"{lam[flat[0]]:.4g}); the slope needs variation at every scale")
    lx, ly = np.log(lam), np.log(variances)
    cx = lx - lx.mean()
    slope = float(cx @ (ly - ly.mean()) / (cx @ cx))
    return GlobalIntegrationResult(value=slope, intercept=float(ly.mean() - slope * lx.mean()), bending_energies=lam,
                                   variances=variances, partial_warps=vec, mean=mean, n_specimens=n,
                                   tolerance=tolerance)
