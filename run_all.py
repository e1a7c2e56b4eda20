#!/usr/bin/env python
"""Regenerate every figure and table of the study into ``results/`` and write ``results/REPORT.md``.

Usage::

    python run_all.py                 # full parameters, all notebooks, in parallel
    python run_all.py --quick         # the quick parameters CI uses
    python run_all.py --only table1_pairwise --force
    python run_all.py --list

Each notebook (``notebooks/<name>.py``, jupytext percent format, one cell tagged
``parameters``) is executed by papermill into a temporary folder ``results/.tmp-<name>-*``
and moved to ``results/<name>/`` only when it succeeds, so a failed or interrupted run never
leaves a half-written folder nor destroys the previous results. A notebook whose inputs
(its source, the ``shapelib`` sources, its parameters, the checksums of its data files) are
unchanged since its last successful run is skipped unless ``--force``.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent
NOTEBOOK_DIR = ROOT / "notebooks"
RESULTS_DIR = ROOT / "results"
REFERENCE_DIR = ROOT / "data" / "reference"

CC_FILES = ["cdfhc/cdfhc_data2D_CC.mat"]

#: name -> full parameters, quick parameters (CI), raw data files used (their checksums key the cache).
#: ``expects`` maps a value-key prefix to how many values the notebook must record under it
#: (checked by tests/test_notebooks.py, so that the report never silently loses a column).
NOTEBOOKS: dict[str, dict] = {
    "fig07_fish_deformations": {
        "params": {}, "quick": {"max_iter": 3},
        "data": ["cdfhc/cdfhc_data2D_fish.mat", "cdfhc/cdfhc_data2D_beijing.mat", "tps-rpm/save_fish_def_2_1.mat"],
        "expects": {"fig08/": 6, "fig09/": 3},
    },
    "fig10_corpus_callosum": {"params": {}, "quick": {}, "data": CC_FILES, "expects": {"fig10/": 2}},
    "fig01_gmm_representation": {"params": {}, "quick": {"resolution": 80}, "data": ["mpeg7/fish-1.gif"] + CC_FILES,
                                 "expects": {"fig01/": 6}},
    "fig02_intrinsic_extrinsic": {"params": {}, "quick": {}, "data": ["mpeg7/fish-1.gif"], "expects": {"fig02/": 3}},
    "fig04_line_bending": {"params": {}, "quick": {"n_steps": 6, "max_iter": 20}, "data": [],
                           "expects": {"fig04/": 6, "fig05/": 1}},
    "fig06_square_rotation": {"params": {}, "quick": {"n_steps": 8, "max_iter": 20}, "data": [],
                              "expects": {"fig06/": 8}},
    "sec3e_extrinsic_warp": {"params": {}, "quick": {"n_steps": 4, "max_iter": 5, "grid_size": 48},
                             "data": ["mpeg7/fish-1.gif"], "expects": {"sec3e/": 3}},
    "alpha_discretisation": {
        "params": {}, "quick": {"n_pairs": 2, "n_steps_list": [2, 4, 8], "max_iter": 20},
        "data": CC_FILES, "expects": {"alpha_discretisation/": 13},
    },
    "table1_pairwise": {
        "params": {"n_steps": 8, "max_iter": 200, "fisher_rao_max_iter": 200, "tol": 1e-6},
        "quick": {"n_steps": 2, "max_iter": 3, "fisher_rao_max_iter": 3, "diffeomorphism_max_iter": 3},
        "data": CC_FILES,
        "expects": {f"table1/{c}/": 21 for c in (
            "procrustes", "hausdorff", "tps", "wendland", "diffeomorphism", "alpha_s2_0.1", "alpha_s2_0.5", "alpha_s2_1.5",
            "fisher_rao_s2_0.1", "fisher_rao_s2_0.5", "fisher_rao_s2_1.5")} | {"fig11/": 28, "speed/": 2, "constant/table1/": 7},
    },
    "adhd200_population": {
        "params": {"store_dir": "results/.stores/adhd200_population"},
        "quick": {"n_shapes": 40, "n_subset": 8, "geodesic_n_steps": 2, "geodesic_max_iter": 1, "permutations": 199,
                  "store_dir": None},
        "data": ["adhd200/ADHD-200.Rdata", "adhd200/clinical_info.csv"],
        "expects": {"adhd200/permanova/": 108, "adhd200/knn/": 36, "adhd200/mantel/": 62, "adhd200/mds/": 14,
                    "adhd200/bracket/": 6, "adhd200/correspondence/": 4, "adhd200/scale/": 3},
    },
}


class NotebookError(RuntimeError):
    """A notebook failed; the message names the failing cell."""


def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def notebook_parameters(name: str, *, quick: bool) -> dict:
    spec = NOTEBOOKS[name]
    params = dict(spec["params"])
    if quick:
        params.update(spec["quick"])
    return params


def input_fingerprint(name: str, params: dict) -> str:
    """Hash of everything a notebook's results depend on."""
    from shapelib.datasets import data_checksums

    h = hashlib.sha256()
    h.update((NOTEBOOK_DIR / f"{name}.py").read_bytes())
    for src in sorted((ROOT / "shapelib").rglob("*.py")):
        h.update(str(src.relative_to(ROOT)).encode())
        h.update(src.read_bytes())
    h.update(json.dumps(params, sort_keys=True).encode())
    h.update(json.dumps(data_checksums(NOTEBOOKS[name]["data"]), sort_keys=True).encode())
    return h.hexdigest()


def _declared_parameters(nb) -> set[str]:
    """Names assigned in the cell tagged ``parameters``."""
    import ast

    for cell in nb.cells:
        if "parameters" in cell.get("metadata", {}).get("tags", []):
            tree = ast.parse(cell.source)
            names = set()
            for node in tree.body:
                targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
                names |= {t.id for t in targets if isinstance(t, ast.Name)}
            return names
    raise NotebookError("no cell tagged 'parameters'")


def execute_notebook(name: str, params: dict, output_dir: Path, *, log_output: bool = False) -> None:
    """Run ``notebooks/<name>.py`` with ``params``; outputs (incl. the executed notebook) go to ``output_dir``.

    Raises
    ------
    ValueError
        If ``params`` names a parameter the notebook does not declare.
    NotebookError
        If a cell raises; the message names the cell.
    """
    import jupytext
    import nbformat
    import papermill as pm

    nb = jupytext.read(NOTEBOOK_DIR / f"{name}.py")
    declared = _declared_parameters(nb)
    unknown = sorted(set(params) - declared)
    if unknown:
        raise ValueError(f"{name}: unknown parameter(s) {unknown}; the notebook declares {sorted(declared)}")
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    output_dir.mkdir(parents=True, exist_ok=True)
    src = output_dir / f"{name}.source.ipynb"
    nbformat.write(nb, src)
    out = output_dir / f"{name}.ipynb"
    try:
        pm.execute_notebook(
            str(src), str(out), parameters={**params, "output_dir": str(output_dir)},
            kernel_name="python3", cwd=str(ROOT), progress_bar=False, log_output=log_output,
        )
    except pm.PapermillExecutionError as exc:
        raise NotebookError(
            f"{name}: cell {exc.cell_index} (execution count {exc.exec_count}) raised {exc.ename}: {exc.evalue}"
        ) from None
    finally:
        src.unlink(missing_ok=True)


def run_one(name: str, *, quick: bool, force: bool, results_dir: Path = RESULTS_DIR) -> tuple[str, str, float, str]:
    """Run one notebook atomically into ``results_dir/<name>``. Returns (name, status, seconds, message)."""
    params = notebook_parameters(name, quick=quick)
    fingerprint = input_fingerprint(name, params)
    final = results_dir / name
    info_path = final / ".inputs.json"
    if not force and info_path.exists():
        try:
            if json.loads(info_path.read_text()).get("fingerprint") == fingerprint:
                return name, "skipped", 0.0, "inputs unchanged"
        except json.JSONDecodeError:
            pass
    results_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".tmp-{name}-", dir=results_dir))
    t0 = time.perf_counter()
    try:
        execute_notebook(name, params, tmp)
        seconds = time.perf_counter() - t0
        if not (tmp / "values.json").exists():
            raise NotebookError(f"{name}: finished without writing values.json")
        (tmp / ".inputs.json").write_text(json.dumps(
            {"fingerprint": fingerprint, "params": params, "mode": "quick" if quick else "full",
             "seconds": round(seconds, 2)}, indent=1, sort_keys=True) + "\n")
        # swap into place: the old folder is only removed once the new one is in place
        old = None
        if final.exists():
            old = Path(tempfile.mkdtemp(prefix=f".old-{name}-", dir=results_dir))
            os.replace(final, old / name)
        os.chmod(tmp, 0o755)
        os.replace(tmp, final)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return name, "ok", seconds, ""
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        return name, "FAILED", time.perf_counter() - t0, str(exc)


def _clean_stale(results_dir: Path) -> None:
    for p in list(results_dir.glob(".tmp-*")) + list(results_dir.glob(".old-*")):
        shutil.rmtree(p, ignore_errors=True)


def run_all(names, *, quick: bool, force: bool, jobs: int, results_dir: Path = RESULTS_DIR) -> int:
    """Run ``names`` (in parallel), print one line per notebook, write the report. Returns an exit code."""
    from shapelib.report import write_report

    results_dir.mkdir(parents=True, exist_ok=True)
    _clean_stale(results_dir)
    failures = []
    done = 0
    with cf.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        futures = [pool.submit(run_one, n, quick=quick, force=force, results_dir=results_dir) for n in names]
        try:
            for fut in cf.as_completed(futures):
                name, status, seconds, msg = fut.result()
                done += 1
                line = f"[{done}/{len(names)}] {name:<28} {status:<8} {seconds:7.1f} s"
                print(line + (f"  {msg}" if msg and status == "FAILED" else ""), flush=True)
                if status == "FAILED":
                    failures.append((name, msg))
        except KeyboardInterrupt:
            for f in futures:
                f.cancel()
            print("interrupted: finished notebooks are in place, the others keep their previous results", file=sys.stderr)
            raise
    report = write_report(results_dir, REFERENCE_DIR)
    print(f"report: {report.relative_to(ROOT) if report.is_relative_to(ROOT) else report}")
    if failures:
        print(f"{len(failures)} notebook(s) failed:", file=sys.stderr)
        for name, msg in failures:
            print(f"  {msg}", file=sys.stderr)
        return 1
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="use each notebook's quick (CI) parameters")
    parser.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1, help="notebooks run in parallel")
    parser.add_argument("--only", action="append", metavar="NAME", help="run only this notebook (repeatable)")
    parser.add_argument("--force", action="store_true", help="re-run notebooks whose inputs are unchanged")
    parser.add_argument("--list", action="store_true", help="list the notebooks and exit")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR, help="where results go (default: results/)")
    args = parser.parse_args(argv)
    if args.list:
        for name in NOTEBOOKS:
            print(name)
        return 0
    names = list(NOTEBOOKS)
    if args.only:
        unknown = sorted(set(args.only) - set(NOTEBOOKS))
        if unknown:
            parser.error(f"unknown notebook(s) {unknown}; choose from {list(NOTEBOOKS)}")
        names = [n for n in names if n in args.only]
    return run_all(names, quick=args.quick, force=args.force, jobs=args.jobs, results_dir=args.results_dir.resolve())


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
