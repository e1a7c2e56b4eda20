"""Dataset registry, fetching and loaders.

Every raw file the study uses is listed in the registry ``shapelib/data/registry.csv`` (shipped
inside the package, read with :mod:`importlib.resources`) with its upstream URL (pinned to a
commit) and its sha256. Files are never committed to this repository:

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
import importlib.resources
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
    "load_tps_rpm_case",
    "TPS_RPM_LEVELS",
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

#: The environment variable naming a folder that holds the datasets in the registry's layout
#: (e.g. ``$SHAPELIB_DATA_DIR/cdfhc/cdfhc_data2D_CC.mat``): the loaders read them from there instead
#: of downloading them.
DATA_DIR_ENV = "SHAPELIB_DATA_DIR"
CACHE_DIR_ENV = "SHAPELIB_CACHE_DIR"
#: the registry as a package resource (``shapelib/data/registry.csv``; in a wheel or a checkout alike)
REGISTRY_PATH = importlib.resources.files("shapelib") / "data" / "registry.csv"

#: Paper ids (Fig. 10 / Table I numbering) of the 7 shapes in ``cdfhc_data2D_CC.mat``, in file order.
CC_PAPER_IDS = (1, 3, 8, 2, 6, 7, 9)


class DataError(ValueError):
    """A raw data file is missing or does not match its registered checksum.

    A :class:`ValueError`; the message names the file, where it was looked for and its upstream URL.

    Examples
    --------
    >>> from shapelib.datasets import DataError, fetch
    >>> try:
    ...     fetch("no/such/file.txt")
    ... except DataError as exc:
    ...     print(str(exc)[:40])
    'no/such/file.txt' is not in the dataset
    """


@functools.lru_cache(maxsize=1)
def registry() -> dict[str, tuple[str, str]]:
    r"""Return ``{relative path: (upstream url, sha256)}`` for every registered raw file.

    Read once (cached) from ``shapelib/data/registry.csv``, a file shipped inside the package: each
    file the study uses, with its upstream URL pinned to a commit and the SHA-256 :math:`h` that :func:`~shapelib.datasets.fetch` checks,

    .. math::

        \operatorname{sha256}(\text{file}) = h.

    Returns
    -------
    dict of str to (str, str)
        Relative path to ``(url, sha256)``.

    Raises
    ------
    DataError
        If the registry file is missing.

    See Also
    --------
    shapelib.datasets.fetch : A verified local copy of a registered file.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    The corpus callosum shapes of Table I of [1]_ are registered:

    >>> from shapelib.datasets import registry
    >>> url, sha = registry()["cdfhc/cdfhc_data2D_CC.mat"]
    >>> url.startswith("https://"), len(sha)
    (True, 64)
    """
    if not REGISTRY_PATH.is_file():
        raise DataError(f"dataset registry not found at {REGISTRY_PATH}")
    with REGISTRY_PATH.open(newline="") as fh:
        return {row["path"]: (row["url"], row["sha256"]) for row in csv.DictReader(fh)}


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fetch(relpath: str) -> Path:
    """Return a local, checksum-verified copy of the registered file ``relpath``.

    From ``$SHAPELIB_DATA_DIR`` when set (same layout as the registry paths), else downloaded once
    with :mod:`pooch` into the user cache (or ``$SHAPELIB_CACHE_DIR``); either way its SHA-256 must
    equal the registry's.

    Parameters
    ----------
    relpath : str
        A path of the registry, e.g. ``"cdfhc/cdfhc_data2D_CC.mat"``.

    Returns
    -------
    pathlib.Path
        The verified local file.

    Raises
    ------
    DataError
        If ``relpath`` is not registered, the file is missing from ``$SHAPELIB_DATA_DIR``,
        its sha256 does not match the registry, or the download fails.

    See Also
    --------
    shapelib.datasets.registry : What can be fetched.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    The data of the study of [1]_ (with ``SHAPELIB_DATA_DIR`` set, offline):

    >>> from shapelib.datasets import fetch
    >>> fetch("cdfhc/cdfhc_data2D_CC.mat").name
    'cdfhc_data2D_CC.mat'
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
    """Registered sha256 of each file in ``relpaths`` (used to key cached results).

    Parameters
    ----------
    relpaths : iterable of str
        Registry paths.

    Returns
    -------
    dict of str to str
        Path to SHA-256 (hex).

    Raises
    ------
    KeyError
        For a path that is not registered.

    See Also
    --------
    shapelib.datasets.registry

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.datasets import data_checksums
    >>> sums = data_checksums(["cdfhc/cdfhc_data2D_CC.mat"])
    >>> len(sums["cdfhc/cdfhc_data2D_CC.mat"])
    64

    These keys identify the raw data of the study of [1]_ in cached results.
    """
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

    The shapes of Fig. 10 and Table I of [1]_, 63 landmarks each.

    Returns
    -------
    shapes : ndarray, shape (7, 63, 2)
        Closed contours, 63 landmarks in correspondence, in the file's normalised coordinates.
    paper_ids : ndarray of int, shape (7,)
        Their numbers in the paper's Figure 10 and Table I: ``[1, 3, 8, 2, 6, 7, 9]``.

    Raises
    ------
    DataError
        If the file cannot be had (see :func:`~shapelib.datasets.fetch`).

    See Also
    --------
    shapelib.to_centroid_size : The study's scale (centroid size 20).

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.datasets import load_corpus_callosum
    >>> shapes, ids = load_corpus_callosum()
    >>> shapes.shape, ids.tolist()
    ((7, 63, 2), [1, 3, 8, 2, 6, 7, 9])
    """
    return _mat_cell("cdfhc/cdfhc_data2D_CC.mat", "CC7"), np.array(CC_PAPER_IDS)


def load_fish2d() -> np.ndarray:
    """``fish2d``: 7 deformed fish, outline plus interior strokes, 150 points each.

    Shapes with interior structure and disconnected parts, as in the fish of Figs. 7–9 of [1]_.

    Returns
    -------
    ndarray, shape (7, 150, 2)
        The fish, points in correspondence.

    Raises
    ------
    DataError
        If the file cannot be had.

    See Also
    --------
    shapelib.datasets.load_beijing : The other multi-part shapes of the same source.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.datasets import load_fish2d
    >>> load_fish2d().shape
    (7, 150, 2)
    """
    return _mat_cell("cdfhc/cdfhc_data2D_fish.mat", "fish2d")


def load_beijing() -> np.ndarray:
    """``beijing``: 7 drawings of a Chinese character with disconnected strokes.

    Shapes with disconnected components, the topology the GMM representation of [1]_ does not
    constrain.

    Returns
    -------
    ndarray, shape (7, 113, 2)
        The drawings, points in correspondence.

    Raises
    ------
    DataError
        If the file cannot be had.

    See Also
    --------
    shapelib.datasets.load_fish2d

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.datasets import load_beijing
    >>> load_beijing().shape
    (7, 113, 2)
    """
    return _mat_cell("cdfhc/cdfhc_data2D_beijing.mat", "beijing")


_TPS_RPM = re.compile(r"^(fish|chinese)_(def|noise|occlusion|outlier|rot)_(\d)$")

#: the 56 levels of the Chui–Rangarajan benchmark: shape × degradation × level (samples 1–10 each)
TPS_RPM_LEVELS = tuple(f"{shape}_{kind}_{level}" for shape in ("fish", "chinese")
                       for kind, top in (("def", 5), ("noise", 6), ("outlier", 5), ("occlusion", 6), ("rot", 6))
                       for level in range(1, top + 1))


def _tps_rpm_file(name: str, sample: int) -> str:
    rel = f"tps-rpm/save_{name}_{sample}.mat"
    if _TPS_RPM.match(name) is None or name not in TPS_RPM_LEVELS:
        raise ValueError(f"unknown TPS-RPM level {name!r}; choose one of {list(TPS_RPM_LEVELS)}")
    if isinstance(sample, bool) or not isinstance(sample, (int, np.integer)) or rel not in registry():
        raise ValueError(f"TPS-RPM level {name!r} has samples 1 to 10; got sample={sample!r}")
    return rel


def load_tps_rpm(name: str = "fish_def_1", *, sample: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """A Chui–Rangarajan TPS-RPM benchmark pair, e.g. ``"fish_def_3"`` -> ``(x1, y2a)``.

    The synthetic point-matching sets of [1]_ (fish or Chinese character; deformation 1–5, noise
    1–6, outlier 1–5, occlusion 1–6 or rotation 1–6: :data:`TPS_RPM_LEVELS`). With the ground
    truth: :func:`load_tps_rpm_case`.

    Parameters
    ----------
    name : str, default "fish_def_1"
        ``"<fish|chinese>_<def|noise|occlusion|outlier|rot>_<level>"``.
    sample : int, default 1
        1 to 10.

    Returns
    -------
    x1 : ndarray, shape (M, 2)
        The template.
    y2a : ndarray, shape (N, 2)
        The deformed/noisy/occluded/rotated target.

    Raises
    ------
    ValueError
        For an unknown set (the message lists the registered ones).
    DataError
        If the file cannot be had.

    See Also
    --------
    shapelib.datasets.load_cpd_fish, shapelib.datasets.load_gmmreg_fish

    References
    ----------
    .. [1] H. Chui and A. Rangarajan, "A new point matching algorithm for non-rigid registration",
       *Computer Vision and Image Understanding* 89(2–3), 114–141, 2003.

    Examples
    --------
    >>> from shapelib.datasets import load_tps_rpm
    >>> x1, y2a = load_tps_rpm("fish_def_3")
    >>> x1.shape, y2a.shape
    ((98, 2), (98, 2))
    """
    case = load_tps_rpm_case(name, sample=sample)
    return case["x1"], case["y2a"]


def load_tps_rpm_case(name: str = "fish_def_1", *, sample: int = 1) -> dict:
    """One registration case of the Chui–Rangarajan benchmark with its ground truth.

    Parameters
    ----------
    name : str
        A level of :data:`TPS_RPM_LEVELS`: ``{fish,chinese}_{def 1–5, noise 1–6, outlier 1–5,
        occlusion 1–6, rot 1–6}``.
    sample : int
        1 to 10.

    Returns
    -------
    dict
        ``x1`` the template (98 × 2 fish, 105 × 2 Chinese character), ``y2a`` the target
        (deformed, noisy, with outliers, occluded or rotated), ``y2`` the clean warped template,
        point for point with the first ``len(y2)`` points of ``x1``: the registration error of a
        method is ``mean_i |moved_i − y2_i|`` over those points.

    See Also
    --------
    shapelib.datasets.load_tps_rpm : The benchmark's first template and target.
    shapelib.pointsets.registration.register : Registers ``x1`` onto ``y2a``.

    Notes
    -----
    The synthetic fish and Chinese-character sets of TPS-RPM [1]_, in the levels of deformation, noise,
    outliers, occlusion and rotation of its benchmark.

    References
    ----------
    .. [1] H. Chui and A. Rangarajan, "A new point matching algorithm for non-rigid registration",
       *Computer Vision and Image Understanding* 89(2–3), 114–141, 2003.

    Examples
    --------
    >>> from shapelib.datasets import load_tps_rpm_case
    >>> case = load_tps_rpm_case("fish_occlusion_3", sample=2)
    >>> case["x1"].shape, len(case["y2"]) <= len(case["x1"])
    ((98, 2), True)
    """
    rel = _tps_rpm_file(name, sample)
    from scipy.io import loadmat

    d = loadmat(fetch(rel))
    return {k: np.asarray(d[k], dtype=np.float64) for k in ("x1", "y2a", "y2")}


def load_cpd_fish() -> tuple[np.ndarray, np.ndarray]:
    """The Coherent Point Drift demo fish pair ``(source, target)``, 91 points each.

    The fish of pycpd's examples, derived from the TPS-RPM fish of [1]_.

    Returns
    -------
    source, target : ndarray, shape (91, 2)
        The two point sets.

    Raises
    ------
    DataError
        If the files cannot be had.

    See Also
    --------
    shapelib.datasets.load_tps_rpm

    References
    ----------
    .. [1] H. Chui and A. Rangarajan, "A new point matching algorithm for non-rigid registration",
       *Computer Vision and Image Understanding* 89(2–3), 114–141, 2003.

    Examples
    --------
    >>> from shapelib.datasets import load_cpd_fish
    >>> source, target = load_cpd_fish()
    >>> source.shape, target.shape
    ((91, 2), (91, 2))
    """
    return (
        np.loadtxt(fetch("cpd/fish_source.txt"), dtype=np.float64),
        np.loadtxt(fetch("cpd/fish_target.txt"), dtype=np.float64),
    )


def load_gmmreg_fish(name: str = "fish_X") -> np.ndarray:
    """A gmmreg test fish: ``fish_X``, ``fish_Y``, ``fish_X_nohead``, ``fish_Y_notail``, ``fish_ctrl_pts``.

    The fish point sets of the gmmreg test data, from the TPS-RPM fish of [1]_.

    Parameters
    ----------
    name : str, default "fish_X"
        Which file.

    Returns
    -------
    ndarray, shape (M, 2)
        The points.

    Raises
    ------
    ValueError
        For an unknown name (the message lists the registered ones).
    DataError
        If the file cannot be had.

    See Also
    --------
    shapelib.datasets.load_tps_rpm

    References
    ----------
    .. [1] H. Chui and A. Rangarajan, "A new point matching algorithm for non-rigid registration",
       *Computer Vision and Image Understanding* 89(2–3), 114–141, 2003.

    Examples
    --------
    >>> from shapelib.datasets import load_gmmreg_fish
    >>> load_gmmreg_fish("fish_X").shape
    (98, 2)
    """
    rel = f"gmmreg/{name}.txt"
    if rel not in registry():
        options = sorted(Path(p).stem for p in registry() if p.startswith("gmmreg/"))
        raise ValueError(f"unknown gmmreg fish {name!r}; choose one of {options}")
    return np.loadtxt(fetch(rel), dtype=np.float64)


def mpeg7_names() -> list[str]:
    """Names (without ``.gif``) of the 1,400 MPEG-7 CE-Shape-1 silhouettes, e.g. ``"fish-3"``.

    Returns
    -------
    list of str
        Sorted names.

    See Also
    --------
    shapelib.datasets.mpeg7_landmarks : Landmarks of one silhouette.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    Silhouettes for retrieval with the shape distances of [1]_:

    >>> from shapelib.datasets import mpeg7_names
    >>> names = mpeg7_names()
    >>> len(names), "fish-3" in names
    (1400, True)
    """
    return sorted(Path(p).stem for p in registry() if p.startswith("mpeg7/") and p.endswith(".gif"))


def load_mpeg7_image(name: str) -> np.ndarray:
    """The binary silhouette ``name`` (e.g. ``"fish-3"``) as a boolean image, foreground True.

    Parameters
    ----------
    name : str
        A name of :func:`~shapelib.datasets.mpeg7_names`.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        Foreground (grey level above 127.5) True.

    Raises
    ------
    ValueError
        For an unknown name.
    DataError
        If the file cannot be had.

    See Also
    --------
    shapelib.datasets.mpeg7_boundary, shapelib.datasets.mpeg7_landmarks

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.datasets import load_mpeg7_image
    >>> img = load_mpeg7_image("fish-3")
    >>> img.dtype, img.shape
    (dtype('bool'), (101, 271))

    Its outline can be represented as the mixture of eq. (5) of [1]_ once landmarked.
    """
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
    (the image border counts as background); ``y`` grows upwards (image row flipped). These are
    the ambient (extrinsic) points of §III-E of [1]_.

    Parameters
    ----------
    name : str
        A name of :func:`~shapelib.datasets.mpeg7_names`.

    Returns
    -------
    ndarray, shape (M, 2)
        Pixel coordinates (x, y).

    Raises
    ------
    ValueError
        For an unknown name.

    See Also
    --------
    shapelib.extrinsic_warp : Moves such points along a geodesic.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.datasets import mpeg7_boundary
    >>> mpeg7_boundary("fish-3").shape
    (741, 2)
    """
    img = load_mpeg7_image(name)
    pad = np.pad(img, 1, constant_values=False)
    core = pad[1:-1, 1:-1]
    interior = pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    rows, cols = np.nonzero(core & ~interior)
    return np.column_stack([cols, img.shape[0] - 1 - rows]).astype(np.float64)


def mpeg7_landmarks(name: str, n: int) -> np.ndarray:
    r"""``n`` landmarks evenly spaced by arc length along the outer boundary of ``name``.

    The outer boundary is the longest iso-contour (level 0.5, marching squares) of the silhouette;
    landmarks start at its point with the smallest x and run counter-clockwise, at arc lengths

    .. math::

        s_j = \frac{j}{n} S, \qquad j = 0, \dots, n - 1,

    :math:`S` the contour's length: the landmarks (GMM means, eq. 5 of [1]_) of the silhouette.

    Parameters
    ----------
    name : str
        A name of :func:`~shapelib.datasets.mpeg7_names`.
    n : int
        Number of landmarks (>= 3).

    Returns
    -------
    ndarray, shape (n, 2)
        The landmarks, in pixel units (bring them to the study's scale with
        :func:`shapelib.to_centroid_size`).

    Raises
    ------
    ValueError
        For ``n`` not an integer >= 3, or an unknown name.

    See Also
    --------
    shapelib.datasets.mpeg7_boundary : Every boundary pixel.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.datasets import mpeg7_landmarks
    >>> mpeg7_landmarks("fish-3", 50).shape
    (50, 2)
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
    """The 70 class names of MPEG-7 CE-Shape-1 (file-name prefixes, e.g. ``"Bone"``, ``"fish"``), sorted.

    The classes of the MPEG-7 core experiment CE-Shape-1 [1]_, 20 silhouettes each.

    Returns
    -------
    list of str
        The 70 names, sorted as Python sorts strings (capitals first).

    See Also
    --------
    shapelib.datasets.mpeg7_names : The 1,400 file names.
    shapelib.datasets.load_mpeg7 : Silhouettes or outlines of chosen classes.

    References
    ----------
    .. [1] L. J. Latecki, R. Lakämper and U. Eckhardt, "Shape descriptors for non-rigid shapes with a single closed
       contour", *Proceedings of the IEEE Conference on Computer Vision and Pattern Recognition*, 424–429, 2000.

    Examples
    --------
    >>> from shapelib.datasets import mpeg7_classes
    >>> classes = mpeg7_classes()
    >>> len(classes), classes[:3], "deer" in classes
    (70, ['Bone', 'Comma', 'Glas'], True)
    """
    return sorted({n.rsplit("-", 1)[0] for n in mpeg7_names()})


class MPEG7(NamedTuple):
    """MPEG-7 CE-Shape-1 silhouettes or outlines with their classes (:func:`load_mpeg7`).

    The shapes of the MPEG-7 core experiment CE-Shape-1 [1]_, scored by the bull's-eye test
    (:func:`shapelib.retrieval.bullseye`).

    Attributes
    ----------
    shapes : list of ndarray of bool, or ndarray, shape (N, n_points, 2)
        The silhouettes as boolean images, or (``n_points`` given) their traced outlines.
    labels : ndarray of str, shape (N,)
        The class of each shape, e.g. ``"deer"``.
    names : list of str
        The file name of each shape without ``.gif``, e.g. ``"deer-7"``.

    See Also
    --------
    shapelib.datasets.load_mpeg7 : What returns it.
    shapelib.retrieval.bullseye : The retrieval score on it.

    References
    ----------
    .. [1] L. J. Latecki, R. Lakämper and U. Eckhardt, "Shape descriptors for non-rigid shapes with a single closed
       contour", *Proceedings of the IEEE Conference on Computer Vision and Pattern Recognition*, 424–429, 2000.

    Examples
    --------
    >>> from shapelib.datasets import load_mpeg7
    >>> data = load_mpeg7(classes=["fork"], per_class=1)   # the boolean images
    >>> data.names, data.labels.tolist(), data.shapes[0].dtype
    (['fork-1'], ['fork'], dtype('bool'))
    """

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

    See Also
    --------
    shapelib.datasets.mpeg7_classes : The class names.
    shapelib.pointsets.outline.trace_outline : The outlines of ``n_points``.
    shapelib.retrieval.bullseye : The retrieval score of the MPEG-7 protocol.

    Notes
    -----
    CE-Shape-1 is the shape set of the MPEG-7 core experiment [1]_; its bull's-eye retrieval score is the
    usual benchmark of shape distances, among them inner-distance shape contexts [2]_ and total-Bregman-
    divergence mixtures [3]_.

    References
    ----------
    .. [1] L. J. Latecki, R. Lakämper and U. Eckhardt, "Shape descriptors for non-rigid shapes with a single closed
       contour", *Proceedings of the IEEE Conference on Computer Vision and Pattern Recognition*, 424–429, 2000.
    .. [2] H. Ling and D. W. Jacobs, "Shape classification using the inner-distance", *IEEE Transactions on
       Pattern Analysis and Machine Intelligence* 29(2), 286–299, 2007.
    .. [3] M. Liu, B. C. Vemuri, S. Amari and F. Nielsen, "Shape retrieval using hierarchical total Bregman soft
       clustering", *IEEE Transactions on Pattern Analysis and Machine Intelligence* 34(12), 2407–2419, 2012.

    Examples
    --------
    >>> from shapelib.datasets import load_mpeg7
    >>> data = load_mpeg7(classes=["deer", "fork"], per_class=2, n_points=50)
    >>> data.shapes.shape, data.labels.tolist()
    ((4, 50, 2), ['deer', 'deer', 'fork', 'fork'])
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

    Corpus callosum outlines like those of Table I of [1]_, for a population of 647 subjects.

    Returns
    -------
    contours : ndarray, shape (647, 50, 2)
        Mid-sagittal contours, 50 landmarks (the repeated closing point is dropped).
    labels : pandas.DataFrame
        ``patient.id, gender, age, phenotype`` in the same order.

    Raises
    ------
    DataError
        If the files cannot be had.

    See Also
    --------
    shapelib.to_centroid_size : The study's scale.
    shapelib.pairwise_distances : Distance matrices of the population.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    Reading the R data file takes about 15 s, so this example is not run in the doctests:

    >>> from shapelib.datasets import load_adhd200
    >>> contours, labels = load_adhd200()  # doctest: +SKIP
    >>> contours.shape, list(labels.columns)  # doctest: +SKIP
    ((647, 50, 2), ['patient.id', 'gender', 'age', 'phenotype'])
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
