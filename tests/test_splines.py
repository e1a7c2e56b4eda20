import numpy as np
import pytest
from scipy.spatial.distance import directed_hausdorff

from shapelib.splines import (
    hausdorff_distance,
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
    with pytest.raises(ValueError, match="kernel"):
        tps_kernel(np.array([1.0]), kernel="gauss")


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
