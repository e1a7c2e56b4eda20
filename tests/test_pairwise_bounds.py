"""The pairwise engine computes the closed-form bounds as batched blocks
(shapelib.geometry.bound_matrices): same matrices and stores as pair by pair, in process and
through Dask, resumable, and still naming a bad pair."""

import numpy as np
import pytest
import zarr

from shapelib.distances import pair_record
from shapelib.pairwise import PairError, compute_block, compute_pairwise, open_store


#: the populations here are noisy copies of one random shape, at σ chosen for the identities tested
#: (small σ on purpose): the pose and scale advice of the per-pair entry points is not the subject
pytestmark = [pytest.mark.filterwarnings("ignore::shapelib.geometry.procrustes.PoseWarning"),
              pytest.mark.filterwarnings("ignore::shapelib.geometry.scale.ScaleWarning")]

def _shapes(rng, n=9, k=7, d=2):
    base = rng.normal(size=(k, d)) * 2
    return base + 0.2 * rng.normal(size=(n, k, d))


def _pair_by_pair(x, metric, **params):
    n = len(x)
    out = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            out[i, j] = out[j, i] = pair_record(x[i], x[j], metric=metric, **params)["value"]
    return out


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("metric, rtol", [("alpha_bound", 1e-12), ("fisher_rao_bound", 1e-7)])
def test_engine_bound_matrix_equals_pair_by_pair(rng, metric, rtol, d):
    x = _shapes(rng, n=6 if d == 3 else 9, d=d)
    params = {"sigma2": 0.5}
    if metric == "fisher_rao_bound" and d == 3:
        params["grid_spacing"] = 0.5  # the 3-D per-pair reference stays quick
    r = compute_pairwise(x, metric=metric, n_jobs=1, progress=False, **params)
    assert r.log["blocks_total"] == 1  # one batched call in process
    np.testing.assert_allclose(r.matrix, _pair_by_pair(x, metric, **params), rtol=rtol, atol=0)
    np.testing.assert_array_equal(r.lower, r.matrix)
    np.testing.assert_array_equal(r.upper, r.matrix)
    off = ~np.eye(len(x), dtype=bool)
    assert np.isnan(r.energy[off]).all() and np.all(np.diag(r.energy) == 0)
    assert r.converged.all() and np.all(r.n_iter == 0) and np.all(r.seconds[off] > 0)
    # one batched call: every pair is given the call's wall time over its pairs (a pair-by-pair
    # block times each pair on its own)
    assert np.unique(r.seconds[off]).size == 1


def test_batched_block_has_the_per_pair_block_format(rng):
    """compute_block's dict for a batched block equals the per-pair one in every array but the
    timing (diagonal and off-diagonal blocks)."""
    x = _shapes(rng, n=7)
    for diagonal, (xi, xj) in ((True, (x, x)), (False, (x[:3], x[3:]))):
        got = compute_block(xi, xj, diagonal=diagonal, symmetric=True, metric="alpha_bound", rtol=None,
                            params={"sigma2": 0.4})
        bi, bj = len(xi), len(xj)
        for a in range(bi):
            for b in range(bj):
                if diagonal and a == b:
                    continue
                rec = pair_record(xi[a], xj[b], metric="alpha_bound", sigma2=0.4)
                assert got["matrix"][a, b] == pytest.approx(rec["value"], rel=1e-12)
                assert np.isnan(got["energy"][a, b]) and got["converged"][a, b] and got["n_iter"][a, b] == 0
        if diagonal:
            assert np.all(np.diag(got["matrix"]) == 0) and np.all(np.diag(got["seconds"]) == 0)


def test_bound_store_resumes_and_blocks_assemble(rng, tmp_path):
    """Blocks of 4 shapes (several batched calls), a store, then a rerun that finds every block
    done: the same matrix as one batched call; the store's attributes as for any metric."""
    x = _shapes(rng, n=10)
    path = tmp_path / "fr.zarr"
    first = compute_pairwise(x, metric="fisher_rao_bound", sigma2=0.5, n_jobs=1, block_size=4, store=path,
                             progress=False)
    assert first.log["blocks_total"] == 6 and first.log["blocks_computed"] == 6
    whole = compute_pairwise(x, metric="fisher_rao_bound", sigma2=0.5, n_jobs=1, progress=False)
    np.testing.assert_allclose(first.matrix, whole.matrix, rtol=1e-9, atol=0)
    again = compute_pairwise(x, metric="fisher_rao_bound", sigma2=0.5, n_jobs=1, store=path, progress=False)
    assert again.log["blocks_computed"] == 0 and again.log["blocks_found_done"] == 6
    np.testing.assert_array_equal(open_store(path).matrix, first.matrix)
    attrs = zarr.open_group(str(path), mode="r").attrs["shapelib_pairwise"]
    assert attrs["metric"] == "fisher_rao_bound" and attrs["params"]["grid_spacing"] == 0.35


def test_bound_blocks_through_dask_equal_in_process(rng):
    """The engine's LocalCluster: each block one batched call in a single-threaded worker."""
    from distributed import Client

    from shapelib.pairwise import local_cluster

    x = _shapes(rng, n=8)
    serial = compute_pairwise(x, metric="alpha_bound", sigma2=0.5, n_jobs=1, progress=False).matrix
    with local_cluster(1) as cluster, Client(cluster) as client:
        r = compute_pairwise(x, metric="alpha_bound", sigma2=0.5, client=client, block_size=3, progress=False)
    assert r.log["blocks_total"] == 6
    np.testing.assert_allclose(r.matrix, serial, rtol=1e-12, atol=0)
    for a in range(0, 8, 3):  # each block one batched call: its pairs share the call's time per pair
        for b in range(a + 3, 8, 3):
            assert np.unique(r.seconds[a:a + 3, b:b + 3]).size == 1


def test_a_block_the_batched_call_rejects_goes_pair_by_pair_and_names_the_pair(rng):
    """Shapes thousands of units apart at a small σ: one grid over the block is refused, and so is
    the grid of the far pair — the PairError names it, as the per-pair engine always did."""
    x = _shapes(rng, n=4)
    x[3] += 4000.0
    with pytest.raises(PairError) as err:
        compute_pairwise(x, metric="fisher_rao_bound", sigma2=0.5, n_jobs=1, progress=False)
    assert err.value.j == 3 and "quadrature grid would have" in err.value.reason


def _half_alpha_bound(u, v, *, sigma2):
    """A user's replacement of "alpha_bound" (module level: it travels to Dask workers by name)."""
    from shapelib.geometry.gmm import l2_distance

    return 0.5 * l2_distance(u, v, sigma2=sigma2)


def test_a_bound_replaced_by_the_user_is_computed_by_the_users_function(rng):
    """The engine batches shapelib's own bounds only: a function registered in their place is
    what every pair of the matrix gets."""
    from shapelib.distances import _REGISTRY, register_metric

    x = _shapes(rng, n=6)
    own = compute_pairwise(x, metric="alpha_bound", sigma2=0.5, n_jobs=1, progress=False).matrix
    original = _REGISTRY["alpha_bound"]
    register_metric("alpha_bound", _half_alpha_bound, replace=True)
    try:
        r = compute_pairwise(x, metric="alpha_bound", sigma2=0.5, n_jobs=1, progress=False)
    finally:
        _REGISTRY["alpha_bound"] = original
    np.testing.assert_allclose(r.matrix, 0.5 * own, rtol=1e-12, atol=0)
    again = compute_pairwise(x, metric="alpha_bound", sigma2=0.5, n_jobs=1, progress=False).matrix
    np.testing.assert_array_equal(again, own)
