"""Point sets of different sizes through the pairwise engine, modulo the similarity group:
the same matrix in process, in a zarr store (resumed after a stop) and on a LocalCluster."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.pairwise import open_store


def _sets(n_sets=9):
    rng = np.random.default_rng(3)
    out = []
    for i in range(n_sets):
        n = 30 + 7 * (i % 4)  # sizes differ
        t = np.sort(rng.uniform(0, 2 * np.pi, n))
        r = 1 + 0.3 * np.cos((2 + i % 3) * t + rng.uniform(0, 6))
        pts = np.column_stack([(1.5 + 0.1 * i) * r * np.cos(t), r * np.sin(t)])
        c, s = np.cos(i), np.sin(i)
        out.append(3.0 * pts @ np.array([[c, -s], [s, c]]) + i)  # arbitrary pose
    return out


SETS = _sets()


def test_engine_equals_the_direct_matrix(tmp_path):
    direct = sl.invariant_distance_matrix(SETS, sigma2=0.02)
    D = sl.pairwise_distances(SETS, metric="alpha_bound", modulo="similarity", sigma2=0.02, n_jobs=1,
                              block_size=4, progress=False)
    np.testing.assert_allclose(D, direct, rtol=1e-9, atol=1e-12)
    fr = sl.pairwise_distances(SETS, metric="fisher_rao_bound", modulo="similarity", sigma2=0.02, n_jobs=1,
                               progress=False)
    np.testing.assert_allclose(fr, sl.invariant_distance_matrix(SETS, metric="fisher_rao_bound", sigma2=0.02),
                               rtol=1e-9, atol=1e-12)


def test_store_resumes_after_a_stop_and_checks_its_inputs(tmp_path):
    store = tmp_path / "pairs.zarr"
    calls = []
    partial = sl.pairwise_distances(SETS, metric="alpha_bound", modulo="similarity", sigma2=0.02, n_jobs=1,
                                    block_size=3, store=store, progress=False, return_result=True,
                                    callback=lambda p: calls.append(p) or len(calls) == 2)
    assert not partial.complete and partial.log["blocks_computed"] == 2
    full = sl.pairwise_distances(SETS, metric="alpha_bound", modulo="similarity", sigma2=0.02, n_jobs=1,
                                 store=store, progress=False, return_result=True)
    assert full.complete and full.log["blocks_found_done"] == 2 and full.log["blocks_computed"] == 4
    np.testing.assert_allclose(full.matrix, sl.invariant_distance_matrix(SETS, sigma2=0.02), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(open_store(store).matrix, full.matrix)
    with pytest.raises(ValueError, match="sigma2|param"):
        sl.pairwise_distances(SETS, metric="alpha_bound", modulo="similarity", sigma2=0.03, store=store, progress=False)
    with pytest.raises(ValueError, match="SHA-256|shapes"):
        sl.pairwise_distances(SETS[:-1] + [SETS[-1] + 1e-3 * np.arange(len(SETS[-1]))[:, None]], metric="alpha_bound",
                              modulo="similarity", sigma2=0.02, store=store, progress=False)


@pytest.mark.processes
def test_local_cluster_gives_the_same_matrix():
    D = sl.pairwise_distances(SETS, metric="alpha_bound", modulo="similarity", sigma2=0.02, n_jobs=2,
                              block_size=4, progress=False)
    np.testing.assert_allclose(D, sl.invariant_distance_matrix(SETS, sigma2=0.02), rtol=1e-9, atol=1e-12)


def test_point_set_errors():
    with pytest.raises(ValueError, match="modulo"):
        sl.pairwise_distances(SETS, metric="alpha_bound", modulo="affine", sigma2=0.02)
    with pytest.raises(ValueError, match="sigma2"):
        sl.pairwise_distances(SETS, metric="alpha_bound", modulo="similarity")
    with pytest.raises(ValueError, match="alpha_bound"):
        sl.pairwise_distances(SETS, metric="procrustes", modulo="similarity", sigma2=0.02)
    with pytest.raises(ValueError, match="planar"):
        sl.pairwise_distances([np.random.default_rng(0).normal(size=(10, 3))] * 2, metric="alpha_bound",
                              modulo="similarity", sigma2=0.02)
    with pytest.raises(ValueError, match="n_steps"):
        sl.pairwise_distances(SETS, metric="alpha_bound", modulo="similarity", sigma2=0.02, n_steps=3)
