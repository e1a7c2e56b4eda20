"""The path metrics of ``shapelib.solver.path_metric``, number by number: the Gauss–Legendre rule
against SciPy's shifted-Legendre roots and the moments it must integrate exactly; the quadratic
forms of one landmark against their closed forms (Fisher information |v|²/σ², the α-order metric
|v|²/(8π σ⁴) in the plane); the quadratic form against the metric tensors, its gradient and Hessian
against finite differences; the Fisher–Rao lower bound against the Bhattacharyya coefficient of two
Gaussians, exp(−|Δ|²/(8σ²)), and its limit π for shapes far apart; the grid options passed to the
grid and recorded so that they re-create the metric; the factory's argument checks."""

import numpy as np
import pytest
from scipy.special import roots_sh_legendre

from shapelib.solver.path_metric import (
    AlphaPathMetric,
    FisherRaoPathMetric,
    PathMetric,
    gauss_legendre01,
    path_metric,
)


@pytest.mark.parametrize("q", [1, 3, 5])
def test_gauss_legendre01_is_the_shifted_legendre_rule(q):
    """Nodes and weights are SciPy's roots of the shifted Legendre polynomial; the rule integrates
    τᵏ over [0, 1] to 1/(k+1) for every k ≤ 2q − 1 and misses k = 2q."""
    tau, w = gauss_legendre01(q)
    ref_tau, ref_w = roots_sh_legendre(q)
    np.testing.assert_allclose(tau, ref_tau, atol=1e-14)
    np.testing.assert_allclose(w, ref_w, atol=1e-14)
    for k in range(2 * q):
        assert w @ tau**k == pytest.approx(1.0 / (k + 1), rel=1e-13)
    assert abs(w @ tau ** (2 * q) - 1.0 / (2 * q + 1)) > 1e-6


@pytest.mark.parametrize("s2", [0.3, 1.2])
def test_one_landmark_quadratic_forms_are_the_closed_forms(rng, s2):
    """One Gaussian N(μ, σ² I) in the plane moving with velocity v: the Fisher information of its
    mean is I/σ², so Q_FR = |v|²/σ²; ∫ ∂ᵢp ∂ⱼp dx = δᵢⱼ/(8π σ⁴), so Q_α = |v|²/(8π σ⁴). Neither
    depends on μ."""
    theta = rng.normal(size=(3, 1, 2))
    vel = rng.normal(size=(3, 1, 2))
    speed2 = (vel**2).sum(axis=(1, 2))
    alpha, fr = path_metric("alpha", s2), path_metric("fisher_rao", s2)
    np.testing.assert_allclose(alpha.qform(theta, vel, alpha.prepare(theta)), speed2 / (8 * np.pi * s2**2),
                               rtol=1e-12)
    np.testing.assert_allclose(fr.qform(theta, vel, fr.prepare(theta)), speed2 / s2, rtol=1e-6)


def _config(rng, m=2, k=3):
    base = np.array([[0.0, 0.0], [1.0, 0.3], [0.2, 1.1]])[:k]
    return base + 0.2 * rng.normal(size=(m, k, 2)), rng.normal(size=(m, k, 2))


@pytest.mark.parametrize("name", ["alpha", "fisher_rao"])
def test_quadratic_form_its_tensor_and_its_derivatives_agree(rng, name):
    """Q(θ, v) = vᵀ g(θ) v with the tensors (a separate computation); ∂Q/∂θ and ∂Q/∂v are the
    central differences of Q, and the Hessian blocks (Q_θθ, Q_θv, Q_vv) those of the gradient; the
    combined qform_grad_hessian returns the same numbers as its parts."""
    metric = path_metric(name, 0.6)
    theta, vel = _config(rng)
    m, k, d = theta.shape
    ctx = metric.prepare(np.concatenate([theta - 0.1, theta + 0.1]))
    q = metric.qform(theta, vel, ctx)
    g = metric.tensors(theta, ctx)
    flat = vel.reshape(m, -1)
    np.testing.assert_allclose(q, np.einsum("mi,mij,mj->m", flat, g, flat), rtol=1e-10)
    q2, d_theta, d_vel = metric.qform_grad(theta, vel, ctx)
    np.testing.assert_allclose(q2, q, rtol=1e-12)
    h_tt, h_tv, h_vv = metric.qform_hessian(theta, vel, ctx)
    eps = 1e-6
    for j in range(k * d):
        e = np.zeros(k * d)
        e[j] = eps
        e = np.broadcast_to(e.reshape(k, d), theta.shape)
        fd_t = (metric.qform(theta + e, vel, ctx) - metric.qform(theta - e, vel, ctx)) / (2 * eps)
        fd_v = (metric.qform(theta, vel + e, ctx) - metric.qform(theta, vel - e, ctx)) / (2 * eps)
        np.testing.assert_allclose(d_theta.reshape(m, -1)[:, j], fd_t, rtol=1e-6, atol=1e-8 * np.abs(q).max())
        np.testing.assert_allclose(d_vel.reshape(m, -1)[:, j], fd_v, rtol=1e-6, atol=1e-8 * np.abs(q).max())
        gt_p, gt_m = metric.qform_grad(theta + e, vel, ctx), metric.qform_grad(theta - e, vel, ctx)
        gv_p, gv_m = metric.qform_grad(theta, vel + e, ctx), metric.qform_grad(theta, vel - e, ctx)
        scale = 1e-6 * max(np.abs(h_tt).max(), np.abs(h_vv).max())
        np.testing.assert_allclose(h_tt[:, :, j], ((gt_p[1] - gt_m[1]) / (2 * eps)).reshape(m, -1), atol=scale)
        np.testing.assert_allclose(h_tv[:, j, :], ((gt_p[2] - gt_m[2]) / (2 * eps)).reshape(m, -1), atol=scale)
        np.testing.assert_allclose(h_vv[:, :, j], ((gv_p[2] - gv_m[2]) / (2 * eps)).reshape(m, -1), atol=scale)
    both = metric.qform_grad_hessian(theta, vel, ctx)
    for got, want in zip(both, (q2, d_theta, d_vel, (h_tt, h_tv, h_vv))):
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("s2", [0.4, 1.0])
@pytest.mark.parametrize("gap", [0.0, 0.5, 1.5, 4.0])
def test_fisher_rao_lower_bound_is_the_bhattacharyya_angle_of_two_gaussians(s2, gap):
    """Two one-landmark shapes, Gaussians a distance Δ apart: ∫√(p_u p_v) = exp(−Δ²/(8σ²)), and
    the bound is the great-circle distance 2 arccos of it on the sphere of radius 2."""
    u = np.array([[0.3, -0.2]])
    v = u + gap * np.sqrt(s2) * np.array([0.6, 0.8])
    want = 2.0 * np.arccos(np.exp(-(gap**2) / 8.0))
    assert path_metric("fisher_rao", s2).lower_bound(u, v) == pytest.approx(want, abs=1e-7)


@pytest.mark.parametrize("s2", [0.4, 1.0])
@pytest.mark.parametrize("gap", [0.0, 0.5, 1.5, 4.0])
def test_alpha_lower_bound_is_the_l2_distance_of_two_gaussians(s2, gap):
    """Two Gaussians in the plane a distance Δ apart: ∫ p_u p_v dx = exp(−Δ²/(4σ²))/(4π σ²), so
    ‖p_u − p_v‖² = 2 (1 − exp(−Δ²/(4σ²)))/(4π σ²)."""
    u = np.array([[0.3, -0.2]])
    v = u + gap * np.sqrt(s2) * np.array([0.6, 0.8])
    want = np.sqrt(2.0 * (1.0 - np.exp(-(gap**2) / 4.0)) / (4.0 * np.pi * s2))
    assert path_metric("alpha", s2).lower_bound(u, v) == pytest.approx(want, rel=1e-10, abs=1e-12)


def test_fisher_rao_lower_bound_of_shapes_far_apart_is_pi():
    """Densities with (numerically) disjoint supports are orthogonal: ψ_u ⊥ ψ_v on the sphere of
    radius 2, a quarter of the great circle apart, 2 arccos 0 = π."""
    u = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert path_metric("fisher_rao", 0.5).lower_bound(u, u + [40.0, 0.0]) == pytest.approx(np.pi, abs=1e-9)
    assert path_metric("fisher_rao", 0.5).lower_bound(u, u) == 0.0


@pytest.mark.parametrize("spacing, margin", [(0.2, 4.0), (0.5, 7.0)])
def test_the_grid_options_reach_the_grid_and_re_create_the_metric(spacing, margin):
    """The quadrature grid of a Fisher–Rao path metric has step spacing·σ and reaches margin·σ
    beyond the points; settings() names the options so that path_metric(**settings) re-creates
    the same grid."""
    s2 = 0.8
    sigma = np.sqrt(s2)
    metric = path_metric("fisher_rao", s2, grid_spacing=spacing, grid_margin=margin)
    points = np.array([[[0.0, 0.0], [2.0, 1.0]], [[0.5, -1.0], [1.0, 3.0]]])
    grid = metric.prepare(points)
    for axis, coord in zip(grid.axes, points.reshape(-1, 2).T):
        np.testing.assert_allclose(np.diff(axis), spacing * sigma, rtol=1e-12)
        assert axis[0] <= coord.min() - margin * sigma < axis[0] + spacing * sigma
        assert axis[-1] - spacing * sigma < coord.max() + margin * sigma <= axis[-1]
    again = path_metric("fisher_rao", s2, **metric.settings()).prepare(points)
    assert np.array_equal(again.nodes, grid.nodes) and again.weight == grid.weight
    assert path_metric("alpha", s2).settings() == {}
    assert path_metric("alpha", s2).prepare(points) is None


def test_the_factory_names_the_bad_argument():
    with pytest.raises(ValueError, match="^grid_spacing must"):
        path_metric("fisher_rao", 0.5, grid_spacing=0.0)
    with pytest.raises(ValueError, match="^grid_margin must"):
        path_metric("fisher_rao", 0.5, grid_margin=-1.0)
    with pytest.raises(ValueError, match="^metric must be one of"):
        path_metric("hellinger", 0.5)
    assert isinstance(path_metric("alpha", 0.5), AlphaPathMetric)
    assert isinstance(path_metric("fisher_rao", 0.5), FisherRaoPathMetric)
    assert PathMetric().prepare(np.zeros((2, 3, 2))) is None and PathMetric().settings() == {}


class _ContextMetric(PathMetric):
    """A user's metric g = c I whose constant c is the context prepare() returns (a quantity computed
    once per path, as the Fisher–Rao grid is): Q = c |v|², ∂Q/∂θ = 0, ∂Q/∂v = 2 c v."""

    name = "context"
    has_exact_hessian = True

    def prepare(self, points):
        return 1.0 + float(np.ptp(points))

    def _c(self, ctx):
        if ctx is None:
            raise ValueError("ctx must be what prepare returned; got None")
        return ctx

    def qform(self, theta, vel, ctx):
        return self._c(ctx) * np.einsum("mkd,mkd->m", vel, vel)

    def qform_grad(self, theta, vel, ctx):
        return self.qform(theta, vel, ctx), np.zeros_like(theta), 2 * self._c(ctx) * vel

    def qform_hessian(self, theta, vel, ctx):
        m, k, d = vel.shape
        z = np.zeros((m, k * d, k * d))
        return z, z.copy(), np.broadcast_to(2 * self._c(ctx) * np.eye(k * d), z.shape).copy()


def test_the_default_qform_grad_hessian_passes_the_context_on(rng):
    """PathMetric.qform_grad_hessian (for a metric that does not override it) is qform_grad and
    qform_hessian at the same (θ, v, ctx): here the closed forms Q = c|v|², (0, 2cv), (0, 0, 2cI)."""
    metric = _ContextMetric()
    theta, vel = _config(rng)
    ctx = metric.prepare(theta)
    q, d_theta, d_vel, (h_tt, h_tv, h_vv) = metric.qform_grad_hessian(theta, vel, ctx)
    np.testing.assert_allclose(q, ctx * (vel**2).sum(axis=(1, 2)))
    assert not d_theta.any() and not h_tt.any() and not h_tv.any()
    np.testing.assert_allclose(d_vel, 2 * ctx * vel)
    np.testing.assert_allclose(h_vv, np.broadcast_to(2 * ctx * np.eye(6), (2, 6, 6)))
