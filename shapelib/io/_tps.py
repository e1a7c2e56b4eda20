"""tpsDig ``.tps`` files: :func:`read_tps` and :func:`write_tps` (the format is described in :mod:`shapelib.io`)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .._files import write_text_atomic
from .._validate import InputError, literal
from ._common import (
    NEGATIVE_COORDINATES_COMMENT,
    _check_missing_option,
    _report_missing,
    _NotFinite,
    _parse_number,
    _read_text,
    _fmt,
    _specimen_table,
    _as_writable,
    _warn_duplicate_ids,
)


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
