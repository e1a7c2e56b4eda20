"""Regenerate every figure and table of the study into ``results/`` and write ``results/REPORT.md``.

Usage::

    python run_all.py                 # full parameters, all notebooks, in parallel
    python run_all.py --quick         # the quick parameters CI uses
    python run_all.py --only table1_pairwise --force
    python run_all.py --only fig04_line_bending -p sigma2=0.02 -p n_steps=16
    python run_all.py --list

Each notebook (``notebooks/<name>.py``, jupytext percent format, one cell tagged
``parameters``) is executed by papermill into a temporary folder ``results/.tmp-<name>-*``
and moved to ``results/<name>/`` only when it succeeds, so a failed or interrupted run never
leaves a half-written folder nor destroys the previous results. A notebook whose inputs
(its source, the ``shapelib`` sources, its parameters, the checksums of its data files) are
unchanged since its last successful run is skipped unless ``--force``.

``-p name=value`` (repeatable) sets a parameter of every selected notebook that declares it;
the value is read as a Python literal (``ast.literal_eval``; text that is not a literal is a
string) and must have the type of the notebook's default. The parameters actually used (the
notebook's defaults with every override applied) are recorded in ``values.json`` (meta
``parameters``) and in ``.inputs.json``.

Ctrl-C (SIGINT) or SIGTERM stops every process the run started (the notebook kernels, which
papermill starts in their own process groups, and their worker processes), removes the
temporary folders and leaves the previous results as they were; the exit code is 128 + the
signal number.
"""

from __future__ import annotations

import argparse
import ast
import concurrent.futures as cf
import datetime
import hashlib
import json
import os
import platform
import queue
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

from .notebooks import NOTEBOOKS

#: the source checkout: ``run_all.py``, ``notebooks/``, ``results/`` (this module runs from one)
ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK_DIR = ROOT / "notebooks"
RESULTS_DIR = ROOT / "results"
REFERENCE_DIR = ROOT / "data" / "reference"


class NotebookError(RuntimeError):
    """A notebook failed; the message names the failing cell, or what its run did not produce."""


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived while notebooks were running; ``signum`` says which."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


#: Set while a run is being stopped: notebooks that have not started yet are not started.
_STOPPING = threading.Event()
#: Temporary folders of the notebooks executing right now (removed when a run is stopped).
_RUNNING_TMP: set[Path] = set()
_TMP_LOCK = threading.Lock()


class _Source(str):
    """Source text of a parameter default that is not a Python literal (e.g. a function call)."""


def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# ---------------------------------------------------------------------------------------------
# parameters

def _declared_parameters(nb, name: str = "notebook") -> dict:
    """``{name: default}`` of the assignments in the cell tagged ``parameters``.

    Literal defaults are evaluated (``ast.literal_eval``); others are kept as their source text
    (a :class:`_Source`), which is recorded but never type-checked.
    """
    for cell in nb.cells:
        if "parameters" in cell.get("metadata", {}).get("tags", []):
            declared = {}
            for node in ast.parse(cell.source).body:
                if isinstance(node, ast.Assign):
                    targets, value = node.targets, node.value
                elif isinstance(node, ast.AnnAssign) and node.value is not None:
                    targets, value = [node.target], node.value
                else:
                    continue
                try:
                    default = ast.literal_eval(value)
                except (ValueError, TypeError, SyntaxError):
                    default = _Source(ast.get_source_segment(cell.source, value))
                declared.update({t.id: default for t in targets if isinstance(t, ast.Name)})
            return declared
    raise NotebookError(f"{name}: no cell tagged 'parameters'")


def declared_parameters(name: str) -> dict:
    """The parameters ``notebooks/<name>.py`` declares, with their defaults."""
    import jupytext

    return _declared_parameters(jupytext.read(NOTEBOOK_DIR / f"{name}.py"), name)


def _same_kind(value, default) -> bool:
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(value, bool) and isinstance(default, bool)
    if isinstance(default, float):
        return isinstance(value, (int, float))
    if isinstance(default, (list, tuple)):
        return isinstance(value, (list, tuple))
    return isinstance(value, type(default))


def check_parameters(name: str, params: dict, declared: dict) -> None:
    """ValueError if ``params`` names a parameter ``name`` does not declare, or a value whose type
    differs from the declared default's (an int is accepted for a float)."""
    unknown = sorted(set(params) - set(declared))
    if unknown:
        raise ValueError(f"{name}: unknown parameter(s) {unknown}; the notebook declares {sorted(declared)}")
    for key, value in params.items():
        default = declared[key]
        if default is None or isinstance(default, _Source):
            continue
        if not _same_kind(value, default):
            raise ValueError(
                f"{name}: parameter {key!r} must be a {type(default).__name__} like its default {default!r}; "
                f"got {value!r} ({type(value).__name__})"
            )


def notebook_parameters(name: str, *, quick: bool, overrides: dict | None = None) -> dict:
    """The parameters run_all passes to ``name``: the registry's, its quick ones if ``quick``, then
    those of ``overrides`` the notebook declares."""
    spec = NOTEBOOKS[name]
    params = dict(spec["params"])
    if quick:
        params.update(spec["quick"])
    if overrides:
        declared = declared_parameters(name)
        params.update({k: v for k, v in overrides.items() if k in declared})
    return params


def input_fingerprint(name: str, params: dict) -> str:
    """Hash of everything a notebook's results depend on."""
    from ..datasets import data_checksums

    h = hashlib.sha256()
    h.update((NOTEBOOK_DIR / f"{name}.py").read_bytes())
    for src in sorted((ROOT / "shapelib").rglob("*.py")):
        h.update(str(src.relative_to(ROOT)).encode())
        h.update(src.read_bytes())
    h.update(json.dumps(params, sort_keys=True).encode())
    h.update(json.dumps(data_checksums(NOTEBOOKS[name]["data"]), sort_keys=True).encode())
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------
# executing one notebook

def _kernel_options() -> dict:
    """Options for papermill's kernel client (nbclient).

    * ``--matplotlib=inline``: the kernel draws with matplotlib's inline backend, so the executed
      notebook shows its figures, whatever ``MPLBACKEND`` the caller exported (CI sets Agg);
      ``shapelib.study.save_figure`` still writes every figure as a PNG file.
    * ``--IPKernelApp.log_level=CRITICAL``: jupyter_client interrupts (SIGINT) every kernel it
      shuts down, and an idle kernel logs that as "ERROR | KeyboardInterrupt caught in kernel"
      in the middle of a healthy run. Errors in cells still reach papermill, which names the cell.
    * ``KernelManager.transport_encryption = "auto"``: the kernel manager provisions CurveZMQ keys
      for the kernel's local TCP sockets. Without them ipykernel (>= 7.4) warns "Kernel is running
      over TCP without encryption" at every start. Where pyzmq lacks CurveZMQ, the kernel talks
      over IPC (Unix sockets) instead, which the warning also accepts.
    """
    import zmq
    from traitlets.config import Config

    config = Config()
    if zmq.has("curve"):
        config.KernelManager.transport_encryption = "auto"
    else:
        config.KernelManager.transport = "ipc"
    return {"config": config, "extra_arguments": ["--matplotlib=inline", "--IPKernelApp.log_level=CRITICAL"]}


#: what nbclient says when a kernel exits before it answers (see execute_notebook)
KERNEL_START_FAILURE = "Kernel died before replying to kernel_info"


def execute_notebook(name: str, params: dict, output_dir: Path, *, log_output: bool = False,
                     progress: bool | dict = False) -> dict:
    """Run ``notebooks/<name>.py`` with ``params``; outputs (incl. the executed notebook) go to ``output_dir``.

    ``progress`` is papermill's ``progress_bar`` (a tqdm bar over the cells; a dict gives tqdm
    options). Returns the parameters the notebook ran with: its declared defaults with ``params``
    applied (``output_dir`` left out).

    Raises
    ------
    ValueError
        If ``params`` names a parameter the notebook does not declare, or a value of another type
        than the declared default.
    NotebookError
        If a cell raises; the message names the cell.
    """
    import jupytext
    import nbformat
    import papermill as pm

    nb = jupytext.read(NOTEBOOK_DIR / f"{name}.py")
    declared = _declared_parameters(nb, name)
    check_parameters(name, params, declared)
    used = {k: (str(v) if isinstance(v, _Source) else v) for k, v in declared.items() if k != "output_dir"}
    used.update({k: v for k, v in params.items() if k != "output_dir"})
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    output_dir.mkdir(parents=True, exist_ok=True)
    src = output_dir / f"{name}.source.ipynb"
    nbformat.write(nb, src)
    out = output_dir / f"{name}.ipynb"
    try:
        for attempt in (1, 2):
            try:
                pm.execute_notebook(
                    str(src), str(out), parameters={**params, "output_dir": str(output_dir)},
                    kernel_name="python3", cwd=str(ROOT), progress_bar=progress, log_output=log_output,
                    **_kernel_options(),
                )
                break
            except RuntimeError as exc:
                # the kernel died before running a cell: jupyter_client picks free ports and the kernel
                # binds them a moment later, so on a busy machine another process can take one between
                # ("Address already in use"); nothing has run, so a second start is safe
                if attempt == 2 or KERNEL_START_FAILURE not in str(exc) or _STOPPING.is_set():
                    raise
    except pm.PapermillExecutionError as exc:
        raise NotebookError(
            f"{name}: cell {exc.cell_index} (execution count {exc.exec_count}) raised {exc.ename}: {exc.evalue}"
        ) from None
    finally:
        src.unlink(missing_ok=True)
    return used


def check_outputs(name: str, folder: Path, *, exact: bool) -> None:
    """Check that a finished run of notebook ``name`` in ``folder`` produced what the study needs.

    * Under each value-key prefix of the notebook's ``expects`` it recorded exactly that many
      values (``exact``: a quick run with no parameter changed), or at least as many (a full run,
      or one with other parameters: a sweep of more points, more retained modes): the report
      never loses a column silently.
    * Every key of the Table I columns (``table1/<column>/...``) is one the paper's table has
      (:func:`shapelib.study.report.load_reference`, ``data/reference/table1.csv``): the report can
      place each value.
    * It saved at least the spec's ``figures`` PNG files, and shows each of them in the executed
      notebook (the documentation renders the notebook, not the files).

    Raises
    ------
    NotebookError
        Naming the notebook and every shortfall.
    """
    spec = NOTEBOOKS[name]
    keys = set(json.loads((folder / "values.json").read_text())["values"])
    problems = []
    for prefix, count in spec["expects"].items():
        got = sum(k.startswith(prefix) for k in keys)
        if got != count if exact else got < count:
            problems.append(f"{got} value(s) under {prefix!r}, expected {'' if exact else 'at least '}{count}")
    table1 = {k for k in keys if k.startswith("table1/")}
    if table1:
        from .report import load_reference

        if unknown := sorted(table1 - set(load_reference(REFERENCE_DIR).index)):
            problems.append(f"{len(unknown)} Table I key(s) not in the paper's table, e.g. {unknown[0]!r}")
    pngs = sorted(folder.glob("*.png"))
    if len(pngs) < spec.get("figures", 0):
        problems.append(f"{len(pngs)} figure file(s), expected at least {spec['figures']}")
    nb = json.loads((folder / f"{name}.ipynb").read_text())
    shown = sum("image/png" in out.get("data", {}) for cell in nb["cells"] for out in cell.get("outputs", []))
    if shown < len(pngs):
        problems.append(f"{len(pngs)} figure file(s) but {shown} figure(s) shown in the notebook")
    if problems:
        raise NotebookError(f"{name}: " + "; ".join(problems))


def _machine() -> dict:
    return {"cpus": os.cpu_count(), "machine": platform.machine(), "python": platform.python_version(),
            "loadavg_1min": round(os.getloadavg()[0], 2)}


def run_one(name: str, *, quick: bool, force: bool, results_dir: Path = RESULTS_DIR, overrides: dict | None = None,
            progress: bool | dict = False, on_start=None, jobs: int = 1) -> tuple[str, str, float, str]:
    """Run one notebook atomically into ``results_dir/<name>``. Returns (name, status, seconds, message).

    ``status`` is ``"ok"``, ``"skipped"`` (inputs unchanged), ``"FAILED"`` or ``"interrupted"``
    (the run is being stopped). ``overrides`` are ``-p`` parameters (those the notebook does not
    declare are ignored); ``on_start(name)`` is called when the notebook starts executing;
    ``jobs`` (how many notebooks run side by side) is recorded with the timing.
    """
    params = notebook_parameters(name, quick=quick, overrides=overrides)
    fingerprint = input_fingerprint(name, params)
    final = results_dir / name
    info_path = final / ".inputs.json"
    if not force and info_path.exists():
        try:
            if json.loads(info_path.read_text()).get("fingerprint") == fingerprint:
                return name, "skipped", 0.0, "inputs unchanged"
        except json.JSONDecodeError:
            pass
    if _STOPPING.is_set():
        return name, "interrupted", 0.0, "not started"
    results_dir.mkdir(parents=True, exist_ok=True)
    stores = None
    if NOTEBOOKS[name].get("store") and "store_dir" not in params:
        # the notebook's zarr stores live outside its atomic output folder, keyed by the input
        # fingerprint: a killed or failed run resumes from them; changed code or inputs start afresh
        stores = results_dir / ".stores" / f"{name}-{fingerprint[:16]}"
        for stale in (results_dir / ".stores").glob(f"{name}-*"):
            if stale != stores:
                shutil.rmtree(stale, ignore_errors=True)
        params = {**params, "store_dir": str(stores)}
    tmp = Path(tempfile.mkdtemp(prefix=f".tmp-{name}-", dir=results_dir))
    with _TMP_LOCK:
        _RUNNING_TMP.add(tmp)
    t0 = time.perf_counter()
    try:
        if on_start is not None:
            on_start(name)
        used = execute_notebook(name, params, tmp, progress=progress)
        seconds = time.perf_counter() - t0
        if not (tmp / "values.json").exists():
            raise NotebookError(f"{name}: finished without writing values.json")
        check_outputs(name, tmp, exact=quick and not overrides)
        from . import record_values

        record_values(tmp, {}, meta={"parameters": used})
        (tmp / ".inputs.json").write_text(json.dumps(
            {"fingerprint": fingerprint, "params": used, "overrides": params, "mode": "quick" if quick else "full",
             "seconds": round(seconds, 2), "jobs": jobs, "machine": _machine(),
             "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")},
            indent=1, sort_keys=True) + "\n")
        # swap into place: the old folder is only removed once the new one is in place
        old = None
        if final.exists():
            old = Path(tempfile.mkdtemp(prefix=f".old-{name}-", dir=results_dir))
            os.replace(final, old / name)
        os.chmod(tmp, 0o755)
        os.replace(tmp, final)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        if stores is not None:
            shutil.rmtree(stores, ignore_errors=True)
        return name, "ok", seconds, ""
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        if _STOPPING.is_set():
            return name, "interrupted", time.perf_counter() - t0, "stopped by a signal"
        return name, "FAILED", time.perf_counter() - t0, str(exc)
    finally:
        with _TMP_LOCK:
            _RUNNING_TMP.discard(tmp)


# ---------------------------------------------------------------------------------------------
# stopping

def stop_child_processes(*, grace: float = 5.0) -> int:
    """Stop every process this one started, with all their descendants; return how many there were.

    papermill's kernels run in their own process groups (jupyter_client starts them in a new
    session), so a terminal's Ctrl-C reaches neither them nor their workers (process pools, Dask
    LocalCluster processes). Each such group is signalled as a whole, which also reaches workers
    re-parented after their parent died, and so is every descendant psutil lists: SIGTERM, then
    SIGKILL for whatever still runs after ``grace`` seconds.
    """
    import psutil

    procs = psutil.Process().children(recursive=True)
    own_group = os.getpgrp()
    groups = set()
    for p in procs:
        try:
            group = os.getpgid(p.pid)
        except ProcessLookupError:
            continue
        if group != own_group:
            groups.add(group)

    def send(sig, targets):
        for group in groups:
            try:
                os.killpg(group, sig)
            except (ProcessLookupError, PermissionError):
                pass
        for p in targets:
            try:
                p.send_signal(sig)
            except psutil.NoSuchProcess:
                pass

    def running(p):
        try:
            return p.status() != psutil.STATUS_ZOMBIE
        except psutil.NoSuchProcess:
            return False

    def wait(targets):
        deadline = time.monotonic() + grace
        while targets and time.monotonic() < deadline:
            targets = [p for p in targets if running(p)]
            time.sleep(0.05 if targets else 0)
        return targets

    if not procs:
        return 0
    send(signal.SIGTERM, procs)
    alive = wait(procs)
    send(signal.SIGKILL, alive)  # the groups too: members that were not our descendants any more
    wait(alive)
    return len(procs)


class _Cores:
    """Who may run now: a notebook that starts a worker per core (registry ``"cores": "all"``: a
    Dask cluster or a process pool) runs alone; the others share the machine ``jobs`` at a time.
    Two such notebooks side by side would put twice as many busy processes as cores on the machine:
    no faster in all, and each one's recorded run time would be inflated. A notebook waiting for
    the whole machine goes before any later small one."""

    def __init__(self, jobs: int):
        self.jobs, self.used, self.whole_waiting = jobs, 0, 0
        self.cond = threading.Condition()

    def run(self, whole: bool, fn, *args, **kwargs):
        need = self.jobs if whole else 1
        with self.cond:
            self.whole_waiting += whole
            try:
                while not _STOPPING.is_set() and not (
                        self.used + need <= self.jobs and (whole or not self.whole_waiting)):
                    self.cond.wait(0.5)
            finally:
                self.whole_waiting -= whole
            self.used += need
        try:
            return fn(*args, **kwargs)  # run_one returns "interrupted" at once when stopping
        finally:
            with self.cond:
                self.used -= need
                self.cond.notify_all()


def _stop_run(pool: cf.ThreadPoolExecutor, futures) -> None:
    """Cancel the notebooks not started, stop the running ones' processes, remove their folders."""
    _STOPPING.set()
    pool.shutdown(wait=False, cancel_futures=True)
    running = [f for f in futures if not f.done()]
    while True:
        stop_child_processes()  # again on every pass: a thread may have been starting a kernel
        _, pending = cf.wait(running, timeout=1.0)
        running = list(pending)
        if not running:
            break
    with _TMP_LOCK:
        leftovers = list(_RUNNING_TMP)
    for tmp in leftovers:
        shutil.rmtree(tmp, ignore_errors=True)


def _clean_stale(results_dir: Path) -> None:
    for p in list(results_dir.glob(".tmp-*")) + list(results_dir.glob(".old-*")):
        shutil.rmtree(p, ignore_errors=True)


# ---------------------------------------------------------------------------------------------
# progress

class _Progress:
    """What a run shows while it works.

    On a terminal: a tqdm bar over the notebooks and, for every running notebook, papermill's tqdm
    bar over its cells. Otherwise (a CI log): a line when a notebook starts and, every
    ``heartbeat`` seconds, a line naming the notebooks still running, with no carriage returns.
    Disabled: only the line per finished notebook.
    """

    def __init__(self, total: int, *, enabled: bool, jobs: int, heartbeat: float = 60.0, stream=None):
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = enabled and self.stream.isatty()
        self.heartbeat = heartbeat if enabled and not self.tty else None
        self.started: dict[str, float] = {}
        self.slots: queue.Queue = queue.Queue()
        for i in range(max(1, jobs)):
            self.slots.put(i + 1)
        self.bar = None
        if self.tty:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="notebooks", unit="nb", position=0, file=self.stream, dynamic_ncols=True)

    def run(self, name: str, **kwargs):
        """Call :func:`run_one` for ``name`` in a worker thread, with a cell bar in a free row."""
        slot = self.slots.get()
        try:
            progress = ({"desc": name, "position": slot, "leave": False, "file": self.stream, "dynamic_ncols": True}
                        if self.tty else False)
            return run_one(name, progress=progress, on_start=self._started, **kwargs)
        finally:
            self.started.pop(name, None)
            self.slots.put(slot)

    def _started(self, name: str) -> None:
        self.started[name] = time.monotonic()
        if self.enabled and not self.tty:
            print(f"started {name}", file=self.stream, flush=True)

    def finished(self, line: str) -> None:
        if self.bar is not None:
            self.bar.write(line, file=sys.stdout)
            self.bar.update(1)
        else:
            print(line, flush=True)

    def still_running(self) -> None:
        now = time.monotonic()
        running = ", ".join(f"{n} ({(now - t) / 60:.0f} min)" for n, t in sorted(self.started.items()))
        if running:
            print(f"still running: {running}", file=self.stream, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def run_all(names, *, quick: bool, force: bool, jobs: int, results_dir: Path = RESULTS_DIR,
            overrides: dict | None = None, progress: bool = False) -> int:
    """Run ``names`` (in parallel), print one line per notebook, write the report. Returns an exit code.

    On KeyboardInterrupt (Ctrl-C; :class:`Interrupted` for SIGTERM, see :func:`main`) every process
    the run started is stopped and the temporary folders are removed before it propagates.
    """
    from .report import write_report

    results_dir.mkdir(parents=True, exist_ok=True)
    _clean_stale(results_dir)
    _STOPPING.clear()
    failures = []
    done_count = 0
    show = _Progress(len(names), enabled=progress, jobs=jobs)
    pool = cf.ThreadPoolExecutor(max_workers=max(1, jobs))
    cores = _Cores(max(1, jobs))
    futures = [pool.submit(cores.run, NOTEBOOKS[n].get("cores") == "all", show.run, n, quick=quick, force=force,
                           results_dir=results_dir, overrides=overrides, jobs=jobs) for n in names]
    try:
        pending = set(futures)
        while pending:
            done, pending = cf.wait(pending, timeout=show.heartbeat, return_when=cf.FIRST_COMPLETED)
            if not done:
                show.still_running()
            for fut in done:
                name, status, seconds, msg = fut.result()
                done_count += 1
                line = f"[{done_count}/{len(names)}] {name:<28} {status:<8} {seconds:7.1f} s"
                show.finished(line + (f"  {msg}" if msg and status == "FAILED" else ""))
                if status == "FAILED":
                    failures.append((name, msg))
    except KeyboardInterrupt:
        show.close()
        print("stopping: ending the notebook kernels and their workers ...", file=sys.stderr, flush=True)
        in_main = threading.current_thread() is threading.main_thread()
        previous = {s: signal.signal(s, _still_stopping) for s in (signal.SIGINT, signal.SIGTERM)} if in_main else {}
        try:
            _stop_run(pool, futures)
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)
        print("interrupted: finished notebooks are in place, the others keep their previous results", file=sys.stderr)
        raise
    finally:
        show.close()
        pool.shutdown(wait=True)
    report = write_report(results_dir, REFERENCE_DIR, failures=failures)
    print(f"report: {report.relative_to(ROOT) if report.is_relative_to(ROOT) else report}")
    if failures:
        print(f"{len(failures)} notebook(s) failed:", file=sys.stderr)
        for name, msg in failures:
            print(f"  {msg}", file=sys.stderr)
        return 1
    return 0


# ---------------------------------------------------------------------------------------------
# run times for the documentation

#: where ``--record-timings`` writes the last full run's times; the documentation's performance
#: page renders its table from this file (docs/_ext/shapelib_docs.py)
TIMINGS_RECORD = ROOT / "docs" / "_data" / "benchmarks" / "run_times.json"


def timings_record(results_dir: Path = RESULTS_DIR) -> dict:
    """The last full run's time per notebook, machine and date, from the records REPORT.md's run
    table shows (``results/<name>/.inputs.json``).

    Raises
    ------
    ValueError
        Unless every notebook has a successful full-parameter run in ``results_dir``.
    """
    runs = {}
    for name in NOTEBOOKS:
        path = results_dir / name / ".inputs.json"
        info = json.loads(path.read_text()) if path.is_file() else {}
        if info.get("mode") != "full" or "seconds" not in info:
            raise ValueError(f"{name}: no full run recorded in {path}; run `python run_all.py` first")
        runs[name] = info
    last = max(runs.values(), key=lambda i: i.get("finished", ""))
    m = last.get("machine", {})
    loads = [i["machine"]["loadavg_1min"] for i in runs.values() if "loadavg_1min" in i.get("machine", {})]
    machine = {"date": last.get("finished"), "cpus": m.get("cpus"), "machine": m.get("machine"),
               "python": m.get("python"),
               "loadavg": f"{min(loads):.1f}–{max(loads):.1f} (1-minute, when each notebook ended)" if loads else None}
    notebooks = {n: {"seconds": i["seconds"], "jobs": i.get("jobs", 1), "finished": i.get("finished"),
                     "params": i.get("params", {})} for n, i in runs.items()}
    return {"benchmark": "run_times", "command": "python run_all.py", "machine": machine,
            "results": {"notebooks": notebooks}}


def record_timings(results_dir: Path = RESULTS_DIR, path: Path | None = None) -> Path:
    """Write :func:`timings_record` to ``path`` (default :data:`TIMINGS_RECORD`)."""
    path = TIMINGS_RECORD if path is None else path
    record = timings_record(results_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n")
    return path


# ---------------------------------------------------------------------------------------------
# command line

def _tune_kernel_malloc() -> None:
    """The notebook kernels (started from this process's environment) get the glibc malloc
    settings of the pairwise engine's workers (:data:`shapelib.pairwise.WORKER_ENVIRON`): the
    notebooks also compute in their own process, and glibc's defaults mmap every large temporary
    array afresh (Fisher–Rao brackets 17 % slower, bounds 2.4×). A value already set is kept."""
    from ..pairwise import WORKER_ENVIRON

    for key, value in WORKER_ENVIRON.items():
        os.environ.setdefault(key.rsplit(".", 1)[1], str(value))


def _raise_interrupted(signum, frame):
    raise Interrupted(signum)


def _still_stopping(signum, frame):
    print("still stopping, please wait", file=sys.stderr, flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples (the same options follow `shapelib study`):\n  python run_all.py --quick\n"
               "  python run_all.py --only table1_pairwise --force\n"
               "  python run_all.py --only adhd200_population -p n_subset=60")
    parser.add_argument("--quick", action="store_true", help="use each notebook's quick (CI) parameters")
    parser.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1, help="notebooks run in parallel")
    parser.add_argument("--only", action="append", metavar="NAME", help="run only this notebook (repeatable)")
    parser.add_argument("-p", "--parameter", action="append", default=[], metavar="NAME=VALUE",
                        help="set a parameter of every selected notebook that declares it (repeatable; "
                             "VALUE is a Python literal, e.g. -p sigma2=0.5 -p 'sigma2s=[0.1, 0.5]')")
    parser.add_argument("--force", action="store_true", help="re-run notebooks whose inputs are unchanged")
    parser.add_argument("--list", action="store_true", help="list the notebooks (and their parameters) and exit")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR, help="where results go (default: results/)")
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=True,
                        help="show progress: bars on a terminal, a line per minute in a log (default: on)")
    parser.add_argument("--record-timings", action="store_true",
                        help="write the run times of the last full run (results/*/.inputs.json) to "
                             "docs/_data/benchmarks/run_times.json, for the documentation's performance page, and exit")
    args = parser.parse_args(argv)
    from .._validate import parse_assignment

    if args.record_timings:
        try:
            print(f"updated {record_timings(args.results_dir.resolve())}")
        except ValueError as exc:
            parser.error(str(exc))
        return 0
    if args.list:
        print("parameters as a full run passes them to each notebook (--quick's values in brackets):")
        for name in NOTEBOOKS:
            full = {**declared_parameters(name), **notebook_parameters(name, quick=False)}
            quick = {**full, **notebook_parameters(name, quick=True)}
            print(name + "  " + " ".join(f"{k}={v!s}" + (f" [{quick[k]!s}]" if quick[k] != v else "")
                                         for k, v in full.items() if k != "output_dir"))
        return 0
    names = list(NOTEBOOKS)
    if args.only:
        unknown = sorted(set(args.only) - set(NOTEBOOKS))
        if unknown:
            parser.error(f"unknown notebook(s) {unknown}; choose from {list(NOTEBOOKS)}")
        names = [n for n in names if n in args.only]
    overrides = {}
    try:
        for text in args.parameter:
            key, value = parse_assignment(text, flag="-p", example="sigma2=0.5")
            if key == "output_dir":
                raise ValueError("-p output_dir: run_all.py chooses it (use --results-dir)")
            overrides[key] = value
        declared = {n: declared_parameters(n) for n in names}
        for key, value in overrides.items():
            users = [n for n in names if key in declared[n]]
            if not users:
                raise ValueError(f"-p {key}: no selected notebook declares {key!r} "
                                 f"(declared: {', '.join(f'{n}: {sorted(d)}' for n, d in declared.items())})")
            for n in users:
                check_parameters(n, {key: value}, declared[n])
    except ValueError as exc:
        parser.error(str(exc))
    previous = {s: signal.signal(s, _raise_interrupted) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        _tune_kernel_malloc()
        return run_all(names, quick=args.quick, force=args.force, jobs=args.jobs,
                       results_dir=args.results_dir.resolve(), overrides=overrides, progress=args.progress)
    except KeyboardInterrupt as exc:
        return 128 + getattr(exc, "signum", signal.SIGINT)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
