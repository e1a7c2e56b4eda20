"""Fault injection with real processes: a worker killed mid-run, a client killed mid-run, Ctrl-C.

The cluster is started the way users start one — ``dask scheduler`` and two ``dask worker``
command lines on 127.0.0.1 with OS-chosen ports — and every process is terminated (then killed)
in the fixtures' ``finally``. These tests run in the default ``pytest`` run (marker
``processes``, to select or skip them: ``-m processes`` / ``-m "not processes"``); each takes
10–30 s on two cores.
"""

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from shapelib.pairwise import _Store, compute_pairwise, open_store
from tests.conftest import ROOT

pytestmark = pytest.mark.processes

#: slow enough to kill something mid-run (~0.2-0.6 s per pair, 21 pairs), fast enough for CI
PARAMS = dict(metric="alpha", sigma2=0.3, n_steps=16)
N_SHAPES = 7


def _shapes():
    rng = np.random.default_rng(7)
    t = np.linspace(0, 2 * np.pi, 20, endpoint=False)
    base = np.c_[2 * np.cos(t), np.sin(t)]
    return np.stack([base + 0.2 * rng.normal(size=base.shape) for _ in range(N_SHAPES)])


@pytest.fixture(scope="module")
def serial():
    return compute_pairwise(_shapes(), n_jobs=1, block_size=1, progress=False, **PARAMS)


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


def _n_done(path) -> int:
    """Blocks marked done in the store (0 while it does not exist yet); chunk files are replaced
    atomically by zarr, so reading during a run is safe."""
    try:
        return len(_Store.open(path).task_done())
    except Exception:  # not there yet, or caught between two writes: ask again
        return 0


def _wait_for(cond, timeout, what):
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


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
        _wait_for(lambda: sched_file.is_file() and sched_file.stat().st_size > 0, 60, "the scheduler")
        address = json.loads(sched_file.read_text())["address"]
        workers = [subprocess.Popen([*dask, "worker", address, "--nthreads", "1", "--no-nanny",
                                     "--no-dashboard", "--host", "127.0.0.1"], env=_env(),
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
        procs += workers
        yield address, workers
    finally:
        _stop(procs)


def test_killing_a_worker_mid_run_still_completes_the_matrix(dask_cluster, serial, tmp_path):
    from distributed import Client

    address, workers = dask_cluster
    store = tmp_path / "D.zarr"
    with Client(address, timeout="30s") as watcher:
        watcher.wait_for_workers(2, timeout=60)
        pid_of = watcher.run(os.getpid)  # worker address -> pid
        outcome = {}

        def run():
            try:
                outcome["result"] = compute_pairwise(_shapes(), scheduler=address, store=store, block_size=1,
                                                     progress=False, **PARAMS)
            except BaseException as exc:  # reported below
                outcome["error"] = exc

        thread = threading.Thread(target=run)
        thread.start()
        try:
            _wait_for(lambda: _n_done(store) >= 2, 120, "two finished blocks")
            busy = []

            def computing():  # a worker caught between two tasks would not test a lost task
                busy[:] = [addr for addr, keys in watcher.processing().items() if keys]
                return bool(busy)

            _wait_for(computing, 30, "a worker in the middle of a task")
            victim = pid_of[busy[0]]
            assert victim in {w.pid for w in workers}
            os.kill(victim, signal.SIGKILL)
            done_at_kill = _n_done(store)
        finally:
            thread.join(timeout=300)
        assert "error" not in outcome, outcome.get("error")
        result = outcome["result"]
        assert [w.poll() for w in workers].count(-signal.SIGKILL) == 1
        assert len(watcher.scheduler_info()["workers"]) == 1  # the run finished on the survivor
    total = N_SHAPES * (N_SHAPES + 1) // 2  # upper-triangle blocks of size 1, diagonal included
    assert done_at_kill < total and result.log["blocks_computed"] == total and result.complete
    for name in ("matrix", "lower", "upper", "converged", "n_iter"):
        np.testing.assert_array_equal(getattr(result, name), getattr(serial, name), err_msg=name)


CLIENT = textwrap.dedent("""
    import sys
    import numpy as np
    from shapelib.pairwise import compute_pairwise
    x = np.load(sys.argv[1])
    compute_pairwise(x, n_jobs=1, block_size=1, store=sys.argv[2], progress=False,
                     metric="alpha", sigma2=0.3, n_steps=16)
""")


def test_killing_the_client_mid_run_then_rerunning_resumes(serial, tmp_path):
    x = _shapes()
    np.save(tmp_path / "x.npy", x)
    store = tmp_path / "D.zarr"
    proc = subprocess.Popen([sys.executable, "-c", CLIENT, str(tmp_path / "x.npy"), str(store)], env=_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        _wait_for(lambda: _n_done(store) >= 10 or proc.poll() is not None, 120, "ten finished blocks")
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        _stop([proc])
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()
    before = open_store(store)
    n_done = before.log["blocks_done"]
    total = N_SHAPES * (N_SHAPES + 1) // 2
    assert 10 <= n_done < total and not before.complete

    again = compute_pairwise(x, n_jobs=1, store=store, progress=False, **PARAMS)
    assert again.log["blocks_found_done"] == n_done and again.log["blocks_computed"] == total - n_done
    # the blocks finished before the kill were not recomputed: their timings are the stored ones
    kept = before.computed
    assert np.array_equal(again.seconds[kept], before.seconds[kept])
    for name in ("matrix", "lower", "upper", "converged", "n_iter"):
        np.testing.assert_array_equal(getattr(again, name), getattr(serial, name), err_msg=name)


def test_ctrl_c_keeps_finished_blocks_and_stops_the_local_cluster(tmp_path):
    import psutil

    store = tmp_path / "D.zarr"
    x = np.concatenate([_shapes(), _shapes()[::-1] + 0.05])  # 91 pairs: far more than the interrupt leaves time for
    own = os.getpid()
    fired = threading.Event()
    stop = threading.Event()

    def interrupt():
        while not stop.is_set():
            if _n_done(store) >= 2:
                fired.set()
                os.kill(own, signal.SIGINT)
                return
            time.sleep(0.05)

    before = {p.pid for p in psutil.Process().children(recursive=True)}
    watcher = threading.Thread(target=interrupt)
    watcher.start()
    interrupted = False
    t0 = time.monotonic()
    try:
        compute_pairwise(x, n_jobs=2, block_size=1, store=store, progress=False, **PARAMS)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        stop.set()
        watcher.join()
    # each its own message: a failure under load says which step did not happen
    assert fired.is_set(), f"the watcher never saw 2 finished blocks ({_n_done(store)} done)"
    assert interrupted, f"SIGINT did not stop the run: it finished in {time.monotonic() - t0:.1f} s"
    partial = open_store(store)
    assert 2 <= partial.log["blocks_done"] < partial.log["blocks_total"]
    time.sleep(0.5)
    left = [p for p in psutil.Process().children(recursive=True)
            if p.pid not in before and p.is_running() and p.status() != psutil.STATUS_ZOMBIE
            and "resource_tracker" not in " ".join(p.cmdline())]
    assert not left, f"processes left behind: {[p.cmdline() for p in left]}"
