"""Compiled (numba) kernels for the α-order metric's quadratic form, its gradient and the exact
Hessian of the piecewise-linear path energy.

The formulas are documented once, in :mod:`shapelib.geometry.metrics` (eq. 22: :func:`~shapelib.geometry.metrics._alpha_qform`,
:func:`~shapelib.geometry.metrics._alpha_qform_grad`, :func:`~shapelib.geometry.metrics.alpha_qform_hessian`) and
:mod:`shapelib.solver.energy` (:func:`~shapelib.solver.energy.exact_path_hessian`). The numpy versions
there are the test oracle (``tests/test_kernels.py``: equal to ~1e-12); these loops compute
the same sums pair by pair, without the (m, K, K) temporaries, and use the symmetry of the
summand in (a, b) so that every Gaussian overlap is evaluated once per unordered pair.

Why compiled: at the corpus callosum's K = 63 the numpy versions are memory bound on
(m, K, K) and (m, K d, K d) temporaries (``benchmarks/bench_geodesic.py`` prints the
per-iteration breakdown). The path Hessian's pass also returns Q and its gradient at the nodes,
since it evaluates every overlap there anyway. All kernels are float64, ``fastmath=False`` (IEEE semantics: no
reassociation), single-threaded (the machine's cores go to separate pairs), and cached on disk
(``cache=True``) so that only the first import after installation pays the compilation.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["alpha_qform", "alpha_qform_grad", "alpha_path_grad_hessian"]


#: ``ψ = 2√p`` below this (``p`` below float64's smallest normal number) only far from every
#: landmark, where ``coef ∝ √p`` and ``ψ̇`` are as small: the terms divided by ψ are dropped there
#: (their products with ``coef`` are below 1e-300), instead of dividing by zero or a subnormal.
PSI_FLOOR = 1e-150


@njit(cache=True, fastmath=False)
def _overlap_norm(s2, k, d):
    """``1 / ((4πσ²)^{d/2} K²)``: the factor of ``c_ab = G(Δ_ab)/K²``."""
    return 1.0 / ((4.0 * math.pi * s2) ** (0.5 * d) * k * k)


@njit(cache=True, fastmath=False, inline="always")
def _pair_dots(theta, vel, a, b, delta):
    """For landmarks a, b of one shape (``theta, vel`` (K, d)): writes ``Δ = φ_a − φ_b`` to
    ``delta`` and returns ``|Δ|², V_a·V_b, Δ·V_a, Δ·V_b``."""
    rr = 0.0
    vv = 0.0
    dva = 0.0
    dvb = 0.0
    for i in range(delta.shape[0]):
        x = theta[a, i] - theta[b, i]
        delta[i] = x
        rr += x * x
        vv += vel[a, i] * vel[b, i]
        dva += x * vel[a, i]
        dvb += x * vel[b, i]
    return rr, vv, dva, dvb


@njit(cache=True, fastmath=False, inline="always")
def _add_pair_gradient(vel, a, b, delta, dva, dvb, c, cb, r2, r4, d_theta, d_vel):
    """Adds the pair (a, b) of one shape to ``∂Q/∂θ`` and ``∂Q/∂v`` (``vel``, ``d_theta``, ``d_vel``
    (K, d)), both ordered pairs at once: (b, a) has Δ → −Δ and (Δ·V_a, Δ·V_b) → (−Δ·V_b, −Δ·V_a).
    ``c = G(Δ)/K²`` (with the overlap's norm) and ``cb`` = c (V_a·V_b/(2σ²) − (Δ·V_a)(Δ·V_b)/(4σ⁴)),
    the pair's term of Q; ``r2 = 1/(2σ²)``, ``r4 = 1/(4σ⁴)``. The one copy of these formulas for
    :func:`_alpha_qform_grad` and :func:`_alpha_path_grad_hessian`."""
    c2, c4 = 2.0 * c * r2, 2.0 * c * r4
    for i in range(delta.shape[0]):
        gt = -2.0 * cb * r2 * delta[i] - c4 * (dvb * vel[a, i] + dva * vel[b, i])
        d_theta[a, i] += gt
        d_theta[b, i] -= gt
        d_vel[a, i] += c2 * vel[b, i] - c4 * dvb * delta[i]
        d_vel[b, i] += c2 * vel[a, i] - c4 * dva * delta[i]


def _dims(d):
    """The landmark dimension as a type: a tuple of ``d`` zeros.

    numba compiles a kernel once per argument type, and ``len`` of a tuple is a compile-time
    constant, so a kernel given ``dims`` is compiled (and cached) separately for d = 2 and d = 3
    with its loops over coordinates of known length, which LLVM unrolls (the α path Hessian
    2.9 → 1.9 ms at K = 63, n = 8, d = 2).
    One source serves both dimensions."""
    return (0,) * d


def alpha_qform(theta, vel, s2):
    """``Q = vᵀ g_α(θ) v`` for ``theta, vel`` of shape (m, K, d) -> (m,) (see ``metrics._alpha_qform``)."""
    return _alpha_qform(theta, vel, s2, _dims(theta.shape[2]))


def alpha_qform_grad(theta, vel, s2):
    """``Q``, ``∂Q/∂θ`` and ``∂Q/∂v`` for (m, K, d) inputs (see ``metrics._alpha_qform_grad``)."""
    return _alpha_qform_grad(theta, vel, s2, _dims(theta.shape[2]))


def alpha_path_grad_hessian(path, s2, tau, tw, csign):
    """``Q`` and its gradients at the path's quadrature nodes, and the exact Hessian of the α
    path energy, in one pass (:func:`_alpha_path_grad_hessian`), compiled for ``path``'s d."""
    return _alpha_path_grad_hessian(path, s2, tau, tw, csign, _dims(path.shape[2]))


@njit(cache=True, fastmath=False)
def _alpha_qform(theta, vel, s2, dims):
    m, k = theta.shape[0], theta.shape[1]
    d = len(dims)
    norm = _overlap_norm(s2, k, d)
    r4 = 1.0 / (4.0 * s2 * s2)
    r2 = 1.0 / (2.0 * s2)
    e4 = 1.0 / (4.0 * s2)  # multiplications, not divisions, in the loop over pairs
    out = np.empty(m)
    delta = np.empty(d)
    for n in range(m):
        diag = 0.0
        off = 0.0
        th, ve = theta[n], vel[n]
        for a in range(k):
            vva = 0.0
            for i in range(d):
                vva += vel[n, a, i] * vel[n, a, i]
            diag += vva
            for b in range(a + 1, k):
                rr, vv, dva, dvb = _pair_dots(th, ve, a, b, delta)
                off += math.exp(-rr * e4) * (vv * r2 - dva * dvb * r4)
        out[n] = norm * (diag * r2 + 2.0 * off)
    return out


@njit(cache=True, fastmath=False)
def _alpha_qform_grad(theta, vel, s2, dims):
    m, k = theta.shape[0], theta.shape[1]
    d = len(dims)
    norm = _overlap_norm(s2, k, d)
    r4 = 1.0 / (4.0 * s2 * s2)
    r2 = 1.0 / (2.0 * s2)
    e4 = 1.0 / (4.0 * s2)
    q = np.empty(m)
    d_theta = np.zeros((m, k, d))
    d_vel = np.zeros((m, k, d))
    delta = np.empty(d)
    for n in range(m):
        diag = 0.0
        off = 0.0
        for a in range(k):
            vva = 0.0
            for i in range(d):
                vva += vel[n, a, i] * vel[n, a, i]
                d_vel[n, a, i] += 2.0 * norm * vel[n, a, i] * r2  # the a = b term
            diag += vva
            for b in range(a + 1, k):
                rr, vv, dva, dvb = _pair_dots(theta[n], vel[n], a, b, delta)
                c = norm * math.exp(-rr * e4)
                cb = c * (vv * r2 - dva * dvb * r4)
                off += cb
                _add_pair_gradient(vel[n], a, b, delta, dva, dvb, c, cb, r2, r4, d_theta[n], d_vel[n])
        q[n] = norm * diag * r2 + 2.0 * off
    return q, d_theta, d_vel


@njit(cache=True, fastmath=False)
def _alpha_path_grad_hessian(path, s2, tau, tw, csign, dims):
    """Exact Hessian of the α path energy, block tridiagonal over the interior points, with
    ``Q``, ``∂Q/∂θ`` and ``∂Q/∂v`` at the Gauss–Legendre nodes of every segment (those of
    :func:`_alpha_qform_grad` at ``shapelib.solver.energy.segment_nodes``, same order of summation, so the
    same numbers): the Hessian's pass evaluates every pair's Gaussian overlap anyway.

    ``path`` (n + 1, K, d); the energy is ``Σ_t Σ_k w_k Q(θ_t + τ_k Δ_t, n Δ_t) / n`` (3-point
    Gauss–Legendre nodes ``tau``). On segment t, ``∂/∂θ_t = (1 − τ) ∂_θ − n ∂_v`` and
    ``∂/∂θ_{t+1} = τ ∂_θ + n ∂_v`` (``shapelib.solver.energy.exact_path_hessian``); the second derivatives of
    one pair term of Q (``H``, ``M``, ``N`` and ``g`` of ``metrics.alpha_qform_hessian``) are
    summed over the nodes with the six weights ``tw`` = ``w(1−τ)²/n, w(1−τ)τ/n, wτ²/n,
    w(1−τ), wτ, w n`` and then combined into the segment blocks (t, t), (t, t+1), (t+1, t+1);
    ``csign`` = (1, −1, 1) is the sign of ``Q_vv`` in each. Each pair term is evaluated once per
    unordered pair (a, b), since ``H_ba = H_ab`` and ``M_ba = −N_ab``.

    Returns ``q`` (n·nq,), ``d_theta``, ``d_vel`` (n·nq, K, d) (node ``t·nq + j`` is node j of
    segment t), ``diag`` (n − 1, K, d, K, d) and ``upper`` (n − 2, K, d, K, d).
    """
    n = path.shape[0] - 1
    k, d = path.shape[1], len(dims)
    nq = tau.shape[0]
    norm = _overlap_norm(s2, k, d)
    r4 = 1.0 / (4.0 * s2 * s2)
    r2 = 1.0 / (2.0 * s2)
    e4 = 1.0 / (4.0 * s2)
    diag = np.zeros((max(n - 1, 0), k, d, k, d))
    upper = np.zeros((max(n - 2, 0), k, d, k, d))
    th = np.empty((nq, k, d))
    vel = np.empty((k, d))
    delta = np.empty(d)
    gh = np.empty(d)
    pv = np.empty((d, d))
    acc = np.empty((8, d, d))  # node sums: H·tw0, H·tw1, H·tw2, M·tw3, M·tw4, N·tw3, N·tw4, C·tw5
    blk = np.empty((3, 2, d, d))  # the (a, b) and (b, a) blocks of the three segment blocks
    dacc = np.empty((k, 3, d, d))  # diagonal blocks (a, a) of the three segment blocks
    qf = np.zeros(n * nq)
    d_theta = np.zeros((n * nq, k, d))
    d_vel = np.zeros((n * nq, k, d))
    ctot = 0.0
    for q in range(nq):
        ctot += tw[5, q]
    for t in range(n):
        # segment blocks in the interior Hessian: (t, t) -> diag[t-1], (t, t+1) -> upper[t-1],
        # (t+1, t+1) -> diag[t]
        for a in range(k):
            for i in range(d):
                vel[a, i] = n * (path[t + 1, a, i] - path[t, a, i])
                for q in range(nq):
                    th[q, a, i] = path[t, a, i] + tau[q] * (path[t + 1, a, i] - path[t, a, i])
        dacc[:] = 0.0
        vsum = 0.0
        for a in range(k):
            vva = 0.0
            for i in range(d):
                vva += vel[a, i] * vel[a, i]
                for q in range(nq):  # the a = b term of ∂Q/∂v
                    d_vel[t * nq + q, a, i] += 2.0 * norm * vel[a, i] * r2
            vsum += vva
            for b in range(a + 1, k):
                acc[:] = 0.0
                for i in range(d):
                    for j in range(d):
                        pv[i, j] = vel[a, i] * vel[b, j] + vel[b, i] * vel[a, j]
                for q in range(nq):
                    m = t * nq + q
                    rr, vv, dva, dvb = _pair_dots(th[q], vel, a, b, delta)
                    c = norm * math.exp(-rr * e4)
                    h = vv * r2 - dva * dvb * r4
                    # Q and its gradient, as _alpha_qform_grad
                    qf[m] += c * h
                    _add_pair_gradient(vel, a, b, delta, dva, dvb, c, c * h, r2, r4, d_theta[m], d_vel[m])
                    for i in range(d):
                        gh[i] = -(dvb * vel[a, i] + dva * vel[b, i]) * r4
                    for i in range(d):
                        for j in range(d):
                            eye = 1.0 if i == j else 0.0
                            mij = -c * (eye * dva * r4 + vel[a, i] * delta[j] * r4
                                        + delta[i] * (vel[a, j] * r2 - dva * delta[j] * r4) * r2)
                            nij = -c * (eye * dvb * r4 + vel[b, i] * delta[j] * r4
                                        + delta[i] * (vel[b, j] * r2 - dvb * delta[j] * r4) * r2)
                            acc[3, i, j] += tw[3, q] * mij
                            acc[4, i, j] += tw[4, q] * mij
                            acc[5, i, j] += tw[3, q] * nij
                            acc[6, i, j] += tw[4, q] * nij
                            if j < i:  # H and C are symmetric in (i, j): mirrored below
                                continue
                            hij = c * (-pv[i, j] * r4
                                       + h * r4 * delta[i] * delta[j] - eye * h * r2
                                       - (delta[i] * gh[j] + gh[i] * delta[j]) * r2)
                            cij = 2.0 * c * (eye * r2 - delta[i] * delta[j] * r4)
                            acc[0, i, j] += tw[0, q] * hij
                            acc[1, i, j] += tw[1, q] * hij
                            acc[2, i, j] += tw[2, q] * hij
                            acc[7, i, j] += tw[5, q] * cij
                for i in range(d):
                    for j in range(i):
                        acc[0, i, j] = acc[0, j, i]
                        acc[1, i, j] = acc[1, j, i]
                        acc[2, i, j] = acc[2, j, i]
                        acc[7, i, j] = acc[7, j, i]
                # (t, t): k_a (1−τ)², k_b = k_bᵀ = −(1−τ)n, k_c = n²; (t, t+1): (1−τ)τ, (1−τ)n,
                # −τn, −n²; (t+1, t+1): τ², τn, τn, n²   (all times w/n)
                for x in range(3):
                    hx = x
                    if x == 0:
                        mb, nb, mbt, nbt = -1.0, -1.0, -1.0, -1.0
                        ib, ibt = 3, 3
                    elif x == 1:
                        mb, nb, mbt, nbt = 1.0, 1.0, -1.0, -1.0
                        ib, ibt = 3, 4
                    else:
                        mb, nb, mbt, nbt = 1.0, 1.0, 1.0, 1.0
                        ib, ibt = 4, 4
                    for i in range(d):
                        for j in range(d):
                            hv = acc[hx, i, j]
                            cv = csign[x] * acc[7, i, j]
                            kb_m = mb * acc[ib, i, j]
                            kb_n = nb * acc[ib + 2, i, j]
                            kbt_m = mbt * acc[ibt, j, i]
                            kbt_n = nbt * acc[ibt + 2, j, i]
                            # Q_θθ[a,b] = −2H, Q_θv[a,b] = 2M, Q_θv[b,a] = 2M_ba = −2N, Q_vv[a,b] = g
                            blk[x, 0, i, j] = -2.0 * hv + 2.0 * kb_m - 2.0 * kbt_n + cv
                            blk[x, 1, i, j] = -2.0 * hv - 2.0 * kb_n + 2.0 * kbt_m + cv
                            # Q_θθ[a,a] += 2H, Q_θv[a,a] += 2N; for b: 2H_ba = 2H, 2N_ba = −2M
                            dacc[a, x, i, j] += 2.0 * hv + 2.0 * kb_n + 2.0 * kbt_n
                            dacc[b, x, i, j] += 2.0 * hv - 2.0 * kb_m - 2.0 * kbt_m
                for i in range(d):
                    for j in range(d):
                        if t >= 1:
                            diag[t - 1, a, i, b, j] += blk[0, 0, i, j]
                            diag[t - 1, b, i, a, j] += blk[0, 1, i, j]
                        if 1 <= t <= n - 2:
                            upper[t - 1, a, i, b, j] += blk[1, 0, i, j]
                            upper[t - 1, b, i, a, j] += blk[1, 1, i, j]
                        if t <= n - 2:
                            diag[t, a, i, b, j] += blk[2, 0, i, j]
                            diag[t, b, i, a, j] += blk[2, 1, i, j]
        # diagonal blocks, with the a = b term of Q_vv: g_aa = c_aa I/(2σ²), c_aa = norm (Δ = 0)
        for a in range(k):
            for i in range(d):
                for j in range(d):
                    g0 = 2.0 * ctot * norm * r2 if i == j else 0.0
                    if t >= 1:
                        diag[t - 1, a, i, a, j] += dacc[a, 0, i, j] + csign[0] * g0
                    if 1 <= t <= n - 2:
                        upper[t - 1, a, i, a, j] += dacc[a, 1, i, j] + csign[1] * g0
                    if t <= n - 2:
                        diag[t, a, i, a, j] += dacc[a, 2, i, j] + csign[2] * g0
        for q in range(nq):
            qf[t * nq + q] = norm * vsum * r2 + 2.0 * qf[t * nq + q]
    return qf, d_theta, d_vel, diag, upper


# ---------------------------------------------------------------------------------------------
# Fisher–Rao (eq. 6) by quadrature: the element-wise work over (grid node, landmark), fused
# ---------------------------------------------------------------------------------------------


@njit(cache=True, fastmath=False)
def fr_psidot(x, theta, vel, coef):
    """``ψ̇_m = Σ_a coef_ma (r_ma·V_a)`` (M,) at the grid nodes ``x`` (M, d), ``r_ma = x_m − φ_a``
    (see ``metrics._fr_psidot``)."""
    m_nodes = x.shape[0]
    k = theta.shape[0]
    _, v, tv = _landmarks_by_coordinate(theta, vel)
    rv = np.empty(k)
    out = np.empty(m_nodes)
    for m in range(m_nodes):
        _velocity_dot_offset(x, m, v, tv, rv)
        s = 0.0
        for a in range(k):
            s += coef[m, a] * rv[a]
        out[m] = s
    return out


@njit(cache=True, fastmath=False)
def _landmarks_by_coordinate(theta, vel):
    """``θ`` and ``V`` as (d, K) arrays (landmarks innermost, so that loops over them vectorise)
    and ``φ_a·V_a`` (K,): ``r_ma·V_a = x_m·V_a − φ_a·V_a``."""
    k, d = theta.shape
    th = np.ascontiguousarray(theta.T)
    v = np.ascontiguousarray(vel.T)
    tv = np.zeros(k)
    for i in range(d):
        for a in range(k):
            tv[a] += th[i, a] * v[i, a]
    return th, v, tv


@njit(cache=True, fastmath=False, inline="always")
def _velocity_dot_offset(x, m, v, tv, rv):
    """``rv[a] = (x_m − θ_a) · v_a`` for every landmark ``a`` at grid node ``m`` (into ``rv``),
    from the (d, K) velocities ``v`` and ``tv[a] = θ_a · v_a``."""
    k = rv.shape[0]
    for a in range(k):
        rv[a] = -tv[a]
    for i in range(x.shape[1]):
        xi = x[m, i]
        for a in range(k):
            rv[a] += xi * v[i, a]


@njit(cache=True, fastmath=False)
def fr_qform_grad(x, weight, theta, vel, s2, psi, coef):
    """``Q = ∫ ψ̇²``, ``∂Q/∂θ`` (K, d) and ``∂Q/∂v`` (K, d) for one shape on the grid nodes ``x``
    with trapezoid weight ``weight`` (see ``metrics._fr_qform_grad``). Loops over landmarks
    innermost on (d, K) arrays, so that they vectorise."""
    m_nodes, d = x.shape
    k = theta.shape[0]
    th, v, tv = _landmarks_by_coordinate(theta, vel)
    g_th = np.zeros((d, k))
    g_v = np.zeros((d, k))
    rv = np.empty(k)
    pc = np.empty(k)
    q = 0.0
    inv_s2 = 1.0 / s2
    for m in range(m_nodes):
        _velocity_dot_offset(x, m, v, tv, rv)
        pd = 0.0
        for a in range(k):
            pd += coef[m, a] * rv[a]
        q += pd * pd
        # ψ falls below PSI_FLOOR only far from every landmark, where coef (∝ √p) and ψ̇ vanish with
        # it: the node adds nothing (never a division by zero, nor by a subnormal number)
        ratio = pd / psi[m] if psi[m] > PSI_FLOOR else 0.0
        for a in range(k):
            pc[a] = pd * coef[m, a]
        for i in range(d):
            xi = x[m, i]
            for a in range(k):
                ri = xi - th[i, a]
                g_v[i, a] += pc[a] * ri
                g_th[i, a] += pc[a] * ((rv[a] * inv_s2 - ratio) * ri - v[i, a])
    d_theta = np.empty((k, d))
    d_vel = np.empty((k, d))
    for a in range(k):
        for i in range(d):
            d_vel[a, i] = 2.0 * weight * g_v[i, a]
            d_theta[a, i] = 2.0 * weight * g_th[i, a]
    return weight * q, d_theta, d_vel


@njit(cache=True, fastmath=False)
def fr_hessian_parts(x, theta, vel, s2, psi, coef):
    """The element-wise parts of ``metrics._fr_qform_hessian`` for one shape, in one pass over the
    grid nodes ``x``: the rows ``√p [γ − uβ, β]`` of the Gram factor in the
    (M', 2, d, K) order, and the block-diagonal terms ``Σ_m (2u ∂²s − u² ∂²p)`` and
    ``Σ_m 2u ∂²p`` per landmark, (K, d, d) each, before the factor ``σ² w``. Loops over
    landmarks innermost, so that they vectorise."""
    d = x.shape[1]
    k = theta.shape[0]
    mk = x.shape[0]
    inv_s2 = 1.0 / s2
    th, v, tv = _landmarks_by_coordinate(theta, vel)
    e = np.empty((mk, 2, d, k))
    rv = np.empty(k)
    aa = np.empty(k)
    bb = np.empty(k)
    r = np.empty((d, k))
    # moments: Σ a, Σ b, Σ a rv, Σ a r_i, Σ a r_i r_j, Σ b r_i r_j, Σ a rv r_i r_j
    s_a = np.zeros(k)
    s_b = np.zeros(k)
    s_arv = np.zeros(k)
    s_ar = np.zeros((d, k))
    s_arr = np.zeros((d, d, k))
    s_brr = np.zeros((d, d, k))
    s_arvrr = np.zeros((d, d, k))
    for m in range(mk):
        _velocity_dot_offset(x, m, v, tv, rv)
        for i in range(d):
            xi = x[m, i]
            for a in range(k):
                r[i, a] = xi - th[i, a]
        pd = 0.0
        for a in range(k):
            pd += coef[m, a] * rv[a]
        inv_psi = 1.0 / psi[m] if psi[m] > PSI_FLOOR else 0.0  # far from every landmark: see fr_qform_grad
        u = 2.0 * pd * inv_psi
        bfac = pd * pd * inv_psi
        for a in range(k):
            aa[a] = pd * coef[m, a]
            bb[a] = bfac * coef[m, a]
            s_a[a] += aa[a]
            s_b[a] += bb[a]
            s_arv[a] += aa[a] * rv[a]
        for i in range(d):
            for a in range(k):
                c = coef[m, a]
                b1 = c * r[i, a]
                e[m, 1, i, a] = b1
                e[m, 0, i, a] = c * (r[i, a] * rv[a] * inv_s2 - v[i, a]) - u * b1
                s_ar[i, a] += aa[a] * r[i, a]
            for j in range(i, d):
                for a in range(k):
                    rr = r[i, a] * r[j, a]
                    s_arr[i, j, a] += aa[a] * rr
                    s_brr[i, j, a] += bb[a] * rr
                    s_arvrr[i, j, a] += aa[a] * rv[a] * rr
    s4 = s2 * s2
    dtt = np.empty((k, d, d))
    dtv = np.empty((k, d, d))
    for a in range(k):
        for i in range(d):
            for j in range(i, d):
                eye = 1.0 if i == j else 0.0
                d2p_a = s_arr[i, j, a] / s4 - eye * s_a[a] / s2
                d2p_b = s_brr[i, j, a] / s4 - eye * s_b[a] / s2
                d2s = (s_arvrr[i, j, a] / (s4 * s2)
                       - (eye * s_arv[a] + v[j, a] * s_ar[i, a] + v[i, a] * s_ar[j, a]) / s4)
                dtt[a, i, j] = d2s - d2p_b
                dtt[a, j, i] = dtt[a, i, j]
                dtv[a, i, j] = d2p_a
                dtv[a, j, i] = d2p_a
    return e, dtt, dtv


@njit(cache=True, fastmath=False)
def psi_coef_grid(factors, offsets, shape, top, log_norm, s2):
    """``ψ = 2√p`` (M,) and ``coef`` (M, K) on a tensor grid from the per-axis Gaussian factors
    (see ``metrics.psi_coef``): ``factors[offsets[i] + j]`` is axis i's factor (K,) at its node
    j, ``top`` (M,) the log of the per-node scale. Also returns the nodes where every component
    underflows (``far``), which the caller recomputes in log space."""
    d = shape.shape[0]
    k = factors.shape[1]
    m_nodes = top.shape[0]
    psi = np.empty(m_nodes)
    coef = np.empty((m_nodes, k))
    far = np.zeros(m_nodes, dtype=np.bool_)
    idx = np.empty(d, dtype=np.int64)
    log_k = math.log(k)
    for m in range(m_nodes):
        rem = m
        for ax in range(d - 1, -1, -1):  # C order: the last axis fastest
            idx[ax] = rem % shape[ax]
            rem //= shape[ax]
        row = offsets[0] + idx[0]
        for a in range(k):
            coef[m, a] = 1.0 * factors[row, a]
        for ax in range(1, d):
            row = offsets[ax] + idx[ax]
            for a in range(k):
                coef[m, a] *= factors[row, a]
        total = 0.0
        for a in range(k):
            total += coef[m, a]
        if total < 1e-200:  # every component below 1e-200 of its per-axis peaks
            far[m] = True
            total = 1.0
        log_p = math.log(total) + top[m] + log_norm - log_k
        psi[m] = 2.0 * math.exp(0.5 * log_p)
        scale = math.exp(top[m] + log_norm - 0.5 * log_p) / (k * s2)
        for a in range(k):
            coef[m, a] *= scale
    return psi, coef, far
