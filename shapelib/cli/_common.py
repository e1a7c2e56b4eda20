"""What every ``shapelib`` command shares: reading the landmark file, the metric's options, output
paths, the one-line error and the exit statuses."""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import warnings
from pathlib import Path

import numpy as np

from .._validate import InputError, parse_assignment  # noqa: F401  (shapelib.cli.parse_assignment)

PROG = "shapelib"
#: exit status of ``distances --max-blocks`` stopping before the matrix is complete (sysexits' EX_TEMPFAIL)
EXIT_STOPPED = 75


class CLIError(ValueError):
    """A user-facing error: printed as one line, exit status 1."""


#: exit status of ``distances`` and ``geodesic`` when the results are written but the geodesic
#: solver did not converge on some of them (a warning names them); a bracket that is only wider
#: than ``--rtol`` is certified, said in its own words, and exits 0
EXIT_UNCONVERGED = 4


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------


def _read(args, *, missing="error", curves=False):
    """The shapes and specimens table of ``args.file``; with ``curves`` (a .tps file), also its
    ``CURVES=`` semilandmarks (:func:`shapelib.io.read_tps` ``return_curves=True``)."""
    from .. import io

    kw = {"missing": missing}
    fmt = io._format_of(args.file)
    if fmt == "tps":
        # without the flag, each specimen's own marker decides (files written by shapelib say so)
        kw.update(scale=args.scale, negative="coordinates" if args.negative_coordinates else None)
    elif args.scale or args.negative_coordinates:
        flag = "--scale" if args.scale else "--negative-coordinates"
        raise CLIError(f"{flag} applies to .tps files only; {args.file} is {fmt}")
    if fmt in ("npy", "npz") and args.pkn:
        kw["layout"] = "pkn"
    elif args.pkn:
        raise CLIError(f"--pkn applies to .npy/.npz files only; {args.file} is {fmt}")
    try:
        if curves:
            if not Path(args.file).is_file():
                raise ValueError(f"{args.file}: no such file")
            shapes, spec, curve_points = io.read_tps(args.file, return_curves=True, **kw)
        else:
            shapes, spec = io.read_landmarks(args.file, **kw)
    except InputError as exc:
        raise CLIError(_in_cli_words(exc)) from None
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    _warn_coincident(shapes, spec, args.file)
    if kw.get("layout") == "pkn":
        n, k, d = shapes.shape
        # (K, d, N) and (N, d, K) arrays have the same look: say how the file was read
        print(f"{PROG}: note: read {args.file} as geomorph's p x k x n array: {n} specimens of {k} landmarks in {d}-D "
              f"(if it is (N, d, K) instead, {k} specimens of {n} landmarks, save it as (N, K, d): "
              "numpy.swapaxes(array, 1, 2), and read it without --pkn)", file=sys.stderr)
    return (shapes, spec, curve_points) if curves else (shapes, spec)


def _warn_coincident(shapes, spec, path) -> None:
    """Warn about landmarks that coincide within a specimen (digitised twice?), naming them."""
    if shapes.shape[1] < 2:
        return
    diff = shapes[:, :, None, :] - shapes[:, None, :, :]
    with np.errstate(invalid="ignore"):
        same = np.all(diff == 0, axis=-1)
    k = shapes.shape[1]
    same[:, np.arange(k), np.arange(k)] = False
    rows = np.flatnonzero(same.any(axis=(1, 2)))
    if len(rows):
        r = rows[0]
        a, b = np.argwhere(np.triu(same[r]))[0]
        more = f" (and {len(rows) - 1} more specimens)" if len(rows) > 1 else ""
        warnings.warn(f"{path}: specimen {spec['id'].iloc[r]!r} has landmarks {a + 1} and {b + 1} at the same point "
                      f"{tuple(float(v) for v in shapes[r, a])}{more}: digitised twice? Each landmark should be its own "
                      "point (the thin-plate spline and the missing-landmark estimates cannot use coincident ones)")


#: the remedies an :class:`~shapelib._validate.InputError` names, in the command line's options
CLI_WORDS = {
    "keep_missing": "estimate or drop the missing landmarks first",
    "scale": "--scale",
    "pkn": ("read it with --pkn if it is geomorph's p x k x n array (the command says how it read it), or, if it "
            "is (N, d, K), save it as (N, K, d) with numpy.swapaxes(array, 1, 2)"),
    "sigma2": "--sigma2",
}


def _in_cli_words(exc) -> str:
    """An input error's message with its remedies in the command line's options."""
    words = dict(CLI_WORDS)
    if exc.facts.get("negative_as_missing"):
        words["keep_missing"] += (" (or, if negative values are coordinates, e.g. aligned shapes, add "
                                  "--negative-coordinates)")
    return exc.phrase(words)


def _output_path(path, *, suffixes, option):
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise CLIError(f"{option} {path}: expected a file ending in {' or '.join(suffixes)}")
    if not p.parent.exists():
        raise CLIError(f"{option} {path}: directory {p.parent} does not exist")
    return p


def _write_frame(frame, path, **kw):
    from .._files import write_text_atomic

    write_text_atomic(Path(path), frame.to_csv(lineterminator="\n", **kw))


def _parse_params(items):
    """``--param NAME=VALUE`` items -> dict (:func:`parse_assignment`)."""
    try:
        return dict(parse_assignment(item) for item in items or [])
    except ValueError as exc:
        raise CLIError(str(exc)) from None


def _metric_params(args):
    from ..distances import check_metric_params

    params = _parse_params(args.param)
    params.update(_backend_params(args, args.metric))
    for name in ("sigma2",):
        value = getattr(args, name, None)
        if value is not None:
            if name in params:
                raise CLIError(f"--{name} given twice (also as --param {name}=...)")
            params[name] = 1.0 if value == "auto" else value  # auto: estimated once the shapes are read
    try:
        check_metric_params(args.metric, params, rtol=getattr(args, "rtol", None))
    except InputError as exc:
        missing = exc.facts.get("parameters", ())
        if missing == ("sigma2",):
            raise CLIError(f"--metric {args.metric} needs --sigma2 (σ² of the Gaussian mixture, eq. 5)") from None
        raise CLIError(f"--metric {args.metric}: {_in_cli_words(exc)}") from None
    except ValueError as exc:
        raise CLIError(f"--metric {args.metric}: {exc}") from None
    return params


def _backend_options(p):
    g = p.add_argument_group("where the geodesics are solved (alpha, fisher_rao)")
    g.add_argument("--backend", choices=("cpu", "jax"), default="cpu",
                   help="cpu: the compiled solver (default); jax: batches of pairs by L-BFGS on a JAX device "
                        '(pip install "shapelib[gpu]" on a CUDA 12 machine)')
    g.add_argument("--device", choices=("cpu", "gpu"), default=None,
                   help="with --backend jax: gpu demands a GPU (an error without one), cpu runs JAX on the CPU; "
                        "default: JAX's default device")


def _backend_params(args, metric) -> dict:
    """``backend``/``device`` options of ``--backend``/``--device``, checked (one-line errors: JAX
    missing, no GPU)."""
    from ..solver.batched import check_backend

    backend, device = getattr(args, "backend", "cpu"), getattr(args, "device", None)
    if backend == "cpu" and device is None:
        return {}
    if backend == "cpu":
        raise CLIError("--device needs --backend jax")
    if metric not in ("alpha", "fisher_rao"):
        raise CLIError(f"--backend jax applies to --metric alpha and fisher_rao, not {metric}")
    try:
        check_backend(backend, device)
    except (ImportError, RuntimeError, ValueError) as exc:
        raise CLIError(str(exc)) from None
    return {"backend": backend} if device is None else {"backend": backend, "device": device}


@contextlib.contextmanager
def _notes_from(name):
    """Print the INFO records of logger ``name`` (e.g. the engine's run estimate) as ``shapelib: note:`` lines."""
    class Note(logging.Handler):
        def emit(self, record):
            print(f"{PROG}: note: {record.getMessage()}", file=sys.stderr, flush=True)

    lg, handler = logging.getLogger(name), Note(logging.INFO)
    old = lg.level
    lg.addHandler(handler)
    lg.setLevel(logging.INFO)
    try:
        yield
    finally:
        lg.removeHandler(handler)
        lg.setLevel(old)


def _sigma2_arg(text: str):
    """``--sigma2``: a positive number, or ``auto`` (estimated from the file's shapes)."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or 'auto', got {text!r}") from None


def _auto_sigma2(args, params, shapes):
    """``--sigma2 auto``: σ² from the landmarks' scatter (:func:`shapelib.estimate_sigma2`), said on stdout."""
    if getattr(args, "sigma2", None) != "auto":
        return params
    from ..geometry.scale import estimate_sigma2

    try:
        est = estimate_sigma2(shapes)
    except ValueError as exc:
        raise CLIError(f"--sigma2 auto: {exc}") from None
    print(f"sigma2 = {est.sigma2:.6g} (auto: the landmarks' scatter around the mean shape, sigma = "
          f"{est.sigma_over_spacing:.2g} landmark spacings)")
    if est.pose_share > 0.1:
        warnings.warn(f"--sigma2 auto: {est.pose_share:.0%} of the landmarks' scatter in {args.file} is position and "
                      "orientation; the distances see the shapes as given: align them first (shapelib align)")
    from ..geometry.scale import SIGMA_RATIO_MIN, ScaleWarning

    if est.sigma_over_spacing < SIGMA_RATIO_MIN:
        # said once here, in the command line's words; the shapes are at the scale σ² was estimated
        # for, so the library's per-pair advice to rescale them does not apply
        print(f"{PROG}: note: at this sigma ({est.sigma_over_spacing:.2g} landmark spacings, below {SIGMA_RATIO_MIN:g}) "
              "the Gaussians of neighbouring landmarks barely overlap: the landmarks vary less than they are apart, "
              "geodesics are nearly straight lines and the closed-form lower bounds are loose (wide brackets); "
              f"the metric sees the outline from --sigma2 {(SIGMA_RATIO_MIN * est.spacing) ** 2:.3g} (0.2 spacings) up",
              file=sys.stderr)
        warnings.filterwarnings("ignore", category=ScaleWarning)  # main() restores the filters
    return {**params, "sigma2": float(f"{est.sigma2:.6g}")}


def scale_warning_in_cli_words(warning) -> str:
    """A :class:`~shapelib.ScaleWarning` worded with the command line's options."""
    f = warning.facts
    est = f.get("estimate")
    auto = (f", or --sigma2 auto ({est:.3g} for these shapes: the landmarks' scatter around their mean)"
            if est is not None else "")
    if f.get("kind") == "small":
        return (f"--sigma2 {f['sigma2']:.3g} puts sigma at {f['ratio']:.3g} times the mean nearest-landmark spacing "
                f"{f['spacing']:.3g}: the Gaussians of neighbouring landmarks do not overlap, so the metric sees "
                "isolated points, not a shape, and geodesics are straight lines. Use a larger --sigma2 "
                f"({f['spacing'] ** 2:.3g} puts sigma at one spacing){auto}; `shapelib info` shows both.")
    return (f"--sigma2 {f['sigma2']:.3g}: sigma exceeds the largest extent of the shapes, so each shape is a single "
            f"blob and distances between shapes nearly vanish. Use a smaller --sigma2{auto}; `shapelib info` "
            "shows it.")


def _index_of(specimens, ident, option):
    ids = specimens["id"].astype(str)
    hits = np.flatnonzero(ids.to_numpy() == str(ident))
    if len(hits) == 0:
        shown = ", ".join(ids.iloc[:8])
        more = f", … ({len(ids)} in all)" if len(ids) > 8 else ""
        raise CLIError(f"{option} {ident}: no specimen with that id in {specimens.attrs.get('path', 'the file')} "
                       f"(ids: {shown}{more})")
    if len(hits) > 1:
        raise CLIError(f"{option} {ident}: {len(hits)} specimens have that id (rows {', '.join(str(h + 1) for h in hits)}); "
                       "make the ids unique")
    return int(hits[0])


def _align_pose(args, shapes, params):
    """The shapes a pose-dependent metric sees: aligned by rotations and translations (sizes kept,
    so σ² keeps its meaning), unless --no-align or they are aligned already (within
    :data:`~shapelib.geometry.procrustes.POSE_TOL`); a note on stderr says how far that moved them."""
    from ..distances import pose_dependent
    from ..geometry.procrustes import POSE_TOL, pose_align

    if args.no_align or not pose_dependent(args.metric, params) or shapes.shape[1] < 2:
        return shapes
    aligned, moved = pose_align(shapes)
    if moved.max() <= POSE_TOL:
        return shapes  # aligned already (e.g. by `shapelib align`): the file's values as they are
    print(f"{PROG}: note: {args.metric} depends on the pose of the shapes: aligned the {len(shapes)} specimens of "
          f"{args.file} first (generalized Procrustes rotations and translations, sizes kept), which moved them "
          f"by up to {100 * moved.max():.3g} % of their size; --no-align uses the file's pose", file=sys.stderr)
    return aligned


def save_figure(fig, path) -> None:
    """Write a matplotlib figure to ``path`` (.png without the Software tag, so reruns give the same bytes) and close it."""
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=120, metadata={"Software": None} if Path(path).suffix == ".png" else None)
    plt.close(fig)


def use_agg() -> None:
    """Draw off-screen (a command never opens a window)."""
    import matplotlib

    matplotlib.use("Agg")


# ---------------------------------------------------------------------------------------------
# options shared by several commands
# ---------------------------------------------------------------------------------------------


def _file_options(p):
    p.add_argument("file", metavar="FILE", help="landmark file: .tps, .csv (wide or long), .npy or .npz")
    g = p.add_argument_group("reading the file")
    g.add_argument("--scale", action="store_true", help=".tps: multiply coordinates by each specimen's SCALE=")
    g.add_argument("--negative-coordinates", action="store_true",
                   help=".tps: negative values are coordinates (e.g. aligned shapes), not tpsDig's missing landmarks "
                        "(not needed for files shapelib wrote: they say so themselves)")
    g.add_argument("--pkn", action="store_true", help=".npy/.npz: the array is geomorph's p x k x n layout")


def _where_options(p, *, unit):
    """``--jobs N`` or ``--scheduler ADDRESS`` (one or the other); ``unit``: what the default number of
    workers is measured on ("one pair", "one log map")."""
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=int, metavar="N", help="worker processes on this machine (default: chosen "
                       f"from the measured cost of {unit})")
    where.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786")


def _check_jobs(args) -> None:
    """One-line error for a ``--jobs`` that is neither a positive number of workers nor -1."""
    if args.jobs is not None and args.jobs < 1 and args.jobs != -1:
        raise CLIError(f"--jobs must be a positive number of worker processes (or -1: all cores); got {args.jobs}")


def _check_size(args) -> None:
    """One-line error for a ``--size`` (centroid size to scale to) that is not a positive number."""
    if args.size is not None and not (np.isfinite(args.size) and args.size > 0):
        raise CLIError(f"--size must be a positive number; got {args.size}")


def _metric_options(p, *, metrics, required_sigma2=False):
    p.add_argument("--metric", required=True, metavar="M", help=", ".join(metrics) + " (listed below)")
    p.add_argument("--sigma2", type=_sigma2_arg, metavar="S", required=required_sigma2,
                   help="σ² of the Gaussian mixture (eq. 5), or 'auto': estimated from the landmarks' scatter "
                        "around the mean shape (`shapelib info` shows it); alpha and fisher_rao need it")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="any other option of the metric, e.g. --param n_steps=16 (repeatable)")
    _backend_options(p)
    p.add_argument("--no-align", action="store_true",
                   help="use the file's pose: by default the specimens are aligned first (rotations and "
                        "translations, sizes kept) for the metrics that depend on pose (alpha, fisher_rao, their "
                        "bounds, diffeomorphism, hausdorff)")
