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

from pathlib import Path

from . import _common
from ._common import _format_of
from ._csv import read_csv, write_csv
from ._npy import from_pkn, read_npy, to_pkn, write_npy
from ._pointsets import read_point_sets, write_point_set
from ._sliders import read_sliders
from ._tps import read_tps, write_tps

# Documented here, where the API reference reads them (the ``#:`` comments are their docs).

#: file extension -> format name: the formats :func:`read_landmarks` and :func:`write_landmarks`
#: tell by a file's extension
FORMATS = _common.FORMATS

#: What :func:`write_tps` adds, as a ``COMMENT=`` line, to each specimen with negative coordinates
#: (e.g. aligned shapes), and :func:`read_tps` honours: there a negative value is a coordinate,
#: not tpsDig's missing-landmark code (missing landmarks are then written ``NA``). A standard tps
#: field, which other readers skip or keep as a comment (ktch reads such files; tpsDig still takes
#: the negative values as missing).
NEGATIVE_COORDINATES_COMMENT = _common.NEGATIVE_COORDINATES_COMMENT

__all__ = [
    "read_landmarks", "write_landmarks", "read_tps", "write_tps", "read_csv", "write_csv",
    "read_npy", "write_npy", "from_pkn", "to_pkn", "FORMATS", "NEGATIVE_COORDINATES_COMMENT",
    "read_point_sets", "write_point_set", "read_sliders",
]


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
