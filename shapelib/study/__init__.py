"""Helpers the study notebooks share: recording numbers and saving figures reproducibly.

A notebook records every number the report needs with :func:`record_values`, which
writes ``<output_dir>/values.json``; figures go through :func:`save_figure`, which
produces the same PNG bytes for the same inputs (no timestamps or version strings in the
metadata, fixed DPI).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .._files import write_text_atomic

__all__ = ["stratified_sample", "record_values", "record_verdict", "load_values", "save_figure", "pair_key", "default_output_dir", "VALUES_FILE", "VERDICTS"]

VALUES_FILE = "values.json"


def __getattr__(name):
    # the study's scale, for the notebooks, from the mathematics on first use (a notebook that only
    # records values does not load the compiled kernels and SciPy)
    if name == "PAPER_CENTROID_SIZE":
        from ..geometry.scale import PAPER_CENTROID_SIZE

        return PAPER_CENTROID_SIZE
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def stratified_sample(idx, n: int, cells, rng) -> np.ndarray:
    """``n`` of the indices ``idx``, balanced over ``cells`` (sorted; all of ``idx`` if ``n >= len(idx)``).

    ``cells`` are boolean masks over the whole index range (e.g. diagnosis × sex); cell ``c`` gives
    ``n // C`` indices, the first ``n % C`` cells one more, each drawn by ``rng`` without replacement
    (a cell with fewer gives all it has), in the order of ``cells``, so a seed fixes the sample.
    """
    idx = np.asarray(idx)
    if n >= len(idx):
        return np.sort(idx)
    members = [idx[np.asarray(mask, dtype=bool)[idx]] for mask in cells]
    take = [n // len(members) + (k < n % len(members)) for k in range(len(members))]
    return np.sort(np.concatenate([rng.choice(m, size=min(t, len(m)), replace=False) for m, t in zip(members, take)]))


def project_root(start=None) -> Path | None:
    """The study checkout at or above ``start`` (default: the working directory), or None.

    A checkout is recognised by its ``run_all.py`` beside a ``notebooks/`` folder.
    """
    here = Path(start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        if is_checkout(folder):
            return folder
    return None


def is_checkout(folder) -> bool:
    """Whether ``folder`` is a study checkout: its ``run_all.py`` beside a ``notebooks/`` folder."""
    folder = Path(folder)
    return (folder / "run_all.py").is_file() and (folder / "notebooks").is_dir()


def default_output_dir(name: str, *, start=None) -> Path:
    """Where notebook ``name`` writes when run by hand: ``<checkout>/results/<name>``.

    The checkout is found from the working directory upwards (:func:`project_root`), so a
    notebook opened in Jupyter from ``notebooks/`` writes to the same top-level ``results/``
    as ``run_all.py``; outside a checkout, ``./results/<name>``. ``run_all.py`` passes its own
    ``output_dir`` instead.
    """
    if not name or Path(name).name != name:
        raise ValueError(f"name must be a notebook name without folders; got {name!r}")
    root = project_root(start)
    return (root if root is not None else Path(start or Path.cwd()).resolve()) / "results" / name


def pair_key(item: str, column: str, i: int, j: int) -> str:
    """Canonical key of a pairwise value, e.g. ``table1/procrustes/1-2`` (ids sorted)."""
    a, b = sorted((int(i), int(j)))
    return f"{item}/{column}/{a}-{b}"


def _to_jsonable(x):
    if isinstance(x, dict):
        return {str(k): _to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_to_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _to_jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        if not math.isfinite(x):
            raise ValueError(f"non-finite value {x!r} cannot be recorded")
        return x
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    return x


def record_values(output_dir, values: dict, *, notes: dict | None = None, meta: dict | None = None) -> Path:
    """Merge ``values`` (``{key: number}``) into ``<output_dir>/values.json``.

    Parameters
    ----------
    output_dir : path-like
        The notebook's output folder.
    values : dict
        Numbers keyed as in ``data/reference/*.csv`` (e.g. ``table1/procrustes/1-2``), in the
        quantity's natural units (not the table's printed scale). Must be finite.
    notes : dict, optional
        Free text per item or column (conventions used, caveats), shown in ``REPORT.md``.
    meta : dict, optional
        Anything else worth keeping (timings, solver logs, parameters).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    path = Path(output_dir) / VALUES_FILE
    current = load_values(output_dir) if path.exists() else {"values": {}, "notes": {}, "meta": {}}
    for k, v in values.items():
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise ValueError(f"value for {k!r} must be a real number; got {v!r}")
    current["values"].update(_to_jsonable(values))
    current["notes"].update(_to_jsonable(notes or {}))
    current["meta"].update(_to_jsonable(meta or {}))
    write_text_atomic(path, json.dumps(current, indent=1, sort_keys=True) + "\n")
    return path


#: The statuses a figure verdict may have (``REPORT.md``'s "Figures" table).
VERDICTS = ("reproduced", "reproduced with a difference", "not reproduced")


def record_verdict(output_dir, item: str, status: str, text: str) -> Path:
    """Record the verdict on one paper item (a figure, a section) against its caption and text.

    Stored in ``<output_dir>/values.json`` under ``notes["verdict/<item>"]`` as
    ``{"status": status, "text": text}``; ``REPORT.md`` lists every verdict in its "Figures" table.

    Parameters
    ----------
    output_dir : path-like
        The notebook's output folder.
    item : str
        The paper item, e.g. ``"fig06"`` or ``"sec3e"`` (no ``/``).
    status : {"reproduced", "reproduced with a difference", "not reproduced"}
    text : str
        What was measured and why this status: generated from the notebook's numbers, never
        a hard-coded claim.

    Raises
    ------
    ValueError
        If ``status`` is not one of :data:`VERDICTS`, or ``item`` or ``text`` is empty.
    """
    if status not in VERDICTS:
        raise ValueError(f"verdict status for {item!r} must be one of {VERDICTS}; got {status!r}")
    if not isinstance(item, str) or not item or "/" in item:
        raise ValueError(f"verdict item must be a non-empty name without '/'; got {item!r}")
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"verdict for {item!r} needs a text saying what was measured")
    return record_values(output_dir, {}, notes={f"verdict/{item}": {"status": status, "text": text.strip()}})


def load_values(output_dir) -> dict:
    """Read ``<output_dir>/values.json`` (``{"values": ..., "notes": ..., "meta": ...}``)."""
    with open(Path(output_dir) / VALUES_FILE) as fh:
        data = json.load(fh)
    for key in ("values", "notes", "meta"):
        data.setdefault(key, {})
    return data


def save_figure(fig, output_dir, name: str, *, dpi: int = 120) -> Path:
    """Save ``fig`` as ``<output_dir>/<name>.png`` deterministically and return the path.

    PNG metadata (software version, creation time) is stripped, so identical figures give
    identical bytes.
    """
    path = Path(output_dir) / f"{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, metadata={"Software": None}, bbox_inches=None)
    return path


