"""A flat target — a plane in 3-D, a line in 2-D — against the support of the outlier component: the box
the uniform density lives on is one point spacing thick, not 1e-12."""

import warnings

import numpy as np

import shapelib as sl
from shapelib.pointsets._coherent_em import box_volume


def test_the_box_of_a_flat_target_is_one_spacing_thick():
    g = np.stack(np.meshgrid(np.arange(5.0), np.arange(4.0)), axis=-1).reshape(-1, 2) * 0.5  # spacing 0.5
    flat = np.column_stack([g, np.zeros(len(g))])
    assert box_volume(flat) == 2.0 * 1.5 * 0.5
    # a target that fills its box keeps the box: the floor only acts on a side shorter than the spacing
    rng = np.random.default_rng(0)
    full = rng.uniform(size=(200, 3)) * [2.0, 3.0, 1.0]
    assert box_volume(full) == np.prod(np.ptp(full, axis=0))
    line = np.column_stack([np.linspace(0, 2, 9), np.zeros(9)])
    assert box_volume(line) == 2.0 * 0.25


def test_a_planar_shape_in_3d_is_registered_and_trusted():
    # without the floor the uniform density swamps the Gaussians: every point unmatched, the fit wrong
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    x = np.column_stack([np.cos(t) * (1 + 0.3 * np.cos(3 * t)) + 0.25 * np.sin(2 * t), 0.6 * np.sin(t)])  # no mirror
    truth = x + 0.08 * np.column_stack([np.sin(2 * x[:, 1]), np.cos(1.5 * x[:, 0])])  # a smooth warp
    perm = np.random.default_rng(1).permutation(len(x))
    z0 = np.zeros((len(x), 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error", sl.RegistrationWarning)
        res = sl.register(np.hstack([x, z0]), np.hstack([truth, z0])[perm])
    assert res.reliable  # (it said "100 % of the source points match no target point")
    assert np.mean(np.linalg.norm(res.points[:, :2] - truth, axis=1)) < 0.05  # the benchmark's failure line
    np.testing.assert_allclose(res.points[:, 2], 0.0, atol=1e-9)
