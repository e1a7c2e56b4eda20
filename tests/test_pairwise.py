"""The pairwise engine (shapelib.pairwise): block layout, the zarr store, resume, mismatch and corruption.

Everything here runs in this process except the LocalCluster tests; the fault-injection tests with
separate processes are in test_pairwise_faults.py (and, like the LocalCluster test that stops a run
by its callback, in `make test-processes`).
"""

import json
from pathlib import Path

import numpy as np
import pytest
import zarr

from shapelib.distances import pair_record
from shapelib.pairwise import pairwise_distances
from shapelib.pairwise import block_pairs, compute_pairwise, default_block_size, open_store


@pytest.fixture
def shapes(rng):
    base = np.array([[0.0, 0.0], [1.0, 0.1], [2.0, 0.0], [1.0, -0.9], [0.5, 0.6]])
    return np.stack([base + 0.15 * rng.normal(size=base.shape) for _ in range(7)])


def _direct(x, metric, **kw):
    """Independent computation: pair_record on every ordered pair."""
    n = len(x)
    return np.array([[0.0 if i == j else pair_record(x[i], x[j], metric=metric, **kw)["value"]
                      for j in range(n)] for i in range(n)])


@pytest.mark.parametrize("metric", ["procrustes", "tps"])
@pytest.mark.parametrize("block_size", [1, 3, 7])
def test_every_pair_lands_in_its_place(shapes, metric, block_size):
    """N = 7 is not a multiple of 3: edge blocks are ragged. tps is asymmetric: [i, j] = map i -> j."""
    r = compute_pairwise(shapes, metric=metric, n_jobs=1, block_size=block_size, progress=False)
    np.testing.assert_allclose(r.matrix, _direct(shapes, metric), rtol=1e-13, atol=1e-15)
    assert np.all(np.diag(r.matrix) == 0) and r.complete
    if metric == "procrustes":
        assert np.array_equal(r.matrix, r.matrix.T)
        assert len(r.to_frame()) == 21
    else:
        assert not np.allclose(r.matrix, r.matrix.T)
        assert len(r.to_frame()) == 42
    assert r.converged.all() and np.all(r.n_iter == 0)


def test_block_layout():
    assert block_pairs(7, 3, symmetric=True) == [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    assert len(block_pairs(7, 3, symmetric=False)) == 9
    # a cheap pair gets large blocks, a slow one single pairs; enough tasks for every worker
    assert default_block_size(1e-4, 647) == 141
    assert default_block_size(1.2, 647) == 1
    b = default_block_size(1e-4, 100, n_workers=2)
    nb = -(-100 // b)
    assert nb * (nb + 1) // 2 >= 8


def test_bounds_bracket_the_path_lengths(shapes):
    r = pairwise_distances(shapes[:5], metric="alpha", sigma2=0.5, n_steps=4, n_jobs=1, return_result=True,
                           progress=False)
    bound = pairwise_distances(shapes[:5], metric="alpha_bound", sigma2=0.5, n_jobs=1, progress=False)
    np.testing.assert_allclose(r.lower, bound, rtol=1e-12, atol=1e-15)
    assert np.all(r.lower <= r.upper) and np.array_equal(r.upper, r.matrix)
    off = ~np.eye(5, dtype=bool)
    assert np.all(r.energy[off] >= r.upper[off] ** 2 * (1 - 1e-9))
    assert np.all(r.n_iter[off] > 0) and np.all(r.seconds[off] > 0)
    frame = r.to_frame()
    assert list(frame.columns) == ["i", "j", "value", "lower", "upper", "rel_gap", "energy", "converged", "status",
                                   "n_iter", "seconds"]
    assert (frame.i < frame.j).all() and len(frame) == 10
    fr = pairwise_distances(shapes[:4], metric="fisher_rao_bound", sigma2=0.5, n_jobs=1, progress=False)
    assert np.array_equal(fr, fr.T) and np.all(fr[~np.eye(4, dtype=bool)] > 0)


def test_store_records_the_computation_and_resumes_only_missing_blocks(shapes, tmp_path):
    path = tmp_path / "D.zarr"
    first = compute_pairwise(shapes, metric="alpha", sigma2=0.5, n_steps=4, n_jobs=1, block_size=2,
                             store=path, progress=False)
    attrs = zarr.open_group(str(path), mode="r").attrs["shapelib_pairwise"]
    assert attrs["metric"] == "alpha" and attrs["N"] == 7 and attrs["block_size"] == 2
    assert attrs["params"]["sigma2"] == 0.5 and attrs["params"]["n_steps"] == 4 and attrs["params"]["tol"] == 1e-6
    assert len(attrs["shapes_sha256"]) == 64 and attrs["shapelib_version"]
    assert first.log["blocks_computed"] == 10 and first.store == str(path)

    # forget two blocks as an interrupted run would have, then resume: only those two are computed
    done = zarr.open_array(str(path / "done"), mode="r+")
    done[0, 3] = done[3, 0] = False
    done[2, 2] = False
    again = compute_pairwise(shapes, metric="alpha", sigma2=0.5, n_steps=4, n_jobs=1, store=path, progress=False)
    assert again.log["blocks_found_done"] == 8 and again.log["blocks_computed"] == 2
    np.testing.assert_allclose(again.matrix, first.matrix, rtol=1e-12)
    kept = np.ones((7, 7), bool)
    kept[0:2, 6:7] = kept[6:7, 0:2] = kept[4:6, 4:6] = False
    assert np.array_equal(again.seconds[kept], first.seconds[kept])  # the done blocks were not recomputed
    assert not np.array_equal(again.seconds[~kept], first.seconds[~kept])

    # a finished store: nothing to do (defaults spelled out are the same parameters)
    third = compute_pairwise(shapes, metric="alpha", sigma2=0.5, n_steps=4, tol=1e-6, n_jobs=1, store=path,
                             progress=False)
    assert third.log["blocks_computed"] == 0
    reread = open_store(path)
    assert reread.complete and reread.metric == "alpha" and reread.params["n_steps"] == 4
    assert np.array_equal(reread.matrix, again.matrix)


def test_partial_store_reads_as_partial(shapes, tmp_path):
    path = tmp_path / "D.zarr"
    compute_pairwise(shapes, metric="procrustes", n_jobs=1, block_size=3, store=path, progress=False)
    zarr.open_array(str(path / "done"), mode="r+")[1, 2] = False
    r = open_store(path)
    assert not r.complete and r.log["blocks_done"] == 5
    assert not r.computed[3:6, 6:7].any() and r.computed[0:3, 3:6].all()


def test_reopening_with_other_shapes_or_parameters_is_an_error(shapes, tmp_path):
    path = tmp_path / "D.zarr"
    compute_pairwise(shapes, metric="alpha_bound", sigma2=0.5, n_jobs=1, store=path, progress=False)
    with pytest.raises(ValueError, match=r"other parameters \(sigma2: stored 0.5, given 1.0\)"):
        compute_pairwise(shapes, metric="alpha_bound", sigma2=1.0, n_jobs=1, store=path, progress=False)
    other = shapes.copy()
    other[3, 2, 0] += 1e-9
    with pytest.raises(ValueError, match="shapes \\(SHA-256\\)"):
        compute_pairwise(other, metric="alpha_bound", sigma2=0.5, n_jobs=1, store=path, progress=False)
    with pytest.raises(ValueError, match="number of shapes 7, not 6"):
        compute_pairwise(shapes[:6], metric="alpha_bound", sigma2=0.5, n_jobs=1, store=path, progress=False)
    with pytest.raises(ValueError, match="metric 'alpha_bound', not 'procrustes'"):
        compute_pairwise(shapes, metric="procrustes", n_jobs=1, store=path, progress=False)
    with pytest.raises(ValueError, match="block_size"):
        compute_pairwise(shapes, metric="alpha_bound", sigma2=0.5, n_jobs=1, store=path, block_size=5,
                         progress=False)
    (tmp_path / "notastore").mkdir()
    (tmp_path / "notastore" / "x.txt").write_text("keep me")
    with pytest.raises(ValueError, match="not a pairwise store"):
        compute_pairwise(shapes, metric="procrustes", n_jobs=1, store=tmp_path / "notastore", progress=False)
    assert (tmp_path / "notastore" / "x.txt").read_text() == "keep me"


def test_bad_arguments_are_named(shapes):
    with pytest.raises(ValueError, match="n_jobs"):
        compute_pairwise(shapes, metric="procrustes", n_jobs=0, progress=False)
    with pytest.raises(ValueError, match="block_size"):
        compute_pairwise(shapes, metric="procrustes", n_jobs=1, block_size=0, progress=False)
    with pytest.raises(ValueError, match="client or scheduler, not both"):
        compute_pairwise(shapes, metric="procrustes", client=object(), scheduler="tcp://127.0.0.1:1")
    with pytest.raises(ValueError, match="has no parameter"):
        compute_pairwise(shapes, metric="hausdorff", sigma2=1.0, progress=False)
    with pytest.raises(ValueError, match="cannot be recorded"):
        compute_pairwise(shapes, metric="alpha", sigma2=0.5, init=np.zeros(3), n_jobs=1, store=None,
                         progress=False)


def _chunk_files(path, name):
    return sorted(p for p in (Path(path) / name / "c").rglob("*") if p.is_file())


@pytest.mark.parametrize("damage", ["truncate", "overwrite", "delete"])
def test_corrupt_or_truncated_store_is_named(shapes, tmp_path, damage):
    path = tmp_path / "D.zarr"
    compute_pairwise(shapes, metric="tps", n_jobs=1, block_size=4, store=path, progress=False)
    chunk = _chunk_files(path, "upper")[0]
    data = chunk.read_bytes()
    if damage == "truncate":
        chunk.write_bytes(data[: len(data) // 2])
    elif damage == "overwrite":
        chunk.write_bytes(data[:10] + bytes([data[10] ^ 0xFF]) + data[11:])
    else:
        chunk.unlink()
    zarr.open_array(str(path / "done"), mode="r+")[1, 1] = False  # one block left to do on resume
    resumed = []

    def resume():
        resumed.append(compute_pairwise(shapes, metric="tps", n_jobs=1, store=path, progress=False))

    for call in (lambda: open_store(path), resume):
        with pytest.raises(ValueError) as err:
            call()
        msg = str(err.value)
        assert str(path) in msg and "'upper'" in msg and "upper/c/0/0" in msg, msg
    assert not resumed
    assert zarr.open_array(str(path / "done"), mode="r")[1, 1] == False  # noqa: E712 - refused before any work


def test_damaged_metadata_and_done_mask_are_named(shapes, tmp_path):
    path = tmp_path / "D.zarr"
    compute_pairwise(shapes, metric="procrustes", n_jobs=1, block_size=4, store=path, progress=False)
    done_chunk = _chunk_files(path, "done")[0]
    done_chunk.write_bytes(done_chunk.read_bytes()[:-3])
    with pytest.raises(ValueError, match=r"array 'done' is corrupt or truncated \(chunk done/c/0/0"):
        open_store(path)
    meta = json.loads((path / "zarr.json").read_text())
    (path / "zarr.json").write_text(json.dumps(meta)[:40])
    with pytest.raises(ValueError, match=f"pairwise store {path}: unreadable group metadata"):
        open_store(path)
    (path / "zarr.json").unlink()
    with pytest.raises(ValueError, match="no zarr.json"):
        open_store(path)


@pytest.mark.processes
def test_local_cluster_equals_serial_stops_on_the_callback_and_leaves_no_process(rng, tmp_path):
    import psutil

    base = np.array([[0.0, 0.0], [1.0, 0.1], [2.0, 0.0], [1.0, -0.9], [0.5, 0.6]])
    x = np.stack([base + 0.15 * rng.normal(size=base.shape) for _ in range(14)])
    # 105 one-pair blocks: more than the engine keeps in flight at once (64), so submission refills
    serial = compute_pairwise(x, metric="alpha", sigma2=0.5, n_steps=4, n_jobs=1, block_size=1, progress=False)
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    seen = []

    def stop_at_100(progress):
        seen.append(progress)
        return progress.blocks_computed == 100

    path = tmp_path / "D.zarr"
    par = compute_pairwise(x, metric="alpha", sigma2=0.5, n_steps=4, n_jobs=2, block_size=1, progress=False,
                           store=path, callback=stop_at_100)
    assert par.log["mode"] == "LocalCluster(2 processes)" and par.log["stopped"]
    # stopped right after the 100th block: the tasks still running were cancelled, never written
    assert par.log["blocks_computed"] == 100 and open_store(path).log["blocks_done"] == 100 and not par.complete
    assert [p.blocks_computed for p in seen] == list(range(1, 101))
    last = seen[-1]
    assert (last.blocks_done, last.blocks_total, last.pairs_total) == (100, 105, 91)
    assert last.pairs_done == int(par.computed[np.triu_indices(14, 1)].sum())
    assert par.computed[last.rows.start, last.cols.start]
    rest = compute_pairwise(x, metric="alpha", sigma2=0.5, n_steps=4, n_jobs=1, store=path, progress=False)
    assert rest.log["blocks_found_done"] == 100 and rest.log["blocks_computed"] == 5 and rest.complete
    for name in ("matrix", "lower", "upper", "energy", "converged", "n_iter"):
        np.testing.assert_array_equal(getattr(rest, name), getattr(serial, name), err_msg=name)
    # (Python's multiprocessing resource tracker is one per parent process and not the cluster's)
    after = {p.pid for p in psutil.Process().children(recursive=True) if p.is_running()
             and p.status() != psutil.STATUS_ZOMBIE and "resource_tracker" not in " ".join(p.cmdline())}
    assert after <= before, "the LocalCluster left worker processes behind"


def test_a_callback_stops_an_in_process_run_and_the_store_resumes(shapes, tmp_path):
    path = tmp_path / "D.zarr"
    with pytest.warns(UserWarning, match=r"stopped the run after 2 of 16 blocks.*NaN.*resume"):
        partial = pairwise_distances(shapes, metric="tps", n_jobs=1, block_size=2, store=path, progress=False,
                                     callback=lambda p: p.blocks_computed == 2)
    first_two = np.zeros((7, 7), bool)
    first_two[0:2, 0:4] = True  # blocks (0, 0) and (0, 1) of an asymmetric metric: every block is a task
    assert np.array_equal(np.isfinite(partial), first_two)
    full = compute_pairwise(shapes, metric="tps", n_jobs=1, store=path, progress=False,
                            callback=lambda p: False)
    assert full.complete and full.log["blocks_found_done"] == 2 and not full.log["stopped"]
    np.testing.assert_array_equal(full.matrix[first_two], partial[first_two])
    np.testing.assert_allclose(full.matrix, _direct(shapes, "tps"), rtol=1e-13, atol=1e-15)
    with pytest.raises(ValueError, match="callback must be callable"):
        compute_pairwise(shapes, metric="tps", n_jobs=1, progress=False, callback=3)


def test_store_of_a_non_path_metric_spanning_several_chunks_reopens(rng, tmp_path):
    # its ``energy`` array stays all NaN (the fill value); zarr skips writing such chunks unless
    # told otherwise, and a done block whose chunk file is missing reads as truncated
    from shapelib.pairwise import CHUNK_SIDE

    x = rng.normal(size=(CHUNK_SIDE + 20, 6, 2))
    path = tmp_path / "h.zarr"
    first = pairwise_distances(x, metric="hausdorff", n_jobs=1, store=path, block_size=16, progress=False,
                               return_result=True)
    again = open_store(path)
    assert again.computed[~np.eye(len(x), dtype=bool)].all()
    np.testing.assert_array_equal(again.matrix, first.matrix)
    assert np.isnan(again.energy[~np.eye(len(x), dtype=bool)]).all()  # not applicable, not 0


#: a fresh process: a registered metric that is the Fisher–Rao bound and notes when each call
#: starts and ends; the engine sizes the blocks of a run from its timing of a pair
FRESH = """
import json, time
import numpy as np
from shapelib.distances import register_metric
from shapelib.solver.geodesic import fisher_rao_lower_bound
from shapelib.pairwise import compute_pairwise
calls = []
def timed_bound(u, v, **kw):
    t0 = time.perf_counter()
    out = fisher_rao_lower_bound(u, v, **kw)
    calls.append((t0, time.perf_counter()))
    return out
register_metric("timed_bound", timed_bound)
rng = np.random.default_rng(0)
t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
x = np.stack([np.c_[10 * np.cos(t), 5 * np.sin(t)] + rng.normal(size=(30, 2)) for _ in range(4)])
r = compute_pairwise(x, metric="timed_bound", sigma2=1.0, n_jobs=1, progress=False)
print(json.dumps({"estimate": r.log["seconds_per_pair_estimate"], "calls": calls, "pairs": 6}))
"""


def test_blocks_are_sized_from_a_warm_pair_not_the_first_call_in_a_process():
    """The first call in a process also pays one-off costs (compiled kernels, quadrature grids),
    far above a pair's cost; sizing blocks from it gave the 647-shape Fisher–Rao bound matrix of
    the population study blocks of 2 shapes (52,650 tasks, the client busy writing them). In a
    fresh process, the estimate must come from a later call: it is no longer than the time
    between the end of the first call and the start of the third (which contains the second call
    and the engine's own bookkeeping only). No clock threshold: the order of the calls decides."""
    import subprocess
    import sys

    from tests.conftest import ROOT

    out = subprocess.run([sys.executable, "-c", FRESH], cwd=ROOT, capture_output=True, text=True, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    calls = got["calls"]
    assert len(calls) >= 2 + got["pairs"], calls  # the timing pair was called at least twice, then every pair
    (_, first_end), (second_start, _), (third_start, _) = calls[:3]
    assert 0 < got["estimate"] <= third_start - first_end


def test_local_cluster_workers_get_the_malloc_settings():
    """Dask's nanny exports MALLOC_TRIM_THRESHOLD_=65536, which freezes glibc's mmap threshold and
    made Fisher–Rao bounds 2.4x slower in the workers; the engine's cluster overrides both."""
    import os

    from distributed import Client

    from shapelib.pairwise import WORKER_ENVIRON, local_cluster

    with pytest.raises(ValueError, match="n_workers"):
        local_cluster(0)
    with local_cluster(1) as cluster, Client(cluster) as client:
        (env,) = client.run(lambda: {k: os.environ.get(k) for k in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")}
                            ).values()
    assert env == {key.rsplit(".", 1)[1]: str(value) for key, value in WORKER_ENVIRON.items()}


def test_a_rejected_pair_is_named_in_process_and_through_dask(rng):
    """A metric's input error reaches the caller as a PairError naming the pair (row i = u,
    column j = v), in process and from a real worker process (pickled through Dask)."""
    from distributed import Client

    from shapelib.pairwise import PairError, local_cluster

    base = np.array([[0.0, 0.0], [1.0, 0.1], [2.0, 0.0], [1.0, -0.9], [0.5, 0.6]])
    x = np.stack([base + 0.1 * rng.normal(size=base.shape) for _ in range(5)])
    x[3, 2] = x[3, 1]  # shape 3 has coincident landmarks: no spline from it
    with pytest.raises(PairError) as serial:
        compute_pairwise(x, metric="tps", n_jobs=1, block_size=2, progress=False)
    with local_cluster(1) as cluster, Client(cluster) as client:
        with pytest.raises(PairError) as dask:
            compute_pairwise(x, metric="tps", client=client, block_size=2, progress=False)
    for err in (serial.value, dask.value):
        assert err.i == 3 and err.j != 3 and isinstance(err, ValueError)
        assert "u has coincident landmarks 1 and 2" in err.reason
        assert str(err).startswith(f"pair (shapes[3], shapes[{err.j}]) as (u, v): ")
