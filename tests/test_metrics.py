import numpy as np
import pytest

from shapelib.geometry.gmm import gmm_density
from shapelib.geometry.metrics import (
    _alpha_qform_grad,
    alpha_qform_hessian,
    _fr_qform_grad,
    _fr_qform_hessian,
    fr_tensor_batch,
    psi_coef,
    alpha_metric,
    alpha_quadratic_form,
    fisher_rao_metric,
    fisher_rao_quadratic_form,
)
from shapelib.geometry.quadrature import make_grid


def grid_metrics(theta, s2, spacing=0.125, margin=10):
    """Independent brute-force evaluation of eqs. (6) and (22) on a fine grid."""
    k = len(theta)
    grid = make_grid(theta, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    x = grid.nodes
    n = np.exp(-((x[:, None, :] - theta[None]) ** 2).sum(-1) / (2 * s2)) / (2 * np.pi * s2)
    dp = (n[..., None] * (x[:, None, :] - theta[None]) / (k * s2)).reshape(len(x), -1)
    p = gmm_density(x, theta, sigma2=s2)
    return grid.weight * dp.T @ dp, grid.weight * (dp / p[:, None]).T @ dp


def test_alpha_metric_closed_form_matches_quadrature(rng):
    theta = rng.normal(size=(5, 2))
    ga, _ = grid_metrics(theta, 0.3, spacing=0.25)
    assert np.allclose(alpha_metric(theta, sigma2=0.3), ga, rtol=0, atol=1e-12 * np.abs(ga).max())


def test_alpha_metric_structure(rng):
    theta = rng.normal(size=(4, 2))
    s2, k = 0.7, 4
    g = alpha_metric(theta, sigma2=s2)
    assert np.allclose(g, g.T)
    # diagonal blocks are I / (8 π K² σ⁴): intra-landmark off-diagonals vanish (paper §IV)
    for a in range(k):
        assert np.allclose(g[2 * a:2 * a + 2, 2 * a:2 * a + 2], np.eye(2) / (8 * np.pi * k**2 * s2**2))
    assert np.linalg.eigvalsh(g).min() > -1e-14


@pytest.mark.parametrize("s2", [0.1, 0.5, 1.5])
def test_fisher_rao_default_grid_accuracy(rng, s2):
    theta = rng.normal(size=(8, 2)) * 1.5
    _, gf = grid_metrics(theta, s2)
    g = fisher_rao_metric(theta, sigma2=s2)
    assert np.abs(g - gf).max() <= 1e-5 * np.abs(gf).max()


def test_fisher_rao_single_landmark_is_identity_over_sigma2():
    for s2 in (0.05, 1.0, 3.0):
        assert np.allclose(fisher_rao_metric(np.array([[0.3, -1.0]]), sigma2=s2) * s2, np.eye(2), atol=1e-9)


def test_fisher_rao_dominated_by_complete_data_information(rng):
    theta = rng.normal(size=(6, 2)) * 0.5
    s2 = 0.4
    g = fisher_rao_metric(theta, sigma2=s2)
    assert np.allclose(g, g.T)
    eig = np.linalg.eigvalsh(np.eye(12) / (6 * s2) - g)
    assert eig.min() > -1e-9
    assert np.linalg.eigvalsh(g).min() > -1e-12


def test_well_separated_landmarks_decouple(rng):
    # far apart components: FR -> blockdiag(I/(Kσ²)), α off-diagonal blocks -> 0
    theta = np.array([[0.0, 0.0], [50.0, 0.0], [0.0, 50.0]])
    s2 = 0.5
    assert np.allclose(fisher_rao_metric(theta, sigma2=s2), np.eye(6) / (3 * s2), atol=1e-9)
    g = alpha_metric(theta, sigma2=s2)
    assert np.abs(g[:2, 2:]).max() < 1e-300 + 1e-200


def test_quadratic_forms_match_matrices(rng):
    theta, v = rng.normal(size=(2, 5, 2))
    s2 = 0.6
    assert alpha_quadratic_form(theta, v, sigma2=s2) == pytest.approx(v.ravel() @ alpha_metric(theta, sigma2=s2) @ v.ravel(), rel=1e-12)
    assert fisher_rao_quadratic_form(theta, v, sigma2=s2) == pytest.approx(v.ravel() @ fisher_rao_metric(theta, sigma2=s2) @ v.ravel(), rel=1e-10)


def test_rotation_equivariance(rng):
    theta = rng.normal(size=(4, 2))
    c, s = np.cos(1.1), np.sin(1.1)
    r = np.array([[c, -s], [s, c]])
    big = np.kron(np.eye(4), r)
    for metric in (alpha_metric, fisher_rao_metric):
        g, gr = metric(theta, sigma2=0.5), metric(theta @ r.T, sigma2=0.5)
        assert np.allclose(gr, big @ g @ big.T, atol=1e-8 * np.abs(g).max())


@pytest.mark.parametrize("which", ["alpha", "fisher_rao"])
def test_quadratic_form_gradients_against_finite_differences(rng, which):
    theta, v = rng.normal(size=(2, 4, 2))
    s2 = 0.5
    if which == "alpha":
        f = lambda t, w: _alpha_qform_grad(t[None], w[None], s2)
    else:
        grid = make_grid(theta, sigma2=s2, grid_margin=8)  # fixed grid so the FD is of the same function
        f = lambda t, w: _fr_qform_grad(t[None], w[None], s2, grid)
    q, dt, dv = f(theta, v)
    eps = 1e-6
    for arr, grad in ((theta, dt[0]), (v, dv[0])):
        fd = np.zeros_like(arr)
        for idx in np.ndindex(arr.shape):
            e = np.zeros_like(arr)
            e[idx] = eps
            if arr is theta:
                fd[idx] = (f(theta + e, v)[0][0] - f(theta - e, v)[0][0]) / (2 * eps)
            else:
                fd[idx] = (f(theta, v + e)[0][0] - f(theta, v - e)[0][0]) / (2 * eps)
        assert np.allclose(grad, fd, rtol=1e-6, atol=1e-8 * np.abs(fd).max())


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
@pytest.mark.parametrize("d", [2, 3])
def test_quadratic_form_hessian_against_finite_differences(rng, d, metric):
    """The exact second derivatives used for Newton steps: FD of the analytic gradient, and
    ``Q_vv = 2 g`` against the metric tensor itself."""
    theta, v = rng.normal(size=(2, 2, 5, d))
    s2 = 0.4
    if metric == "alpha":
        hess, grad = (lambda t, w: alpha_qform_hessian(t, w, s2)), (lambda t, w: _alpha_qform_grad(t, w, s2))
        tensors = np.stack([alpha_metric(t, sigma2=s2) for t in theta])
    else:
        grid = make_grid(theta, sigma2=s2, grid_margin=6)  # fixed grid: the FD is of the same function
        hess, grad = (lambda t, w: _fr_qform_hessian(t, w, s2, grid)), (lambda t, w: _fr_qform_grad(t, w, s2, grid))
        tensors = fr_tensor_batch(theta, s2, grid)
    q_tt, q_tv, q_vv = hess(theta, v)
    eps = 1e-6
    size = theta[0].size
    fd_t, fd_v = np.zeros((2, 2, size, 2 * size))
    for j in range(size):
        e = np.zeros(size)
        e[j] = eps
        e = e.reshape(theta.shape[1:])
        for out, (tp, vp, tm, vm) in ((fd_t, (theta + e, v, theta - e, v)), (fd_v, (theta, v + e, theta, v - e))):
            _, gtp, gvp = grad(tp, vp)
            _, gtm, gvm = grad(tm, vm)
            out[:, j] = np.concatenate([(gtp - gtm).reshape(2, -1), (gvp - gvm).reshape(2, -1)], axis=1) / (2 * eps)
    scale = max(np.abs(q_tt).max(), np.abs(q_tv).max(), np.abs(q_vv).max())
    atol = (1e-7 if metric == "alpha" else 5e-7) * scale  # FD error of the quadrature gradient: ~1e-7 in 3-D
    assert np.allclose(fd_t[:, :, :size], q_tt, atol=atol)
    assert np.allclose(fd_t[:, :, size:], q_tv, atol=atol)
    assert np.allclose(fd_v[:, :, :size], np.swapaxes(q_tv, 1, 2), atol=atol)
    assert np.allclose(q_vv, 2 * tensors, rtol=1e-12, atol=1e-14 * scale)
    assert np.allclose(q_tt, np.swapaxes(q_tt, 1, 2))


def test_metric_errors():
    with pytest.raises(ValueError, match="sigma2"):
        alpha_metric(np.zeros((2, 2)), sigma2=0.0)
    with pytest.raises(ValueError, match="non-finite"):
        fisher_rao_metric(np.array([[np.nan, 0.0]]), sigma2=1.0)
    with pytest.raises(ValueError, match="velocity must have the shape"):
        alpha_quadratic_form(np.zeros((2, 2)), np.zeros((3, 2)), sigma2=1.0)
    with pytest.raises(ValueError, match="spacing"):
        fisher_rao_metric(np.zeros((2, 2)), sigma2=1.0, grid_spacing=0)


@pytest.mark.parametrize("d", [2, 3])
def test_psi_on_tensor_grid_matches_direct_log_space_evaluation(rng, d):
    """The separable evaluation of ψ = 2√p on a tensor grid (Σ n_i K exponentials) equals a
    direct evaluation of the density at every node, including nodes so far from every landmark
    that the separable product underflows (clusters at 80σ·e_0 and 80σ·e_1: near the origin the
    component nearest in x is far in y and vice versa, which is the log-space fallback)."""
    s2 = 0.05 if d == 2 else 0.5
    far = 80 * np.sqrt(s2) * np.eye(d)
    theta = np.concatenate([rng.normal(size=(4, d)) * 0.3 + far[0], rng.normal(size=(4, d)) * 0.3 + far[1]])
    grid = make_grid(theta, sigma2=s2, grid_spacing=0.5, grid_margin=4)
    psi, coef = psi_coef(theta, s2, grid)
    p = gmm_density(grid.nodes, theta, sigma2=s2)
    nk = np.exp(-((grid.nodes[:, None, :] - theta[None]) ** 2).sum(-1) / (2 * s2)) / (2 * np.pi * s2) ** (d / 2)
    near = p > 1e-250  # where the direct evaluation itself is meaningful
    assert np.sum(~near) > 0 and np.sum(near) > 0  # both regimes are exercised
    np.testing.assert_allclose(psi[near], 2 * np.sqrt(p[near]), rtol=1e-12)
    ref = nk[near] / (len(theta) * s2 * np.sqrt(p[near]))[:, None]
    np.testing.assert_allclose(coef[near], ref, rtol=1e-10, atol=1e-14 * ref.max())
    assert np.all(np.isfinite(psi)) and np.all(np.isfinite(coef)) and np.all(psi[~near] < 1e-120)


# ---------------------------------------------------------------------------------------------
# the entry points' checks and options, and ψ in log space on nodes that are not a tensor grid
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("call, message", [
    (lambda: alpha_metric(np.zeros(4), sigma2=1.0), r"^theta must be a 2-D array"),
    (lambda: fisher_rao_metric(np.zeros(4), sigma2=1.0), r"^theta must be a 2-D array"),
    (lambda: alpha_quadratic_form(np.zeros(4), np.zeros((2, 2)), sigma2=1.0), r"^theta must be a 2-D array"),
    (lambda: fisher_rao_quadratic_form(np.zeros(4), np.zeros((2, 2)), sigma2=1.0), r"^theta must be a 2-D array"),
    (lambda: alpha_quadratic_form(np.zeros((2, 2)), np.zeros(4), sigma2=1.0), r"^velocity must be a 2-D array"),
    (lambda: fisher_rao_quadratic_form(np.zeros((2, 2)), np.zeros(4), sigma2=1.0), r"^velocity must be a 2-D array"),
    (lambda: alpha_quadratic_form(np.zeros((3, 2)), np.zeros((2, 2)), sigma2=1.0),
     r"^velocity must have the shape of theta \(3, 2\); got \(2, 2\)$"),
    (lambda: fisher_rao_quadratic_form(np.zeros((3, 2)), np.zeros((2, 2)), sigma2=1.0),
     r"^velocity must have the shape of theta \(3, 2\); got \(2, 2\)$"),
    (lambda: fisher_rao_quadratic_form(np.zeros((2, 2)), np.ones((2, 2)), sigma2=-1.0), r"^sigma2 must be"),
    (lambda: fisher_rao_quadratic_form(np.zeros((2, 2)), np.ones((2, 2)), sigma2=1.0, grid_margin=0),
     r"grid_margin"),
])
def test_entry_points_name_the_argument_at_fault(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_fisher_rao_uses_the_grid_it_is_given(rng):
    """A coarse, narrow grid (step 0.6 σ, margin 2.5 σ, far from the defaults): the tensor and the
    quadratic form are the brute-force sums of eq. (6) on that very grid, to rounding — which they
    are not on the default grid (the options are used, each of them)."""
    theta, v = rng.normal(size=(2, 4, 2))
    s2 = 0.3
    _, ref = grid_metrics(theta, s2, spacing=0.6, margin=2.5)
    g = fisher_rao_metric(theta, sigma2=s2, grid_spacing=0.6, grid_margin=2.5)
    assert np.allclose(g, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    q = fisher_rao_quadratic_form(theta, v, sigma2=s2, grid_spacing=0.6, grid_margin=2.5)
    assert q == pytest.approx(v.ravel() @ ref @ v.ravel(), rel=1e-12)
    for spacing, margin in ((0.35, 2.5), (0.6, 6.0)):  # either default alone is another sum
        other = fisher_rao_metric(theta, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
        assert np.abs(other - ref).max() > 1e-6 * np.abs(ref).max()
        assert abs(fisher_rao_quadratic_form(theta, v, sigma2=s2, grid_spacing=spacing, grid_margin=margin) - q) > 1e-6 * q


@pytest.mark.parametrize("d", [2, 3])
def test_psi_coef_on_scattered_nodes_matches_logsumexp(rng, d):
    """Nodes that are not a tensor grid (``Grid.axes`` empty) are evaluated in log space
    (``_psi_coef_nodes``): ψ = 2√p and ``coef_a = N_a/(Kσ²√p)`` against scipy's logsumexp of the
    components, at nodes near the landmarks and at nodes where p is ~1e-100 to 1e-250 (below what
    a direct sum of densities resolves); ``coef`` to 1e-12 of each node's largest entry."""
    from scipy.special import logsumexp

    from shapelib.geometry.quadrature import Grid

    s2, k = 0.7, 5
    theta = rng.normal(size=(k, d))
    near = rng.normal(size=(200, d)) * 2.0
    direction = rng.normal(size=(40, d))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    far = direction * np.sqrt(2 * s2 * rng.uniform(300, 680, size=(40, 1)))  # |x − φ|²/2σ² ~ 300 … 690
    nodes = np.concatenate([near, far])
    grid = Grid(nodes=nodes, weight=1.0, shape=(len(nodes),))
    psi, coef = psi_coef(theta, s2, grid)
    log_n = -((nodes[:, None, :] - theta[None]) ** 2).sum(-1) / (2 * s2) - 0.5 * d * np.log(2 * np.pi * s2)
    log_p = logsumexp(log_n, axis=1) - np.log(k)
    assert log_p.min() < np.log(1e-250) and log_p.max() > np.log(1e-2)  # both regimes
    np.testing.assert_allclose(psi, 2 * np.exp(0.5 * log_p), rtol=1e-12)
    ref = np.exp(log_n - np.log(k * s2) - 0.5 * log_p[:, None])
    assert np.all(np.abs(coef - ref) <= 1e-12 * ref.max(axis=1)[:, None])


def test_fisher_rao_derivatives_where_the_density_underflows(rng):
    """Two clusters 80σ apart: the grid between them has nodes where p underflows and ψ is exactly
    0 (ψ̇ too). The quadratic form's gradient and second derivatives (numpy) stay finite there and
    equal the compiled kernels' (another implementation of the same sums); ψ̇²/ψ is taken as 0."""
    from shapelib.geometry.metrics import fr_qform_grad_hessian_compiled

    s2 = 0.05
    far = 80 * np.sqrt(s2) * np.eye(2)
    theta = np.concatenate([rng.normal(size=(2, 2)) * 0.3 + far[0], rng.normal(size=(2, 2)) * 0.3 + far[1]])[None]
    vel = rng.normal(size=theta.shape)
    grid = make_grid(theta, sigma2=s2, grid_spacing=0.5, grid_margin=4)
    psi, _ = psi_coef(theta[0], s2, grid)
    assert np.sum(psi == 0) > 0  # the underflow is exercised
    q, d_theta, d_vel = _fr_qform_grad(theta, vel, s2, grid)
    hess = _fr_qform_hessian(theta, vel, s2, grid)
    q_c, dt_c, dv_c, hess_c = fr_qform_grad_hessian_compiled(theta, vel, s2, grid)
    for got, ref in zip((q, d_theta, d_vel, *hess), (q_c, dt_c, dv_c, *hess_c)):
        assert np.all(np.isfinite(got))
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
