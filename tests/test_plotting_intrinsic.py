"""Deformation pictures (shapelib.plotting): shapes along a geodesic, the extrinsic-warp grid of a
magnified geodesic, modes and group means; real figures written to disk."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import shapelib  # noqa: E402
from shapelib import plotting  # noqa: E402
from shapelib.statistics.group import mean_difference_test  # noqa: E402
from shapelib.statistics.tangent_pca import tangent_pca  # noqa: E402
from tests.conftest import ellipse




@pytest.fixture(scope="module")
def test_result():
    rng = np.random.default_rng(5)
    base = ellipse(12)
    stretch = np.column_stack([0.2 * base[:, 0], np.zeros(12)])
    x = shapelib.pose_align(np.stack([base + (i >= 8) * stretch + 0.1 * rng.normal(size=base.shape)
                                      for i in range(16)]))[0]
    return mean_difference_test(x, [0] * 8 + [1] * 8, sigma2=1.0, n_permutations=99, geodesic_steps=8, n_jobs=1), x


def test_deformation_grid_follows_the_magnified_geodesic(test_result):
    res, _ = test_result
    grid, warped, end = plotting.deformation_grid(res.geodesic, mag=1.0, n_lines=9, points_per_line=30)
    assert grid.shape == warped.shape and grid.shape[1:] == (30, 2)
    assert np.allclose(end, res.geodesic.path[-1])
    # the warp moves the plane with the shape: points near the landmarks move like them
    _, warped3, end3 = plotting.deformation_grid(res.geodesic, mag=3.0, n_lines=9, points_per_line=30)
    move1 = np.abs(warped - grid).max()
    move3 = np.abs(warped3 - grid).max()
    assert 0 < move1 < move3
    assert np.abs(end3 - res.geodesic.path[0]).max() > 2 * np.abs(end - res.geodesic.path[0]).max()


def test_figures_are_drawn(test_result, tmp_path):
    res, x = test_result
    fig = plotting.plot_mean_difference(res, mag=2.0, n_lines=9)
    fig.savefig(tmp_path / "difference.png")
    assert len(fig.axes) == 2
    pca = tangent_pca(x, mean=res.pooled, modes=(0, 1), sd=(-2, 0, 2), n_jobs=1)
    fig = plotting.plot_modes(pca, components=(0, 1), sd=(-2, 0, 2))
    fig.savefig(tmp_path / "modes.png")
    assert len(fig.axes) == 6
    fig = plotting.plot_modes(pca, components=(0,), sd=(-2, 2), closed=None)  # landmarks without an outline
    assert all(line.get_linestyle() == "None" for line in fig.axes[0].lines)
    plt.close("all")
    assert (tmp_path / "difference.png").stat().st_size > 1000


def test_three_dimensional_shapes_are_drawn_but_have_no_plane_grid():
    rng = np.random.default_rng(1)
    t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    u = np.column_stack([3 * np.cos(t), 2 * np.sin(t), np.sin(2 * t)])
    geo = shapelib.geodesic(u, shapelib.procrustes_align(u, u + 0.3 * rng.normal(size=u.shape), scaling=False),
                            sigma2=1.0, n_steps=4)
    fig = plt.figure()
    plotting.plot_shapes_along(fig.add_subplot(projection="3d"), geo.path)
    plt.close(fig)
    with pytest.raises(ValueError, match="3-D"):
        plotting.deformation_grid(geo)
    no_geo = mean_difference_test(np.stack([u, 1.01 * u, 0.99 * u, 1.02 * u]), [0, 0, 1, 1], sigma2=1.0,
                                  n_permutations=19, group_means=False, n_jobs=1)
    with pytest.raises(ValueError, match="group_means=False"):
        plotting.plot_mean_difference(no_geo)
