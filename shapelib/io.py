"""Landmark files: tpsDig ``.tps``, CSV (wide and long), NumPy ``.npy``/``.npz``, geomorph arrays.

Everything here returns what the rest of the library consumes — a float64 ``(N, K, d)`` array of
``N`` specimens with ``K`` landmarks in ``d = 2`` or ``3`` dimensions (eq. 5's landmark vectors,
one row per landmark) — plus a :class:`pandas.DataFrame` with one row per specimen whose first
column is ``"id"``. Reading is strict: a ragged specimen, a non-numeric cell, a missing
landmark, a landmark-count mismatch or an empty file raise :class:`ValueError` naming the file,
the line or specimen, and the landmark. Missing landmarks become NaN only when the caller asks
for it (``missing="nan"``); nothing downstream accepts NaN, so that is for inspection only.

Formats
-------
``.tps`` (tpsDig, Rohlf; also what geomorph's ``readland.tps``/``writeland.tps`` read and write)
    One block per specimen::

        LM=3                 (LM3= for 3-D; the key is case-insensitive)
        412.0 233.5
        398 240
        -1 -1                (tpsDig's code for a missing landmark: negative coordinates)
        CURVES=1             (optional semilandmarks: CURVES=c, then c blocks POINTS=m + m rows;
        POINTS=2              OUTLINES= blocks are read the same way)
        401 250
        405 260
        IMAGE=fish_01.jpg
        ID=0
        SCALE=0.0254         (units per pixel; applied only with ``scale=True``)
        COMMENT=left side

    Blank lines and lines starting with ``#`` are skipped; CRLF line endings, a UTF-8 byte-order
    mark and scientific notation are accepted. Semilandmarks are never mixed into the fixed
    landmarks: ``read_tps(..., return_curves=True)`` returns them separately.
CSV, wide
    One row per specimen: an id column (``id``, ``specimen``, ``specimen_id``, ``name`` or the
    first non-coordinate column), then coordinate columns named ``x1, y1, x2, y2, …``,
    ``1.X, 1.Y, …`` (geomorph's ``two.d.array``) or ``<landmark>_x, <landmark>_y, …``. Other
    columns are kept as specimen metadata.
CSV, long
    One row per landmark: ``specimen, landmark, x, y[, z]``.
``.npy`` / ``.npz``
    An ``(N, K, d)`` array (``.npz``: key ``shapes`` and optionally ``ids``).
geomorph ``p × k × n`` arrays
    :func:`from_pkn` / :func:`to_pkn`.
"""

from __future__ import annotations

import codecs
import csv
import math
import re
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ._files import write_text_atomic
from ._validate import InputError, check_dimension, literal

__all__ = [
    "read_landmarks", "write_landmarks", "read_tps", "write_tps", "read_csv", "write_csv",
    "read_npy", "write_npy", "from_pkn", "to_pkn", "FORMATS", "NEGATIVE_COORDINATES_COMMENT",
]

#: file extension -> format name
FORMATS = {".tps": "tps", ".csv": "csv", ".npy": "npy", ".npz": "npz"}
#: What :func:`write_tps` adds, as a ``COMMENT=`` line, to each specimen with negative coordinates
#: (e.g. aligned shapes), and :func:`read_tps` honours: there a negative value is a coordinate,
#: not tpsDig's missing-landmark code (missing landmarks are then written ``NA``). A standard tps
#: field, which other readers skip or keep as a comment (ktch reads such files; tpsDig still takes
#: the negative values as missing).
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


# ---------------------------------------------------------------------------------------------
# tpsDig
# ---------------------------------------------------------------------------------------------

_KEY_LINE = re.compile(r"^\s*([A-Za-z][A-Za-z0-9_]*)\s*=\s*(.*?)\s*$")


@dataclass
class _TpsSpecimen:
    number: int                 # 1-based position in the file
    line: int                   # line of its LM= header
    dim: int
    declared: int
    rows: list = field(default_factory=list)
    curves: list = field(default_factory=list)     # list of lists of rows
    meta: dict = field(default_factory=dict)
    negative_coordinates: bool = False             # it has the NEGATIVE_COORDINATES_COMMENT line

    def label(self):
        ident = self.meta.get("ID")
        return f"specimen #{self.number}" + (f" (ID={ident})" if ident is not None else "") + f" (LM= at line {self.line})"


def _read_text(path) -> str:
    raw = Path(path).read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        # tpsDig on Windows writes the ANSI code page; a UTF-8 byte-order mark may still lead it
        text = raw.removeprefix(codecs.BOM_UTF8).decode("latin-1")
    return text.replace("\r\n", "\n").replace("\r", "\n")


def _tps_count(value: str, *, key: str, noun: str, where: str, where_negative: str) -> int:
    """The count that opens a ``LM=`` / ``CURVES=`` / ``POINTS=`` block; ValueError naming the line."""
    try:
        n = int(value.split()[0])
    except (ValueError, IndexError):
        raise ValueError(f"{where}: {key}= needs a {noun}; got {value!r}") from None
    if n < 0:
        raise ValueError(f"{where_negative}: {key}= needs a non-negative {noun}; got {n}")
    return n


def _parse_tps(path):
    """Parse a .tps file into _TpsSpecimen records (no missing-value or scale policy yet)."""
    text = _read_text(path)
    specimens: list[_TpsSpecimen] = []
    cur = None
    pending = 0          # coordinate rows still expected for the current block
    target = None        # list receiving those rows
    block = ""           # what those rows belong to, for messages
    curves_left = 0      # POINTS= blocks still expected after CURVES=
    for lineno, line in enumerate(text.split("\n"), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        m = _KEY_LINE.match(s)
        if m is None:
            # a coordinate row
            if cur is None:
                raise ValueError(f"{path}: line {lineno}: coordinate row {s!r} appears before the first LM= line "
                                 "(each specimen starts with LM=<number of landmarks>, or LM3= for 3-D)")
            if pending == 0:
                raise ValueError(f"{path}: line {lineno}: unexpected data {s!r} in {cur.label()}: "
                                 f"more coordinate rows than its {block} header declares")
            dim = cur.dim
            tokens = s.replace(",", " ").split()
            index = len(target) + 1
            if len(tokens) != dim:
                raise ValueError(f"{path}: line {lineno}, {cur.label()}, {block} point {index}: "
                                 f"expected {dim} coordinates, got {len(tokens)} ({s!r})")
            values = []
            for t in tokens:
                try:
                    values.append(_parse_number(t))
                except _NotFinite:
                    raise ValueError(f"{path}: line {lineno}, {cur.label()}, {block} point {index}: "
                                     f"non-finite coordinate {t!r} (coordinates must be finite numbers)") from None
                except ValueError:
                    raise ValueError(f"{path}: line {lineno}, {cur.label()}, {block} point {index}: "
                                     f"non-numeric coordinate {t!r}") from None
            target.append((lineno, values))
            pending -= 1
            continue
        key, value = m.group(1).upper(), m.group(2)
        if pending:
            raise ValueError(f"{path}: line {lineno}: {cur.label()}: its {block} header declares "
                             f"{len(target) + pending} points but only {len(target)} coordinate row(s) "
                             f"precede {key}=")
        if key in ("LM", "LM3"):
            if curves_left:
                raise ValueError(f"{path}: line {lineno}: {cur.label()}: CURVES= declares "
                                 f"{curves_left} more POINTS= block(s) than the file has")
            at = f"{path}: line {lineno}"
            n = _tps_count(value, key=key, noun="landmark count", where=at, where_negative=at)
            cur = _TpsSpecimen(number=len(specimens) + 1, line=lineno, dim=3 if key == "LM3" else 2, declared=n)
            specimens.append(cur)
            pending, target, block = n, cur.rows, f"{key}={n}"
            continue
        if cur is None:
            raise ValueError(f"{path}: line {lineno}: {key}= appears before the first LM= line")
        if key in ("CURVES", "OUTLINES"):
            curves_left = _tps_count(value, key=key, noun="count", where=f"{path}: line {lineno}",
                                     where_negative=f"{path}: line {lineno}: {cur.label()}")
            cur.meta.setdefault("CURVE_KIND", key)
        elif key == "POINTS":
            if curves_left <= 0:
                raise ValueError(f"{path}: line {lineno}: {cur.label()}: POINTS= outside a CURVES= block "
                                 "(or more POINTS= blocks than CURVES= declares)")
            n = _tps_count(value, key=key, noun="point count", where=f"{path}: line {lineno}",
                           where_negative=f"{path}: line {lineno}: {cur.label()}")
            curves_left -= 1
            cur.curves.append([])
            pending, target, block = n, cur.curves[-1], f"curve {len(cur.curves)} (POINTS={n})"
        else:
            if curves_left:
                raise ValueError(f"{path}: line {lineno}: {cur.label()}: CURVES= declares "
                                 f"{curves_left} more POINTS= block(s) before {key}=")
            if key in cur.meta and key not in ("COMMENT", "COMMENTS"):
                raise ValueError(f"{path}: line {lineno}: {cur.label()} has a second {key}= line "
                                 "(is an LM= line missing?)")
            if key in ("COMMENT", "COMMENTS") and value.strip() == NEGATIVE_COORDINATES_COMMENT:
                cur.negative_coordinates = True  # written by write_tps: not the user's comment
            elif key in ("COMMENT", "COMMENTS"):
                prev = cur.meta.get("COMMENT")
                cur.meta["COMMENT"] = value if prev is None else f"{prev}; {value}"
            else:
                cur.meta[key] = value
    if pending:
        raise ValueError(f"{path}: end of file: {cur.label()}: its {block} header declares "
                         f"{len(target) + pending} points but only {len(target)} coordinate row(s) follow")
    if curves_left:
        raise ValueError(f"{path}: end of file: {cur.label()}: CURVES= declares {curves_left} more POINTS= block(s)")
    if not specimens:
        raise ValueError(f"{path}: no landmarks: the file has no LM= or LM3= line (empty or not a tpsDig file)")
    return specimens


def read_tps(path, *, scale: bool = False, missing: str = "error", negative: str | None = None,
             return_curves: bool = False):
    """Read a tpsDig ``.tps`` file (the layout is in the module docstring).

    Parameters
    ----------
    path : str or Path
    scale : bool
        Multiply each specimen's coordinates by its ``SCALE=`` value (pixels to units). Every
        specimen must then have one. The specimens table always reports ``scale`` (NaN where the
        file has none) and whether it was ``scaled``.
    missing : {"error", "nan"}
        A missing landmark (``NA`` or, with ``negative="missing"``, negative coordinates) raises
        a ``ValueError`` naming the file, specimen and landmark; ``"nan"`` keeps it as NaN.
    negative : {"missing", "coordinates"}, optional
        tpsDig records a missing landmark as negative coordinates (e.g. ``-1 -1``), so by default
        a landmark with a negative coordinate is missing — except in the specimens that
        :func:`write_tps` marked with the :data:`NEGATIVE_COORDINATES_COMMENT` line (e.g.
        Procrustes-aligned shapes), where negative values are coordinates. ``"coordinates"`` or
        ``"missing"`` decides for every specimen (e.g. ``"coordinates"`` for aligned shapes written
        by another program).
    return_curves : bool
        Also return the ``CURVES=``/``POINTS=`` semilandmarks, kept apart from the landmarks: one
        list per specimen of ``(m, d)`` arrays (scaled and checked like the landmarks).

    Returns
    -------
    shapes : ndarray, shape (N, K, d), float64
        The fixed landmarks (``LM=``/``LM3=``).
    specimens : DataFrame
        ``id`` (``ID=``, else the ``IMAGE=`` file name without extension, else the 0-based
        position, as tpsUtil numbers specimens), ``image``, ``scale``, ``scaled``, ``comment``,
        ``line`` (of the ``LM=`` header), ``n_curves``, ``n_curve_points``, ``n_missing``, and
        any other ``KEY=`` fields in lower case.
    curves : list of list of ndarray
        Only with ``return_curves=True``.

    See Also
    --------
    write_tps : The writer that reads back through this reader.
    read_landmarks : Any format, chosen by the file's extension.

    Examples
    --------
    Two specimens of three landmarks; tpsDig's ``-1 -1`` marks the second one's third landmark
    as missing:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from shapelib.io import read_tps
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = Path(tmp.name) / "fish.tps"
    >>> _ = path.write_text("LM=3\\n1 2\\n3 4\\n5 6\\nID=a\\nLM=3\\n1.5 2\\n3 4.5\\n-1 -1\\nID=b\\n")
    >>> shapes, specimens = read_tps(path, missing="nan")
    >>> shapes.shape, specimens["id"].tolist(), specimens["n_missing"].tolist()
    ((2, 3, 2), ['a', 'b'], [0, 1])
    >>> shapes[1, 2]
    array([nan, nan])
    >>> read_tps(path)
    Traceback (most recent call last):
    ...
    shapelib._validate.InputError: ...: line 9, specimen 'b' (#2): landmark 3 is missing ...
    >>> tmp.cleanup()
    """
    _check_missing_option(missing)
    if negative not in (None, "missing", "coordinates"):
        raise ValueError(f"negative must be None, 'missing' or 'coordinates'; got {negative!r}")
    records = _parse_tps(path)
    dims = {r.dim for r in records}
    if len(dims) > 1:
        other = next(r for r in records if r.dim != records[0].dim)
        raise ValueError(f"{path}: {other.label()} is {other.dim}-D but specimen #1 is {records[0].dim}-D "
                         "(LM= and LM3= blocks mixed)")
    counts = [r.declared for r in records]
    for r in records:
        if r.declared == 0:
            raise ValueError(f"{path}: {r.label()} has no landmarks (LM=0)")
        if r.declared != counts[0]:
            raise ValueError(f"{path}: {r.label()} has {r.declared} landmarks but specimen #1 has {counts[0]}: "
                             "all specimens must have the same landmarks")
    ids = []
    for r in records:
        if "ID" in r.meta and r.meta["ID"] != "":
            ids.append(r.meta["ID"])
        elif r.meta.get("IMAGE"):
            ids.append(Path(r.meta["IMAGE"].replace("\\", "/")).stem)
        else:
            ids.append(str(r.number - 1))
    scales = []
    for r in records:
        if "SCALE" in r.meta:
            try:
                sc = float(r.meta["SCALE"])
            except ValueError:
                raise ValueError(f"{path}: {r.label()}: SCALE={r.meta['SCALE']!r} is not a number") from None
            if not (math.isfinite(sc) and sc > 0):
                raise ValueError(f"{path}: {r.label()}: SCALE={r.meta['SCALE']!r} must be a positive number")
            scales.append(sc)
        else:
            scales.append(np.nan)
    if scale:
        lacking = [r for r, sc in zip(records, scales) if np.isnan(sc)]
        if lacking:
            raise InputError(f"{literal(path)}: {{scale}} but {literal(lacking[0].label())} has no SCALE= line "
                             f"({len(lacking)} of {len(records)} specimens lack one)")

    def negative_missing(r):
        return negative == "missing" or (negative is None and not r.negative_coordinates)

    def to_array(rows, r, what):
        arr = np.array([[np.nan if v is None else v for v in vals] for _, vals in rows], dtype=np.float64)
        arr = arr.reshape(len(rows), r.dim)
        if negative_missing(r):
            arr[(arr < 0).any(axis=1)] = np.nan
        return arr

    shapes = np.stack([to_array(r.rows, r, "landmark") for r in records])
    curves = [[to_array(c, r, "curve") for c in r.curves] for r in records]
    if scale:
        shapes = shapes * np.asarray(scales)[:, None, None]
        curves = [[c * sc for c in cs] for cs, sc in zip(curves, scales)]
    table = {
        "id": ids,
        "image": [r.meta.get("IMAGE") for r in records],
        "scale": scales,
        "scaled": [bool(scale)] * len(records),
        "comment": [r.meta.get("COMMENT") for r in records],
        "line": [r.line for r in records],
        "n_curves": [len(r.curves) for r in records],
        "n_curve_points": [sum(len(c) for c in r.curves) for r in records],
    }
    extra = sorted({k for r in records for k in r.meta} - {"ID", "IMAGE", "SCALE", "COMMENT", "CURVE_KIND"})
    for k in extra:
        table[k.lower()] = [r.meta.get(k) for r in records]
    specimens = pd.DataFrame(table)
    specimens.attrs.update(path=str(path), format="tps")
    negative_as_missing = any(negative_missing(r) for r in records)
    hint = " (NA or negative coordinates, tpsDig's code for a missing landmark)" if negative_as_missing else " (NA)"
    _report_missing(shapes, specimens, path, missing, hint=hint, lines=[[ln for ln, _ in r.rows] for r in records],
                    negative_as_missing=negative_as_missing)
    if missing == "error":
        for i, (r, cs) in enumerate(zip(records, curves)):
            for c_idx, c in enumerate(cs):
                bad = np.isnan(c).any(axis=1)
                if bad.any():
                    raise InputError(f"{literal(path)}: specimen {literal(repr(ids[i]))} (#{i + 1}): curve {c_idx + 1} "
                                     f"point {int(np.argmax(bad)) + 1} is missing{literal(hint)}; {{keep_missing}}",
                                     {"negative_as_missing": negative_as_missing})
    _warn_duplicate_ids(specimens, path)
    return (shapes, specimens, curves) if return_curves else (shapes, specimens)


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


def write_tps(path, shapes, specimens=None, *, curves=None, missing_value: float = -1.0) -> Path:
    """Write shapes as a tpsDig ``.tps`` file that tpsDig, geomorph and :func:`read_tps` read back.

    Parameters
    ----------
    path : str or Path
    shapes : array_like, shape (N, K, d), d = 2 (``LM=``) or 3 (``LM3=``)
    specimens : DataFrame or sequence of str, optional
        ``id`` (``ID=``), and optionally ``image`` (``IMAGE=``), ``scale`` (``SCALE=``, written
        only where the coordinates were not already ``scaled``) and ``comment`` (``COMMENT=``).
        Default ids: ``0, 1, …``.
    curves : list of list of array_like, optional
        Semilandmarks per specimen, written as ``CURVES=``/``POINTS=`` blocks.
    missing_value : float
        What NaN (missing) landmarks are written as, in each coordinate (tpsDig: negative), in a
        file without negative coordinates.

    Returns
    -------
    Path
        ``path``, written atomically (a reader never sees half a file).

    Notes
    -----
    tpsDig reads negative coordinates as missing landmarks. When some coordinates are negative
    (e.g. aligned shapes), every specimen gets the :data:`NEGATIVE_COORDINATES_COMMENT` line, which
    :func:`read_tps` (and so ``shapelib`` commands) honours, and missing landmarks are written
    ``NA``: the file reads back as written, with no options. tpsDig itself would still take the
    negative values as missing.

    See Also
    --------
    read_tps : Reads the file back.
    write_landmarks : Any format, chosen by the file's extension.

    Examples
    --------
    The second shape has a negative coordinate, so the file marks its negative values as
    coordinates and reads back as written:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from shapelib.io import read_tps, write_tps
    >>> shapes = np.array([[[0, 0], [1, 0], [0, 1.5]], [[0, 0], [2, 0], [0, -1]]])
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = write_tps(Path(tmp.name) / "two.tps", shapes, ["a", "b"])
    >>> print(path.read_text().split("\\n\\n")[0])
    LM=3
    0 0
    1 0
    0 1.5
    ID=a
    COMMENT=shapelib: negative values are coordinates, not missing landmarks
    >>> back, specimens = read_tps(path)
    >>> np.array_equal(back, shapes), specimens["id"].tolist()
    (True, ['a', 'b'])
    >>> tmp.cleanup()
    """
    path = Path(path)
    x = _as_writable(shapes, path)
    table = _specimen_table(specimens, len(x), path)
    if curves is not None and len(curves) != len(x):
        raise ValueError(f"{path}: curves has {len(curves)} entries for {len(x)} shapes")
    marked = bool((x < 0).any() or any((np.asarray(c) < 0).any() for cs in (curves or []) for c in cs))
    key = "LM" if x.shape[2] == 2 else "LM3"
    out = []

    def rows(a):
        for p in np.asarray(a, dtype=np.float64):
            out.append(" ".join(("NA" if marked else _fmt(missing_value)) if np.isnan(v) else _fmt(v) for v in p))

    for i, shape in enumerate(x):
        rec = table.iloc[i]
        out.append(f"{key}={len(shape)}")
        rows(shape)
        if curves is not None and len(curves[i]):
            out.append(f"CURVES={len(curves[i])}")
            for c in curves[i]:
                c = np.asarray(c, dtype=np.float64)
                if c.ndim != 2 or c.shape[1] != x.shape[2]:
                    raise ValueError(f"{path}: specimen {rec['id']!r}: each curve must have shape (m, {x.shape[2]})")
                out.append(f"POINTS={len(c)}")
                rows(c)
        image = rec.get("image")
        if isinstance(image, str) and image:
            out.append(f"IMAGE={image}")
        out.append(f"ID={rec['id']}")
        sc = rec.get("scale")
        if sc is not None and not pd.isna(sc) and not bool(rec.get("scaled", False)):
            out.append(f"SCALE={_fmt(sc)}")
        comment = rec.get("comment")
        if isinstance(comment, str) and comment:
            out.append(f"COMMENT={comment}")
        if marked:
            out.append(f"COMMENT={NEGATIVE_COORDINATES_COMMENT}")
        out.append("")
    write_text_atomic(path, "\n".join(out) + "\n")
    return path


def _warn_duplicate_ids(specimens, path):
    dup = specimens["id"][specimens["id"].duplicated()]
    if len(dup):
        warnings.warn(f"{path}: specimen id {dup.iloc[0]!r} occurs more than once ({len(dup)} duplicate(s)); "
                      "ids label distance matrices, so make them unique", UserWarning, stacklevel=3)


# ---------------------------------------------------------------------------------------------
# CSV
# ---------------------------------------------------------------------------------------------

_ID_NAMES = ("id", "specimen", "specimen_id", "specimenid", "name", "specimen_name")
_COORD_PATTERNS = (
    re.compile(r"^(?P<ax>[xyz])(?P<lm>\d+)$", re.I),                 # x1, Y12
    re.compile(r"^(?P<lm>.+?)[_.\- ](?P<ax>[xyz])$", re.I),          # 1.X (geomorph), snout_x
    re.compile(r"^(?P<ax>[xyz])[_.\- ](?P<lm>.+)$", re.I),           # x_snout
)


def _coordinate_column(name):
    for pat in _COORD_PATTERNS:
        m = pat.match(str(name).strip())
        if m:
            return m.group("lm"), m.group("ax").lower()
    return None


def _csv_layout(columns) -> str:
    lower = {str(c).strip().lower() for c in columns}
    if "landmark" in lower and {"x", "y"} <= lower and lower & set(_ID_NAMES):
        return "long"
    return "wide"


def _cell(value, path, line, specimen, landmark, column):
    try:
        return _parse_number(value)
    except _NotFinite:
        raise ValueError(f"{path}: line {line}, specimen {specimen!r}, landmark {landmark}: "
                         f"non-finite value {value!r} in column {column!r} (coordinates must be finite numbers)") from None
    except ValueError:
        raise ValueError(f"{path}: line {line}, specimen {specimen!r}, landmark {landmark}: "
                         f"non-numeric value {value!r} in column {column!r}") from None


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_csv(path, *, layout: str = "auto", missing: str = "error", id_column: str | None = None):
    """Read landmarks from a CSV file, wide (one row per specimen) or long (one row per landmark).

    Parameters
    ----------
    path : str or Path
    layout : {"auto", "wide", "long"}
        ``"auto"``: long if the columns include ``landmark``, ``x``, ``y`` and a specimen column.
    missing : {"error", "nan"}
        Empty or ``NA`` cells raise ``ValueError`` naming file, line, specimen and landmark
        unless ``"nan"``.
    id_column : str, optional
        The specimen-id column (default: ``id``/``specimen``/``specimen_id``/``name``, else the
        first non-coordinate column, else ``0, 1, …``).

    Returns
    -------
    shapes : ndarray, shape (N, K, d), float64
    specimens : DataFrame
        ``id`` first, then the other non-coordinate columns (wide layout), ``line``,
        ``n_missing``; ``attrs["landmarks"]`` holds the landmark labels in order.

    See Also
    --------
    write_csv : Writes both layouts.
    read_landmarks : Any format, chosen by the file's extension.

    Examples
    --------
    A wide file, one specimen per row, with a metadata column:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from shapelib.io import read_csv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = Path(tmp.name) / "wide.csv"
    >>> _ = path.write_text("id,sex,x1,y1,x2,y2,x3,y3\\na,F,0,0,1,0,0,1\\nb,M,0,0,2,0,0,1\\n")
    >>> shapes, specimens = read_csv(path)
    >>> shapes.shape, specimens["id"].tolist(), specimens["sex"].tolist()
    ((2, 3, 2), ['a', 'b'], ['F', 'M'])
    >>> shapes[1]
    array([[0., 0.],
           [2., 0.],
           [0., 1.]])
    >>> specimens.attrs["layout"], specimens.attrs["landmarks"]
    ('wide', ['1', '2', '3'])
    >>> tmp.cleanup()
    """
    _check_missing_option(missing)
    if layout not in ("auto", "wide", "long"):
        raise ValueError(f"layout must be 'auto', 'wide' or 'long'; got {layout!r}")
    text = _read_text(path)
    if not text.strip():
        raise ValueError(f"{path}: empty file")
    import io as _io

    try:
        df = pd.read_csv(_io.StringIO(text), dtype=str, keep_default_na=False, skip_blank_lines=True,
                         skipinitialspace=True)
    except pd.errors.ParserError as exc:
        raise ValueError(f"{path}: not a valid CSV file: {exc}") from None
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: empty file") from None
    if df.empty:
        raise ValueError(f"{path}: no data rows under the header {list(df.columns)}")
    df.columns = [str(c).strip() for c in df.columns]
    # line numbers in the file (header = line 1), ignoring blank lines as pandas does
    nonblank = [i for i, ln in enumerate(text.split("\n"), start=1) if ln.strip()]
    data_lines = nonblank[1:]
    # pandas renames a repeated header (x2, x2 -> x2, x2.1), so look for repeats in the header as
    # written; a column genuinely named x2.1 is not one. Blank names become "Unnamed: n" and lose nothing.
    rest = text.split("\n", nonblank[0] - 1)[-1]      # from the header line on
    header = next(csv.reader(_io.StringIO(rest), skipinitialspace=True), [])
    names = [c.strip() for c in header if c.strip()]
    if len(names) == 1 and text.count(";") >= text.count("\n"):
        raise ValueError(f"{path}: line {nonblank[0]}: the columns are separated by ';', not ','; shapelib reads "
                         "comma-separated files: save it with ',' as the delimiter (and '.' as the decimal mark)")
    if names and all(_is_number(c) for c in names):
        raise ValueError(f"{path}: line {nonblank[0]}: the first line holds numbers ({', '.join(names[:4])}"
                         f"{', …' if len(names) > 4 else ''}), not column names: add a header row naming the columns "
                         "(id, x1, y1, x2, y2, … for one specimen per row)")
    repeated = [c for c, n in Counter(names).items() if n > 1]
    if not repeated and len(set(df.columns)) != len(df.columns):
        repeated = df.columns[df.columns.duplicated()].tolist()
    if repeated:
        raise ValueError(f"{path}: line {nonblank[0]}: duplicate column names {repeated} in the header "
                         "(each column may appear once)")
    if layout == "auto":
        layout = _csv_layout(df.columns)
    if layout == "long":
        shapes, specimens = _read_long(df, path, data_lines, id_column)
    else:
        shapes, specimens = _read_wide(df, path, data_lines, id_column)
    specimens.attrs.update(path=str(path), format="csv", layout=layout)
    check_dimension(shapes, name=str(path))
    _report_missing(shapes, specimens, path, missing, hint=" (empty or NA cell)")
    _warn_duplicate_ids(specimens, path)
    return shapes, specimens


def _read_wide(df, path, data_lines, id_column):
    groups: dict[str, dict[str, str]] = {}
    meta_cols = []
    for c in df.columns:
        parsed = _coordinate_column(c)
        if parsed is None or c == id_column:
            meta_cols.append(c)
            continue
        lm, ax = parsed
        if ax in groups.setdefault(lm, {}):
            raise ValueError(f"{path}: columns {groups[lm][ax]!r} and {c!r} are both coordinate {ax} of landmark {lm!r}")
        groups[lm][ax] = c
    if not groups:
        raise ValueError(f"{path}: no coordinate columns (expected x1, y1, … or <landmark>_x, <landmark>_y, …); "
                         f"got columns {list(df.columns)}")
    dims = {len(g) for g in groups.values()}
    for lm, g in groups.items():
        axes = "".join(sorted(g))
        if axes not in ("xy", "xyz"):
            raise ValueError(f"{path}: landmark {lm!r} has coordinate column(s) {sorted(g.values())}: every landmark "
                             "needs x and y (and z for 3-D) columns")
    if len(dims) > 1:
        lm = next(lm for lm, g in groups.items() if len(g) != len(next(iter(groups.values()))))
        raise ValueError(f"{path}: landmark {lm!r} has {len(groups[lm])} coordinates but landmark "
                         f"{next(iter(groups))!r} has {len(next(iter(groups.values())))}")
    d = dims.pop()
    if id_column is not None:
        if id_column not in df.columns:
            raise ValueError(f"{path}: id_column {id_column!r} is not a column; got {list(df.columns)}")
        idc = id_column
    else:
        named = [c for c in meta_cols if c.lower() in _ID_NAMES]
        idc = named[0] if named else (meta_cols[0] if meta_cols else None)
    ids = df[idc].astype(str).str.strip().tolist() if idc is not None else [str(i) for i in range(len(df))]
    labels = list(groups)
    shapes = np.empty((len(df), len(labels), d))
    for i in range(len(df)):
        for k, lm in enumerate(labels):
            for a, ax in enumerate(_AXES[:d]):
                col = groups[lm][ax]
                v = _cell(df[col].iat[i], path, data_lines[i], ids[i], f"{k + 1} ({lm!r})", col)
                shapes[i, k, a] = np.nan if v is None else v
    table = {"id": ids}
    for c in meta_cols:
        if c != idc:
            table[c] = df[c].tolist()
    table["line"] = data_lines[: len(df)]
    specimens = pd.DataFrame(table)
    specimens.attrs["landmarks"] = labels
    return shapes, specimens


def _read_long(df, path, data_lines, id_column):
    lower = {c.lower(): c for c in df.columns}
    idc = id_column or next(lower[n] for n in _ID_NAMES if n in lower)
    lmc, axes = lower["landmark"], [lower[a] for a in _AXES if a in lower]
    d = len(axes)
    order_specimens, order_landmarks, values = [], [], {}
    first_line = {}
    for i in range(len(df)):
        sid = str(df[idc].iat[i]).strip()
        lm = str(df[lmc].iat[i]).strip()
        if sid == "":
            raise ValueError(f"{path}: line {data_lines[i]}: empty specimen in column {idc!r}")
        if sid not in first_line:
            first_line[sid] = data_lines[i]
            order_specimens.append(sid)
        if lm not in order_landmarks:
            order_landmarks.append(lm)
        if (sid, lm) in values:
            raise ValueError(f"{path}: line {data_lines[i]}: specimen {sid!r} has landmark {lm!r} twice")
        values[sid, lm] = [_cell(df[a].iat[i], path, data_lines[i], sid, lm, a) for a in axes]
    if all(lm.lstrip("-").isdigit() for lm in order_landmarks):
        order_landmarks.sort(key=int)
    shapes = np.empty((len(order_specimens), len(order_landmarks), d))
    for s, sid in enumerate(order_specimens):
        for k, lm in enumerate(order_landmarks):
            if (sid, lm) not in values:
                have = sum((sid, m) in values for m in order_landmarks)
                raise ValueError(f"{path}: specimen {sid!r} (first at line {first_line[sid]}) has no row for landmark "
                                 f"{lm!r}: it has {have} landmark(s), others have {len(order_landmarks)}")
            shapes[s, k] = [np.nan if v is None else v for v in values[sid, lm]]
    specimens = pd.DataFrame({"id": order_specimens, "line": [first_line[s] for s in order_specimens]})
    specimens.attrs["landmarks"] = order_landmarks
    return shapes, specimens


def write_csv(path, shapes, specimens=None, *, layout: str = "wide", landmarks=None) -> Path:
    """Write shapes as CSV: ``wide`` (``id, [metadata…], x1, y1, x2, y2, …``) or ``long``
    (``specimen, landmark, x, y[, z]``). Missing (NaN) coordinates are written as ``NA``.

    Parameters
    ----------
    path : str or Path
        The file to write (replaced atomically if it exists).
    shapes : array_like, shape (N, K, d) or (K, d), d = 2 or 3
        The landmarks; NaN marks a missing landmark.
    specimens : DataFrame or sequence of str, optional
        The specimen ids (a table's ``id`` column); a table's other columns are written as
        metadata columns of the wide layout (all-NaN columns and the readers' ``line``,
        ``n_missing`` and ``scaled`` are left out). Default ids: ``0, 1, …``.
    layout : {"wide", "long"}
        ``"wide"``: one row per specimen; ``"long"``: one row per landmark.
    landmarks : sequence of str, optional
        Landmark labels, one per landmark (default ``1…K``). Wide columns are then named
        ``<label>_x, <label>_y`` unless the labels are ``1…K``.

    Returns
    -------
    Path
        ``path``.

    See Also
    --------
    read_csv : Reads either layout back.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from shapelib.io import read_csv, write_csv
    >>> shapes = np.array([[[0, 0], [1, 0], [0, 1.5]], [[0, 0], [2, 0], [0, -1]]])
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = write_csv(Path(tmp.name) / "long.csv", shapes, ["a", "b"], layout="long")
    >>> print(path.read_text().splitlines()[:3])
    ['specimen,landmark,x,y', 'a,1,0.0,0.0', 'a,2,1.0,0.0']
    >>> back, specimens = read_csv(path)
    >>> np.array_equal(back, shapes), specimens.attrs["layout"]
    (True, 'long')
    >>> tmp.cleanup()
    """
    path = Path(path)
    x = _as_writable(shapes, path)
    n, k, d = x.shape
    table = _specimen_table(specimens, n, path)
    labels = [str(i + 1) for i in range(k)] if landmarks is None else [str(s) for s in landmarks]
    if len(labels) != k:
        raise ValueError(f"{path}: {len(labels)} landmark labels for {k} landmarks")
    if layout == "wide":
        numbered = labels == [str(i + 1) for i in range(k)]
        cols = [f"{ax}{lm}" if numbered else f"{lm}_{ax}" for lm in labels for ax in _AXES[:d]]
        out = pd.DataFrame(x.reshape(n, k * d), columns=cols)
        meta = table.drop(columns=[c for c in ("line", "n_missing", "scaled") if c in table])
        meta = meta[[c for c in meta.columns if c == "id" or not meta[c].isna().all()]]
        out = pd.concat([meta.reset_index(drop=True), out], axis=1)
    elif layout == "long":
        out = pd.DataFrame({
            "specimen": np.repeat(table["id"].to_numpy(), k),
            "landmark": np.tile(labels, n),
            **{ax: x[:, :, a].ravel() for a, ax in enumerate(_AXES[:d])},
        })
    else:
        raise ValueError(f"layout must be 'wide' or 'long'; got {layout!r}")
    text = out.to_csv(index=False, na_rep="NA", float_format=lambda v: repr(float(v)), lineterminator="\n")
    write_text_atomic(path, text)
    return path


# ---------------------------------------------------------------------------------------------
# NumPy and geomorph arrays
# ---------------------------------------------------------------------------------------------


def read_npy(path, *, missing: str = "error", layout: str = "nkd"):
    """Read an ``(N, K, d)`` array from ``.npy`` or ``.npz`` (key ``shapes``, else the only array;
    optional ``ids``). ``layout="pkn"`` reads geomorph's ``p × k × n`` order (:func:`from_pkn`).

    Parameters
    ----------
    path : str or Path
        A ``.npy`` file (one numeric array) or ``.npz`` archive (``shapes``, else its only
        array, and optionally ``ids``).
    missing : {"error", "nan"}
        A NaN coordinate raises ``ValueError`` naming the file, specimen and landmark unless
        ``"nan"``.
    layout : {"nkd", "pkn"}
        ``"nkd"``: specimens first, shapelib's ``(N, K, d)``; ``"pkn"``: geomorph's
        ``(K, d, N)``.

    Returns
    -------
    shapes : ndarray, shape (N, K, d), float64
        The landmarks.
    specimens : DataFrame
        Column ``id``: the archive's ``ids``, else ``0, 1, …``; ``attrs["format"]`` is
        ``"npy"`` or ``"npz"``.

    See Also
    --------
    write_npy : Writes both.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from shapelib.io import read_npy
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = Path(tmp.name) / "shapes.npz"
    >>> np.savez(path, shapes=np.zeros((2, 4, 2)), ids=np.array(["left", "right"]))
    >>> shapes, specimens = read_npy(path)
    >>> shapes.shape, specimens["id"].tolist(), specimens.attrs["format"]
    ((2, 4, 2), ['left', 'right'], 'npz')
    >>> tmp.cleanup()
    """
    _check_missing_option(missing)
    path = Path(path)
    ids = None
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, EOFError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable NumPy file ({exc})") from None
    if isinstance(loaded, np.lib.npyio.NpzFile):
        with loaded as z:
            keys = list(z.keys())
            arrays = [k for k in keys if k != "ids"]
            if "shapes" in keys:
                arr = z["shapes"]
            elif len(arrays) == 1:
                arr = z[arrays[0]]
            else:
                raise ValueError(f"{path}: expected an array named 'shapes'; the file has {keys}")
            if "ids" in keys:
                ids = [str(s) for s in z["ids"]]
    else:
        arr = loaded
    if not np.issubdtype(arr.dtype, np.number):
        raise ValueError(f"{path}: the array is {arr.dtype}, not numeric")
    if layout == "pkn":
        arr = from_pkn(arr)
    elif layout != "nkd":
        raise ValueError(f"layout must be 'nkd' or 'pkn'; got {layout!r}")
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim != 3 or arr.size == 0:
        raise ValueError(f"{path}: expected a non-empty (N, K, d) array; got shape {arr.shape}")
    check_dimension(arr, name=str(path))
    if np.isinf(arr).any():
        i, k, _ = np.argwhere(np.isinf(arr))[0]
        raise ValueError(f"{path}: specimen #{i + 1}, landmark {k + 1} is infinite")
    ids = [str(i) for i in range(len(arr))] if ids is None else ids
    if len(ids) != len(arr):
        raise ValueError(f"{path}: {len(ids)} ids for {len(arr)} shapes")
    specimens = pd.DataFrame({"id": ids})
    specimens.attrs.update(path=str(path), format=path.suffix.lower().lstrip("."))
    _report_missing(arr, specimens, path, missing)
    _warn_duplicate_ids(specimens, path)
    return arr, specimens


def write_npy(path, shapes, specimens=None) -> Path:
    """Write ``.npy`` (the array only) or ``.npz`` (``shapes`` and ``ids``).

    Parameters
    ----------
    path : str or Path
        The file; its suffix chooses ``.npz`` (an archive with ``shapes`` and ``ids``), else
        ``.npy`` (the array only: the ids are not kept). Replaced atomically if it exists.
    shapes : array_like, shape (N, K, d) or (K, d), d = 2 or 3
        The landmarks.
    specimens : DataFrame or sequence of str, optional
        The specimen ids (a table's ``id`` column); default ``0, 1, …``.

    Returns
    -------
    Path
        ``path``.

    See Also
    --------
    read_npy : Reads both back.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from shapelib.io import read_npy, write_npy
    >>> shapes = np.arange(12.0).reshape(2, 3, 2)
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = write_npy(Path(tmp.name) / "shapes.npz", shapes, ["a", "b"])
    >>> back, specimens = read_npy(path)
    >>> np.array_equal(back, shapes), specimens["id"].tolist()
    (True, ['a', 'b'])
    >>> tmp.cleanup()
    """
    path = Path(path)
    x = _as_writable(shapes, path)
    table = _specimen_table(specimens, len(x), path)
    tmp = path.with_name(f".{path.name}.tmp{path.suffix}")
    if path.suffix.lower() == ".npz":
        np.savez(tmp, shapes=x, ids=table["id"].to_numpy(dtype=str))
    else:
        np.save(tmp, x)
    tmp.replace(path)
    return path


def from_pkn(array) -> np.ndarray:
    """geomorph's ``p × k × n`` landmark array (``p`` landmarks, ``k`` = 2 or 3 coordinates,
    ``n`` specimens, as ``readland.tps`` returns) as shapelib's ``(n, p, k)`` float64 array.

    Parameters
    ----------
    array : array_like, shape (p, k, n), k = 2 or 3
        Landmarks in geomorph's order.

    Returns
    -------
    ndarray, shape (n, p, k), float64
        The same landmarks, specimens first (C-contiguous): ``out[i, j] == array[j, :, i]``.

    See Also
    --------
    to_pkn : The inverse.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.io import from_pkn
    >>> pkn = np.zeros((5, 2, 3))          # 5 landmarks, 2-D, 3 specimens
    >>> pkn[:, 0, 2] = np.arange(5)        # the x coordinates of the third specimen
    >>> shapes = from_pkn(pkn)
    >>> shapes.shape, shapes[2, :, 0].tolist()
    ((3, 5, 2), [0.0, 1.0, 2.0, 3.0, 4.0])
    """
    a = np.asarray(array, dtype=np.float64)
    if a.ndim != 3:
        raise ValueError(f"a p x k x n array must be 3-D; got shape {a.shape}")
    if a.shape[1] not in (2, 3):
        hint = " (it looks like shapelib's (N, K, d) already)" if a.shape[2] in (2, 3) else ""
        raise ValueError(f"p x k x n array: k = shape[1] must be 2 or 3 coordinates; got shape {a.shape}{hint}")
    return np.ascontiguousarray(a.transpose(2, 0, 1))


def to_pkn(shapes) -> np.ndarray:
    """shapelib's ``(N, K, d)`` array as geomorph's ``p × k × n`` (``K × d × N``).

    Parameters
    ----------
    shapes : array_like, shape (N, K, d), d = 2 or 3
        Landmarks, specimens first.

    Returns
    -------
    ndarray, shape (K, d, N), float64
        The same landmarks in geomorph's order (C-contiguous): ``out[j, :, i] == shapes[i, j]``.

    See Also
    --------
    from_pkn : The inverse.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.io import from_pkn, to_pkn
    >>> shapes = np.random.default_rng(0).normal(size=(3, 5, 2))
    >>> to_pkn(shapes).shape, np.array_equal(from_pkn(to_pkn(shapes)), shapes)
    ((5, 2, 3), True)
    """
    x = np.asarray(shapes, dtype=np.float64)
    if x.ndim != 3:
        raise ValueError(f"shapes must have shape (N, K, d); got {x.shape}")
    check_dimension(x, name="shapes")
    return np.ascontiguousarray(x.transpose(1, 2, 0))


# ---------------------------------------------------------------------------------------------
# Dispatch
# ---------------------------------------------------------------------------------------------


def read_landmarks(path, *, format: str | None = None, **kw):
    """Read a landmark file, choosing the reader by extension (``.tps``, ``.csv``, ``.npy``, ``.npz``).

    Parameters
    ----------
    path : str or Path
    format : {"tps", "csv", "npy", "npz"}, optional
        Override the extension.
    **kw
        Options of :func:`read_tps` (``scale``, ``missing``, ``negative``), :func:`read_csv`
        (``layout``, ``missing``, ``id_column``) or :func:`read_npy` (``missing``, ``layout``).

    Returns
    -------
    shapes : ndarray, shape (N, K, d), float64
        The landmarks.
    specimens : DataFrame
        Column ``id`` first; ``attrs["format"]`` records the format read.

    See Also
    --------
    write_landmarks : The writer, by extension too.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from shapelib.io import read_landmarks
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = Path(tmp.name) / "long.csv"
    >>> _ = path.write_text("specimen,landmark,x,y\\nA,1,0,0\\nA,2,1,0\\nB,1,0,0\\nB,2,0,2\\n")
    >>> shapes, specimens = read_landmarks(path)
    >>> shapes.shape, specimens["id"].tolist(), specimens.attrs["format"]
    ((2, 2, 2), ['A', 'B'], 'csv')
    >>> tmp.cleanup()
    """
    fmt = _format_of(path, format)
    if not Path(path).is_file():
        raise ValueError(f"{path}: no such file")
    if fmt == "tps":
        kw.pop("return_curves", None)
        return read_tps(path, **kw)
    if fmt == "csv":
        return read_csv(path, **kw)
    return read_npy(path, **kw)


def write_landmarks(path, shapes, specimens=None, *, format: str | None = None, **kw) -> Path:
    """Write shapes in the format given by ``path``'s extension (or ``format``); ``**kw`` go to
    :func:`write_tps` (``curves``, ``missing_value``) or :func:`write_csv` (``layout``, ``landmarks``).

    Parameters
    ----------
    path : str or Path
        The file to write; its extension (``.tps``, ``.csv``, ``.npy``, ``.npz``) chooses the
        format.
    shapes : array_like, shape (N, K, d) or (K, d), d = 2 or 3
        The landmarks.
    specimens : DataFrame or sequence of str, optional
        Specimen ids and metadata, as the format's writer takes them; default ``0, 1, …``.
    format : {"tps", "csv", "npy", "npz"}, optional
        Override the extension.
    **kw
        Options of :func:`write_tps` (``curves``, ``missing_value``) or :func:`write_csv`
        (``layout``, ``landmarks``).

    Returns
    -------
    Path
        ``path``.

    See Also
    --------
    read_landmarks : The reader, by extension too.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from shapelib.io import read_landmarks, write_landmarks
    >>> shapes = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
    >>> tmp = tempfile.TemporaryDirectory()
    >>> for name in ("one.tps", "one.csv", "one.npz"):
    ...     back, specimens = read_landmarks(write_landmarks(Path(tmp.name) / name, shapes, ["s1"]))
    ...     print(specimens.attrs["format"], np.array_equal(back, shapes), specimens["id"].tolist())
    tps True ['s1']
    csv True ['s1']
    npz True ['s1']
    >>> tmp.cleanup()
    """
    fmt = _format_of(path, format)
    if fmt == "tps":
        return write_tps(path, shapes, specimens, **kw)
    if fmt == "csv":
        return write_csv(path, shapes, specimens, **kw)
    return write_npy(path, shapes, specimens, **kw)
