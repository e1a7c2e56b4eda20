"""What the landmark readers and writers share: the formats, number parsing, the missing-landmark report."""

from __future__ import annotations

import codecs
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .._validate import InputError, check_dimension, literal


# file extension -> format name (documented in shapelib/io/__init__.py, which serves it)
FORMATS = {".tps": "tps", ".csv": "csv", ".npy": "npy", ".npz": "npz"}


# what write_tps marks specimens with negative coordinates with (documented in shapelib/io/__init__.py)
NEGATIVE_COORDINATES_COMMENT = "shapelib: negative values are coordinates, not missing landmarks"


_MISSING_TOKENS = {"", "na", "nan", "n/a", "null", "none"}


_AXES = "xyz"


def _format_of(path, format=None) -> str:
    if format is not None:
        if format not in FORMATS.values():
            raise ValueError(f"format must be one of {sorted(set(FORMATS.values()))}; got {format!r}")
        return format
    ext = Path(path).suffix.lower()
    if ext not in FORMATS:
        raise ValueError(f"{path}: unknown landmark file extension {ext!r}; expected one of {sorted(FORMATS)}")
    return FORMATS[ext]


def _check_missing_option(missing):
    if missing not in ("error", "nan"):
        raise ValueError(f"missing must be 'error' or 'nan'; got {missing!r}")


def _report_missing(shapes, specimens, path, missing, hint="", lines=None, negative_as_missing=False):
    """Raise on NaN landmarks (naming file, line, specimen and landmark) unless ``missing == "nan"``.

    ``lines`` (N, K): the file line of each landmark, else the specimen's ``line`` column is used."""
    bad = np.isnan(shapes).any(axis=2)
    specimens["n_missing"] = bad.sum(axis=1).astype(int)
    if missing == "error" and bad.any():
        i, k = (int(a) for a in np.argwhere(bad)[0])
        where = f"{path}: "
        if lines is not None:
            where += f"line {int(lines[i][k])}, "
        elif "line" in specimens and not pd.isna(specimens["line"].iloc[i]):
            where += f"line {int(specimens['line'].iloc[i])}, "
        where += f"specimen {specimens['id'].iloc[i]!r} (#{i + 1})"
        raise InputError(
            f"{literal(where)}: landmark {k + 1} is missing{literal(hint)} ({int(bad.sum())} missing landmark(s) in "
            f"{int(bad.any(axis=1).sum())} specimen(s) in all); {{keep_missing}}",
            {"negative_as_missing": negative_as_missing})


class _NotFinite(ValueError):
    """A number that is not finite (``inf``, ``-Infinity``, ``1e400``): numeric, but not a coordinate."""


def _parse_number(token: str):
    """float, or None for a missing-value token; raises :class:`_NotFinite` for an infinite
    number (``inf``, or one that overflows, like ``1e400``) and ValueError for anything else."""
    t = token.strip()
    if t.lower() in _MISSING_TOKENS:
        return None
    x = float(t)  # accepts scientific notation; "nan"/"inf" variants handled below
    if not math.isfinite(x):
        if math.isnan(x):
            return None
        raise _NotFinite(token)
    return x


def _read_text(path) -> str:
    raw = Path(path).read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        # tpsDig on Windows writes the ANSI code page; a UTF-8 byte-order mark may still lead it
        text = raw.removeprefix(codecs.BOM_UTF8).decode("latin-1")
    return text.replace("\r\n", "\n").replace("\r", "\n")


def _fmt(x: float) -> str:
    """Shortest round-tripping positional decimal (what tpsDig and ktch's reader expect)."""
    return np.format_float_positional(float(x), unique=True, trim="-")


def _specimen_table(specimens, n, path):
    """Normalise the ``specimens`` argument of the writers to a DataFrame with ``id`` first."""
    if specimens is None:
        return pd.DataFrame({"id": [str(i) for i in range(n)]})
    if isinstance(specimens, pd.DataFrame):
        table = specimens.reset_index(drop=True)
        if "id" not in table:
            raise ValueError(f"{path}: the specimens table needs an 'id' column; got columns {list(table.columns)}")
    else:
        table = pd.DataFrame({"id": list(specimens)})
    if len(table) != n:
        raise ValueError(f"{path}: {len(table)} specimen ids for {n} shapes")
    table = table.copy()
    table["id"] = table["id"].astype(str)
    return table


def _as_writable(shapes, path):
    x = np.asarray(shapes, dtype=np.float64)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3:
        raise ValueError(f"{path}: shapes must have shape (N, K, d); got {x.shape}")
    check_dimension(x, name=str(path))
    if np.isinf(x).any():
        i, k, _ = np.argwhere(np.isinf(x))[0]
        raise ValueError(f"{path}: shapes[{i}] landmark {k + 1} is infinite")
    return x


def _warn_duplicate_ids(specimens, path):
    dup = specimens["id"][specimens["id"].duplicated()]
    if len(dup):
        warnings.warn(f"{path}: specimen id {dup.iloc[0]!r} occurs more than once ({len(dup)} duplicate(s)); "
                      "ids label distance matrices, so make them unique", UserWarning, stacklevel=3)
