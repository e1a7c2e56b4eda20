"""CSV landmark tables, wide and long: :func:`read_csv` and :func:`write_csv`."""

from __future__ import annotations

import csv
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd

from .._files import write_text_atomic
from .._validate import check_dimension
from ._common import (
    _AXES,
    _check_missing_option,
    _report_missing,
    _NotFinite,
    _parse_number,
    _read_text,
    _specimen_table,
    _as_writable,
    _warn_duplicate_ids,
)


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
