"""Allometry: how shape changes with size — shape regressed on log centroid size, with a permutation
p, and size-corrected shapes (the residuals added back to the mean), as geomorph's
``procD.lm(coords ~ log(Csize))``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import as_shapes

__all__ = ["allometry", "AllometryResult"]


@dataclass
class AllometryResult:
    """Result of :func:`allometry`.

    Attributes
    ----------
    centroid_size : ndarray (N,)
        Of the shapes as given (before alignment).
    slope : ndarray (K, d)
        Change of the aligned Procrustes coordinates per unit of log centroid size: the
        allometric shape vector.
    r2, F, p_value : float
        Share of the shape variation explained by log size, its F and permutation p.
    mean : ndarray (K, d)
        Mean of the aligned shapes.
    corrected : ndarray (N, K, d)
        Size-corrected shapes: ``mean + residual`` of each shape (the shape it would have at the
        mean log size, under the linear model).
    n_permutations : int

    See Also
    --------
    allometry : What returns it.
    shapelib.statistics.linear_model.ShapeLinearModel : The general linear model's result.

    Notes
    -----
    ``p_value`` comes from the residual randomisation of [1]_ (with one term, a permutation of whole rows).

    References
    ----------
    .. [1] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for phenotypes
       described by high-dimensional data", *Heredity* 115, 357–365, 2015.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.statistics.allometry import allometry
    >>> rng = np.random.default_rng(0)
    >>> base = np.array([[0, 0], [2, 0], [2, 1], [0, 1.0]])
    >>> shapes = np.stack([s * base + rng.normal(scale=0.01, size=(4, 2)) for s in (1.0, 1.5, 2.0, 2.5, 3.0)])
    >>> res = allometry(shapes, n_permutations=19)
    >>> res.slope.shape, res.corrected.shape, res.n_permutations
    ((4, 2), (5, 4, 2), 19)
    """

    centroid_size: np.ndarray
    slope: np.ndarray
    r2: float
    F: float
    p_value: float
    mean: np.ndarray
    corrected: np.ndarray = field(repr=False)
    n_permutations: int = 0

    def summary(self) -> str:
        cs = self.centroid_size
        return (f"allometry: shape on log centroid size ({len(cs)} shapes, size {cs.min():.4g} … {cs.max():.4g}): "
                f"R² = {self.r2:.4g}, F = {self.F:.4g}, permutation p = {self.p_value:.4g} "
                f"({self.n_permutations} permutations)")


def allometry(shapes, *, n_permutations: int = 999, seed: int | None = 0) -> AllometryResult:
    """Regress shape on log centroid size; size-corrected shapes.

    The shapes (as given, with their sizes) are aligned by generalized Procrustes at unit size;
    the Procrustes coordinates ``Y`` are regressed on ``log CS`` (centred),
    ``Y = Ȳ + log CS · b + E``, and tested by permutation (:func:`shapelib.shape_lm` with one
    term). The size-corrected shapes are ``Ȳ + E``.

    Parameters
    ----------
    shapes : array_like (N, K, d)
        Landmarks in their original units (centroid size is what they carry; do not align them
        to unit size first).
    n_permutations : int
    seed : int or None

    Returns
    -------
    AllometryResult

    See Also
    --------
    shapelib.statistics.linear_model.shape_lm : The linear model it fits.
    shapelib.geometry.procrustes.centroid_size : The size.
    shapelib.statistics.linear_model.procrustes_coordinates : The response.

    Notes
    -----
    Shape is the Procrustes shape of [1]_ and size the centroid size; the test is the one-term residual
    randomisation of [2]_.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.
    .. [2] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for phenotypes
       described by high-dimensional data", *Heredity* 115, 357–365, 2015.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.statistics.allometry import allometry
    >>> rng = np.random.default_rng(1)
    >>> base = np.array([[0, 0], [2, 0], [2, 1], [0, 1.0]])
    >>> size = rng.uniform(1, 3, 30)
    >>> shapes = np.stack([s * (base + [[0, 0], [0, 0], [0.3 * np.log(s), 0], [0, 0]]) for s in size])
    >>> res = allometry(shapes + rng.normal(scale=0.005, size=shapes.shape), n_permutations=99)
    >>> bool(res.r2 > 0.9 and res.p_value <= 0.01)
    True
    """
    import pandas as pd

    from ..geometry.procrustes import centroid_size
    from .linear_model import procrustes_coordinates, shape_lm

    x = as_shapes(shapes, name="shapes", min_shapes=3)
    n, k, d = x.shape
    cs = np.array([centroid_size(s) for s in x])
    if np.ptp(cs) <= 1e-12 * cs.max():
        raise ValueError("the shapes all have the same centroid size: were they scaled to unit size already? "
                         "allometry needs the shapes as measured")
    y = procrustes_coordinates(x)
    log_cs = np.log(cs)
    fit = shape_lm("~ log_size", pd.DataFrame({"log_size": log_cs}), y, n_permutations=n_permutations, seed=seed)
    row = fit.table.loc["log_size"]
    c = log_cs - log_cs.mean()
    ybar = y.mean(axis=0)
    slope = (c @ (y - ybar)) / (c @ c)
    resid = y - ybar - np.outer(c, slope)
    return AllometryResult(centroid_size=cs, slope=slope.reshape(k, d), r2=float(row["r2"]), F=float(row["F"]),
                           p_value=float(row["p_value"]), mean=ybar.reshape(k, d),
                           corrected=(ybar + resid).reshape(n, k, d), n_permutations=int(n_permutations))
