"""Sliding semilandmarks: points on curves that slide along their tangents during the
superimposition, by minimum bending energy or minimum Procrustes distance to the mean (Bookstein
1997; Gunz & Mitteroecker 2013; geomorph's ``gpagen(curves=, ProcD=)``).

A slider is a triple ``(before, point, after)`` of landmark indices: ``point`` slides along the
unit tangent ``T = (x_after − x_before) / |x_after − x_before|``. One step moves every slider of a
specimen ``x`` (a vector of its coordinates) to ``x + U t``, ``U`` holding the tangents:

* Procrustes distance: ``t_j = T_jᵀ (m_j − x_j)`` — each point to the foot of the mean's point on
  its tangent, minimising ``|x + U t − m|²``;
* bending energy: ``t = −(Uᵀ L U)⁻¹ Uᵀ L x`` with ``L = I_d ⊗ L_K`` the thin-plate bending-energy
  matrix of the mean ``m`` — minimising the bending energy ``xᵀ L x`` of the spline from the
  mean to the specimen.

The specimens are aligned (generalized Procrustes, unit size), slid, aligned again, until the
Procrustes sum of squares around the mean settles (relative change below ``tol``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validate import as_shapes
from .procrustes import generalized_procrustes

__all__ = ["slide_semilandmarks", "SlideResult", "curve_sliders", "bending_energy_matrix", "SLIDE_CRITERIA"]

SLIDE_CRITERIA = ("bending_energy", "procrustes")


@dataclass
class SlideResult:
    """Result of :func:`slide_semilandmarks`.

    Attributes
    ----------
    shapes : ndarray (N, K, d)
        Aligned (unit centroid size) with the semilandmarks slid.
    mean : ndarray (K, d)
    sliders : ndarray (m, 3)
    criterion : {"bending_energy", "procrustes"}
    converged : bool
    n_iter : int
    stop_reason : str
        ``"tol"`` or ``"max_iter"``.

    See Also
    --------
    slide_semilandmarks : The sliding.
    curve_sliders : Sliders of a curve.

    Notes
    -----
    The semilandmarks slide by minimum bending energy [1]_ or minimum Procrustes distance [2]_.

    References
    ----------
    .. [1] F. L. Bookstein, "Landmark methods for forms without landmarks: morphometrics of group differences in
       outline shape", *Medical Image Analysis* 1(3), 225–243, 1997.
    .. [2] P. Gunz and P. Mitteroecker, "Semilandmarks: a method for quantifying curves and surfaces",
       *Hystrix, the Italian Journal of Mammalogy* 24(1), 103–109, 2013.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.semilandmarks import curve_sliders, slide_semilandmarks
    >>> rng = np.random.default_rng(0)
    >>> t = np.linspace(0, np.pi, 7)                      # 7 points on an arc, its ends fixed
    >>> shapes = np.stack([np.c_[np.cos(t), (1 + 0.1 * i) * np.sin(t)] + rng.normal(scale=0.02, size=(7, 2))
    ...                    for i in range(5)])
    >>> res = slide_semilandmarks(shapes, curve_sliders(0, 7))
    >>> res.criterion, res.shapes.shape, res.sliders.shape, res.converged
    ('bending_energy', (5, 7, 2), (5, 3), True)
    """

    shapes: np.ndarray
    mean: np.ndarray
    sliders: np.ndarray
    criterion: str
    converged: bool
    n_iter: int
    stop_reason: str

    def summary(self) -> str:
        return (f"{len(self.sliders)} semilandmarks slid by minimum {self.criterion.replace('_', ' ')} on "
                f"{len(self.shapes)} shapes: converged {self.converged} in {self.n_iter} iterations "
                f"({self.stop_reason})")


def curve_sliders(start: int, n_points: int, *, closed: bool = False) -> np.ndarray:
    """Sliders of a curve of ``n_points`` consecutive landmarks from index ``start``: every interior
    point slides between its neighbours (the ends stay fixed), or, ``closed``, every point.

    Each slider ``(before, point, after)`` lets ``point`` slide along the chord of its two
    neighbours, the tangent estimate of [1]_ and [2]_.

    Parameters
    ----------
    start : int
        Index of the curve's first landmark.
    n_points : int
        Number of consecutive landmarks on the curve.
    closed : bool
        The curve closes on itself: its first and last points are neighbours and every point slides.

    Returns
    -------
    ndarray of int, shape (m, 3)
        ``(before, point, after)`` rows: ``n_points − 2`` of them, or ``n_points`` when ``closed``.

    See Also
    --------
    slide_semilandmarks : Slides them.

    References
    ----------
    .. [1] F. L. Bookstein, "Landmark methods for forms without landmarks: morphometrics of group differences in
       outline shape", *Medical Image Analysis* 1(3), 225–243, 1997.
    .. [2] P. Gunz and P. Mitteroecker, "Semilandmarks: a method for quantifying curves and surfaces",
       *Hystrix, the Italian Journal of Mammalogy* 24(1), 103–109, 2013.

    Examples
    --------
    >>> from shapelib.geometry.semilandmarks import curve_sliders
    >>> curve_sliders(3, 4).tolist()
    [[3, 4, 5], [4, 5, 6]]
    """
    idx = np.arange(start, start + n_points)
    if closed:
        return np.column_stack([np.roll(idx, 1), idx, np.roll(idx, -1)])
    return np.column_stack([idx[:-2], idx[1:-1], idx[2:]]) if n_points > 2 else np.zeros((0, 3), int)


def bending_energy_matrix(reference) -> np.ndarray:
    """The thin-plate spline bending-energy matrix ``L_K`` (K, K) of ``reference`` (K, d): the
    upper-left block of ``[[U, P], [Pᵀ, 0]]⁻¹`` (``U`` the kernel ``r² log r`` in 2-D, ``−r`` in
    3-D, ``P = [1, x]``); ``vᵀ L_K v`` is the bending energy of the spline taking the reference
    onto reference + ``v`` along one coordinate, zero for affine ``v``.

    This is the matrix of [1]_ that minimum-bending-energy sliding [2]_ uses. It is computed at unit
    centroid size and rescaled exactly, ``L_K(s·x) = s⁻² L_K(x)`` in 2-D and ``s⁻¹ L_K(x)`` in 3-D, so
    raw coordinates of any size (pixels, micrometres) keep full accuracy.

    Parameters
    ----------
    reference : array_like, shape (K, d)
        The landmarks the splines start from (the mean shape, when sliding).

    Returns
    -------
    ndarray, shape (K, K)
        ``L_K``: symmetric, positive semi-definite, with the affine functions of the reference in
        its null space.

    Raises
    ------
    ValueError
        If all the landmarks of ``reference`` coincide.

    See Also
    --------
    slide_semilandmarks : Minimises ``xᵀ (I_d ⊗ L_K) x`` along the sliders.
    shapelib.comparison.splines.tps_bending_energy : The bending energy of a thin-plate spline.

    References
    ----------
    .. [1] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of deformations",
       *IEEE Transactions on Pattern Analysis and Machine Intelligence* 11(6), 567–585, 1989.
    .. [2] F. L. Bookstein, "Landmark methods for forms without landmarks: morphometrics of group differences in
       outline shape", *Medical Image Analysis* 1(3), 225–243, 1997.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.semilandmarks import bending_energy_matrix
    >>> ref = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.4]])
    >>> L = bending_energy_matrix(ref)
    >>> L.shape, bool(np.allclose(L, L.T)), bool(np.allclose(L @ np.c_[np.ones(5), ref], 0))
    ((5, 5), True, True)
    >>> v = np.array([0, 0, 0, 0, 0.1])            # one landmark moved: the spline bends
    >>> round(float(v @ L @ v), 4)
    0.0198
    """
    x = np.asarray(reference, dtype=np.float64)
    k, d = x.shape
    # Solved at unit centroid size, then rescaled exactly: the bordered system of raw coordinates
    # (say 10⁴ pixels) mixes entries of r² log r ~ 10⁹ with ones and loses most of its digits.
    # On the space Pᵀv = 0 that L_K acts on, U(s·x) = s² U(x) in 2-D (the extra s² log s · r² is
    # annihilated: r²_ij = |x_i|² + |x_j|² − 2 x_i·x_j) and s U(x) in 3-D, so L_K(s·x) = s⁻² L_K(x)
    # in 2-D and s⁻¹ L_K(x) in 3-D; a translation changes nothing.
    x = x - x.mean(axis=0)
    size = float(np.sqrt(np.sum(x ** 2)))
    if size == 0:
        raise ValueError("reference: all its landmarks coincide: there is no thin-plate spline")
    x = x / size
    r = np.linalg.norm(x[:, None] - x[None], axis=-1)
    if d == 2:
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(r > 0, r ** 2 * np.log(r), 0.0)
    else:
        u = -r
    p = np.hstack([np.ones((k, 1)), x])
    full = np.block([[u, p], [p.T, np.zeros((d + 1, d + 1))]])
    lk = np.linalg.pinv(full)[:k, :k]
    return lk / size ** (2 if d == 2 else 1)


def _tangents(x, sliders):
    t = x[sliders[:, 2]] - x[sliders[:, 0]]
    norm = np.linalg.norm(t, axis=1, keepdims=True)
    return np.divide(t, norm, out=np.zeros_like(t), where=norm > 0)


def _slide_one(x, mean, sliders, criterion, lk):
    t = _tangents(x, sliders)
    pts = sliders[:, 1]
    out = x.copy()
    if criterion == "procrustes":
        step = np.einsum("jd,jd->j", t, mean[pts] - x[pts])
        out[pts] += step[:, None] * t
        return out
    k, d = x.shape
    m = len(pts)
    u = np.zeros((k * d, m))  # coordinate-major vector: all x, then all y (, all z)
    for c in range(d):
        u[c * k + pts, np.arange(m)] = t[:, c]
    big = np.kron(np.eye(d), lk)
    vec = x.T.ravel()
    lu = big @ u
    step = -np.linalg.lstsq(u.T @ lu, lu.T @ vec, rcond=None)[0]
    return (vec + u @ step).reshape(d, k).T


def slide_semilandmarks(shapes, sliders, *, criterion: str = "bending_energy", max_iter: int = 20,
                        tol: float = 1e-4) -> SlideResult:
    """Generalized Procrustes alignment with sliding semilandmarks.

    Parameters
    ----------
    shapes : array_like (N, K, d)
        Fixed landmarks and semilandmarks together (e.g. tpsDig's landmarks followed by its CURVES
        points, :func:`shapelib.io.read_tps` with ``return_curves=True``).
    sliders : array_like (m, 3) of int
        ``(before, point, after)`` landmark indices, 0-based (:func:`curve_sliders`).
    criterion : {"bending_energy", "procrustes"}
        Minimum bending energy to the mean (geomorph's default) or minimum Procrustes distance.
    max_iter : int
    tol : float
        Stop when the Procrustes sum of squares around the mean changes by less than this
        fraction in one iteration (default 1e-4, geomorph's ``gpagen`` default: semilandmarks on a straight stretch can
        keep drifting along it together at no cost, so their positions need not settle).

    Returns
    -------
    SlideResult
        The aligned, slid shapes: any metric of shapelib takes them as shapes.

    See Also
    --------
    curve_sliders : Sliders along a curve.
    bending_energy_matrix : The matrix of the bending-energy criterion.
    shapelib.geometry.procrustes.generalized_procrustes : The alignment between the slides.

    Notes
    -----
    Sliding by minimum bending energy follows [1]_, by minimum Procrustes distance [2]_ (module docstring);
    the slid shapes are landmark shapes for the metrics of [3]_.

    References
    ----------
    .. [1] F. L. Bookstein, "Landmark methods for forms without landmarks: morphometrics of group differences in
       outline shape", *Medical Image Analysis* 1(3), 225–243, 1997.
    .. [2] P. Gunz and P. Mitteroecker, "Semilandmarks: a method for quantifying curves and surfaces",
       *Hystrix, the Italian Journal of Mammalogy* 24(1), 103–109, 2013.
    .. [3] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.semilandmarks import curve_sliders, slide_semilandmarks
    >>> rng = np.random.default_rng(0)
    >>> def specimen():                                   # a quadrilateral, 3 points on its bottom edge
    ...     quad = np.array([[0, 0], [2, 0], [2.2, 1], [-0.1, 1.1]]) + rng.normal(scale=0.05, size=(4, 2))
    ...     s = np.r_[0.0, np.sort(rng.uniform(0.05, 0.95, 3)), 1.0][:, None]
    ...     return np.vstack([quad, quad[0] + s * (quad[1] - quad[0])])
    >>> shapes = np.stack([specimen() for _ in range(8)])
    >>> res = slide_semilandmarks(shapes, curve_sliders(4, 5), criterion="procrustes")
    >>> res.converged
    True
    """
    if criterion not in SLIDE_CRITERIA:
        raise ValueError(f"criterion must be one of {SLIDE_CRITERIA}; got {criterion!r}")
    x = as_shapes(shapes, name="shapes", min_shapes=2)
    s = np.asarray(sliders)
    if s.ndim != 2 or s.shape[1] != 3 or not np.issubdtype(s.dtype, np.integer):
        raise ValueError(f"sliders must be an (m, 3) array of landmark indices; got {s.shape} {s.dtype}")
    k = x.shape[1]
    if len(s) and (s.min() < 0 or s.max() >= k):
        raise ValueError(f"sliders name landmark {int(s.max() if s.max() >= k else s.min())}; the shapes have "
                         f"landmarks 0 to {k - 1}")
    if len(set(s[:, 1].tolist())) != len(s):
        raise ValueError("a landmark slides twice: each point may appear once in the middle column of sliders")
    aligned, mean = generalized_procrustes(x, scaling=False)
    ss = float(np.sum((aligned - mean) ** 2))
    converged, n_iter = False, 0
    for n_iter in range(1, max_iter + 1):
        lk = bending_energy_matrix(mean) if criterion == "bending_energy" else None
        slid = np.stack([_slide_one(a, mean, s, criterion, lk) for a in aligned])
        aligned, mean = generalized_procrustes(slid, scaling=False)
        new_ss = float(np.sum((aligned - mean) ** 2))
        change, ss = abs(ss - new_ss) / max(new_ss, np.finfo(float).tiny), new_ss
        if change < tol:
            converged = True
            break
    return SlideResult(shapes=aligned, mean=mean, sliders=s, criterion=criterion, converged=converged, n_iter=n_iter,
                       stop_reason="tol" if converged else "max_iter")
