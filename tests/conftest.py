import os
import sys
import time
from pathlib import Path

# Under pytest-xdist the workers already fill the cores: each gets its share of them for BLAS and
# OpenMP (one thread each with ``-n logical``) instead of every worker starting a thread per core
# (OpenBLAS's idle threads spin on the other worker's core; the JAX and metric test files on two
# workers and two cores: 60–63 s against 63–67 s). The environment variables reach the processes the
# tests start (CLI runs, notebook kernels; an explicit setting wins); this process's pools are limited in
# place, NumPy being loaded already (zarr's pytest plugin imports it). A single-process run keeps every core.
if int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")) > 1:
    _THREADS = str(max(1, (os.cpu_count() or 1) // int(os.environ["PYTEST_XDIST_WORKER_COUNT"])))
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, _THREADS)
    if "numpy" in sys.modules:  # else OpenBLAS reads the variables above when NumPy loads it
        from threadpoolctl import threadpool_limits

        threadpool_limits(int(_THREADS))

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"

# Offline default for a checkout that sits beside the shared data mirror (as in CI).
if not os.environ.get("SHAPELIB_DATA_DIR") and (SHARED / "data").is_dir():
    os.environ["SHAPELIB_DATA_DIR"] = str(SHARED / "data")

sys.path.insert(0, str(ROOT))

# JAX's compiled programs are kept on disk and shared by the xdist workers (and by the next run): a
# program one worker compiled, the other reads instead of compiling it again (the JAX test files on two
# workers from an empty cache: 13 % less CPU). JAX keys each entry by its version, its flags and the
# program; a JAX_COMPILATION_CACHE_DIR already set wins.
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(ROOT / "build" / "jax-cache"))


def pytest_configure(config):
    """Ctrl-C behaves as at a terminal, however the suite was started.

    A shell without job control starts a background command (``make test &`` in a script, a CI
    runner's ``nohup``) with SIGINT ignored, and Python keeps an ignored SIGINT ignored: the tests
    that press Ctrl-C (on this process, or on a subprocess, which inherits the disposition) then
    test nothing and wait for a run that cannot be interrupted. Python's own handler is put back
    (in every xdist worker too); a handler installed in this process is reset to the default at
    ``exec``, so subprocesses start with Python's handler as well."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)

#: Fetched once per session before the first test that needs the raw data: a probe, so that
#: when the data can be had neither from SHAPELIB_DATA_DIR nor by download every such test
#: fails with the same one-line reason instead of a traceback each.
PROBE_FILE = "cdfhc/cdfhc_data2D_CC.mat"


@pytest.fixture(scope="session")
def raw_data():
    """The raw data, obtained the way the notebooks obtain them (``shapelib.datasets.fetch``):
    from ``SHAPELIB_DATA_DIR`` when set, else downloaded with pooch into the user cache. If
    neither works the test fails (never skips) and says why."""
    from shapelib.datasets import DataError, fetch

    try:
        return fetch(PROBE_FILE)
    except DataError as exc:
        pytest.fail(f"raw data unavailable: {exc}", pytrace=False)


requires_data = pytest.mark.usefixtures("raw_data")


def in_ci() -> bool:
    """``CI`` is set (to anything but empty, 0, false or no): .ci/run and hosted CI runners set it."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def missing(reason: str):
    """Something a test needs is not here: the test FAILS in CI (where everything must be there)
    and is skipped elsewhere, saying why in one line either way."""
    if in_ci():
        pytest.fail(f"{reason} (CI is set: a test may not skip for want of it)", pytrace=False)
    pytest.skip(reason)


def needs(available: bool, reason: str):
    """Decorator: run the test when ``available``; else :func:`missing` (fail in CI, skip elsewhere)."""
    import functools

    def decorate(test):
        if available:
            return test

        @functools.wraps(test)
        def unavailable(*args, **kwargs):
            missing(reason)

        return unavailable

    return decorate


def import_or_missing(module: str, reason: str):
    """``pytest.importorskip`` that fails in CI: the module, or the whole test module skipped
    (failed in CI) with ``reason`` and the import error."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if in_ci():
            pytest.fail(f"{reason}: {exc} (CI is set: a test may not skip for want of it)", pytrace=False)
        pytest.skip(f"{reason}: {exc}", allow_module_level=True)


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


def wait_for(cond, what, timeout=120):
    """Wait for something that must happen (a process up, a file written, a run blocked at a
    gate); the deadline only turns a hang into a failure, it never decides a result."""
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def command_line(process) -> str:
    """A psutil process's command line, or "" if it has gone (or is a zombie) since it was listed."""
    import psutil

    try:
        return " ".join(process.cmdline())
    except psutil.Error:
        return ""


def ellipse(k, a=3.0, b=2.0, d=2):
    """An outline of ``k`` landmarks on an ellipse with axes ``a``, ``b`` (d = 3: lifted by a
    saddle ``0.8 sin 2t``): the test shapes of the intrinsic statistics."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    x = np.column_stack([a * np.cos(t), b * np.sin(t)])
    if d == 3:
        x = np.column_stack([x, 0.8 * np.sin(2 * t)])
    return x


def ellipse_population(rng, n, k=10, d=2, *, noise, second_mode=0.0):
    """``n`` shapes with structure, rigidly aligned (the statistics take aligned populations): the
    :func:`ellipse` stretched along one mode by a standard normal amount, with ``second_mode > 0``
    also slid along the outline (landmarks towards their neighbours) by ``second_mode`` times
    another, plus isotropic ``noise``."""
    import shapelib

    base = ellipse(k, d=d)
    mode1 = np.column_stack([base[:, 0] * 0.15, -base[:, 1] * 0.1] + ([0.1 * base[:, 2]] if d == 3 else []))
    mode2 = np.roll(base, 1, axis=0) - base
    out = []
    for _ in range(n):
        x = base + rng.normal() * mode1
        if second_mode:
            x = x + second_mode * rng.normal() * mode2
        out.append(x + noise * rng.normal(size=base.shape))
    return shapelib.pose_align(np.stack(out))[0]


class CountingExecutor:
    """A thread pool that records the size of every task it is given (the log maps run for real)."""

    def __init__(self):
        from concurrent.futures import ThreadPoolExecutor

        self.pool = ThreadPoolExecutor(2)
        self.tasks = []

    def submit(self, fn, base, shapes, *args, **kw):
        self.tasks.append(len(shapes))
        return self.pool.submit(fn, base, shapes, *args, **kw)
