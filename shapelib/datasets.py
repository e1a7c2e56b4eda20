"""Dataset registry, fetching and loaders.

Every raw file the study uses is listed in ``data/registry.csv`` with its upstream URL
(pinned to a commit) and its sha256. Files are never committed to this repository:

* when the environment variable ``SHAPELIB_DATA_DIR`` is set, files are taken from that
  folder (same layout as the registry paths, e.g. ``$SHAPELIB_DATA_DIR/cdfhc/...``) and
  their checksum is verified;
* otherwise they are downloaded once with :mod:`pooch` into the user cache (or
  ``SHAPELIB_CACHE_DIR``) and verified against the same checksum.

Loaders return float64 arrays.
"""

from __future__ import annotations

import csv
import functools
import hashlib
import os
import re
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

__all__ = [
    "DATA_DIR_ENV",
    "registry",
    "fetch",
    "data_checksums",
    "load_corpus_callosum",
    "load_fish2d",
    "load_beijing",
    "load_tps_rpm",
    "load_cpd_fish",
    "load_gmmreg_fish",
    "mpeg7_names",
    "load_mpeg7_image",
    "mpeg7_boundary",
    "mpeg7_landmarks",
    "mpeg7_classes",
    "load_mpeg7",
    "MPEG7",
    "load_adhd200",
    "CC_PAPER_IDS",
]

DATA_DIR_ENV = "SHAPELIB_DATA_DIR"
CACHE_DIR_ENV = "SHAPELIB_CACHE_DIR"
REGISTRY_PATH = Path(__file__).resolve().parents[1] / "data" / "registry.csv"

#: Paper ids (Fig. 10 / Table I numbering) of the 7 shapes in ``cdfhc_data2D_CC.mat``, in file order.
CC_PAPER_IDS = (1, 3, 8, 2, 6, 7, 9)


class DataError(ValueError):
    """A raw data file is missing or does not match its registered checksum."""


@functools.lru_cache(maxsize=1)
def registry() -> dict[str, tuple[str, str]]:
    """Return ``{relative path: (upstream url, sha256)}`` for every registered raw file."""
    if not REGISTRY_PATH.is_file():
        raise DataError(f"dataset registry not found at {REGISTRY_PATH}")
    with open(REGISTRY_PATH, newline="") as fh:
        return {row["path"]: (row["url"], row["sha256"]) for row in csv.DictReader(fh)}


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fetch(relpath: str) -> Path:
    """Return a local, checksum-verified copy of the registered file ``relpath``.

    Raises
    ------
    DataError
        If ``relpath`` is not registered, the file is missing from ``$SHAPELIB_DATA_DIR``,
        or its sha256 does not match the registry.
    """
    reg = registry()
    if relpath not in reg:
        raise DataError(f"{relpath!r} is not in the dataset registry {REGISTRY_PATH}")
    url, sha = reg[relpath]
    local_dir = os.environ.get(DATA_DIR_ENV)
    if local_dir:
        path = Path(local_dir) / relpath
        if not path.is_file():
            raise DataError(
                f"data file {relpath!r} not found in {DATA_DIR_ENV}={local_dir!r} "
                f"(expected {path}); upstream URL: {url}. Unset {DATA_DIR_ENV} to download it."
            )
        got = _sha256(path)
        if got != sha:
            raise DataError(
                f"checksum mismatch for {path}: sha256 {got}, registry expects {sha} (upstream {url})"
            )
        return path
    import pooch  # imported lazily: only needed when downloading

    cache = os.environ.get(CACHE_DIR_ENV) or pooch.os_cache("shapelib")
    try:
        fname = pooch.retrieve(
            url, known_hash=f"sha256:{sha}", fname=relpath.replace("/", "__"), path=cache, progressbar=False
        )
    except ValueError as exc:  # pooch raises ValueError on a hash mismatch
        raise DataError(f"checksum mismatch for {relpath!r} downloaded from {url}: {exc}") from None
    except Exception as exc:  # network errors: say what to do
        raise DataError(
            f"could not download {relpath!r} from {url} ({type(exc).__name__}: {exc}); "
            f"set {DATA_DIR_ENV} to a folder holding a copy to work offline"
        ) from None
    return Path(fname)


def data_checksums(relpaths) -> dict[str, str]:
    """Registered sha256 of each file in ``relpaths`` (used to key cached results)."""
    reg = registry()
    return {p: reg[p][1] for p in relpaths}


def _mat_cell(relpath: str, key: str) -> np.ndarray:
    from scipy.io import loadmat

    m = loadmat(fetch(relpath))
    if key not in m:
        raise DataError(f"{relpath}: variable {key!r} not found (has {sorted(k for k in m if not k.startswith('__'))})")
    cell = m[key].ravel()
    arrays = [np.asarray(c, dtype=np.float64) for c in cell]
    return np.stack(arrays)


def load_corpus_callosum() -> tuple[np.ndarray, np.ndarray]:
    """The 7 corpus callosum shapes of ``cdfhc_data2D_CC.mat`` (variable ``CC7``).

    Returns
    -------
    shapes : ndarray, shape (7, 63, 2)
        Closed contours, 63 landmarks in correspondence, in the file's normalised coordinates.
    paper_ids : ndarray of int, shape (7,)
        Their numbers in the paper's Figure 10 and Table I: ``[1, 3, 8, 2, 6, 7, 9]``.
    """
    return _mat_cell("cdfhc/cdfhc_data2D_CC.mat", "CC7"), np.array(CC_PAPER_IDS)


def load_fish2d() -> np.ndarray:
    """``fish2d``: 7 deformed fish, outline plus interior strokes, 150 points each -> (7, 150, 2)."""
    return _mat_cell("cdfhc/cdfhc_data2D_fish.mat", "fish2d")


def load_beijing() -> np.ndarray:
    """``beijing``: 7 drawings of a Chinese character with disconnected strokes -> (7, 113, 2)."""
    return _mat_cell("cdfhc/cdfhc_data2D_beijing.mat", "beijing")


_TPS_RPM = re.compile(r"^(fish|chinese)_(def|noise|occlusion|outlier|rot)_(\d)$")


def load_tps_rpm(name: str = "fish_def_1") -> tuple[np.ndarray, np.ndarray]:
    """A Chui–Rangarajan TPS-RPM benchmark pair, e.g. ``"fish_def_3"`` -> ``(x1, y2a)``.

    ``x1`` is the template, ``y2a`` the deformed/noisy/occluded/rotated target (sample 1 of the level).
    """
    m = _TPS_RPM.match(name)
    rel = f"tps-rpm/save_{name}_1.mat"
    if m is None or rel not in registry():
        options = sorted(p[len("tps-rpm/save_"):-len("_1.mat")] for p in registry() if p.startswith("tps-rpm/"))
        raise ValueError(f"unknown TPS-RPM set {name!r}; choose one of {options}")
    from scipy.io import loadmat

    d = loadmat(fetch(rel))
    return np.asarray(d["x1"], dtype=np.float64), np.asarray(d["y2a"], dtype=np.float64)


def load_cpd_fish() -> tuple[np.ndarray, np.ndarray]:
    """The Coherent Point Drift demo fish pair ``(source, target)``, 91 points each."""
    return (
        np.loadtxt(fetch("cpd/fish_source.txt"), dtype=np.float64),
        np.loadtxt(fetch("cpd/fish_target.txt"), dtype=np.float64),
    )


def load_gmmreg_fish(name: str = "fish_X") -> np.ndarray:
    """A gmmreg test fish: ``fish_X``, ``fish_Y``, ``fish_X_nohead``, ``fish_Y_notail``, ``fish_ctrl_pts``."""
    rel = f"gmmreg/{name}.txt"
    if rel not in registry():
        options = sorted(Path(p).stem for p in registry() if p.startswith("gmmreg/"))
        raise ValueError(f"unknown gmmreg fish {name!r}; choose one of {options}")
    return np.loadtxt(fetch(rel), dtype=np.float64)


def mpeg7_names() -> list[str]:
    """Names (without ``.gif``) of the 1,400 MPEG-7 CE-Shape-1 silhouettes, e.g. ``"fish-3"``."""
    return sorted(Path(p).stem for p in registry() if p.startswith("mpeg7/") and p.endswith(".gif"))


def load_mpeg7_image(name: str) -> np.ndarray:
    """The binary silhouette ``name`` (e.g. ``"fish-3"``) as a boolean image, foreground True."""
    rel = f"mpeg7/{name}.gif"
    if rel not in registry():
        raise ValueError(f"unknown MPEG-7 image {name!r}; see shapelib.datasets.mpeg7_names()")
    from PIL import Image

    with Image.open(fetch(rel)) as im:
        img = np.asarray(im.convert("L"), dtype=np.float64)
    return img > 127.5


def mpeg7_boundary(name: str) -> np.ndarray:
    """Every boundary pixel of silhouette ``name`` (all parts and holes) as ``(M, 2)`` float64 (x, y).

    A boundary pixel is a foreground pixel with at least one 4-connected background neighbour
    (the image border counts as background). ``y`` grows upwards (image row flipped).
    """
    img = load_mpeg7_image(name)
    pad = np.pad(img, 1, constant_values=False)
    core = pad[1:-1, 1:-1]
    interior = pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    rows, cols = np.nonzero(core & ~interior)
    return np.column_stack([cols, img.shape[0] - 1 - rows]).astype(np.float64)


def mpeg7_landmarks(name: str, n: int) -> np.ndarray:
    """``n`` landmarks evenly spaced by arc length along the outer boundary of ``name``.

    The outer boundary is the longest iso-contour (level 0.5, marching squares) of the
    silhouette; landmarks start at its point with the smallest x and run counter-clockwise.
    """
    if int(n) != n or n < 3:
        raise ValueError(f"n must be an integer >= 3; got {n!r}")
    import contourpy

    img = load_mpeg7_image(name).astype(np.float64)
    img = np.pad(img, 1)
    lines = contourpy.contour_generator(z=img).lines(0.5)
    outer = max(lines, key=len)
    outer = outer - 1.0  # undo the padding
    outer[:, 1] = img.shape[0] - 3 - outer[:, 1]
    if np.allclose(outer[0], outer[-1]):
        outer = outer[:-1]
    # counter-clockwise orientation, starting at the leftmost point
    x, y = outer[:, 0], outer[:, 1]
    if 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        outer = outer[::-1]
    outer = np.roll(outer, -int(np.argmin(outer[:, 0])), axis=0)
    closed = np.vstack([outer, outer[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], int(n), endpoint=False)
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def mpeg7_classes() -> list[str]:
    """The 70 class names of MPEG-7 CE-Shape-1 (file-name prefixes, e.g. ``"Bone"``, ``"fish"``), sorted."""
    return sorted({n.rsplit("-", 1)[0] for n in mpeg7_names()})


class MPEG7(NamedTuple):
    """MPEG-7 CE-Shape-1 silhouettes or outlines with their classes (:func:`load_mpeg7`)."""

    #: boolean images (list), or ``(N, n_points, 2)`` outlines
    shapes: object
    #: class of each shape, e.g. ``"deer"``
    labels: np.ndarray
    #: file name of each shape without ``.gif``, e.g. ``"deer-7"``
    names: list


def load_mpeg7(*, classes=None, per_class: int | None = None, n_points: int | None = None) -> MPEG7:
    """MPEG-7 CE-Shape-1 (1,400 silhouettes, 70 classes × 20): images or traced outlines, with labels.

    Files come through the dataset registry (:func:`fetch`: ``$SHAPELIB_DATA_DIR`` offline, else
    downloaded once with pooch and checked against their sha256).

    Parameters
    ----------
    classes : sequence of str, optional
        Class names to load (default: all 70, :func:`mpeg7_classes`), in the order given.
    per_class : int, optional
        The first ``per_class`` shapes of each class by number (``deer-1``, ``deer-2``, …;
        default all 20).
    n_points : int, optional
        If given, each silhouette's outline — the longest outer boundary, holes and other parts
        dropped (:func:`shapelib.pointsets.outline.trace_outline`) — resampled to ``n_points``
        by arc length; otherwise the boolean images (foreground True).

    Returns
    -------
    MPEG7
        ``(shapes, labels, names)``.

    Examples
    --------
    >>> from shapelib.datasets import load_mpeg7
    >>> data = load_mpeg7(classes=["deer", "fork"], per_class=3, n_points=50)  # doctest: +SKIP
    >>> data.shapes.shape, data.labels[:4].tolist()  # doctest: +SKIP
    ((6, 50, 2), ['deer', 'deer', 'deer', 'fork'])
    """
    known = mpeg7_classes()
    classes = known if classes is None else [str(c) for c in classes]
    unknown = [c for c in classes if c not in known]
    if unknown:
        raise ValueError(f"unknown MPEG-7 class(es) {unknown}; choose from {known}")
    if per_class is not None and (int(per_class) != per_class or not 1 <= per_class <= 20):
        raise ValueError(f"per_class must be an integer from 1 to 20; got {per_class!r}")
    names = []
    for c in classes:
        members = sorted((n for n in mpeg7_names() if n.rsplit("-", 1)[0] == c), key=lambda n: int(n.rsplit("-", 1)[1]))
        names += members[:per_class]
    labels = np.array([n.rsplit("-", 1)[0] for n in names])
    images = [load_mpeg7_image(n) for n in names]
    if n_points is None:
        return MPEG7(images, labels, names)
    from .pointsets.outline import trace_outline

    return MPEG7(np.stack([trace_outline(im, n_points=n_points) for im in images]), labels, names)


def load_adhd200():
    """The ADHD-200 corpus callosum contours with their clinical labels.

    Returns
    -------
    contours : ndarray, shape (647, 50, 2)
        Mid-sagittal contours, 50 landmarks (the repeated closing point is dropped).
    labels : pandas.DataFrame
        ``patient.id, gender, age, phenotype`` in the same order.
    """
    import pandas as pd
    import rdata

    with warnings.catch_warnings():  # rdata warns about R classes it maps to plain frames
        warnings.simplefilter("ignore", UserWarning)
        parsed = rdata.read_rda(fetch("adhd200/ADHD-200.Rdata"))
    # each entry: {"id", "x", "plg.chains": {"1": DataArray (51, 2) with X, Y columns}}
    arrs = [
        np.asarray(next(iter(c["plg.chains"].values())), dtype=np.float64) for c in parsed["chains"]
    ]
    arrs = [a[:-1] if np.allclose(a[0], a[-1]) else a for a in arrs]
    labels = pd.read_csv(fetch("adhd200/clinical_info.csv"))
    return np.stack(arrs), labels
