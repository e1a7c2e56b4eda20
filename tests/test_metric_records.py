"""The metric record is all the engine knows about a metric: a batched ``block`` function, pose
dependence and an unchecked core, each honoured for a metric registered by the user exactly as
for shapelib's own; options and shapes checked once at the door."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from shapelib.distances import (_REGISTRY, POSE_DEPENDENT, check_metric_params, distance, metric_info, pair_record,
                                pose_dependent, register_metric)
from shapelib.geometry.procrustes import PoseWarning, procrustes_distance, procrustes_distance_unchecked
from shapelib.pairwise import PairError, compute_block, compute_pairwise

#: calls of :func:`_mean_landmark_block` (module level: in-process runs only read it)
BLOCK_CALLS = []


def _mean_landmark_gap(u, v, *, scale=1.0):
    """A user's metric: ``scale`` × the mean distance of corresponding landmarks."""
    return scale * float(np.mean(np.linalg.norm(np.asarray(u) - np.asarray(v), axis=-1)))


def _mean_landmark_block(rows, cols=None, *, scale=1.0, n_threads=None):
    """The same for every pair of two sets at once (the record's batched ``block``)."""
    BLOCK_CALLS.append((len(rows), None if cols is None else len(cols)))
    cols = rows if cols is None else cols
    diff = np.asarray(rows)[:, None] - np.asarray(cols)[None, :]
    return scale * np.linalg.norm(diff, axis=-1).mean(axis=-1)


@pytest.fixture
def user_metric():
    info = register_metric("mean_gap", _mean_landmark_gap, block=_mean_landmark_block, pose_dependent=True,
                           description="mean landmark gap")
    yield info
    _REGISTRY.pop("mean_gap", None)


@pytest.mark.filterwarnings("ignore::shapelib.geometry.procrustes.PoseWarning")
def test_a_registered_block_function_computes_the_matrix_in_one_call(rng, user_metric):
    x = rng.normal(size=(7, 5, 2))
    BLOCK_CALLS.clear()
    r = compute_pairwise(x, metric="mean_gap", scale=2.0, n_jobs=1, block_size=7, progress=False)
    assert BLOCK_CALLS and all(c == (7, None) for c in BLOCK_CALLS)  # the timing call and the one block
    want = np.array([[_mean_landmark_gap(a, b, scale=2.0) for b in x] for a in x])
    np.testing.assert_allclose(r.matrix, want, rtol=1e-13, atol=1e-15)
    assert r.converged.all() and (r.lower == r.matrix).all() and (r.upper == r.matrix).all()
    # blocks off the diagonal get rows and columns
    BLOCK_CALLS.clear()
    r3 = compute_pairwise(x, metric="mean_gap", scale=2.0, n_jobs=1, block_size=3, progress=False)
    assert (3, 3) in BLOCK_CALLS or (3, 1) in BLOCK_CALLS
    np.testing.assert_allclose(r3.matrix, want, rtol=1e-13, atol=1e-15)


@pytest.mark.filterwarnings("ignore::shapelib.geometry.procrustes.PoseWarning")
def test_a_metric_without_a_block_function_goes_pair_by_pair(rng):
    register_metric("mean_gap_pairs", _mean_landmark_gap)
    try:
        x = rng.normal(size=(5, 4, 2))
        BLOCK_CALLS.clear()
        r = compute_pairwise(x, metric="mean_gap_pairs", n_jobs=1, progress=False)
    finally:
        _REGISTRY.pop("mean_gap_pairs")
    assert not BLOCK_CALLS
    assert r.matrix[1, 3] == pytest.approx(_mean_landmark_gap(x[1], x[3]), rel=1e-15)


def test_pose_dependence_is_read_from_the_record(rng, user_metric):
    assert "mean_gap" in POSE_DEPENDENT and pose_dependent("mean_gap") and pose_dependent(user_metric)
    assert "procrustes" not in POSE_DEPENDENT and not pose_dependent("procrustes")
    assert not pose_dependent("wendland") and pose_dependent("wendland", {"affine": False})
    assert set(POSE_DEPENDENT) == {"alpha", "fisher_rao", "alpha_bound", "fisher_rao_bound", "diffeomorphism",
                                   "hausdorff", "mean_gap"}
    assert {n for n in ("alpha", "fisher_rao", "alpha_bound", "fisher_rao_bound", "mean_gap")
            if metric_info(n).quadrature} == {"fisher_rao", "fisher_rao_bound"}
    base = rng.normal(size=(6, 2))
    x = np.stack([base + 0.01 * rng.normal(size=base.shape) for _ in range(4)])
    t = np.pi / 2
    x[2] = x[2] @ np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]).T + 5.0  # one shape turned and moved
    with pytest.warns(PoseWarning):
        compute_pairwise(x, metric="mean_gap", n_jobs=1, progress=False)
    with pytest.raises(ValueError, match="pose_dependent must be a bool or callable"):
        register_metric("bad_pose", _mean_landmark_gap, pose_dependent="yes")


def test_the_unchecked_core_equals_the_checked_function(rng):
    u, v = rng.normal(size=(2, 50, 2))
    for kind in ("angle", "full", "partial"):
        assert procrustes_distance_unchecked(u, v, kind=kind) == procrustes_distance(u, v, kind=kind)
        assert metric_info("procrustes").record(u, v, kind=kind)["value"] == procrustes_distance(u, v, kind=kind)
    assert pair_record(u, v, metric="procrustes")["value"] == distance(u, v, metric="procrustes")
    with pytest.raises(ValueError, match="kind must be"):
        procrustes_distance_unchecked(u, v, kind="bogus")


def test_options_and_shapes_are_checked_once_at_each_door(rng):
    x = rng.normal(size=(4, 5, 2))
    with pytest.raises(ValueError, match=r"has no parameter\(s\) \['kernel'\]"):
        compute_block(x, x, diagonal=True, symmetric=True, metric="procrustes", rtol=None, params={"kernel": 1})
    bad = x.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match="rows"):
        compute_block(bad, x, diagonal=False, symmetric=True, metric="procrustes", rtol=None, params={})
    with pytest.raises(ValueError, match="needs"):
        check_metric_params("alpha", {})
    # a pair the metric itself rejects is still named
    y = x.copy()
    y[2] = 0.0  # all landmarks of shape 2 coincide: no Procrustes distance from it
    with pytest.raises(PairError) as err:
        compute_pairwise(y, metric="procrustes", n_jobs=1, progress=False)
    assert 2 in (err.value.i, err.value.j) and "zero centroid size" in err.value.reason


def test_the_bound_block_functions_are_the_matrices(rng):
    from shapelib.geometry.bound_matrices import (BLOCKS, alpha_bound_matrix, bound_block, fisher_rao_bound_matrix)

    x = rng.normal(size=(5, 6, 2)) * 0.5
    assert metric_info("alpha_bound").block is BLOCKS["alpha_bound"]
    assert metric_info("fisher_rao_bound").block is BLOCKS["fisher_rao_bound"]
    np.testing.assert_array_equal(BLOCKS["alpha_bound"](x, sigma2=0.5), alpha_bound_matrix(x, sigma2=0.5))
    np.testing.assert_array_equal(bound_block("fisher_rao_bound", x, sigma2=0.5),
                                  fisher_rao_bound_matrix(x, sigma2=0.5))
    # an independent computation of the α bound of one pair: the L² distance by cdist sums
    s2 = 0.5
    u, v = x[0], x[3]

    def overlap(a, b):
        return np.exp(-cdist(a, b, "sqeuclidean") / (4 * s2)).sum() / (4 * np.pi * s2) / len(a) ** 2

    want = np.sqrt(overlap(u, u) + overlap(v, v) - 2 * overlap(u, v))
    assert BLOCKS["alpha_bound"](x[:1], x[3:4], sigma2=s2)[0, 0] == pytest.approx(want, rel=1e-10)
