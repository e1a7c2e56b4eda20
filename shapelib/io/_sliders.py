"""Reading sliding-semilandmark definitions from files: geomorph's ``curveslide.csv``.

geomorph's ``define.sliders`` writes one row per semilandmark with three columns ``before``,
``slide``, ``after``: the point that slides and the two points whose chord gives its tangent,
numbered from 1 as R numbers them::

    "before","slide","after"
    1,2,3
    2,3,4
    3,4,5

:func:`read_sliders` reads that table (comma-, semicolon- or whitespace-separated, the header
optional, R's row-name column of ``write.csv`` allowed) and returns the 0-based ``(m, 3)`` array
that :func:`shapelib.slide_semilandmarks` takes.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

__all__ = ["read_sliders"]

_COLUMNS = ("before", "slide", "after")
#: a decimal number (``7``, ``7.0``, ``7.000000000000000000e+00`` as numpy.savetxt writes it)
_NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?")


def _tokens(line: str) -> list[str]:
    sep = "," if "," in line else ";" if ";" in line else None
    return [t.strip().strip('"').strip("'").strip() for t in (line.split(sep) if sep else line.split())]


def _landmark_number(text: str, where: str, column: str) -> int:
    value = float(text) if _NUMBER.fullmatch(text) else math.nan
    if not (math.isfinite(value) and value == int(value)):
        raise ValueError(f"{where}: {column} {text!r} is not a landmark number (a whole number from 1)")
    return int(value)


def read_sliders(path, *, n_landmarks: int | None = None) -> np.ndarray:
    """Read a sliders table as geomorph's ``define.sliders`` writes it (``curveslide.csv``).

    Each row ``before, slide, after`` says that landmark ``slide`` slides along the chord from
    ``before`` to ``after`` (Bookstein's tangent estimate). The numbers in the file count from 1, as
    in geomorph and R; the array returned counts from 0, as Python and :func:`shapelib.curve_sliders`.

    Parameters
    ----------
    path : str or Path
        A text table of three columns, separated by commas, semicolons or white space, with or
        without the header ``before,slide,after`` (quoted or not, as R's ``write.table`` quotes
        it); a first column of row names (R's ``write.csv`` with its default ``row.names=TRUE``,
        header ``"","before","slide","after"``) is skipped. Blank lines and lines starting with
        ``#`` are ignored.
    n_landmarks : int, optional
        The number of landmarks of the shapes the sliders will act on: a number above it is an
        error (without it only numbers below 1 are).

    Returns
    -------
    ndarray of int, shape (m, 3)
        ``(before, point, after)`` rows, 0-based: the ``sliders`` of
        :func:`shapelib.slide_semilandmarks`.

    Raises
    ------
    ValueError
        Naming the file, the row (and its line) and the value: a number that is not a whole
        number, 0 or below (geomorph counts from 1), above ``n_landmarks``, a point that is its own
        anchor (``slide`` equal to ``before`` or ``after``), anchors that coincide (no tangent), a
        point that slides in two rows, a row without three columns, or a file with no rows.

    See Also
    --------
    shapelib.curve_sliders : The sliders of a curve of consecutive points.
    shapelib.slide_semilandmarks : Slides them.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import shapelib as sl
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "curveslide.csv"
    >>> _ = path.write_text('"before","slide","after"\\n1,2,3\\n2,3,4\\n3,4,5\\n')   # as geomorph writes it
    >>> sl.read_sliders(path).tolist()                                                # counted from 0
    [[0, 1, 2], [1, 2, 3], [2, 3, 4]]
    >>> bool((sl.read_sliders(path, n_landmarks=5) == sl.curve_sliders(0, 5)).all())
    True
    """
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{path}: no such file")
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (expected a before,slide,after table)") from None
    if n_landmarks is not None and (int(n_landmarks) != n_landmarks or n_landmarks < 1):
        raise ValueError(f"n_landmarks must be a positive whole number; got {n_landmarks!r}")
    rows, row_names, first = [], False, True
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        tokens = _tokens(line)
        if first:  # the first line may be the header
            first = False
            names = [t.lower() for t in tokens]
            if names[-3:] == list(_COLUMNS) and len(names) in (3, 4):
                row_names = len(names) == 4
                continue
        where = f"{path}: row {len(rows) + 1} (line {lineno})"
        if row_names:
            tokens = tokens[1:]
        if len(tokens) != 3:
            raise ValueError(f"{where}: expected 3 columns (before, slide, after); got {len(tokens)}: {line.strip()!r}")
        rows.append(([_landmark_number(t, where, c) for t, c in zip(tokens, _COLUMNS)], lineno))
    if not rows:
        raise ValueError(f"{path}: no sliders (expected rows before, slide, after)")
    first_row_of = {}
    for i, ((before, slide, after), lineno) in enumerate(rows, start=1):
        where = f"{path}: row {i} (line {lineno})"
        for column, value in zip(_COLUMNS, (before, slide, after)):
            if value < 1:
                raise ValueError(f"{where}: {column} {value}: landmark numbers start at 1 (geomorph's numbering)")
            if n_landmarks is not None and value > n_landmarks:
                raise ValueError(f"{where}: {column} {value}: the shapes have landmarks 1 to {n_landmarks}")
        if slide in (before, after):
            raise ValueError(f"{where}: slide {slide} is also its own anchor ({before}, {slide}, {after}): a point "
                             "slides between two other points")
        if before == after:
            raise ValueError(f"{where}: before and after are both {before}: the tangent of slide {slide} is the chord "
                             "between two different points")
        if slide in first_row_of:
            raise ValueError(f"{where}: slide {slide} already slides in row {first_row_of[slide]}: each point "
                             "slides once")
        first_row_of[slide] = i
    return np.asarray([r for r, _ in rows], dtype=np.intp) - 1
