"""A metric whose timing the test controls, for the fault-injection tests.

Importing this module registers ``"gated_alpha"`` the way a user registers a metric
(:func:`shapelib.distances.register_metric`): the α geodesic length of ``"alpha"``, computed by
the same function with the same options, so its matrices equal ``"alpha"``'s exactly. Two extra
options make it wait:

``gate`` (a directory, see :class:`Gate`)
    Every call takes a ticket first: the files ``ticket-0``, ``ticket-1``, ... in ``gate``, each
    created with ``O_CREAT | O_EXCL``, so the numbering is shared by every process (the test,
    Dask workers, a CLI subprocess) and no two calls get the same number.
``free`` (int)
    Calls with a ticket below ``free`` run at once; the others first take a shared
    ``flock`` on ``gate/lock``, which the test holds exclusively until it releases the gate.

So a run computes exactly ``free`` pairs and then waits, with every worker blocked inside a
pair, for as long as the test wants: a signal or a kill lands after those pairs and before the
last one, whatever the speed of the machine. The lock is the kernel's: when the test process
ends, however it ends, the lock is released and nothing waits forever.

Workers import this module when they unpickle the metric's function (the engine sends it with
each task), so they need the repository root on their path: spawned LocalCluster workers
inherit the test's ``sys.path``; ``dask worker`` processes and CLI subprocesses get
``PYTHONPATH=<repository root>``.
"""

from __future__ import annotations

import fcntl
import os
import threading
from pathlib import Path

from shapelib.distances import register_metric
from shapelib.solver.geodesic import geodesic

NAME = "gated_alpha"


def _take_ticket(gate: str) -> int:
    n = 0
    while True:
        try:
            os.close(os.open(os.path.join(gate, f"ticket-{n}"), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            return n
        except FileExistsError:
            n += 1


def gated_alpha(u, v, *, gate: str, free: int = 0, **params):
    """``geodesic(u, v, metric="alpha", **params)``, after the gate (see the module docstring)."""
    if _take_ticket(gate) >= free:
        fd = os.open(os.path.join(gate, "lock"), os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_SH)  # blocks while the test holds the gate
        finally:
            os.close(fd)  # and lets the next caller through at once
    return geodesic(u, v, metric="alpha", **params)


register_metric(NAME, gated_alpha, path=True, lower_bound="alpha_bound", replace=True,
                description="alpha, but calls beyond the first `free` wait for a test's gate (tests only)")


class Gate:
    """The test's side: a directory for the tickets and the lock, closed on creation.

    ``Gate(path)`` creates the directory and takes the exclusive lock; :meth:`release` (or
    leaving the ``with`` block) opens it for every waiting and later call.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._fd = os.open(self.path / "lock", os.O_RDWR | os.O_CREAT, 0o644)
        fcntl.flock(self._fd, fcntl.LOCK_EX)

    def params(self, free: int) -> dict:
        """The metric options of a run through this gate: ``free`` calls run, the others wait."""
        return {"metric": NAME, "gate": str(self.path), "free": int(free)}

    def tickets(self) -> int:
        """Calls started so far (all processes)."""
        return sum(1 for p in self.path.iterdir() if p.name.startswith("ticket-"))

    def release(self) -> None:
        """Open the gate (idempotent; any thread: a test's watcher may open it to end a hang)."""
        with self._lock:
            if self._fd is not None:
                fcntl.flock(self._fd, fcntl.LOCK_UN)
                os.close(self._fd)
                self._fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
        return False
