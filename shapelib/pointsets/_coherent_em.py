"""The EM of a registration: the moved source mixture explains the target beside a uniform outlier
component, and the source's means move by the metric's kernel.

The one place where the registration's equations live (:func:`shapelib.register` calls them).
Both sets are in normalised units (zero mean, unit RMS radius). The source ``u`` (n, d) is the mean
set of a mixture whose component ``i`` has weight ``(1 − w)/n``; the target ``y`` (m, d) is a sample
of that mixture plus a uniform density ``1/V`` of weight ``w`` over the target's bounding box of
volume ``V`` (Coherent Point Drift's model [1]_, with the uniform density in place of CPD's
``1/m``; each side of the box at least the target's point spacing: :func:`box_volume`). E-step, the
posterior that target point j came from source point i:

.. math::

    P_{ij} = \\frac{\\exp(-|y_j - θ_i|^2 / 2σ^2)}
                  {\\sum_k \\exp(-|y_j - θ_k|^2 / 2σ^2) + (2πσ^2)^{d/2} \\frac{w}{1 - w} \\frac{n}{V}} .

M-step: the means move as ``θ = u + G W`` with ``G`` the kernel of the metric (the α-order metric of
the source mixture in its weight coordinates, ``G_ab = exp(−|u_a − u_b|²/4σ_g²)``, or another kernel
of :mod:`shapelib.pointsets.registration`), and ``W`` solves

.. math::

    (\\operatorname{diag}(P\\mathbf 1)\\, G + λσ^2 I)\\, W = P y - \\operatorname{diag}(P\\mathbf 1)\\, u ,

the minimiser of ``Σ_ij P_ij |y_j − θ_i|²/2σ² + (λ/2) tr(Wᵀ G W)``; then
``σ² = Σ_ij P_ij |y_j − θ_i|² / (d Σ_ij P_ij)``. The objective that EM decreases, and by which
:func:`shapelib.register` compares fits from different starts and outlier weights, is the
negative log-posterior

.. math::

    F = -\\sum_j \\log\\Big[\\frac{1 - w}{n} \\sum_i N(y_j; θ_i, σ^2 I) + \\frac{w}{V}\\Big]
        + \\frac{λ}{2} \\operatorname{tr}(W^T G W) .

A kernel of the weight coordinates (the same (n, n) matrix for every coordinate) is used through its
eigendecomposition ``G = Q Λ Qᵀ`` (eigenvalues below ``EIG_RTOL`` of the largest dropped, as CPD's
low-rank variant does), which is the same for every rotation of the source; the M-step is then
``W = (B − D Q z) / λσ²`` with ``z = (λσ² Λ⁻¹ + Qᵀ D Q)⁻¹ Qᵀ B`` (Woodbury, ``D = diag(P1)``,
``B = P y − D u``; the k × k system by Cholesky) and ``G W = Q z``: O(n k²) instead of O(n³).

**Acceleration.** EM converges linearly, slowly once σ² is small: a fit of ~100 points often
stopped at 150 iterations without meeting its tolerance. After the first ``PLAIN_ITER`` iterations of
a fit, :func:`run_em` accelerates it with SQUAREM [2]_: with ``x = (W, log σ²)`` and ``M`` one EM
iteration, each cycle takes ``x1 = M(x0)``, ``x2 = M(x1)``, the extrapolated point
``x' = x0 − 2α r + α² v`` (``r = x1 − x0``, ``v = x2 − 2x1 + x0``, ``α = min(−‖r‖/‖v‖, −1)``: scheme
S3) and one EM iteration from it, ``M(x')``, which is kept only if ``F(x') ≤ F(x1)``; otherwise the
cycle ends at ``x2``. Each E-step gives ``F`` at its own input (its column normalisers are the
likelihood), so the safeguard costs nothing, and ``F`` never increases from one cycle to the next.
The fixed points are EM's: a fit stops when one EM iteration changes σ² by less than the tolerance.
The first iterations stay plain EM because they decide the basin: σ² shrinks from the spread of the
whole target, and an extrapolation there jumps past the slow shrinking (measured on the
Chui–Rangarajan samples 1–5: accelerated from the first iteration, several fits end in worse
basins and a registration of the tests failed silently; after ``PLAIN_ITER``, about the same fits as
plain EM (27 failures of 280 against 26, mean error 0.0257 against 0.0259), 15 % fewer iterations
in all, and 279 of 280 registrations meeting their tolerance instead of 259).

References
----------
.. [1] A. Myronenko and X. Song, "Point set registration: coherent point drift", *IEEE Transactions on
   Pattern Analysis and Machine Intelligence* 32(12), 2262–2275, 2010.
.. [2] R. Varadhan and C. Roland, "Simple and globally convergent methods for accelerating the
   convergence of any EM algorithm", *Scandinavian Journal of Statistics* 35(2), 335–353, 2008.
"""

from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np
from numba import njit

#: eigenvalues of the weight kernel below this fraction of the largest are dropped. 1e-8 (1e-10 before
#: the M-step's Cholesky solve; the fish's 98-point kernel keeps rank 27 instead of 37): on samples 1–5
#: of the Chui–Rangarajan benchmark the same failures and mean error (20, 0.0229), every error within
#: 5e-5 of 1e-10's, 7 % less time; on samples 6–10, not used to choose it, the same (25, 0.0203),
#: every error within 7e-4. 1e-7: mean error 0.0230; 1e-6: 22 failures, 0.0235
EIG_RTOL = 1e-8
#: EM iterations of a fit before SQUAREM's acceleration starts (module docstring)
PLAIN_ITER = 40


def sq_dist(x, y):
    """Squared distances (n, m) by the expansion |x|² + |y|² − 2 x·y (clipped at 0)."""
    out = np.einsum("id,id->i", x, x)[:, None] + np.einsum("jd,jd->j", y, y)[None, :] - 2.0 * (x @ y.T)
    return np.maximum(out, 0.0, out=out)


def point_spacing(y):
    """The median distance from each point of ``y`` to its nearest other point (0 for a single point)."""
    if len(y) < 2:
        return 0.0
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(y).query(y, k=2)
    return float(np.median(dist[:, 1]))


def box_volume(y):
    """Volume of the target's bounding box, each side at least the target's point spacing
    (:func:`point_spacing`): the support of the uniform (outlier) component.

    The floor matters for a flat target — a straight line in 2-D, a plane in 3-D — whose box has a
    side of zero: without it the uniform density would swamp every Gaussian term and leave every
    point unmatched. With it the box is a slab one spacing thick, in which the outlier density stands
    to the Gaussian terms as it does for a target that fills its box."""
    side = np.maximum(np.ptp(y, axis=0), point_spacing(y))
    return float(np.prod(np.maximum(side, 1e-12)))


def posteriors(theta, y, s2, w, volume, labels=None):
    """``P`` (n, m) of the module docstring (the outlier component's share is ``1 − Σ_i P_ij``); the
    column of a target point with a known source point (``labels[j] = i ≥ 0``, :func:`label_array`)
    is 1 at that point and 0 elsewhere."""
    n, d = theta.shape
    e = np.exp(-sq_dist(theta, y) / (2 * s2))
    c = outlier_term(n, d, s2, w, volume)
    den = e.sum(axis=0) + c
    den[den == 0] = np.finfo(float).tiny
    p = e / den
    if labels is not None and len(labels):
        known = np.flatnonzero(labels >= 0)
        p[:, known] = 0.0
        p[labels[known], known] = 1.0
    return p


def label_array(pairs, m):
    """The known correspondences ``pairs`` (k, 2) of (source index, target index) as the int64 array
    (m,) of the compiled loops: the source index of each target point, −1 where it is not known (an
    empty array when no pair is given)."""
    if pairs is None or len(pairs) == 0:
        return np.zeros(0, dtype=np.int64)
    lab = np.full(m, -1, dtype=np.int64)
    lab[pairs[:, 1]] = pairs[:, 0]
    return lab


#: a term of ``P``'s denominator below ``exp(−PRUNE)`` times its largest is skipped (``exp(−37)``
#: is 8.5e-17, below float64's resolution of the sum)
PRUNE = 37.0

#: the compiled loops may reassociate sums (vectorised reductions: the same sums to round-off) and
#: fuse multiply-adds, and assume no division traps (``error_model="numpy"``: a branch per division
#: would stop the compiler from vectorising)
_FAST = {"reassoc", "contract", "nsz", "arcp"}

_LOG2E = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01  # ln 2 in two parts (Cody–Waite): k · _LN2_HI is exact for |k| < 2^20
_LN2_LO = 1.90821492927058770002e-10
_SHIFT = 6755399441055744.0  # 1.5 · 2⁵²: x + _SHIFT rounds x (|x| < 2⁵¹) to an integer held in its low bits
_SHIFT_BITS = np.float64(_SHIFT).view(np.int64)
_INF_BITS = np.float64(np.inf).view(np.int64)  # the bit pattern of +inf, above every finite non-negative float64


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def _exp_neg(a, out):
    """``out[i] = exp(−a[i])`` for ``0 ≤ a[i] ≤ 700``, vectorised.

    ``math.exp`` in a compiled loop is a scalar library call (no vector math library here), about
    half of the E-step's time (46 µs of 90 for 98 × 98 points); this is the textbook exponential
    written so that the compiler vectorises it:
    ``x = k ln 2 + r`` with ``k = round(x / ln 2)`` and ``|r| ≤ ln 2 / 2`` (Cody–Waite reduction),
    ``exp(r)`` by its Taylor polynomial of degree 13 (remainder ``|r|¹⁴/14! < 1e-17``) in Horner form,
    and ``2^k`` built from its exponent bits. ``k`` is rounded by adding and subtracting
    ``1.5 · 2⁵²`` (``_SHIFT``), whose sum holds ``k`` in its low bits: no float-to-integer conversion,
    which has no vector instruction below AVX-512 (98 values: 40 ns against 65 ns with
    ``math.floor`` and ``np.int64``). Within one unit in the last place of ``np.exp`` over the range
    (``tests/test_coherent_em.py``). Compiled without reassociation, which would fold the shift away.
    """
    for i in range(a.size):
        x = -a[i]
        t = x * _LOG2E + _SHIFT  # k + 1.5 · 2⁵², rounded to the nearest integer by the addition
        kf = t - _SHIFT
        r = (x - kf * _LN2_HI) - kf * _LN2_LO
        p = 1.6059043836821613e-10  # 1/13!
        p = p * r + 2.08767569878681e-09  # 1/12!
        p = p * r + 2.505210838544172e-08
        p = p * r + 2.755731922398589e-07
        p = p * r + 2.7557319223985893e-06
        p = p * r + 2.48015873015873e-05
        p = p * r + 0.0001984126984126984
        p = p * r + 0.001388888888888889
        p = p * r + 0.008333333333333333
        p = p * r + 0.041666666666666664
        p = p * r + 0.16666666666666666
        p = p * r + 0.5
        p = p * r + 1.0
        k = np.float64(t).view(np.int64) - _SHIFT_BITS
        out[i] = (p * r + 1.0) * np.int64((k + 1023) << 52).view(np.float64)  # exp(r) · 2^k


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _column(tx, y, j, dist):
    """``dist[i] = |y_j − θ_i|²`` for every ``i`` (``tx`` is θᵀ, (d, n), contiguous); returns the smallest.

    The smallest is taken over the distances' bit patterns as integers, which order non-negative
    float64 numbers as the numbers do (a sum of squares is never −0): the compiler vectorises an
    integer minimum and not a floating-point one (whose NaN rules it must keep), which took a third
    of the E-step (98 × 98 points: 4.8 µs against 2.9 µs for the distances and this minimum)."""
    d, n = tx.shape
    if d == 2:  # one pass (the planar case is the common one)
        y0, y1 = y[j, 0], y[j, 1]
        for i in range(n):
            t0 = y0 - tx[0, i]
            t1 = y1 - tx[1, i]
            dist[i] = t0 * t0 + t1 * t1
    else:
        for i in range(n):
            dist[i] = 0.0
        for k in range(d):
            yk = y[j, k]
            for i in range(n):
                t = yk - tx[k, i]
                dist[i] += t * t
    bits = dist.view(np.int64)
    low = _INF_BITS
    for i in range(n):
        low = min(low, bits[i])
    return np.int64(low).view(np.float64)


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _estep(theta, y, s2, c, with_lse, lab):
    """The sums the M-step needs, without the (n, m) matrix: ``P1 = Σ_j P_ij`` (n,), ``Pᵀ1`` (m,),
    ``P y`` (n, d) and ``Σ_ij P_ij |y_j − θ_i|²``, with ``c`` the outlier term of ``P``'s
    denominator, and the sum of the denominators' logarithms ``Σ_j log(Σ_i exp(−|y_j − θ_i|²/2σ²) + c)``
    (the log-likelihood up to terms in σ², w and n: :func:`_em_map`; 0 unless ``with_lse``). Each
    column is scaled by its largest term, ``exp(−r_min/2σ²)``, and the terms ``PRUNE`` below it are
    dropped (the same sums to float64 precision); a column skipped for taking no posterior adds ``−r_min/2σ²``, its
    logarithm to within ``log n``. A target point with a known source point (``lab[j] = i ≥ 0``; ``lab`` is
    empty when none is known) has the posterior 1 at ``i`` and adds ``−|y_j − θ_i|²/2σ²`` (the log-likelihood
    of its known component, to the same terms)."""
    n, d = theta.shape
    m = y.shape[0]
    tx = np.ascontiguousarray(theta.T)
    p1 = np.zeros(n)
    pt1 = np.zeros(m)
    pyt = np.zeros((d, n))
    e = np.empty(n)
    a = np.empty(n)
    dist = np.empty(n)
    sse = 0.0
    lse = 0.0
    half = 0.5 / s2
    n_lab = lab.shape[0]
    for j in range(m):
        rmin = _column(tx, y, j, dist)
        if n_lab > 0 and lab[j] >= 0:  # a known correspondence: all of the point's posterior at lab[j]
            i = lab[j]
            pt1[j] = 1.0
            p1[i] += 1.0
            for k in range(d):
                pyt[k, i] += y[j, k]
            sse += dist[i]
            if with_lse:
                lse -= dist[i] * half
            continue
        if c == 0.0 and rmin * half > 708.0:
            if with_lse:
                lse -= rmin * half
            continue  # every term underflows and no outlier term: the point takes no posterior
        for i in range(n):
            a[i] = min((dist[i] - rmin) * half, PRUNE + 1.0)
        _exp_neg(a, e)
        s = 0.0
        for i in range(n):
            v = e[i] if a[i] <= PRUNE else 0.0
            e[i] = v
            s += v
        inv = 1.0 / (s + (c * math.exp(rmin * half) if c > 0.0 else 0.0))
        pt1[j] = s * inv
        # the column's log-denominator −r_min/2σ² − log(inv); log c where c exp(r_min/2σ²) overflowed
        if with_lse:
            lse += -(rmin * half + math.log(inv)) if inv > 0.0 else math.log(c)
        if d == 2:  # one pass; the column's share of the distances summed, then scaled once
            y0, y1 = y[j, 0] * inv, y[j, 1] * inv
            col = 0.0
            for i in range(n):
                v = e[i]
                col += v * dist[i]
                p1[i] += v * inv
                pyt[0, i] += v * y0
                pyt[1, i] += v * y1
            sse += col * inv
        else:
            for i in range(n):
                q = e[i] * inv
                e[i] = q
                p1[i] += q
                sse += q * dist[i]
            for k in range(d):
                yk = y[j, k]
                for i in range(n):
                    pyt[k, i] += e[i] * yk
    return p1, pt1, np.ascontiguousarray(pyt.T), sse, lse


@njit(cache=True, fastmath=False)
def _apply(q, qt, ev, full, coef):
    """``G W`` (n, d): the factored weight-coordinate kernel ``Q diag(ev) Qᵀ`` (``q`` has columns), the
    dense kernel on the means ``full`` (non-empty), or no kernel (zeros)."""
    if full.shape[0] > 0:
        return (full @ np.ascontiguousarray(coef).ravel()).reshape(coef.shape)
    if q.shape[1] > 0:
        return q @ (ev[:, None] * (qt @ coef))
    return np.zeros_like(coef)


@njit(cache=True, error_model="numpy", fastmath=_FAST, inline="always")
def _row_dots(a, b):
    """``out[x, y] = a[x] · b[y]`` (a (p, k), b (r, k), both C-ordered): ``a bᵀ`` as contiguous dot
    products, which the compiler vectorises."""
    out = np.empty((a.shape[0], b.shape[0]))
    for x in range(a.shape[0]):
        for y in range(b.shape[0]):
            s = 0.0
            for t in range(a.shape[1]):
                s += a[x, t] * b[y, t]
            out[x, y] = s
    return out


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _woodbury(q, qt, ev, p1, b, lam_s2):
    """``Q z`` (n, d) with ``z = (λσ² Λ⁻¹ + Qᵀ D Q)⁻¹ Qᵀ B`` of :func:`_m_step` (``q`` (n, k) with
    ``qt`` its contiguous transpose, ``D = diag(p1)``), written out: the lower triangle of the
    symmetric ``Qᵀ D Q`` (k(k+1)/2 dot products of length n), its Cholesky factor ``L Lᵀ`` in place,
    and the two triangular solves. For the fish's 98 points at rank 27 about 4 µs against 11 µs
    for the same steps through BLAS and LAPACK calls (``qt @ (p1 q)``, ``np.linalg.cholesky``),
    whose per-call costs dominate matrices this small (measured in compiled loops). The system is
    positive definite for any ``p1 ≥ 0``: ``λσ² Λ⁻¹`` is."""
    k, n = qt.shape
    d = b.shape[1]
    a = np.empty((k, k))
    row = np.empty(n)
    for r in range(k):  # the lower triangle of Qᵀ D Q + λσ² Λ⁻¹
        for i in range(n):
            row[i] = qt[r, i] * p1[i]
        for c in range(r, k):
            s = 0.0
            for i in range(n):
                s += row[i] * qt[c, i]
            a[c, r] = s
        a[r, r] += lam_s2 / ev[r]
    bt = np.empty((d, n))  # the coordinates' rows: every product below a contiguous dot product
    for i in range(n):
        for c in range(d):
            bt[c, i] = b[i, c]
    zt = _row_dots(bt, qt)  # (Qᵀ B)ᵀ, then zᵀ
    for j in range(k):  # a = L Lᵀ, L over a's lower triangle
        s = a[j, j]
        for t in range(j):
            s -= a[j, t] * a[j, t]
        piv = math.sqrt(s)
        a[j, j] = piv
        for i in range(j + 1, k):
            s = a[i, j]
            for t in range(j):
                s -= a[i, t] * a[j, t]
            a[i, j] = s / piv
    for c in range(d):
        v = zt[c]
        for i in range(k):  # L v = Qᵀ B
            s = v[i]
            for t in range(i):
                s -= a[i, t] * v[t]
            v[i] = s / a[i, i]
        for i in range(k - 1, -1, -1):  # Lᵀ z = v
            s = v[i]
            for t in range(i + 1, k):
                s -= a[t, i] * v[t]
            v[i] = s / a[i, i]
    return _row_dots(q, zt)  # Q z


@njit(cache=True, fastmath=False)
def _m_step(q, qt, ev, full, p1, b, lam_s2):
    """``W`` with ``(diag(P1) G + λσ² I) W = B`` (module docstring) and ``G W``: Woodbury through the
    factored kernel (:func:`_woodbury`), or a dense solve with the kernel on the means.

    With ``z = (λσ² Λ⁻¹ + Qᵀ D Q)⁻¹ Qᵀ B`` (SPD: its Cholesky solve), ``W = (B − D Q z)/λσ²`` and
    ``G W = Q z``: from ``Qᵀ D Q z = Qᵀ B − λσ² Λ⁻¹ z`` follows ``Qᵀ W = Λ⁻¹ z``, so that the means
    ``θ = u + G W`` cost one (n, k) product."""
    n, d = b.shape
    if full.shape[0] > 0:
        a = np.repeat(p1, d).reshape(-1, 1) * full
        for k in range(n * d):
            a[k, k] += lam_s2
        coef = np.linalg.solve(a, np.ascontiguousarray(b).ravel()).reshape(n, d)
        return coef, (full @ coef.ravel()).reshape(n, d)
    qz = _woodbury(q, qt, ev, p1, b, lam_s2)
    return (b - p1[:, None] * qz) / lam_s2, qz


@njit(cache=True, fastmath=False)
def _sse(pt1, yy, py, p1, u, gw):
    """``Σ_ij P_ij |y_j − θ_i|² = Σ_j (Pᵀ1)_j |y_j|² − 2 Σ_i (P y)_i · θ_i + Σ_i (P1)_i |θ_i|²`` at the
    means ``θ = u + G W`` of the M-step (``yy`` holds ``|y_j|²``), in loops: a BLAS call per dot product
    costs more than these products of ~100 terms, and its calls from several threads contend."""
    n, d = u.shape
    sse = 0.0
    for j in range(pt1.shape[0]):
        sse += pt1[j] * yy[j]
    for i in range(n):
        tt = 0.0
        ty = 0.0
        for k in range(d):
            t = u[i, k] + gw[i, k]
            tt += t * t
            ty += py[i, k] * t
        sse += p1[i] * tt - 2.0 * ty
    return sse


@njit(cache=True, fastmath=False)
def _em_map(u, q, qt, ev, full, y, yy, coef, gw, s2, c_unit, lam, fixed, s2_floor, log_wn, lab, with_f=True):
    """One EM iteration from ``(W, σ²)`` (``gw`` is ``G W``): E-step, the M-step of the module docstring
    (:func:`_m_step`; none without a kernel) and σ²'s update (σ² kept when ``fixed``). Returns ``W``,
    ``G W``, σ² and the objective ``F`` at the *input* ``(W, σ²)`` (its E-step's log-normalisers give it:
    ``F = −Σ_j L_j − m log((1 − w)/n) + (m d/2) log(2πσ²) + (λ/2) tr(Wᵀ G W)``, ``log_wn`` is
    ``log((1 − w)/n)``; NaN unless ``with_f``). ``c_unit`` is the outlier term at σ² = 1 (it scales
    as ``σ^d``); ``lab`` the known correspondences (:func:`_estep`)."""
    n, d = u.shape
    p1, pt1, py, sse, lse = _estep(u + gw, y, s2, c_unit * s2 ** (d / 2), with_f, lab)
    f = np.nan
    if with_f:
        f = 0.5 * lam * np.sum(coef * gw) - lse - y.shape[0] * (log_wn - 0.5 * d * math.log(2.0 * math.pi * s2))
    if full.shape[0] > 0 or q.shape[1] > 0:
        coef, gw = _m_step(q, qt, ev, full, p1, py - p1[:, None] * u, lam * s2)
        sse = _sse(pt1, yy, py, p1, u, gw)
    if fixed:
        return coef, gw, s2, f
    return coef, gw, max(sse / (max(p1.sum(), 1e-300) * d), s2_floor), f


@njit(cache=True, fastmath=False)
def _step_length(c0, s0, c1, s1, c2, s2):
    """SQUAREM's ``α`` (scheme S3 of [2]_) from three successive EM iterates ``x0, x1 = M(x0),
    x2 = M(x1)`` of ``x = (W, log σ²)``: ``−‖r‖/‖v‖`` with ``r = x1 − x0``, ``v = x2 − 2 x1 + x0``,
    held at most −1."""
    l0, l1, l2 = math.log(s0), math.log(s1), math.log(s2)
    rl, vl = l1 - l0, l2 - 2.0 * l1 + l0
    r = c1 - c0
    v = c2 - 2.0 * c1 + c0
    rr = np.sum(r * r) + rl * rl
    vv = np.sum(v * v) + vl * vl
    alpha = -math.sqrt(rr / vv) if vv > 0.0 else -1.0
    return min(alpha, -1.0)


@njit(cache=True, fastmath=False)
def _along(alpha, x0, x1, x2):
    """``x0 − 2α r + α² v`` with ``r = x1 − x0``, ``v = x2 − 2 x1 + x0``: SQUAREM's extrapolated point
    (``α = −1`` gives ``x2``). Linear in the iterates, so that ``G W'`` is ``G W`` extrapolated."""
    return x0 - 2.0 * alpha * (x1 - x0) + alpha * alpha * (x2 - 2.0 * x1 + x0)


@njit(cache=True, fastmath=False)
def _extrapolate(c0, s0, c1, s1, c2, s2, s2_floor):
    """SQUAREM's step (scheme S3 of [2]_) from three successive EM iterates ``x0, x1 = M(x0),
    x2 = M(x1)`` of ``x = (W, log σ²)``: ``α`` of :func:`_step_length` and ``x' = x0 − 2α r + α² v``
    (:func:`_along`). Returns ``W'``, σ²' (at least ``s2_floor``) and ``α``, with which the caller
    extrapolates whatever is linear in ``W`` (``G W``)."""
    alpha = _step_length(c0, s0, c1, s1, c2, s2)
    lx = _along(alpha, math.log(s0), math.log(s1), math.log(s2))
    return _along(alpha, c0, c1, c2), max(math.exp(min(lx, 30.0)), s2_floor), alpha


@njit(cache=True, fastmath=False, nogil=True)
def _em_loop(u, q, ev, full, y, coef, s2, c_unit, lam, max_iter, tol, fixed, s2_floor, log_wn, plain, lab):
    """:func:`run_em`'s iterations, compiled (the kernel as :func:`_apply` takes it): ``plain`` EM
    iterations, then the cycle of the module docstring (two EM iterations, SQUAREM's extrapolation,
    one EM iteration from it, kept only if ``F`` did not increase). Returns ``W``, σ², the EM
    iterations run (the extrapolated ones included) and whether one EM iteration changed σ² by less
    than ``tol`` (relative)."""
    d = u.shape[1]
    yy = np.zeros(y.shape[0])
    for j in range(y.shape[0]):
        for k in range(d):
            yy[j] += y[j, k] * y[j, k]
    qt = np.ascontiguousarray(q.T)
    gw = _apply(q, qt, ev, full, coef)  # G W, carried along with W from here on
    it = 0
    while it < max_iter:
        c1, g1, s1, _ = _em_map(u, q, qt, ev, full, y, yy, coef, gw, s2, c_unit, lam, fixed, s2_floor, log_wn, lab,
                                False)
        it += 1
        if not fixed and abs(s1 - s2) <= tol * s2:
            return c1, s1, it, True
        if it <= plain or it + 2 > max_iter:
            coef, gw, s2 = c1, g1, s1
            continue
        c2, g2, s2b, f1 = _em_map(u, q, qt, ev, full, y, yy, c1, g1, s1, c_unit, lam, fixed, s2_floor, log_wn, lab)
        it += 1
        if not fixed and abs(s2b - s1) <= tol * s1:
            return c2, s2b, it, True
        cx, sx, alpha = _extrapolate(coef, s2, c1, s1, c2, s2b, s2_floor)
        gx = _along(alpha, gw, g1, g2)
        c3, g3, s3, fx = _em_map(u, q, qt, ev, full, y, yy, cx, gx, sx, c_unit, lam, fixed, s2_floor, log_wn, lab)
        it += 1
        if not fx <= f1:  # the extrapolation did not decrease F (or is not a number): the EM iterate
            coef, gw, s2 = c2, g2, s2b
            continue
        if not fixed and abs(s3 - sx) <= tol * sx:
            return c3, s3, it, True
        coef, gw, s2 = c3, g3, s3
    return coef, s2, it, False


def outlier_term(n, d, s2, w, volume):
    """``(2πσ²)^{d/2} w/(1 − w) · n/V``: the uniform component's term in ``P``'s denominator."""
    return (2 * np.pi * s2) ** (d / 2) * w / (1 - w) * n / volume if w > 0 else 0.0


@dataclass
class Kernel:
    """The deformation's kernel: ``G = Q diag(ev) Qᵀ`` (weight coordinates, shared by the coordinates),
    or a dense (n d, n d) matrix ``full`` (the metric on the means)."""

    q: np.ndarray | None = None
    ev: np.ndarray | None = None
    full: np.ndarray | None = None

    @classmethod
    def of(cls, g):
        """From an (n, n) kernel matrix of the weight coordinates, factored once, the eigenvalues below
        ``EIG_RTOL`` of the largest dropped (:meth:`truncated`)."""
        ev, q = np.linalg.eigh(0.5 * (g + g.T))
        return cls(q=q, ev=ev).truncated(EIG_RTOL)

    def truncated(self, rtol):
        """The same kernel with the eigenvalues below ``rtol`` of the largest dropped too (a dense
        kernel is returned as it is): its eigenvectors are a subset of this kernel's, so that
        coefficients ``W`` of it, taken in its range (:meth:`in_range`), give the same ``G W`` under
        this kernel. The kernel itself when none is dropped."""
        if self.full is not None:
            return self
        keep = self.ev > rtol * max(self.ev.max(initial=0.0), 0.0)
        if keep.all():
            return self
        return Kernel(q=np.ascontiguousarray(self.q[:, keep]), ev=self.ev[keep].copy())

    def apply(self, coef):
        """``G W`` as (n, d)."""
        if self.full is not None:
            return (self.full @ coef.ravel()).reshape(coef.shape)
        return self.q @ (self.ev[:, None] * (self.q.T @ coef))

    def energy(self, coef):
        """``tr(Wᵀ G W)``."""
        return float(np.sum(coef * self.apply(coef)))

    def in_range(self, coef):
        """``W`` with its part along the dropped eigenvectors removed, ``Q Qᵀ W`` (a dense kernel drops
        none): the same ``G W`` and ``tr(Wᵀ G W)``, and the coefficients whose interpolant with the
        untruncated kernel, ``z ↦ Σ_b G(z, u_b) W_b``, gives ``G W`` at the source points. The M-step's
        ``W`` carries ``B / λσ²`` along the dropped directions, which the truncated ``G`` ignores and
        the untruncated kernel would not."""
        if self.full is not None:
            return coef
        return self.q @ (self.q.T @ coef)


@dataclass
class EMState:
    """One fit: the posed source ``u``, the coefficients ``coef`` (``θ = u + G W``), σ², w."""

    u: np.ndarray
    kernel: Kernel | None
    coef: np.ndarray
    s2: float
    w: float
    it: int = 0
    ok: bool = False
    why: str = "max_iter"

    @property
    def theta(self):
        return self.u if self.kernel is None else self.u + self.kernel.apply(self.coef)


def initial_sigma2(u, y):
    """``Σ_ij |y_j − u_i|² / (d n m)``: CPD's start, wide enough to see the whole target, without the
    (n, m) distances: ``(m Σ_i |u_i|² + n Σ_j |y_j|² − 2 (Σ_i u_i)·(Σ_j y_j)) / (d n m)``."""
    (n, d), m = u.shape, len(y)
    total = m * np.einsum("id,id->", u, u) + n * np.einsum("jd,jd->", y, y) - 2.0 * float(u.sum(axis=0) @ y.sum(axis=0))
    return float(max(total, 0.0) / (d * n * m))


def run_em(st, y, *, lam, volume, max_iter, tol, fixed_s2=None, s2_floor=1e-12, accelerate=True, labels=None):
    """Continue the EM of the module docstring for up to ``max_iter`` more iterations (w fixed),
    accelerated by SQUAREM once the fit has run ``PLAIN_ITER`` iterations (never with
    ``accelerate=False``).

    Stops (``ok``, ``why="tolerance"``) when one EM iteration changes σ² by less than ``tol``
    (relative); with ``fixed_s2`` it runs ``max_iter`` iterations. ``st.it`` counts EM iterations,
    the extrapolated ones included.
    """
    n, d = st.u.shape
    y = np.ascontiguousarray(y, dtype=float)
    k = st.kernel
    fixed = fixed_s2 is not None
    log_wn = math.log((1 - st.w) / n)
    plain = PLAIN_ITER - st.it if accelerate else max_iter  # iterations of this call before the acceleration
    q, ev, full = np.zeros((n, 0)), np.zeros(0), np.zeros((0, 0))  # no kernel: σ² alone
    if k is not None and k.full is None:
        q, ev = np.ascontiguousarray(k.q, dtype=float), np.ascontiguousarray(k.ev, dtype=float)
    elif k is not None:
        full = np.ascontiguousarray(k.full, dtype=float)
    coef, s2, it, ok = _em_loop(np.ascontiguousarray(st.u, dtype=float), q, ev, full, y,
                                np.ascontiguousarray(st.coef, dtype=float), float(st.s2),
                                outlier_term(n, d, 1.0, st.w, volume), float(lam), int(max_iter), float(tol), fixed,
                                float(s2_floor), log_wn, int(plain),
                                np.zeros(0, np.int64) if labels is None else np.asarray(labels, dtype=np.int64))
    st.coef, st.s2, st.it = coef, s2, st.it + it
    if fixed or ok:
        st.ok, st.why = True, "tolerance"
    return st


@njit(cache=True, error_model="numpy", fastmath=_FAST, nogil=True)
def _neg_loglik(theta, y, s2, log_wn, log_wv, lab):
    """``−Σ_j log[(1 − w)/n Σ_i N(y_j; θ_i, σ²I) + w/V]`` with ``log_wn = log((1 − w)/n)`` and
    ``log_wv = log(w/V)`` (−inf without outliers), each column's sum scaled by its largest term; a
    target point with a known source point ``lab[j] = i ≥ 0`` adds ``−log[(1 − w)/n N(y_j; θ_i, σ²I)]``."""
    n, d = theta.shape
    m = y.shape[0]
    tx = np.ascontiguousarray(theta.T)
    half = 0.5 / s2
    lognorm = -0.5 * d * math.log(2.0 * math.pi * s2)
    dist = np.empty(n)
    a = np.empty(n)
    e = np.empty(n)
    total = 0.0
    n_lab = lab.shape[0]
    for j in range(m):
        rmin = _column(tx, y, j, dist)
        if n_lab > 0 and lab[j] >= 0:
            total -= log_wn + lognorm - dist[lab[j]] * half
            continue
        for i in range(n):
            a[i] = min((dist[i] - rmin) * half, 700.0)
        _exp_neg(a, e)
        acc = 0.0
        for i in range(n):
            acc += e[i]
        mix = log_wn + lognorm - rmin * half + math.log(acc)
        if log_wv > -np.inf:  # log(exp(mix) + exp(log_wv))
            hi, lo = (mix, log_wv) if mix > log_wv else (log_wv, mix)
            mix = hi + math.log1p(math.exp(lo - hi))
        total -= mix
    return total


def objective(st, y, *, lam, volume, labels=None):
    """``F`` of the module docstring: the negative log-posterior, comparable between starts and w
    (``labels``: the known correspondences of :func:`label_array`)."""
    n, d = st.u.shape
    log_wv = np.log(st.w / volume) if st.w > 0 else -np.inf
    nll = _neg_loglik(np.ascontiguousarray(st.theta, dtype=float), np.ascontiguousarray(y, dtype=float),
                      float(st.s2), float(np.log((1 - st.w) / n)), float(log_wv),
                      np.zeros(0, np.int64) if labels is None else np.asarray(labels, dtype=np.int64))
    prior = 0.0 if st.kernel is None else 0.5 * lam * st.kernel.energy(st.coef)
    return float(nll + prior)
