"""NumPy ``.npy``/``.npz`` landmark arrays and geomorph's ``p × k × n`` arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .._validate import check_dimension
from ._common import (
    _check_missing_option,
    _report_missing,
    _specimen_table,
    _as_writable,
    _warn_duplicate_ids,
)


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
