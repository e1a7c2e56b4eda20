"""Riemannian metrics on the GMM shape parameters: α-order entropy (closed form) and Fisher–Rao.

Parameters are ordered as in eq. (9): ``θ = (φ_1^1, φ_1^2, φ_2^1, …)``, i.e. the ``(K, d)``
landmark array flattened row by row. With ``N_a(x) = N(x; φ_a, σ²I)`` and ``r_a = x − φ_a``,
the density (eq. 5) has ``∂p/∂φ_a = N_a r_a / (K σ²)``.

α-order entropy metric, α = 2 (eq. 22)
    ``g_ij = ∫ ∂_i p ∂_j p dx``. With ``Δ = φ_a − φ_b`` and the overlap ``G(Δ)`` of
    :mod:`shapelib.gmm`, the (a, b) block is

        g_ab = G(Δ) / (K² σ⁴) · [ (σ²/2) I − Δ Δᵀ / 4 ],

    so the diagonal blocks are ``I / (2 K² σ² (4πσ²)^{d/2})`` and, as the paper notes, the
    off-diagonal entries *within* a landmark vanish. Since ``θ̇ᵀ g θ̇ = ∫ (∂_t p)² dx``, the
    metric is the flat L² metric pulled back to the parameters.

Fisher–Rao metric (eq. 6)
    ``g_ij = ∫ (1/p) ∂_i p ∂_j p dx = ∫ ∂_i ψ ∂_j ψ dx`` with ``ψ = 2√p``: the pull-back of
    the L² metric by ``θ ↦ 2√p``, which maps into the sphere of radius 2. It has no closed
    form; it is integrated on a grid (:mod:`shapelib.quadrature`). Bounds used in the tests:
    ``g ≼ I/(Kσ²)`` (the complete-data information) and ``g = I/σ²`` exactly when K = 1.
"""

from __future__ import annotations

import numpy as np

from ._validate import as_shape, check_sigma2
from .quadrature import DEFAULT_MARGIN, DEFAULT_SPACING, Grid, make_grid

__all__ = [
    "alpha_metric",
    "alpha_quadratic_form",
    "fisher_rao_metric",
    "fisher_rao_quadratic_form",
]


# ---------------------------------------------------------------------------------------------
# α-order entropy metric (eq. 22), closed form
# ---------------------------------------------------------------------------------------------


def _alpha_gram(x: np.ndarray, y: np.ndarray, s2: float) -> np.ndarray:
    """``∫ ∂p_x/∂x_a^i ∂p_y/∂y_b^j dx`` for two shapes with the same K, as a ``(K d, K d)`` matrix.

    With ``x = y`` this is the α-order metric; with consecutive shapes of a path it is the
    cross term of the Gauss–Newton Hessian of the discrete path energy.
    """
    k, d = x.shape
    delta = x[:, None, :] - y[None, :, :]  # (K, K, d)
    sq = np.einsum("abi,abi->ab", delta, delta)
    g = np.exp(-sq / (4 * s2)) / (4 * np.pi * s2) ** (d / 2) / (k * k * s2 * s2)
    blocks = (s2 / 2) * np.eye(d)[None, None] - 0.25 * delta[..., :, None] * delta[..., None, :]
    blocks *= g[..., None, None]  # (K, K, d, d)
    return blocks.transpose(0, 2, 1, 3).reshape(k * d, k * d)


def alpha_metric(theta, sigma2) -> np.ndarray:
    """The α-order (α = 2) entropy metric tensor of eq. (22), in closed form.

    Parameters
    ----------
    theta : array_like, shape (K, d)
        Landmarks (GMM means).
    sigma2 : float
        σ² of eq. (5).

    Returns
    -------
    ndarray, shape (K d, K d)
        ``g_ij = ∫ ∂p/∂θ_i ∂p/∂θ_j dx``, parameters ordered as in eq. (9). Symmetric positive
        semi-definite.
    """
    theta = as_shape(theta, name="theta")
    return _alpha_gram(theta, theta, check_sigma2(sigma2))


def _alpha_qform(theta: np.ndarray, vel: np.ndarray, s2: float) -> np.ndarray:
    """Batched ``vᵀ g_α(θ) v`` for ``theta, vel`` of shape (m, K, d); O(m K² d) memory-light."""
    m, k, d = theta.shape
    delta = theta[:, :, None, :] - theta[:, None, :, :]  # (m, K, K, d)
    sq = np.einsum("mabi,mabi->mab", delta, delta)
    g = np.exp(-sq / (4 * s2)) / (4 * np.pi * s2) ** (d / 2) / (k * k * s2 * s2)
    vv = np.einsum("mai,mbi->mab", vel, vel)
    dv_a = np.einsum("mabi,mai->mab", delta, vel)
    dv_b = np.einsum("mabi,mbi->mab", delta, vel)
    return np.einsum("mab,mab->m", g, (s2 / 2) * vv - 0.25 * dv_a * dv_b)


def alpha_quadratic_form(theta, velocity, sigma2) -> float:
    """``θ̇ᵀ g_α(θ) θ̇ = ∫ (∂_t p)² dx`` without forming the ``(Kd, Kd)`` matrix (eq. 8 integrand)."""
    theta = as_shape(theta, name="theta")
    vel = as_shape(velocity, name="velocity")
    if vel.shape != theta.shape:
        raise ValueError(f"velocity must have the shape of theta {theta.shape}; got {vel.shape}")
    return float(_alpha_qform(theta[None], vel[None], check_sigma2(sigma2))[0])


# ---------------------------------------------------------------------------------------------
# Fisher–Rao metric (eq. 6), by quadrature
# ---------------------------------------------------------------------------------------------


def _psi_coef(theta: np.ndarray, s2: float, nodes: np.ndarray):
    """``ψ = 2√p`` at the nodes (M,) and ``coef_ma = N_a(x_m) / (K σ² √p(x_m))`` (M, K), log-space stable.

    ``∂ψ/∂φ_a (x_m) = coef_ma r_ma`` with ``r_ma = x_m − φ_a``.
    """
    k, d = theta.shape
    expo = np.zeros((len(nodes), k))
    for i in range(d):  # −|x − φ|² / (2σ²), one coordinate at a time
        expo -= np.subtract.outer(nodes[:, i], theta[:, i]) ** 2
    expo *= 0.5 / s2
    # one exponential pass: e = N_a / N_max with N_max the largest component at each node;
    # ratios below e^-60 are set to e^-60·(tiny): exp of huge negative numbers is slow and
    # they are negligible next to the leading component (which is 1)
    top = expo.max(axis=1)
    expo -= top[:, None]
    np.maximum(expo, -60.0, out=expo)
    e = np.exp(expo)
    total = e.sum(axis=1)
    log_norm = -0.5 * d * np.log(2 * np.pi * s2)
    log_p = np.log(total) + top + log_norm - np.log(k)  # log p(x_m)
    psi = 2.0 * np.exp(0.5 * log_p)
    # coef = N_a / (K σ² √p) = e · exp(top + log_norm − ½ log p) / (K σ²)
    coef = e * (np.exp(top + log_norm - 0.5 * log_p) / (k * s2))[:, None]
    return psi, coef


def _r_weighted(w: np.ndarray, nodes: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``Σ_m w_ma r_ma`` for ``r_ma = x_m − φ_a`` without forming r: (K, d)."""
    return w.T @ nodes - w.sum(axis=0)[:, None] * theta


def _psi_and_jacobian(theta: np.ndarray, s2: float, nodes: np.ndarray, *, jacobian: bool = True):
    """``ψ = 2√p`` at the grid nodes (M,) and, if requested, ``∂ψ/∂φ_a = N_a r_a / (K σ² √p)`` (M, K, d)."""
    psi, coef = _psi_coef(theta, s2, nodes)
    if not jacobian:
        return psi, None
    return psi, coef[..., None] * (nodes[:, None, :] - theta[None, :, :])


def fisher_rao_metric(theta, sigma2, *, spacing: float = DEFAULT_SPACING, margin: float = DEFAULT_MARGIN) -> np.ndarray:
    """The Fisher–Rao metric tensor of eq. (6) for the GMM of eq. (5), by quadrature.

    ``g_ij = ∫ (1/p) ∂_i p ∂_j p dx`` is computed as ``∫ ∂_i ψ ∂_j ψ dx`` with ``ψ = 2√p``
    (numerically stable in the tails) by the trapezoid rule on a grid of step ``spacing·σ``
    reaching ``margin·σ`` beyond the landmarks (see :mod:`shapelib.quadrature` for accuracy).

    Parameters
    ----------
    theta : array_like, shape (K, d)
    sigma2 : float
    spacing, margin : float, keyword-only
        Grid step and margin in units of σ.

    Returns
    -------
    ndarray, shape (K d, K d)
        Symmetric positive semi-definite; ``I/σ²`` for K = 1, and ``≼ I/(Kσ²)`` in general.
    """
    theta = as_shape(theta, name="theta")
    s2 = check_sigma2(sigma2)
    grid = make_grid(theta, s2, spacing=spacing, margin=margin)
    _, jac = _psi_and_jacobian(theta, s2, grid.nodes)
    a = jac.reshape(len(grid.nodes), -1)
    g = grid.weight * (a.T @ a)
    return 0.5 * (g + g.T)


def _fr_qform(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid) -> np.ndarray:
    """Batched ``vᵀ g_FR(θ) v = ∫ ṗ²/p`` for ``theta, vel`` of shape (m, K, d) on a common grid."""
    out = np.empty(len(theta))
    x = grid.nodes
    for i in range(len(theta)):
        _, coef = _psi_coef(theta[i], s2, x)
        rv = x @ vel[i].T - np.einsum("ki,ki->k", theta[i], vel[i])[None, :]  # r_ma · V_a
        out[i] = grid.integrate(np.einsum("mk,mk->m", coef, rv) ** 2)
    return out


def fisher_rao_quadratic_form(theta, velocity, sigma2, *, spacing: float = DEFAULT_SPACING,
                              margin: float = DEFAULT_MARGIN) -> float:
    """``θ̇ᵀ g_FR(θ) θ̇ = ∫ (∂_t p)² / p dx`` by quadrature, without forming the matrix."""
    theta = as_shape(theta, name="theta")
    vel = as_shape(velocity, name="velocity")
    if vel.shape != theta.shape:
        raise ValueError(f"velocity must have the shape of theta {theta.shape}; got {vel.shape}")
    s2 = check_sigma2(sigma2)
    grid = make_grid(theta, s2, spacing=spacing, margin=margin)
    return float(_fr_qform(theta[None], vel[None], s2, grid)[0])


# ---------------------------------------------------------------------------------------------
# Quadratic forms with their gradients (what the geodesic solver needs), batched over points
# ---------------------------------------------------------------------------------------------


def _alpha_qform_grad(theta: np.ndarray, vel: np.ndarray, s2: float):
    """``Q = vᵀ g_α(θ) v`` and its gradients ``∂Q/∂θ`` and ``∂Q/∂v``, batched over (m, K, d).

    ``Q = Σ_ab (G_ab/K²) B_ab`` with ``B_ab = V_a·V_b/(2σ²) − (Δ·V_a)(Δ·V_b)/(4σ⁴)``,
    ``Δ = φ_a − φ_b``. Since the summand is even in Δ and symmetric in (a, b),
    ``∂Q/∂φ_a = 2 Σ_b (G_ab/K²) [−Δ B_ab/(2σ²) − (V_a (Δ·V_b) + V_b (Δ·V_a))/(4σ⁴)]`` and
    ``∂Q/∂V_a = 2 (g_α v)_a``.
    """
    m, k, d = theta.shape
    delta = theta[:, :, None, :] - theta[:, None, :, :]  # (m, K, K, d)
    g = np.exp(-np.einsum("mabi,mabi->mab", delta, delta) / (4 * s2)) / (4 * np.pi * s2) ** (d / 2) / (k * k)
    vv = np.einsum("mai,mbi->mab", vel, vel)
    dva = np.einsum("mabi,mai->mab", delta, vel)  # Δ_ab · V_a
    dvb = np.einsum("mabi,mbi->mab", delta, vel)  # Δ_ab · V_b
    b = vv / (2 * s2) - dva * dvb / (4 * s2 * s2)
    q = np.einsum("mab,mab->m", g, b)
    d_theta = 2 * (
        -np.einsum("mab,mabi->mai", g * b, delta) / (2 * s2)
        - (np.einsum("mab,mai->mai", g * dvb, vel) + np.einsum("mab,mbi->mai", g * dva, vel)) / (4 * s2 * s2)
    )
    # (g v)_a = Σ_b (G/K²)[V_b/(2σ²) − Δ (Δ·V_b)/(4σ⁴)]
    gv = np.einsum("mab,mbi->mai", g, vel) / (2 * s2) - np.einsum("mab,mabi->mai", g * dvb, delta) / (4 * s2 * s2)
    return q, d_theta, 2 * gv


def _alpha_qform_hessian(theta: np.ndarray, vel: np.ndarray, s2: float):
    """Second derivatives of ``Q = vᵀ g_α(θ) v``: ``(Q_θθ, Q_θv, Q_vv)``, each (m, K d, K d).

    ``Q = Σ_ab f(Δ_ab, V_a, V_b)`` with ``f = c(Δ) h``, ``c = exp(−|Δ|²/4σ²)/((4πσ²)^{d/2} K²)``,
    ``h = V_a·V_b/(2σ²) − (Δ·V_a)(Δ·V_b)/(4σ⁴)`` and ``Δ = φ_a − φ_b``. Each term depends on
    the positions only through Δ, so its Hessian in ``(Δ, V_a, V_b)`` is scattered with signs
    ±1; the terms (a, b) and (b, a) are the same function, hence the factors 2. ``Q_θv`` has rows
    indexed by θ and columns by v; ``Q_vv = 2 g_α``. Used for exact Newton steps on the α path
    energy; checked against finite differences of :func:`_alpha_qform_grad` in the tests.
    """
    m, k, d = theta.shape
    eye = np.eye(d)
    iu, ju = np.triu_indices(k, 1)  # the terms (a, b) and (b, a) are equal: work on a < b
    delta = theta[:, iu] - theta[:, ju]  # (m, P, d)
    va, vb = vel[:, iu], vel[:, ju]
    dot = lambda x, y: np.einsum("mpi,mpi->mp", x, y)  # noqa: E731
    outer = lambda x, y: x[..., :, None] * y[..., None, :]  # noqa: E731
    s4 = 4 * s2 * s2
    c = 2 * np.exp(-dot(delta, delta) / (4 * s2)) / (4 * np.pi * s2) ** (d / 2) / (k * k)  # 2×: both orders
    dva, dvb = dot(delta, va), dot(delta, vb)
    h = dot(va, vb) / (2 * s2) - dva * dvb / s4
    gh = -(dvb[..., None] * va + dva[..., None] * vb) / s4  # ∇_Δ h;  ∇_Δ c = −c Δ / (2σ²)
    sym = lambda x: x + np.swapaxes(x, -1, -2)  # noqa: E731
    h_dd = c[..., None, None] * (
        -sym(outer(va, vb)) / s4 + (h / s4)[..., None, None] * outer(delta, delta)
        - (h / (2 * s2))[..., None, None] * eye - sym(outer(delta, gh)) / (2 * s2))

    def h_dv(other, d_other):
        """∂²f/∂Δ∂V_a with ``other = V_b`` (or ∂²f/∂Δ∂V_b with ``other = V_a``): rows Δ, columns V."""
        return -c[..., None, None] * ((d_other / s4)[..., None, None] * eye + outer(other, delta) / s4
                                      + outer(delta, other / (2 * s2) - (d_other / s4)[..., None] * delta) / (2 * s2))

    h_dva, h_dvb = h_dv(vb, dvb), h_dv(va, dva)
    idx = np.arange(k)

    def full(upper_blocks, lower_blocks):
        out = np.zeros((m, k, k, d, d))
        out[:, iu, ju] = upper_blocks
        out[:, ju, iu] = lower_blocks
        return out

    # Δ = φ_a − φ_b: ∂²/∂φ_a² = ∂²/∂φ_b² = H_ΔΔ, ∂²/∂φ_a∂φ_b = −H_ΔΔ (summed over the pairs)
    q_tt = -full(h_dd, h_dd)
    q_tt[:, idx, idx] = -q_tt.sum(axis=2)
    # block (θ_x, V_y): (θ_a, V_a) +H_ΔVa, (θ_b, V_a) −H_ΔVa, (θ_a, V_b) +H_ΔVb, (θ_b, V_b) −H_ΔVb
    q_tv = full(h_dvb, -h_dva)
    q_tv[:, idx, idx] = _pair_sum(h_dva, iu, k) - _pair_sum(h_dvb, ju, k)
    shape = (m, k * d, k * d)
    q_tt, q_tv = (x.transpose(0, 1, 3, 2, 4).reshape(shape) for x in (q_tt, q_tv))
    return q_tt, q_tv, 2 * _alpha_tensor_batch(theta, s2)


def _pair_sum(values, owner, k):
    """Sum (m, P, …) pair values into (m, K, …) by the landmark ``owner[p]`` of each pair."""
    out = np.zeros((values.shape[0], k) + values.shape[2:])
    np.add.at(out, (slice(None), owner), values)
    return out


def _alpha_tensor_batch(theta: np.ndarray, s2: float) -> np.ndarray:
    """α metric tensors for a batch of shapes (m, K, d) -> (m, K d, K d)."""
    return np.stack([_alpha_gram(t, t, s2) for t in theta])


def _fr_qform_grad(theta: np.ndarray, vel: np.ndarray, s2: float, grid: Grid):
    """``Q = ∫ ṗ²/p = ∫ ψ̇²`` (ψ = 2√p) and its gradients, batched over (m, K, d), on ``grid``.

    With ``ψ̇ = Σ_a coef_a (r_a·V_a)`` (``coef_a = N_a/(Kσ²√p)``):
    ``∂Q/∂V_a = 2 ∫ ψ̇ coef_a r_a`` and
    ``∂Q/∂φ_a = 2 ∫ ψ̇ coef_a [(r_a·V_a) r_a/σ² − V_a] − 2 ∫ ψ̇² coef_a r_a / ψ``.
    """
    m = len(theta)
    q = np.empty(m)
    d_theta = np.empty_like(theta)
    d_vel = np.empty_like(theta)
    x = grid.nodes
    for i in range(m):
        th, v = theta[i], vel[i]
        psi, coef = _psi_coef(th, s2, x)
        rv = x @ v.T - np.einsum("ki,ki->k", th, v)[None, :]
        psidot = np.einsum("mk,mk->m", coef, rv)
        q[i] = grid.integrate(psidot**2)
        pc = psidot[:, None] * coef  # (M, K)
        d_vel[i] = 2 * grid.weight * _r_weighted(pc, x, th)
        d_theta[i] = 2 * grid.weight * (
            _r_weighted(pc * rv, x, th) / s2
            - pc.sum(axis=0)[:, None] * v
            - _r_weighted(pc * (psidot / psi)[:, None], x, th)
        )
    return q, d_theta, d_vel


def _fr_tensor_batch(theta: np.ndarray, s2: float, grid: Grid) -> np.ndarray:
    """Fisher–Rao metric tensors for a batch of shapes (m, K, d) on a common grid -> (m, K d, K d)."""
    out = []
    for t in theta:
        _, jac = _psi_and_jacobian(t, s2, grid.nodes)
        a = jac.reshape(len(grid.nodes), -1)
        out.append(grid.weight * (a.T @ a))
    return np.stack(out)
