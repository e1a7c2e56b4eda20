"""Two-block partial least squares: how strongly two blocks of variables covary (the integration of
two parts of a shape, or shape and a set of covariates), with a permutation test, as geomorph's
``two.b.pls`` and ``integration.test``.

Equations
    Each block is centred (``X₁`` (N, p), ``X₂`` (N, q)); their cross-covariance
    ``S₁₂ = X₁ᵀ X₂ / (N − 1)`` has the singular value decomposition ``S₁₂ = U diag(σ) Vᵀ`` [1]_.
    The k-th pair of singular vectors ``(u_k, v_k)`` are the directions of the two blocks whose
    scores ``t₁ = X₁ u_k``, ``t₂ = X₂ v_k`` have the largest covariance (``σ_k``) orthogonal to the
    earlier pairs. The statistic is the correlation of the first pair's scores,

        r_PLS = corr(X₁ u₁, X₂ v₁),

    and the p-value is ``(1 + #{r*_PLS ≥ r_PLS}) / (1 + n_permutations)`` with the rows of the
    second block permuted [2]_ (the specimens' pairing broken). ``z`` is the effect size of [3]_:
    ``r_PLS``'s standard deviate in its permutation distribution, for comparing the strength of
    integration between data sets (here without geomorph's Box–Cox step).

Computation
    Through thin decompositions of the blocks, ``X_b = A_b W_bᵀ`` with ``A_b`` (N, r_b) of orthogonal
    columns scaled by the singular values: ``S₁₂ ∝ W₁ (A₁ᵀ A₂) W₂ᵀ``, so a permutation ``Π`` costs an
    SVD of the (r₁, r₂) matrix ``A₁ᵀ Π A₂`` (r_b ≤ N − 1), however many variables the blocks have.

References
----------
.. [1] F. L. Bookstein, *Morphometric Tools for Landmark Data*, Cambridge University Press, 1991;
   F. J. Rohlf and M. Corti, "Use of two-block partial least-squares to study covariation in
   shape", *Systematic Biology* 49(4), 740–753, 2000.
.. [2] D. C. Adams and M. L. Collyer, "On the comparison of the strength of morphological
   integration across morphometric datasets", *Evolution* 70(11), 2623–2631, 2016.
.. [3] D. C. Adams and M. L. Collyer, "Comparing the strength of modular signal, and evaluating
   alternative modular hypotheses, using covariance ratio effect sizes with morphometric data",
   *Evolution* 73(12), 2352–2367, 2019.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import check_positive_int
from .group import MIN_PERMUTATIONS

__all__ = ["PLSResult", "two_block_pls"]


@dataclass
class PLSResult:
    """Result of :func:`two_block_pls`.

    Attributes
    ----------
    value : float
        ``r_PLS`` [1]_: the correlation of the first pair of scores.
    p_value : float
        Its permutation p-value.
    z : float
        Its standard deviate in the permutation distribution (the effect size); 0 when every
        permutation gives the same r_PLS as the data (to rounding).
    singular_values : ndarray (r,)
        ``σ_k`` of ``S₁₂`` (covariances of the score pairs), largest first.
    covariance_share : ndarray (r,)
        ``σ_k² / Σ σ²``: each pair's share of the squared covariance between the blocks (0 for blocks
        that do not covary at all).
    weights1, weights2 : ndarray (p, r), (q, r)
        The singular vectors ``u_k``, ``v_k`` (columns; the sign of each pair is arbitrary but shared).
    scores1, scores2 : ndarray (N, r)
        ``X₁ u_k``, ``X₂ v_k``.
    n_permutations : int
    null : ndarray (n_permutations,)
        ``r*_PLS`` of the permutations.

    See Also
    --------
    two_block_pls : What returns it.

    References
    ----------
    .. [1] D. C. Adams and M. L. Collyer, "On the comparison of the strength of morphological
       integration across morphometric datasets", *Evolution* 70(11), 2623–2631, 2016 (r_PLS and its
       effect size).

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> a = rng.normal(size=(30, 4))
    >>> b = a[:, :2] @ rng.normal(size=(2, 3)) + 0.3 * rng.normal(size=(30, 3))
    >>> res = sl.two_block_pls(a, b, n_permutations=99)
    >>> bool(res.value > 0.8), res.p_value
    (True, 0.01)
    """

    value: float
    p_value: float
    z: float
    singular_values: np.ndarray
    covariance_share: np.ndarray
    weights1: np.ndarray = field(repr=False)
    weights2: np.ndarray = field(repr=False)
    scores1: np.ndarray = field(repr=False)
    scores2: np.ndarray = field(repr=False)
    n_permutations: int = 0
    null: np.ndarray = field(default=None, repr=False)

    def summary(self) -> str:
        """r_PLS with its p-value and effect size, and the first pairs' shares of the covariance."""
        n = len(self.scores1)
        shares = ", ".join(f"{100 * s:.1f} %" for s in self.covariance_share[:3])
        return (f"two-block PLS ({n} specimens, blocks of {self.weights1.shape[0]} and {self.weights2.shape[0]} "
                f"variables): r_PLS = {self.value:.4g}, p = {self.p_value:.4g} ({self.n_permutations} permutations "
                f"of the second block's rows), z = {self.z:.3g}; squared covariance of the first pairs: {shares}")


def _block(x, name):
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 3:  # (N, K, d) landmarks: one row per specimen
        arr = arr.reshape(len(arr), -1)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] < 3 or arr.shape[1] < 1:
        raise ValueError(f"{name}: expected (N, p) variables or (N, K, d) landmarks with N >= 3; got shape "
                         f"{np.shape(x)}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"{name}: variable {bad[0][1]} of specimen {bad[0][0]} is not finite")
    c = arr - arr.mean(axis=0)
    if not np.any(np.abs(c) > 1e-12 * max(np.abs(arr).max(), 1.0)):
        raise ValueError(f"{name}: every variable is constant across the specimens")
    return c


def _thin(c):
    """``c = A Wᵀ`` with A (N, r) = U S and W (p, r) orthonormal, r the numerical rank."""
    u, s, vt = np.linalg.svd(c, full_matrices=False)
    keep = s > s[0] * max(c.shape) * np.finfo(float).eps
    return u[:, keep] * s[keep], vt[keep].T


def _first_r(a1, a2):
    """r_PLS of the blocks ``A₁``, ``A₂`` (their first pair of scores' correlation)."""
    m = a1.T @ a2
    x, s, yt = np.linalg.svd(m, full_matrices=False)
    t1, t2 = a1 @ x[:, 0], a2 @ yt[0]
    return float(t1 @ t2 / np.sqrt((t1 @ t1) * (t2 @ t2)))


def two_block_pls(block1, block2, *, n_permutations: int = 999, seed: int | None = 0) -> PLSResult:
    """Two-block partial least squares between two sets of variables measured on the same specimens.

    The SVD of the cross-covariance ``S₁₂ = X₁ᵀ X₂ / (N − 1) = U diag(σ) Vᵀ`` of the centred blocks
    (the two-block PLS of [1]_); ``r_PLS = corr(X₁ u₁, X₂ v₁)``, tested by permuting the rows of ``X₂``
    as in [2]_ (module docstring).

    Parameters
    ----------
    block1, block2 : array_like (N, p) / (N, q), or (N, K, d) landmarks
        The same N specimens in the same order. Landmarks are flattened as given: for the
        integration of two parts of one configuration, align the whole configuration first
        (:func:`shapelib.procrustes_coordinates`) and pass the two parts' columns.
    n_permutations : int
        At least 19.
    seed : int or None

    Returns
    -------
    PLSResult

    See Also
    --------
    shapelib.procrustes_coordinates : Aligned coordinates to pass as blocks.

    References
    ----------
    .. [1] F. J. Rohlf and M. Corti, "Use of two-block partial least-squares to study covariation in
       shape", *Systematic Biology* 49(4), 740–753, 2000.
    .. [2] D. C. Adams and M. L. Collyer, "On the comparison of the strength of morphological
       integration across morphometric datasets", *Evolution* 70(11), 2623–2631, 2016.

    Examples
    --------
    Integration of the front and back halves of a configuration:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(2)
    >>> base = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1.0]])
    >>> bend = rng.normal(size=40)
    >>> shapes = base + 0.05 * bend[:, None, None] * base[None, :, ::-1] + 0.01 * rng.normal(size=(40, 6, 2))
    >>> y = sl.procrustes_coordinates(shapes)
    >>> res = sl.two_block_pls(y[:, :6], y[:, 6:], n_permutations=199)
    >>> res.p_value < 0.05
    True
    """
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    if n_permutations < MIN_PERMUTATIONS:
        raise ValueError(f"n_permutations must be at least {MIN_PERMUTATIONS}; got {n_permutations}")
    c1, c2 = _block(block1, "block1"), _block(block2, "block2")
    if len(c1) != len(c2):
        raise ValueError(f"block2: {len(c2)} specimens where block1 has {len(c1)}")
    n = len(c1)
    u, s, vt = np.linalg.svd(c1.T @ c2 / (n - 1), full_matrices=False)
    r = int(np.sum(s > s[0] * max(c1.shape[1], c2.shape[1]) * np.finfo(float).eps)) if s[0] > 0 else 1
    u, s, v = u[:, :r], s[:r], vt[:r].T
    t1, t2 = c1 @ u, c2 @ v
    value = float(t1[:, 0] @ t2[:, 0] / np.sqrt((t1[:, 0] @ t1[:, 0]) * (t2[:, 0] @ t2[:, 0])))
    a1, _ = _thin(c1)
    a2, _ = _thin(c2)
    rng = np.random.default_rng(seed)
    null = np.array([_first_r(a1, a2[rng.permutation(n)]) for _ in range(n_permutations)])
    p = (1.0 + np.sum(null >= value * (1 - 1e-12))) / (1.0 + n_permutations)
    # a permutation distribution without spread (every pairing gives the same r_PLS, to rounding, and so
    # does the data's own pairing): no effect
    sd = null.std(ddof=1)
    z = float((value - null.mean()) / sd) if sd > 1e-12 * max(abs(value), 1.0) else 0.0
    total = np.sum(s**2)
    share = s**2 / total if total > 0 else np.zeros_like(s)  # blocks that do not covary at all: no shares
    return PLSResult(value=value, p_value=float(p), z=z, singular_values=s, covariance_share=share,
                     weights1=u, weights2=v, scores1=t1, scores2=t2, n_permutations=n_permutations, null=null)
