"""Parallel transport by the pole ladder: exact limits (flat space, transport to the same shape),
the geodesic's own velocity, the metric norm, pose equivariance and convergence in the steps."""

import numpy as np
import pytest

import shapelib as sl

S2 = 0.3
SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
WIDE = SQUARE * [1.3, 1.0] + [[0, 0], [0, 0.1], [0, 0], [0.1, 0]]
SHEAR = SQUARE + [[0, 0], [0, 0], [0.15, 0], [0.15, 0]]


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("d", [2, 3])
def test_one_landmark_lives_in_flat_space_where_transport_is_the_identity(d):
    rng = np.random.default_rng(d)
    a, b, v = rng.normal(size=(3, 1, d))
    np.testing.assert_allclose(sl.parallel_transport(a, v, b, sigma2=0.5), v, atol=1e-8)


def test_transport_to_the_same_shape_is_the_identity():
    v = sl.log_map(SQUARE, SHEAR, sigma2=S2)
    # exp then the reflection through the base itself then −log: v back, to the solvers' tolerance
    assert _rel(sl.parallel_transport(SQUARE, v, SQUARE, sigma2=S2, n_rungs=1), v) < 1e-4


def test_the_geodesic_velocity_is_transported_to_minus_the_reverse_log():
    # along the geodesic from a to b the velocity is parallel: Π log_a(b) = −log_b(a)
    u = sl.log_map(SQUARE, WIDE, sigma2=S2, n_steps=8)
    back = sl.log_map(WIDE, SQUARE, sigma2=S2, n_steps=8)
    w = sl.parallel_transport(SQUARE, u, WIDE, sigma2=S2)
    assert _rel(w, -back) < 0.01
    coarse = sl.parallel_transport(SQUARE, u, WIDE, sigma2=S2, n_rungs=1, n_steps=8)
    assert _rel(w, -back) < _rel(coarse, -back)


def test_the_fisher_rao_ladder_uses_the_fisher_rao_maps():
    a, b = np.array([[0, 0], [1, 0.0]]), np.array([[0, 0], [1.3, 0.3]])
    opts = dict(sigma2=S2, metric="fisher_rao", n_steps=4)
    u, back = sl.log_map(a, b, **opts), sl.log_map(b, a, **opts)
    w = sl.parallel_transport(a, u, b, n_rungs=1, **opts)
    assert _rel(w, -back) < 0.03  # the α ladder misses by 14 %


def test_the_metric_norm_is_kept_and_the_error_falls_with_the_steps():
    v = sl.log_map(SQUARE, SHEAR, sigma2=S2, n_steps=16)
    norm_a = sl.tangent_space(SQUARE, sigma2=S2).norm(v)
    fine = sl.parallel_transport(SQUARE, v, WIDE, sigma2=S2, n_rungs=4, n_steps=16)
    errors = []
    for n_steps in (4, 8):
        w = sl.parallel_transport(SQUARE, v, WIDE, sigma2=S2, n_rungs=4, n_steps=n_steps)
        assert sl.tangent_space(WIDE, sigma2=S2).norm(w) == pytest.approx(norm_a, rel=0.03)
        errors.append(_rel(w, fine))
    assert errors[1] < 0.6 * errors[0]  # first order in 1/n_steps, or better
    # it is not the identity: the vector turns with the tangent space
    assert _rel(fine, v) > 0.05


def test_transport_commutes_with_a_rigid_motion():
    rot = np.array([[0.6, -0.8], [0.8, 0.6]])
    v = sl.log_map(SQUARE, SHEAR, sigma2=S2)
    w = sl.parallel_transport(SQUARE, v, WIDE, sigma2=S2, n_rungs=2, n_steps=4)
    moved = sl.parallel_transport(SQUARE @ rot.T + [2, -1], v @ rot.T, WIDE @ rot.T + [2, -1], sigma2=S2,
                                  n_rungs=2, n_steps=4)
    np.testing.assert_allclose(moved, w @ rot.T, atol=1e-5)  # to the log maps' solver tolerance


@pytest.mark.parametrize("kwargs, match", [
    (dict(end=np.zeros((3, 2))), r"\bend\b"),
    (dict(vector=np.zeros((3, 2))), r"\bvector\b"),
    (dict(base=np.full((4, 2), np.nan)), r"\bbase\b"),
    (dict(n_rungs=0), r"\bn_rungs\b"),
    (dict(n_steps=1.5), r"\bn_steps\b"),
    (dict(metric="euclid"), "metric"),
])
def test_bad_input_names_the_parameter(kwargs, match):
    args = dict(base=SQUARE, vector=SHEAR - SQUARE, end=WIDE, metric="alpha", sigma2=S2)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        sl.parallel_transport(args.pop("base"), args.pop("vector"), args.pop("end"), **args)
