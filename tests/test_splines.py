import warnings

import numpy as np
import pytest
from scipy.spatial.distance import directed_hausdorff

from shapelib import InputError
from shapelib.comparison.hausdorff import hausdorff_distance
from shapelib.geometry.procrustes import PoseWarning
from shapelib.comparison.splines import (
    tps_bending_energy,
    tps_bending_matrix,
    tps_kernel,
    wendland_bending_energy,
    wendland_psi31,
)


@pytest.fixture
def pair(rng):
    u = rng.normal(size=(9, 2))
    return u, u + 0.15 * rng.normal(size=u.shape)


def test_hausdorff_matches_scipy(pair):
    u, v = pair
    ref = max(directed_hausdorff(u, v)[0], directed_hausdorff(v, u)[0])
    assert hausdorff_distance(u, v) == pytest.approx(ref)
    assert hausdorff_distance(u, v) == pytest.approx(hausdorff_distance(v, u))
    assert hausdorff_distance(u, u[::-1]) == 0.0  # ignores correspondence


@pytest.mark.parametrize("energy", [tps_bending_energy, wendland_bending_energy])
def test_bending_energy_vanishes_on_affine_maps(pair, energy):
    u, _ = pair
    a = np.array([[1.3, 0.4], [-0.1, 0.8]])
    assert abs(energy(u, u @ a.T + [2, -1])) < 1e-10
    assert energy(u, u) == 0.0


def test_bending_energies_positive_and_not_symmetric(pair):
    u, v = pair
    for energy in (tps_bending_energy, wendland_bending_energy):
        assert energy(u, v) > 0
        assert energy(u, v) != pytest.approx(energy(v, u), rel=1e-6)


def test_plain_wendland_is_not_affine_invariant(pair):
    u, _ = pair
    assert wendland_bending_energy(u, u + [1.0, 0.0], affine=False) > 0.1


def test_tps_bending_energy_equals_the_integral_of_second_derivatives(rng):
    """∫(f_xx² + 2f_xy² + f_yy²) = 8π tr(VᵀBV) for U = r² log r (independent grid integral)."""
    u = rng.uniform(-1, 1, size=(6, 2))
    v = u + 0.2 * rng.normal(size=u.shape)
    b = tps_bending_matrix(u, kernel="r2logr")
    w = b @ (v - u)  # kernel weights (B annihilates the affine part)
    h = 0.01
    ax = np.arange(-12, 12, h) + h / 2  # cell centres avoid the log singularity at the landmarks
    x, y = np.meshgrid(ax, ax, indexing="ij")
    total = 0.0
    for i in range(2):
        fxx = fxy = fyy = 0.0
        for (cx, cy), wi in zip(u, w[:, i]):
            dx, dy = x - cx, y - cy
            r2 = dx * dx + dy * dy
            lg = 0.5 * np.log(r2)
            # second derivatives of U = r² log r
            fxx = fxx + wi * (2 * lg + 1 + 2 * dx * dx / r2)
            fyy = fyy + wi * (2 * lg + 1 + 2 * dy * dy / r2)
            fxy = fxy + wi * (2 * dx * dy / r2)
        total += np.sum(fxx**2 + 2 * fxy**2 + fyy**2) * h * h
    assert total == pytest.approx(8 * np.pi * tps_bending_energy(u, v, kernel="r2logr"), rel=2e-2)


def test_kernels():
    assert tps_kernel(np.array([0.0]))[0] == 0.0
    assert tps_kernel(np.array([2.0]))[0] == pytest.approx(4 * np.log(4))
    assert tps_kernel(np.array([2.0]), kernel="r2logr")[0] == pytest.approx(4 * np.log(2))
    assert wendland_psi31(np.array([0.0, 1.0, 2.0])).tolist() == [1.0, 0.0, 0.0]
    assert tps_kernel(np.array([0.0, 2.0]), kernel="r").tolist() == [0.0, -2.0]
    with pytest.raises(ValueError, match="'r2logr2', 'r2logr', 'r'; got 'gauss'"):
        tps_kernel(np.array([1.0]), kernel="gauss")
    with pytest.raises(ValueError, match="'r2logr2', 'r2logr', 'r'; got 'gauss'"):
        tps_bending_energy(np.eye(4, 3), np.eye(4, 3), kernel="gauss")


def test_errors():
    u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="coincident landmarks 1 and 2"):
        tps_bending_energy(u, u)
    with pytest.raises(ValueError, match="at least 3 landmarks"):
        tps_bending_energy(np.eye(2), np.eye(2))
    with pytest.raises(ValueError, match="collinear|degenerate"):
        tps_bending_energy(np.array([[0.0, 0], [1, 0], [2, 0], [3, 0]]), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="support"):
        wendland_bending_energy(np.eye(3, 2), np.eye(3, 2), support=0)


# --- 3-D thin-plate spline: kernel U(r) = −r ------------------------------------------------


@pytest.fixture
def pair3(rng):
    u = rng.normal(size=(10, 3))
    return u, u + 0.15 * rng.normal(size=u.shape)


def test_3d_default_kernel_is_minus_r(pair3):
    u, v = pair3
    e = tps_bending_energy(u, v)
    assert e == tps_bending_energy(u, v, kernel="r")
    assert np.array_equal(tps_bending_matrix(u), tps_bending_matrix(u, kernel="r"))
    assert e != pytest.approx(tps_bending_energy(u, v, kernel="r2logr2"), rel=1e-3)
    assert e > 0


def test_2d_default_kernel_unchanged(pair):
    u, v = pair
    assert tps_bending_energy(u, v) == tps_bending_energy(u, v, kernel="r2logr2")
    assert np.array_equal(tps_bending_matrix(u), tps_bending_matrix(u, kernel="r2logr2"))
    assert tps_bending_energy(u, v) != pytest.approx(tps_bending_energy(u, v, kernel="r"), rel=1e-3)


def test_no_default_kernel_outside_2d_and_3d(rng):
    u = rng.normal(size=(8, 4))
    v = u + 0.1 * rng.normal(size=u.shape)
    with pytest.raises(ValueError, match="no default thin-plate kernel for 4-D"):
        tps_bending_energy(u, v)
    assert tps_bending_energy(u, v, kernel="r") > 0  # an explicit kernel is still honoured


@pytest.mark.parametrize("energy", [tps_bending_energy, wendland_bending_energy])
def test_3d_bending_energy_vanishes_on_affine_maps(pair3, rng, energy):
    u, _ = pair3
    a = rng.normal(size=(3, 3))
    v = u @ a.T + rng.normal(size=3)
    assert abs(energy(u, v)) < 1e-10 * np.sum((v - u) ** 2)
    assert energy(u, v + 0.1 * rng.normal(size=u.shape)) > 1e-3  # ... but not on non-affine ones


@pytest.mark.parametrize("d", [2, 3])
def test_bending_matrix_is_positive_semidefinite_with_affine_null_space(rng, d):
    for k in (d + 2, 7, 15, 30):
        for spread in (0.01, 1.0, 100.0):
            u = spread * rng.normal(size=(k, d))
            b = tps_bending_matrix(u)
            assert np.allclose(b, b.T, atol=1e-12 * np.abs(b).max())
            eig = np.linalg.eigvalsh(b)
            assert eig[0] >= -1e-10 * eig[-1], (k, spread, eig[:d + 2])
            # exactly d + 1 null directions (the affine functions of u), the rest positive
            assert np.sum(eig > 1e-10 * eig[-1]) == k - d - 1
            assert np.allclose(b @ np.hstack([np.ones((k, 1)), u]), 0, atol=1e-9 * eig[-1] * max(spread, 1))


def test_bending_energy_scaling_3d_linear_2d_invariant(pair, pair3):
    for (u, v), power in ((pair, 0), (pair3, 1)):
        e = tps_bending_energy(u, v)
        for s in (0.01, 0.5, 3.0, 250.0):
            assert tps_bending_energy(s * u, s * v) == pytest.approx(s**power * e, rel=1e-8)
    u, v = pair3  # the 2-D kernel in 3-D would not scale linearly (log term)
    ratio = tps_bending_energy(3 * u, 3 * v, kernel="r2logr2") / tps_bending_energy(u, v, kernel="r2logr2")
    assert ratio != pytest.approx(3.0, rel=1e-3)


def test_3d_tps_bending_energy_equals_8pi_times_the_integral_of_second_derivatives(rng):
    """∫ Σ_ij (∂_i∂_j f)² over R³ = 8π tr(DᵀBD) for U = −r (independent quadrature).

    The interpolant is f(x) = Σ_a w_a U(|x − u_a|) + affine with w = B D (checked to
    interpolate). Its Hessian is Σ_a w_a H_a, H_a = −(I − n nᵀ)/r_a (n, r_a: direction and
    distance from u_a): singular like 1/r at the landmarks, decaying like r⁻³ far away (the side
    conditions cancel the monopole and dipole terms). The integral is split with the partition
    of unity φ_a = r_a⁻⁴ / Σ_b r_b⁻⁴ and each ∫ φ_a F is done in spherical coordinates centred on
    u_a (the r² Jacobian removes the 1/r² singularity; φ_a damps the other landmarks'), with
    Gauss–Legendre in r = t/(1 − t) on t ∈ (0, 1) (all of R³, no truncation), in cos θ, and the
    midpoint rule in φ.
    """
    k = 6
    u = rng.uniform(-1, 1, size=(k, 3))
    v = u + 0.2 * rng.normal(size=u.shape)
    dsp = v - u
    b = tps_bending_matrix(u)
    w = b @ dsp
    # w are the interpolant's kernel weights: v − u − K w is affine in u and Pᵀ w = 0
    p = np.hstack([np.ones((k, 1)), u])
    resid = dsp - tps_kernel(np.linalg.norm(u[:, None] - u, axis=-1), kernel="r") @ w
    coef = np.linalg.lstsq(p, resid, rcond=None)[0]
    assert np.allclose(p @ coef, resid, atol=1e-10)
    assert np.allclose(p.T @ w, 0, atol=1e-10)

    def integrand(x):  # Σ_coord Σ_ij (∂_i∂_j f_coord)², x of shape (..., 3)
        hess = 0.0
        for ua, wa in zip(u, w):
            d = x - ua
            r = np.linalg.norm(d, axis=-1)[..., None, None]
            n = d[..., :, None] * d[..., None, :] / r**2
            ha = -(np.eye(3) - n) / r
            hess = hess + wa[:, None, None] * ha[..., None, :, :]
        return np.sum(hess**2, axis=(-3, -2, -1))

    nr, nt, nphi = 48, 32, 64
    t, wt = np.polynomial.legendre.leggauss(nr)
    t, wt = (t + 1) / 2, wt / 2
    r = t / (1 - t)
    wr = wt / (1 - t) ** 2 * r**2
    ct, wct = np.polynomial.legendre.leggauss(nt)
    phi = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    st = np.sqrt(1 - ct**2)
    dirs = np.stack([st[:, None] * np.cos(phi), st[:, None] * np.sin(phi), np.repeat(ct[:, None], nphi, 1)], -1)
    weights = wr[:, None, None] * wct[None, :, None] * (2 * np.pi / nphi)
    total = 0.0
    for a in range(k):
        x = u[a] + r[:, None, None, None] * dirs  # (nr, nt, nphi, 3)
        g = np.linalg.norm(x[..., None, :] - u, axis=-1) ** -4.0
        total += np.sum(weights * g[..., a] / g.sum(-1) * integrand(x))
    assert total == pytest.approx(8 * np.pi * tps_bending_energy(u, v), rel=1e-4)
    # the energy of the other sign convention/kernel is not what the integral measures
    assert total != pytest.approx(8 * np.pi * tps_bending_energy(u, v, kernel="r2logr2"), rel=1e-2)


def test_wendland_unchanged_in_3d(pair3):
    """The Wendland energy is still ψ₃,₁ with the diameter as support (no TPS kernel involved)."""
    u, v = pair3
    dist = np.linalg.norm(u[:, None] - u, axis=-1)
    kmat = wendland_psi31(dist / dist.max())
    dsp = v - u
    assert wendland_bending_energy(u, v, affine=False) == pytest.approx(np.trace(dsp.T @ np.linalg.solve(kmat, dsp)), rel=1e-10)
    assert wendland_bending_energy(u, v) != pytest.approx(tps_bending_energy(u, v), rel=1e-3)


@pytest.mark.filterwarnings("ignore::shapelib.PoseWarning")  # the far point is a pose difference too
def test_hausdorff_takes_the_larger_of_the_two_directed_distances():
    """One far point of v: v → u is 8 (10 to 2), u → v is 1 (2 to 1); the distance is 8 both ways."""
    u = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    v = np.array([[0.0, 0.0], [1.0, 0.0], [10.0, 0.0]])
    assert directed_hausdorff(u, v)[0] == 1.0 and directed_hausdorff(v, u)[0] == 8.0
    assert hausdorff_distance(u, v) == 8.0 and hausdorff_distance(v, u) == 8.0


def test_hausdorff_of_unaligned_shapes_warns_naming_it():
    import shapelib as sl

    u = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.5], [0.2, 0.9]])
    with pytest.warns(sl.PoseWarning, match=r"\bhausdorff\b"):
        hausdorff_distance(u, u @ np.array([[0.0, -1.0], [1.0, 0.0]]).T)


def test_kernel_values_off_the_special_points():
    """U(3) = 9 log 9 (r² log r², not r² log 2r, which agrees at r = 2), also for integer input;
    ψ₃,₁(r) = (1 − r)⁴ (4r + 1) inside the support: ψ(½) = 3/16, ψ(0.9) = 1e-4 · 4.6, 0 from r = 1."""
    assert tps_kernel(np.array([3.0]))[0] == pytest.approx(9 * np.log(9), rel=1e-15)
    assert tps_kernel(np.array([3]))[0] == pytest.approx(9 * np.log(9), rel=1e-15)
    np.testing.assert_allclose(wendland_psi31(np.array([0.5, 0.9, 1.0, 1.5])), [3 / 16, 4.6e-4, 0.0, 0.0],
                               rtol=1e-12, atol=0)


def test_wendland_energy_scales_with_the_support_and_names_its_errors(pair):
    """ψ(|u_a − u_b| / a) is unchanged when u, v and the support scale together by s, the affine
    side conditions too (P's columns scale), and D = v − u scales by s: E(su, sv; sa) = s² E(u, v; a)
    (here a = 1 and 2); and the errors say what is wrong."""
    u, v = pair
    e1 = wendland_bending_energy(u, v, support=1.0)
    assert wendland_bending_energy(2 * u, 2 * v, support=2.0) == pytest.approx(4 * e1, rel=1e-9)
    assert e1 != pytest.approx(wendland_bending_energy(u, v), rel=1e-3)
    with pytest.raises(ValueError, match=r"^support\b"):
        wendland_bending_energy(u, v, support=-1.0)
    with pytest.raises(ValueError, match=r"^support radius is zero \(a single landmark\); pass support=\.\.\.$"):
        wendland_bending_energy([[0.0, 0.0]], [[1.0, 0.0]], affine=False)


def test_plain_wendland_warns_about_pose_in_its_own_name(pair):
    """affine=False keeps the affine part in the energy, so a rotated copy warns, naming the metric;
    affine=True (the affine part free) does not."""
    u, v = pair
    c, s = np.cos(0.5), np.sin(0.5)
    rot = (v - v.mean(0)) @ np.array([[c, -s], [s, c]]).T + 3.0
    with pytest.warns(PoseWarning, match=r"^wendland \(affine=False\) depends on the pose of the shapes"):
        wendland_bending_energy(u, rot, affine=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PoseWarning)
        wendland_bending_energy(u, rot)


def test_spline_errors_name_the_landmarks_and_the_fix():
    u = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    with pytest.raises(InputError, match=r"^u has coincident landmarks 1 and 3: a spline cannot interpolate them$") as exc:
        tps_bending_energy(u, u)
    assert exc.value.facts == {"landmarks": (1, 3)}
    with pytest.raises(ValueError, match=r"^u must be a 2-D array"):
        tps_bending_matrix(np.zeros(3))
    with pytest.raises(ValueError, match=r"^the landmarks are degenerate \(collinear in 2-D, coplanar in 3-D, or "
                                         r"coincident\): the spline system is singular$"):
        tps_bending_matrix(np.array([[0.0, 0], [1, 0], [2, 0], [3, 0]]))
    with pytest.raises(ValueError, match=r"^no default thin-plate kernel for 4-D landmarks \(defaults: 'r2logr2' in "
                                         r"2-D, 'r' in 3-D\); pass kernel= one of 'r2logr2', 'r2logr', 'r'$"):
        tps_bending_matrix(np.eye(6, 4))
