"""Reading point sets — shapes without landmarks — from files: any number of points per specimen.

:func:`read_point_sets` reads one or several point sets from

* ``.csv``: columns ``x, y`` (and ``z``), one row per point: one set; with an ``id`` (or
  ``specimen``) column, one set per id, in order of first appearance;
* ``.npy``: an ``(n, d)`` array (one set) or ``(N, n, d)`` (N sets of n points);
* ``.npz``: one ``(n_i, d)`` array per key (the keys are the ids);
* ``.tps`` (tpsDig): each specimen's ``LM=``/``LM3=`` points and the points of its ``CURVES=``
  blocks (``POINTS=m`` + m rows; ``OUTLINES=`` the same) together, counts free to differ between
  specimens.

Landmark files with a fixed number of landmarks in correspondence: :mod:`shapelib.io`.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .._validate import InputError, literal
from ..pointsets.checks import as_point_set, as_point_sets

__all__ = ["read_point_sets", "write_point_set"]

_SUFFIXES = (".csv", ".npy", ".npz", ".tps")


def read_point_sets(path) -> tuple[list[np.ndarray], list[str]]:
    """Read the point sets of a file (CSV, NumPy or tpsDig), counts free to differ between sets.

    Parameters
    ----------
    path : str or Path
        A ``.csv``, ``.npy``, ``.npz`` or ``.tps`` file (the layouts are in the module docstring).

    Returns
    -------
    sets : list of ndarray
        One ``(n_i, d)`` float64 array per set (checked by :func:`shapelib.as_point_sets`: at
        least 2 finite, distinct points, one d for all).
    ids : list of str
        The sets' ids (CSV ``id`` column, NumPy keys or positions, tps ``ID=``/``IMAGE=`` or
        positions).

    Raises
    ------
    InputError
        Naming the file (and line or set) for an unreadable file or a bad point set.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from shapelib.io import read_point_sets
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "two.csv"
    >>> _ = f.write_text("id,x,y\\na,0,0\\na,1,0\\na,0,1\\nb,0,0\\nb,2,1\\n")
    >>> sets, ids = read_point_sets(f)
    >>> [s.shape for s in sets], ids
    ([(3, 2), (2, 2)], ['a', 'b'])
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in _SUFFIXES:
        raise InputError(f"{literal(p)}: point sets are read from {', '.join(_SUFFIXES)} files; got {literal(suffix or 'no suffix')}")
    if not p.is_file():
        raise InputError(f"{literal(p)}: no such file")
    if suffix == ".csv":
        sets, ids = _read_csv(p)
    elif suffix == ".npy":
        arr = np.load(p, allow_pickle=False)
        if arr.ndim == 3:
            sets, ids = list(arr), [str(i) for i in range(len(arr))]
        else:
            sets, ids = [arr], [p.stem]
    elif suffix == ".npz":
        with np.load(p, allow_pickle=False) as z:
            ids = list(z.files)
            sets = [z[k] for k in ids]
    else:
        sets, ids = _read_tps(p)
    if len(sets) == 1:
        return [as_point_set(sets[0], name=f"{p} ({ids[0]})" if ids[0] != p.stem else str(p))], ids
    return as_point_sets(sets, name=str(p)), ids


def _read_csv(p):
    import pandas as pd

    try:
        df = pd.read_csv(p)
    except Exception as exc:  # pandas' parser errors carry the line
        raise InputError(f"{literal(p)}: not a readable CSV file: {literal(exc)}") from None
    cols = {c.strip().lower(): c for c in df.columns}
    coords = [cols[c] for c in ("x", "y", "z") if c in cols]
    if len(coords) < 2 or "x" not in cols or "y" not in cols:
        raise InputError(f"{literal(p)}: a point-set CSV needs columns x and y (and z); got {literal(list(df.columns))}")
    key = cols.get("id", cols.get("specimen"))
    if key is None:
        return [df[coords].to_numpy(dtype=float)], [p.stem]
    ids = list(dict.fromkeys(df[key].astype(str)))
    groups = df.groupby(df[key].astype(str), sort=False)
    return [groups.get_group(i)[coords].to_numpy(dtype=float) for i in ids], ids


_KEY = re.compile(r"^\s*([A-Za-z0-9]+)\s*=\s*(.*?)\s*$")


def _read_tps(p):
    sets, ids = [], []
    cur, need, dim = None, 0, 2
    for lineno, line in enumerate(p.read_text(errors="replace").splitlines(), 1):
        if not line.strip():
            continue
        m = _KEY.match(line)
        if need and not m:
            vals = line.split()
            if len(vals) != dim:
                raise InputError(f"{literal(p)}: line {lineno}: expected {dim} coordinates, got {literal(line.strip())}")
            try:
                cur["points"].append([float(v) for v in vals])
            except ValueError:
                raise InputError(f"{literal(p)}: line {lineno}: not a number in {literal(line.strip())}") from None
            need -= 1
            continue
        if not m:
            raise InputError(f"{literal(p)}: line {lineno}: unexpected {literal(line.strip())} (more rows than a "
                             "LM=/POINTS= count declares?)")
        key, value = m.group(1).upper(), m.group(2)
        if key in ("LM", "LM3"):
            cur = {"points": [], "id": None, "image": None}
            sets.append(cur)
            dim = 3 if key == "LM3" else 2
            need = _count(value, p, lineno, key)
        elif key == "POINTS":
            if cur is None:
                raise InputError(f"{literal(p)}: line {lineno}: POINTS= before any LM= specimen header")
            need = _count(value, p, lineno, key)
        elif cur is not None and key == "ID":
            cur["id"] = value
        elif cur is not None and key == "IMAGE":
            cur["image"] = Path(value.replace("\\", "/")).stem
    if need:
        raise InputError(f"{literal(p)}: end of file with {need} more point row(s) expected")
    if not sets:
        raise InputError(f"{literal(p)}: no LM= specimen header: not a tpsDig file")
    out_ids = [s["id"] or s["image"] or str(i) for i, s in enumerate(sets)]
    return [np.asarray(s["points"], dtype=float).reshape(-1, 3 if len(s["points"]) and len(s["points"][0]) == 3 else 2)
            for s in sets], out_ids


def _count(value, p, lineno, key):
    try:
        n = int(value)
    except ValueError:
        raise InputError(f"{literal(p)}: line {lineno}: {key}= needs a count; got {literal(value)}") from None
    if n < 0:
        raise InputError(f"{literal(p)}: line {lineno}: {key}= needs a count >= 0; got {n}")
    return n


def write_point_set(path, points) -> Path:
    """Write one point set to ``.csv`` (columns x, y[, z]) or ``.npy``; returns the path.

    Parameters
    ----------
    path : str or Path
        The file; its suffix, ``.csv`` or ``.npy``, chooses the format. A CSV file is replaced
        atomically if it exists.
    points : array_like, shape (n, d)
        The points, one row each (d = 2 or 3 for CSV: columns ``x, y[, z]``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        For a suffix other than ``.csv`` or ``.npy``.

    See Also
    --------
    read_point_sets : Reads it back.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from shapelib.io import read_point_sets, write_point_set
    >>> tmp = tempfile.TemporaryDirectory()
    >>> f = write_point_set(Path(tmp.name) / "p.csv", [[0.5, 1.0], [2.0, -1.0]])
    >>> print(f.read_text(), end="")
    x,y
    0.5,1.0
    2.0,-1.0
    >>> read_point_sets(f)[0][0].tolist()
    [[0.5, 1.0], [2.0, -1.0]]
    >>> tmp.cleanup()
    """
    from .._files import write_text_atomic

    p = Path(path)
    x = np.asarray(points, dtype=float)
    if p.suffix.lower() == ".npy":
        np.save(p, x)
        return p
    if p.suffix.lower() != ".csv":
        raise InputError(f"{literal(p)}: a point set is written as .csv or .npy")
    head = ",".join("xyz"[: x.shape[1]])
    rows = "\n".join(",".join(repr(float(v)) for v in row) for row in x)
    write_text_atomic(p, f"{head}\n{rows}\n")
    return p
