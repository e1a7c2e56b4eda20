"""Fault injection with real processes: a worker killed mid-task, a client killed mid-run, Ctrl-C.

The cluster is started the way users start one — ``dask scheduler`` and two ``dask worker``
command lines on 127.0.0.1 with OS-chosen ports — and every process is terminated (then killed)
in the fixtures' ``finally``. No fault races the work: the runs use the metric
``"gated_alpha"`` of ``tests/gated_metric.py`` (``"alpha"``, registered as a user registers a
metric, whose calls beyond the first ``free`` wait for a lock the test holds), so a kill or a
signal always lands after exactly ``free`` pairs are in the store and while every worker is
inside a pair, however fast or loaded the machine is. The test then releases the gate and the
resumed (or surviving) run must give the matrix of an uninterrupted ``"alpha"`` run.

These tests run in the default ``pytest`` run (marker ``processes``, to select or skip them:
``-m processes`` / ``-m "not processes"``).
"""

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

from shapelib.pairwise import _Store, block_pairs, compute_pairwise, open_store
from tests.conftest import ROOT, command_line, wait_for
from tests.gated_metric import Gate

pytestmark = pytest.mark.processes

#: options of the α geodesic (the pairs are cheap: the gate, not their cost, holds a run up)
PARAMS = dict(sigma2=0.3, n_steps=6)
N_SHAPES = 6
TOTAL = N_SHAPES * (N_SHAPES + 1) // 2  # upper-triangle blocks of size 1, diagonal included


def _shapes():
    rng = np.random.default_rng(7)
    t = np.linspace(0, 2 * np.pi, 20, endpoint=False)
    base = np.c_[2 * np.cos(t), np.sin(t)]
    return np.stack([base + 0.2 * rng.normal(size=base.shape) for _ in range(N_SHAPES)])


@pytest.fixture(scope="module")
def serial():
    """The uninterrupted reference: ``"alpha"`` itself, in this process."""
    return compute_pairwise(_shapes(), metric="alpha", n_jobs=1, block_size=1, progress=False, **PARAMS)


def _env():
    return {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
            "MKL_NUM_THREADS": "1"}


def _stop(procs):
    procs = procs[::-1]  # workers before their scheduler
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _pairs_done(path) -> int:
    """Off-diagonal blocks (one pair each) marked done in the store; 0 while it does not exist.
    Chunk files are replaced atomically by zarr, so reading during a run is safe."""
    try:
        return sum(a != b for a, b in _Store.open(path).task_done())
    except Exception:  # not there yet, or caught between two writes: ask again
        return 0


def _blocked(gate, store, *, free, waiting):
    """``free`` pairs are in the store and ``waiting`` calls wait at the gate: the run can go no further."""
    return lambda: gate.tickets() >= free + waiting and _pairs_done(store) >= free


def _same_as(result, serial):
    for name in ("matrix", "lower", "upper", "converged", "n_iter"):
        np.testing.assert_array_equal(getattr(result, name), getattr(serial, name), err_msg=name)


@pytest.fixture
def dask_cluster(tmp_path):
    """``dask scheduler`` + two ``dask worker --no-nanny`` processes (the worker pid is the process a
    kill -9 must hit; with a nanny it would be restarted behind our back)."""
    dask = [sys.executable, "-m", "dask"]
    sched_file = tmp_path / "scheduler.json"
    procs = []
    try:
        procs.append(subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                       "--scheduler-file", str(sched_file)], env=_env(),
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        wait_for(lambda: sched_file.is_file() and sched_file.stat().st_size > 0, "the scheduler's start")
        address = json.loads(sched_file.read_text())["address"]
        workers = [subprocess.Popen([*dask, "worker", address, "--nthreads", "1", "--no-nanny",
                                     "--no-dashboard", "--host", "127.0.0.1"], env=_env(),
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
        procs += workers
        yield address, workers
    finally:
        _stop(procs)


def test_killing_a_worker_mid_task_still_completes_the_matrix(dask_cluster, serial, tmp_path):
    from distributed import Client

    address, workers = dask_cluster
    store = tmp_path / "D.zarr"
    outcome = {}
    with Client(address, timeout="30s") as watcher, Gate(tmp_path / "gate") as gate:
        watcher.wait_for_workers(2, timeout=60)

        def run():
            try:
                outcome["result"] = compute_pairwise(_shapes(), scheduler=address, store=store, block_size=1,
                                                     progress=False, **PARAMS, **gate.params(free=2))
            except BaseException as exc:  # reported below
                outcome["error"] = exc

        thread = threading.Thread(target=run)
        thread.start()
        try:
            # two pairs done, then each single-threaded worker blocks inside a pair of its own
            wait_for(_blocked(gate, store, free=2, waiting=2), "two pairs done and both workers inside a pair")
            busy = [addr for addr, keys in watcher.processing().items() if keys]
            assert len(busy) == 2, watcher.processing()
            victim = workers[0].pid
            os.kill(victim, signal.SIGKILL)
            workers[0].wait(timeout=30)
            done_at_kill = _pairs_done(store)
            gate.release()  # the survivor, and the task the scheduler moves to it, go on
        finally:
            gate.release()
            thread.join(timeout=300)
        assert "error" not in outcome, outcome.get("error")
        result = outcome["result"]
        assert workers[0].returncode == -signal.SIGKILL and workers[1].poll() is None
        assert len(watcher.scheduler_info()["workers"]) == 1  # the run finished on the survivor
    assert done_at_kill == 2 and result.log["blocks_computed"] == TOTAL and result.complete
    _same_as(result, serial)


CLIENT = textwrap.dedent("""
    import sys
    import numpy as np
    import tests.gated_metric  # registers "gated_alpha", as a user's own module would
    from shapelib.pairwise import compute_pairwise
    x = np.load(sys.argv[1])
    compute_pairwise(x, n_jobs=1, block_size=1, store=sys.argv[2], progress=False, metric="gated_alpha",
                     gate=sys.argv[3], free=int(sys.argv[4]), sigma2=0.3, n_steps=6)
""")


def test_killing_the_client_mid_run_then_rerunning_resumes(serial, tmp_path):
    x = _shapes()
    np.save(tmp_path / "x.npy", x)
    store = tmp_path / "D.zarr"
    free = 8
    with Gate(tmp_path / "gate") as gate:
        proc = subprocess.Popen([sys.executable, "-c", CLIENT, str(tmp_path / "x.npy"), str(store), str(gate.path),
                                 str(free)], env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            wait_for(lambda: _blocked(gate, store, free=free, waiting=1)() or proc.poll() is not None,
                     f"{free} pairs done and the next one waiting")
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=30)
        finally:
            _stop([proc])
        assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()
        before = open_store(store)
        # in process the blocks go in order: every block before the first gated pair, and no other
        order = block_pairs(N_SHAPES, 1, symmetric=True)
        first_gated = [i for i, (a, b) in enumerate(order) if a != b][free]
        assert before.log["blocks_done"] == first_gated and not before.complete
        assert _Store.open(store).task_done() == set(order[:first_gated])
        gate.release()
        again = compute_pairwise(x, n_jobs=1, store=store, progress=False, **PARAMS, **gate.params(free=free))
    assert again.log["blocks_found_done"] == first_gated and again.log["blocks_computed"] == TOTAL - first_gated
    # the blocks finished before the kill were not recomputed: their timings are the stored ones
    kept = before.computed
    assert np.array_equal(again.seconds[kept], before.seconds[kept])
    _same_as(again, serial)


def _new_children(before):
    import psutil

    # (Python's multiprocessing resource tracker is one per parent process and not the cluster's)
    return [p for p in psutil.Process().children(recursive=True)
            if p.pid not in before and "resource_tracker" not in command_line(p)]


def test_ctrl_c_keeps_finished_blocks_and_stops_the_local_cluster(serial, tmp_path):
    import psutil

    store = tmp_path / "D.zarr"
    own = os.getpid()
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    seen = {}
    returned = threading.Event()
    with Gate(tmp_path / "gate") as gate:

        def interrupt():
            try:
                wait_for(_blocked(gate, store, free=2, waiting=2), "two pairs done and both workers inside a pair")
            except AssertionError as exc:
                seen["error"] = exc
                gate.release()  # a failure, not a run waiting forever at the gate
                return
            seen["workers"] = _new_children(before)
            os.kill(own, signal.SIGINT)  # as a Ctrl-C: to this process, while it waits for the blocked pairs
            # hang guard, like wait_for's deadline: a run the Ctrl-C did not stop would wait at the
            # gate forever; opened, it finishes and the test fails. A Ctrl-C that works stops the run
            # within POLL_SECONDS plus the cluster's close (NANNY_CLOSE_SECONDS), far inside 120 s
            if not returned.wait(timeout=120):
                seen["error"] = AssertionError("the Ctrl-C did not stop the run in 120 s; the gate was opened")
                gate.release()

        watcher = threading.Thread(target=interrupt)
        watcher.start()
        try:
            with pytest.raises(KeyboardInterrupt):
                compute_pairwise(_shapes(), n_jobs=2, block_size=1, store=store, progress=False, **PARAMS,
                                 **gate.params(free=2))
        finally:
            returned.set()
            gate.release()
            watcher.join()
        assert "error" not in seen, seen["error"]
        assert len(seen["workers"]) >= 2, seen["workers"]  # the LocalCluster was running
        _, alive = psutil.wait_procs(seen["workers"], timeout=30)
        assert not alive, f"processes left behind: {[p.cmdline() for p in alive]}"
        partial = open_store(store)
        assert _pairs_done(store) == 2 and partial.log["blocks_done"] < TOTAL and not partial.complete
        again = compute_pairwise(_shapes(), n_jobs=1, store=store, progress=False, **PARAMS, **gate.params(free=2))
    assert again.log["blocks_found_done"] == partial.log["blocks_done"]
    _same_as(again, serial)


class _SendsCtrlC:
    """An object whose finalizer is where a Ctrl-C lands (as in a Dask future the client lets go)."""

    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)  # raises KeyboardInterrupt here, inside __del__


def test_a_ctrl_c_raised_inside_a_finalizer_still_stops_the_run(tmp_path):
    """Python runs the SIGINT handler wherever the main thread is; inside a finalizer the
    KeyboardInterrupt it raises is printed as "Exception ignored" and lost, and the run went on
    to the end. The engine records it and stops after the block."""
    lost = []

    def callback(progress):
        if progress.blocks_computed == 3:
            _SendsCtrlC()  # dropped at once: its __del__ runs now
        return False

    hook, sys.unraisablehook = sys.unraisablehook, lost.append
    try:
        with pytest.raises(KeyboardInterrupt):
            compute_pairwise(_shapes(), metric="procrustes", n_jobs=1, block_size=1, store=tmp_path / "D.zarr",
                             progress=False, callback=callback)
    finally:
        sys.unraisablehook = hook
    assert len(lost) == 1 and isinstance(lost[0].exc_value, KeyboardInterrupt)  # swallowed where it was raised
    assert open_store(tmp_path / "D.zarr").log["blocks_done"] == 3  # and still stopped the run there


def test_a_ctrl_c_during_dask_calls_waits_for_a_safe_point_and_the_callers_client_still_works(serial, tmp_path):
    """On Dask, a KeyboardInterrupt raised in the middle of the client's own calls (e.g. half-way
    through scheduling a callback on its event loop) left the caller's Client cancelling every
    later future. So while Dask is in use the engine records a Ctrl-C and raises it at its next
    check (after the block, or within POLL_SECONDS while waiting). Here the Ctrl-C comes from the
    callback itself: the callback runs on, the run stops right after it, and the same Client
    then finishes the matrix."""
    from distributed import Client

    from shapelib.pairwise import local_cluster

    store = tmp_path / "D.zarr"
    after_signal = []

    def ctrl_c_at_the_third_block(progress):
        if progress.blocks_computed == 3:
            os.kill(os.getpid(), signal.SIGINT)
            after_signal.append(progress.blocks_computed)  # still here: the interrupt was deferred
        return False

    with local_cluster(1) as cluster, Client(cluster) as client:
        with pytest.raises(KeyboardInterrupt):
            compute_pairwise(_shapes(), metric="alpha", client=client, block_size=1, store=store, progress=False,
                             callback=ctrl_c_at_the_third_block, **PARAMS)
        assert after_signal == [3] and open_store(store).log["blocks_done"] == 3
        again = compute_pairwise(_shapes(), metric="alpha", client=client, store=store, progress=False, **PARAMS)
    assert again.log["blocks_found_done"] == 3 and again.complete
    _same_as(again, serial)
