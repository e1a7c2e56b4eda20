"""The registration methods the registration benchmarks run beside shapelib, each with its defaults.

Every peer gets the same normalised inputs (each set to zero mean and unit RMS radius, as MATLAB CPD
does) and its result is mapped back with the target's mean and scale. shapelib gets the raw inputs
and its defaults (``sl.register(source, target)``): what a user runs is what is reported.

What runs in which dimension (probreg 0.3.8, read from its source):

* ``cpd`` — pycpd ``DeformableRegistration`` (λ = 2, β = 2, w = 0), 2-D and 3-D.
* ``probreg_cpd`` — ``probreg.cpd.registration_cpd(tf_type_name="nonrigid")`` (β = 2, λ = 2, w = 0),
  any dimension up to 3.
* ``probreg_filterreg`` — ``probreg.filterreg.registration_filterreg``: rigid only (the function
  builds ``RigidFilterReg``; the deformable variant needs skinning nodes and 3-D). Its rigid motion
  is a 3-D rotation, so a 2-D set is embedded with z = 0 and z is dropped from the result; the
  motion found stays in the plane up to round-off. It is scored on the non-rigid benchmark as what
  it is, a rigid fit.
* ``probreg_gmmtree`` — ``probreg.gmmtree.registration_gmmtree``: rigid only and 3-D only (its
  compiled tree takes ``N × 3`` points). A 2-D set is embedded with z = 0; the tree's covariances
  are then singular and it raises on every planar input, which is counted as a failure — the
  embedding is an unfair input for it, and the record says so.
* ``probreg_bcpd`` — ``probreg.bcpd.registration_bcpd`` (combined similarity + non-rigid with
  priors, w = 0), any dimension.

A method that raises, or returns a non-finite point, is a failure of that registration: its error
is the error of not moving the source (the source as given), and the exception's class is recorded.
With a time limit, a registration still running after it is stopped and counted the same way
(``TimeoutError``); the limit is the same for every method. shapelib's registration is stopped by a
signal, checked between its Python steps. The peers then run in a child process, which is killed
when its registration overruns and replaced for the next: a signal cannot stop a compiled loop that
holds the GIL (probreg's ``GMMTree.__init__`` stayed in one for over 30 minutes on some 3-D sets).
The child measures each registration's time as this process measures shapelib's, around the call.
"""

from __future__ import annotations

import atexit
import importlib
import multiprocessing
import signal
import time
import warnings
from contextlib import contextmanager

import numpy as np

import shapelib as sl

#: the peers in the order the reports list them
PEERS = ("cpd", "probreg_cpd", "probreg_filterreg", "probreg_gmmtree", "probreg_bcpd")
METHODS = ("shapelib", *PEERS)

#: one line per method for the record and the performance page
DESCRIPTIONS = {
    "shapelib": "shapelib.register(source, target), its defaults, raw inputs",
    "cpd": "pycpd DeformableRegistration, its defaults (λ = 2, β = 2, w = 0)",
    "probreg_cpd": "probreg registration_cpd(tf_type_name='nonrigid'), its defaults",
    "probreg_filterreg": "probreg registration_filterreg, its defaults; rigid only (2-D embedded with z = 0)",
    "probreg_gmmtree": "probreg registration_gmmtree, its defaults; rigid only, 3-D only (2-D embedded with z = 0)",
    "probreg_bcpd": "probreg registration_bcpd, its defaults (similarity + non-rigid, priors)",
}

#: the labels the tables use
LABELS = {"shapelib": "shapelib", "cpd": "pycpd CPD", "probreg_cpd": "probreg CPD", "probreg_filterreg": "FilterReg",
          "probreg_gmmtree": "GMMTree", "probreg_bcpd": "BCPD"}


def normalise(a):
    """Zero mean and unit RMS radius: ``(a − mean) / s``, ``s = sqrt(Σ|a_i − mean|² / n)``."""
    m = a.mean(axis=0)
    s = float(np.sqrt(np.sum((a - m) ** 2) / len(a)))
    return (a - m) / s, m, s


def _embed(a):
    return a if a.shape[1] == 3 else np.c_[a, np.zeros(len(a))]


def _pycpd(xn, yn):
    from pycpd import DeformableRegistration

    return DeformableRegistration(X=yn, Y=xn).register()[0]


def _probreg_cpd(xn, yn):
    from probreg import cpd

    return cpd.registration_cpd(xn, yn, tf_type_name="nonrigid").transformation.transform(xn)


def _filterreg(xn, yn):
    from probreg import filterreg

    x3 = _embed(xn)
    return np.asarray(filterreg.registration_filterreg(x3, _embed(yn)).transformation.transform(x3))[:, : xn.shape[1]]


def _gmmtree(xn, yn):
    from probreg import gmmtree

    x3 = _embed(xn)
    return np.asarray(gmmtree.registration_gmmtree(x3, _embed(yn)).transformation.transform(x3))[:, : xn.shape[1]]


def _bcpd(xn, yn):
    from probreg import bcpd

    return bcpd.registration_bcpd(xn, yn).transform(xn)


_PEER_FUNCTIONS = {"cpd": _pycpd, "probreg_cpd": _probreg_cpd, "probreg_filterreg": _filterreg,
                   "probreg_gmmtree": _gmmtree, "probreg_bcpd": _bcpd}


@contextmanager
def _time_limit(seconds):
    """Raise ``TimeoutError`` in the main thread after ``seconds`` (no limit when ``seconds`` is falsy)."""
    if not seconds:
        yield
        return

    def _stop(signum, frame):
        raise TimeoutError(f"stopped after {seconds} s")

    old = signal.signal(signal.SIGALRM, _stop)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


#: seconds a new child process may take to import the peers before it is given up
CHILD_START_S = 300.0


def _peer_call(method, source, target):
    """``(moved, seconds, exception class name or None)`` of one peer: both sets normalised, the result
    mapped back with the target's mean and scale, timed around all of it."""
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")  # every method is judged by its error, not its warnings
            xn, _, _ = normalise(source)
            yn, my, sy = normalise(target)
            moved = np.asarray(_PEER_FUNCTIONS[method](xn, yn), dtype=float) * sy + my
        return moved, time.perf_counter() - t0, None
    except Exception as exc:  # noqa: BLE001 - a peer's failure is a result of the benchmark
        return None, time.perf_counter() - t0, type(exc).__name__


def _serve(conn):
    """The child's loop: the peers imported and BLAS on one thread (as in the parent's runs), then one
    registration per message until the parent closes the pipe."""
    from threadpoolctl import threadpool_limits

    for name in ("pycpd", "probreg"):  # imported before "ready": import time is not registration time
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 - its peers then raise ImportError per registration, as in-process
            pass
    with threadpool_limits(limits=1, user_api="blas"):
        conn.send("ready")
        while True:
            try:
                method, source, target = conn.recv()
            except (EOFError, OSError):
                return
            conn.send(_peer_call(method, source, target))


class _Child:
    """A process that runs the peers' registrations under a hard time limit (module docstring)."""

    def __init__(self):
        ctx = multiprocessing.get_context("spawn")
        self.conn, theirs = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(theirs,), daemon=True, name="shapelib-bench-peer")
        self.proc.start()
        theirs.close()
        try:
            ready = self.conn.poll(CHILD_START_S) and self.conn.recv() == "ready"
        except EOFError:  # the process ended before it was ready
            ready = False
        if not ready:
            self.close()
            raise RuntimeError(f"the peers' process did not start within {CHILD_START_S:.0f} s")

    def call(self, method, source, target, seconds):
        """The child's ``_peer_call``, or None when it is still running after ``seconds``."""
        self.conn.send((method, source, target))
        if self.conn.poll(seconds):
            return self.conn.recv()
        return None

    def close(self):
        self.conn.close()
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join()


_CHILD = []


def _close_child():
    while _CHILD:
        _CHILD.pop().close()


atexit.register(_close_child)


def _peer_in_child(method, source, target, seconds):
    """A peer's ``_peer_call`` in the child process, killed (and replaced at the next call) when it
    overruns ``seconds``: then ``(None, seconds, "TimeoutError")``."""
    if not _CHILD:
        _CHILD.append(_Child())
    out = _CHILD[0].call(method, source, target, seconds)
    if out is None:
        _close_child()
        return None, float(seconds), "TimeoutError"
    return out


def run(method: str, source, target, time_limit: float | None = None):
    """Register ``source`` onto ``target`` with ``method``.

    Returns ``(moved, seconds, info)``; ``info`` has ``exception`` (the class name, or None) and,
    for shapelib, ``reliable`` (the result's flag, None where the result has none) and ``converged``.
    ``time_limit`` (seconds, None: none) stops a registration that runs longer, as a failure; with
    it, the peers run in a child process that is killed when they overrun (module docstring).
    """
    source = np.asarray(source, dtype=float)
    target = np.asarray(target, dtype=float)
    info = {"exception": None}
    if method != "shapelib":
        moved, seconds, info["exception"] = (_peer_in_child(method, source, target, time_limit) if time_limit
                                             else _peer_call(method, source, target))
    else:
        t0 = time.perf_counter()
        try:
            with _time_limit(time_limit), warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")  # every method is judged by its error, not its warnings
                res = sl.register(source, target)
            moved = np.asarray(res.points, dtype=float)
            rel = getattr(res, "reliable", None)
            info["reliable"] = None if rel is None else bool(rel)
            info["converged"] = bool(getattr(res, "converged", True))
        except Exception as exc:  # noqa: BLE001 - a failure is a result of the benchmark
            moved, info["exception"] = None, type(exc).__name__
        seconds = time.perf_counter() - t0
    if info["exception"] is None and (moved.shape != source.shape or not np.all(np.isfinite(moved))):
        info["exception"] = "FloatingPointError"  # a non-finite or misshapen result
    return (source if info["exception"] else moved), seconds, info


def warm_up(methods=METHODS, dim: int = 2, time_limit: float | None = None) -> None:
    """One untimed registration per method on a small set, so imports and first-call costs stay out of the
    timings (with ``time_limit``, the peers' in the child process that will time them)."""
    rng = np.random.default_rng(0)
    x = rng.normal(size=(30, dim))
    for m in methods:
        run(m, x, 1.1 * x + 0.1, time_limit=None if time_limit is None else max(time_limit, 60.0))
