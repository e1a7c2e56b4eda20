"""Missing landmarks: estimated from the complete specimens, by a thin-plate spline from a
reference or by multivariate regression, as geomorph's ``estimate.missing(method="TPS" / "Reg")``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.procrustes import generalized_procrustes, optimal_rotation
from .splines import _spline_system, tps_kernel

__all__ = ["estimate_missing", "MissingEstimate", "tps_map"]

MISSING_METHODS = ("tps", "regression")


@dataclass
class MissingEstimate:
    """Result of :func:`estimate_missing`.

    Attributes
    ----------
    shapes : ndarray (N, K, d)
        The shapes with every missing landmark estimated (the others unchanged).
    estimated : ndarray of bool (N, K)
        True where a landmark was estimated: mark them in figures and tables.
    method : {"tps", "regression"}
    n_reference : int
        Complete specimens the estimates come from.

    See Also
    --------
    estimate_missing : The estimate.
    tps_map : The spline behind ``method="tps"``.

    Notes
    -----
    The ``"tps"`` estimates bend the complete specimens' mean onto the present landmarks by the thin-plate
    spline of [1]_.

    References
    ----------
    .. [1] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of deformations",
       *IEEE Transactions on Pattern Analysis and Machine Intelligence* 11(6), 567–585, 1989.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.comparison.missing import estimate_missing
    >>> t = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    >>> x = np.stack([np.c_[np.cos(t), (1 + 0.1 * i) * np.sin(t)] for i in range(6)])
    >>> gone = x.copy(); gone[0, 1] = np.nan
    >>> res = estimate_missing(gone, method="regression")
    >>> res.method, res.n_reference, np.argwhere(res.estimated).tolist()
    ('regression', 5, [[0, 1]])
    """

    shapes: np.ndarray
    estimated: np.ndarray
    method: str
    n_reference: int

    def summary(self) -> str:
        rows = np.flatnonzero(self.estimated.any(axis=1))
        return (f"{int(self.estimated.sum())} missing landmark(s) in {len(rows)} specimen(s) estimated by "
                f"{'thin-plate spline from the mean of' if self.method == 'tps' else 'multivariate regression on'} "
                f"{self.n_reference} complete specimens")


def _kernel(r, d):
    """Thin-plate radial basis: ``r² log r`` in 2-D, ``−r`` in 3-D (the biharmonic Green's functions)."""
    return tps_kernel(r, kernel="r2logr" if d == 2 else "r")


def tps_map(source, target, points):
    """The thin-plate spline taking ``source`` landmarks (m, d) exactly onto ``target`` (m, d),
    applied to ``points`` (q, d): ``f(x) = a + A x + Σ_i w_i U(|x − s_i|)`` with the bending energy
    minimal [1]_.

    Parameters
    ----------
    source : array_like, shape (m, d)
        Landmarks the spline starts from (``m ≥ d + 1``).
    target : array_like, shape (m, d)
        Where the spline takes them, exactly.
    points : array_like, shape (q, d)
        Points to map (one point may be given as a (d,) array).

    Returns
    -------
    ndarray, shape (q, d)
        ``f(points)``.

    See Also
    --------
    estimate_missing : Uses it to place missing landmarks.
    shapelib.comparison.splines.tps_bending_energy : The bending energy this spline minimises.

    References
    ----------
    .. [1] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of deformations",
       *IEEE Transactions on Pattern Analysis and Machine Intelligence* 11(6), 567–585, 1989.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.comparison.missing import tps_map
    >>> s = np.array([[0, 0], [1, 0], [0, 1], [1, 1.0]])
    >>> t = 2 * s + [1, -1]                         # an affine map is reproduced exactly
    >>> np.allclose(tps_map(s, t, [[0.5, 0.25]]), [[2.0, -0.5]])
    True
    """
    s = np.asarray(source, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    q = np.atleast_2d(np.asarray(points, dtype=np.float64))
    m, d = s.shape
    if m < d + 1:
        raise ValueError(f"a thin-plate spline in {d}-D needs at least {d + 1} landmarks; got {m}")
    k = _kernel(np.linalg.norm(s[:, None] - s[None], axis=-1), d)
    rhs = np.vstack([t, np.zeros((d + 1, d))])
    coef = np.linalg.lstsq(_spline_system(k, s), rhs, rcond=None)[0]
    w, a = coef[:m], coef[m:]
    u = _kernel(np.linalg.norm(q[:, None] - s[None], axis=-1), d)
    return u @ w + np.hstack([np.ones((len(q), 1)), q]) @ a


def _fit_onto(ref, target):
    """Similarity (scale, rotation, translation) taking ``ref`` (m, d) onto ``target`` (m, d):
    returns a function applying it to any points."""
    mr, mt = ref.mean(axis=0), target.mean(axis=0)
    a, b = ref - mr, target - mt
    r, trace = optimal_rotation(b, a)  # a @ r ≈ b, no reflection
    scale = trace / np.sum(a ** 2)
    return lambda pts: (np.asarray(pts) - mr) @ r * scale + mt


def estimate_missing(shapes, *, method: str = "tps") -> MissingEstimate:
    """Estimate missing landmarks (NaN) from the complete specimens.

    ``"tps"``: the complete specimens' generalized Procrustes mean is fitted (similarity) onto the
    specimen's present landmarks, then bent onto them exactly by a thin-plate spline
    (:func:`tps_map`); the missing landmarks are where the spline takes the mean's. ``"regression"``:
    the complete specimens are each fitted onto the specimen's present landmarks, their missing
    landmarks' coordinates regressed on the present ones (least squares, minimum-norm when the
    present coordinates outnumber the specimens), and the regression predicts the specimen's.

    Parameters
    ----------
    shapes : array_like (N, K, d)
        NaN marks a missing landmark (``shapelib.io.read_landmarks(..., missing="nan")``).
    method : {"tps", "regression"}

    Returns
    -------
    MissingEstimate
        ``shapes`` completed, ``estimated`` marks which landmarks were estimated.

    See Also
    --------
    tps_map : The thin-plate spline of ``method="tps"``.
    MissingEstimate : The result.
    shapelib.geometry.procrustes.generalized_procrustes : The mean of the complete specimens.

    Notes
    -----
    ``"tps"`` maps the mean by the minimum-bending-energy thin-plate spline [1]_ that interpolates the present
    landmarks; the completed shapes may then be compared by the metrics of [2]_, as any shapes.

    References
    ----------
    .. [1] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of deformations",
       *IEEE Transactions on Pattern Analysis and Machine Intelligence* 11(6), 567–585, 1989.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.comparison.missing import estimate_missing
    >>> t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> rng = np.random.default_rng(0)
    >>> x = np.stack([np.c_[np.cos(t), (1 + 0.2 * rng.normal()) * np.sin(t)] for _ in range(10)])
    >>> gone = x.copy(); gone[0, 2] = np.nan
    >>> res = estimate_missing(gone)
    >>> bool(np.linalg.norm(res.shapes[0, 2] - x[0, 2]) < 0.1), int(res.estimated.sum())
    (True, 1)
    """
    if method not in MISSING_METHODS:
        raise ValueError(f"method must be one of {MISSING_METHODS}; got {method!r}")
    x = np.asarray(shapes, dtype=np.float64)
    if x.ndim != 3:
        raise ValueError(f"shapes must be an (N, K, d) array; got shape {x.shape}")
    n, k, d = x.shape
    lost = np.isnan(x).any(axis=2)
    if np.isinf(x).any():
        raise ValueError("shapes have infinite coordinates; only NaN marks a missing landmark")
    complete = ~lost.any(axis=1)
    out = x.copy()
    if not lost.any():
        return MissingEstimate(out, lost, method, int(complete.sum()))
    need = d + 2 if method == "tps" else 3
    if complete.sum() < need:
        raise ValueError(f"{int(complete.sum())} complete specimen(s): estimating missing landmarks needs at least "
                         f"{need}")
    ref_set = x[complete]
    mean = generalized_procrustes(ref_set, scaling=False)[0].mean(axis=0)
    for i in np.flatnonzero(lost.any(axis=1)):
        have, miss = ~lost[i], lost[i]
        if have.sum() < d + 1:
            raise ValueError(f"specimen {i}: {int(have.sum())} landmark(s) present; at least {d + 1} are needed to "
                             "place the others")
        target = x[i, have]
        if method == "tps":
            fitted = _fit_onto(mean[have], target)
            out[i, miss] = tps_map(fitted(mean[have]), target, fitted(mean[miss]))
        else:
            placed = np.stack([_fit_onto(r[have], target)(r) for r in ref_set])  # (M, K, d)
            xp = placed[:, have].reshape(len(placed), -1)
            yp = placed[:, miss].reshape(len(placed), -1)
            xm, ym = xp.mean(axis=0), yp.mean(axis=0)
            coef = np.linalg.lstsq(xp - xm, yp - ym, rcond=1e-10)[0]
            out[i, miss] = (ym + (target.ravel() - xm) @ coef).reshape(-1, d)
    return MissingEstimate(out, lost, method, int(complete.sum()))
