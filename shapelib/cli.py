"""The ``shapelib`` command line: landmark files in, aligned shapes, distance matrices and geodesics out.

Subcommands (``shapelib <command> --help`` shows an example for each)::

    shapelib info FILE
    shapelib align FILE -o OUT [--size S]
    shapelib distances FILE --metric M [--sigma2 S|auto] [--rtol R] [--jobs N | --scheduler ADDRESS]
                           [--store D.zarr [--max-blocks N]] [--no-progress] -o D.csv
    shapelib geodesic FILE --from ID --to ID --metric M --sigma2 S|auto -o path.csv [--plot P.png] [--animate A.gif]
    shapelib mean FILE --metric M --sigma2 S [--size S] [--jobs N | --scheduler ADDRESS] -o mean.tps [--plot P.png]
    shapelib pca FILE --metric M --sigma2 S [--size S] [--n-components K] -o scores.csv [--plot modes.png]
    shapelib study [run_all.py options: --quick, --only NAME, -p NAME=VALUE, -j N, --force, --list, ...]

Files are read by :func:`shapelib.io.read_landmarks` (``.tps``, ``.csv``, ``.npy``, ``.npz``). Bad
input ends the command with one line ``shapelib: error: …`` on stderr (naming the file, specimen,
landmark or parameter) and exit status 1; usage errors exit with 2, as argparse does. A Ctrl-C
ends it with ``shapelib: interrupted`` and status 130; ``distances --max-blocks N`` stopping before
the matrix is complete exits with status 75 (``EX_TEMPFAIL``: rerun to resume), writing no ``-o``.
A geodesic (``geodesic``, or a pair of ``distances`` without ``--rtol``) whose solver did not
converge is written, said in a warning, and the command exits with status 4 (:data:`EXIT_UNCONVERGED`).
``shapelib study`` is ``run_all.py`` itself: its help, usage errors and exit codes are run_all's.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import logging
import os
import sys
import warnings
from pathlib import Path

import numpy as np

from ._validate import InputError

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


def _read(args, *, missing="error"):
    from . import io

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
        return io.read_landmarks(args.file, **kw)
    except InputError as exc:
        raise CLIError(_in_cli_words(exc)) from None
    except ValueError as exc:
        raise CLIError(str(exc)) from None


#: the remedies an :class:`~shapelib._validate.InputError` names, in the command line's options
CLI_WORDS = {
    "keep_missing": "estimate or drop the missing landmarks first",
    "scale": "--scale",
    "pkn": "read it with --pkn",
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
    from ._files import write_text_atomic

    write_text_atomic(Path(path), frame.to_csv(lineterminator="\n", **kw))


def parse_assignment(text: str, *, flag: str = "--param", example: str = "n_steps=16") -> tuple[str, object]:
    """``"sigma2=0.5"`` -> ``("sigma2", 0.5)``: ``NAME=VALUE`` with the value read as a Python literal
    (numbers, True, lists, 'text'), else kept as a string. The one parser of ``shapelib --param``
    and ``run_all.py -p``; a ValueError names ``flag`` and the text, and shows ``example``."""
    key, sep, raw = text.partition("=")
    key, raw = key.strip(), raw.strip()
    if not sep or not key.isidentifier():
        raise ValueError(f"{flag} {text!r}: expected NAME=VALUE, e.g. {flag} {example}")
    try:
        return key, ast.literal_eval(raw)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        return key, raw


def _parse_params(items):
    """``--param NAME=VALUE`` items -> dict (:func:`parse_assignment`)."""
    try:
        return dict(parse_assignment(item) for item in items or [])
    except ValueError as exc:
        raise CLIError(str(exc)) from None


def _metric_params(args):
    from .distances import check_metric_params

    params = _parse_params(args.param)
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
    from .geometry.scale import estimate_sigma2

    try:
        est = estimate_sigma2(shapes)
    except ValueError as exc:
        raise CLIError(f"--sigma2 auto: {exc}") from None
    print(f"sigma2 = {est.sigma2:.6g} (auto: the landmarks' scatter around the mean shape, sigma = "
          f"{est.sigma_over_spacing:.2g} landmark spacings)")
    if est.pose_share > 0.1:
        warnings.warn(f"--sigma2 auto: {est.pose_share:.0%} of the landmarks' scatter in {args.file} is position and "
                      "orientation; the distances see the shapes as given: align them first (shapelib align)")
    return {**params, "sigma2": float(f"{est.sigma2:.6g}")}


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
    from .distances import pose_dependent
    from .geometry.procrustes import POSE_TOL, pose_align

    if args.no_align or not pose_dependent(args.metric, params) or shapes.shape[1] < 2:
        return shapes
    aligned, moved = pose_align(shapes)
    if moved.max() <= POSE_TOL:
        return shapes  # aligned already (e.g. by `shapelib align`): the file's values as they are
    if moved.max() > POSE_TOL:
        print(f"{PROG}: note: {args.metric} depends on the pose of the shapes: aligned the {len(shapes)} specimens of "
              f"{args.file} first (generalized Procrustes rotations and translations, sizes kept), which moved them "
              f"by up to {100 * moved.max():.3g} % of their size; --no-align uses the file's pose", file=sys.stderr)
    return aligned


# ---------------------------------------------------------------------------------------------
# subcommands
# ---------------------------------------------------------------------------------------------


def cmd_info(args) -> int:
    from .geometry.procrustes import centroid_size

    shapes, spec = _read(args, missing="nan")
    n, k, d = shapes.shape
    print(f"file        {args.file} ({spec.attrs.get('format')}"
          + (f", {spec.attrs['layout']} layout" if "layout" in spec.attrs else "") + ")")
    print(f"specimens   {n}")
    print(f"landmarks   {k}")
    print(f"dimension   {d}")
    n_missing = int(spec["n_missing"].sum())
    if n_missing:
        rows = np.flatnonzero(spec["n_missing"].to_numpy() > 0)

        def which(row):  # landmark numbers from 1, as in the file
            lms = np.flatnonzero(np.isnan(shapes[row]).any(axis=1)) + 1
            return "landmark" + ("s " if len(lms) > 1 else " ") + ", ".join(map(str, lms[:6])) + (
                ", …" if len(lms) > 6 else "")

        listed = ", ".join(f"{spec['id'].iloc[r]} ({which(r)})" for r in rows[:5])
        more = ", …" if len(rows) > 5 else ""
        print(f"missing     {n_missing} landmark(s) in {len(rows)} specimen(s): {listed}{more}")
        if spec.attrs.get("format") == "tps" and not args.negative_coordinates:
            print("            (NA or negative coordinates, tpsDig's code for a missing landmark; if the "
                  "coordinates are genuinely negative, e.g. aligned shapes, add --negative-coordinates)")
    else:
        print("missing     none")
    if "scale" in spec:
        has = int(spec["scale"].notna().sum())
        state = "applied" if spec["scaled"].any() else "not applied (--scale applies it)"
        print(f"SCALE=      {has} of {n} specimens" + (f", {state}" if has else ""))
    if "n_curve_points" in spec and spec["n_curve_points"].any():
        print(f"curves      {int(spec['n_curves'].max())} per specimen, {int(spec['n_curve_points'].max())} "
              "semilandmarks (read apart; not used by the other commands)")
    ok = ~np.isnan(shapes).any(axis=(1, 2))
    if ok.any():
        lo, hi = np.nanmin(shapes, axis=(0, 1)), np.nanmax(shapes, axis=(0, 1))
        print("range       " + ", ".join(f"{a} {lo[i]:.6g} … {hi[i]:.6g}" for i, a in enumerate("xyz"[:d])))
        sizes = [centroid_size(s) for s in shapes[ok]]
        print(f"centroid    size {min(sizes):.6g} … {max(sizes):.6g}")
        if k >= 2:
            from .geometry.scale import landmark_spacing

            h = landmark_spacing(shapes[ok])
            print(f"spacing     {h:.6g} mean nearest-landmark distance")
            if ok.sum() >= 2:
                from .geometry.scale import estimate_sigma2

                try:
                    est = estimate_sigma2(shapes[ok])
                except ValueError as exc:
                    print(f"sigma2      not estimated: {exc}")
                else:
                    print(f"sigma2      {est.sigma2:.4g} ± {est.standard_error:.2g} from the landmarks' scatter around "
                          f"the mean shape (sigma = {est.sigma_over_spacing:.2g} spacings; `--sigma2 auto` uses it; "
                          "align --size rescales it by size²)")
                    if est.pose_share > 0.1:
                        print(f"            {est.pose_share:.0%} of the scatter as given is position and orientation: "
                              "align the shapes (shapelib align) before computing distances")
    shown = ", ".join(spec["id"].astype(str).iloc[:8])
    print(f"ids         {shown}" + (f", … ({n} in all)" if n > 8 else ""))
    return 0


def cmd_align(args) -> int:
    from . import io
    from .geometry.procrustes import generalized_procrustes

    fmt = io._format_of(args.file)
    out = Path(args.output)
    try:
        out_fmt = io._format_of(out)
    except ValueError:
        out_fmt = None
    if out_fmt != fmt:
        raise CLIError(f"-o {args.output}: align writes the input's format ({fmt}); name the output *.{fmt}")
    _output_path(out, suffixes=(f".{fmt}",), option="-o")
    if args.size is not None and not (np.isfinite(args.size) and args.size > 0):
        raise CLIError(f"--size must be a positive number; got {args.size}")
    shapes, spec = _read(args)
    aligned, _ = generalized_procrustes(shapes, scaling=args.scaling)
    aligned = aligned * (1.0 if args.size is None else args.size)
    spec = spec.copy()
    if "scaled" in spec:
        spec["scaled"] = True  # SCALE= no longer describes aligned coordinates
    kw = {}
    if fmt == "csv" and spec.attrs.get("layout") == "long":
        kw["layout"] = "long"
    if fmt == "csv" and spec.attrs.get("landmarks"):
        kw["landmarks"] = spec.attrs["landmarks"]
    io.write_landmarks(out, aligned, spec, **kw)
    print(f"aligned {len(aligned)} specimen{'s' if len(aligned) != 1 else ''} (generalized Procrustes, {'full' if args.scaling else 'unit-size'} "
          f"scaling, centroid size {args.size or 1:g}) -> {out}")
    if fmt == "tps" and (aligned < 0).any():
        print(f"{PROG}: note: aligned coordinates are centred, so some are negative: each specimen of {out.name} says "
              f"so in a COMMENT= line, which shapelib reads back as coordinates (tpsDig itself reads negative values "
              f"as missing landmarks)", file=sys.stderr)
    return 0


def cmd_distances(args) -> int:
    import pandas as pd

    from .pairwise import pairwise_distances
    from .pairwise import PairError
    from .solver.geodesic import GeodesicWarning

    out = _output_path(args.output, suffixes=(".csv",), option="-o")
    diag = _output_path(args.pairs, suffixes=(".csv",), option="--pairs") if args.pairs else None
    if diag is not None and diag.resolve() == out.resolve():
        raise CLIError(f"--pairs {args.pairs}: the same file as -o; give the pair table its own name")
    params = _metric_params(args)
    if args.jobs is not None and args.jobs < 1 and args.jobs != -1:
        raise CLIError(f"--jobs must be a positive number of worker processes (or -1: all cores); got {args.jobs}")
    shapes, spec = _read(args)
    ids = spec["id"].astype(str).tolist()
    if len(set(ids)) != len(ids):
        dup = pd.Series(ids)[pd.Series(ids).duplicated()].iloc[0]
        raise CLIError(f"{args.file}: specimen id {dup!r} occurs more than once; the matrix needs unique ids")
    if args.block_size is not None and args.block_size < 1:
        raise CLIError(f"--block-size must be >= 1; got {args.block_size}")
    if args.store and Path(args.store).exists() and not Path(args.store).is_dir():
        raise CLIError(f"--store {args.store}: exists and is not a zarr directory")
    stop = None
    if args.max_blocks is not None:
        if args.max_blocks < 1:
            raise CLIError(f"--max-blocks must be >= 1; got {args.max_blocks}")
        if not args.store:
            raise CLIError("--max-blocks needs --store: the blocks computed are kept there to resume from")
        stop = lambda p: p.blocks_computed >= args.max_blocks  # noqa: E731
    params = _auto_sigma2(args, params, shapes)
    shapes = _align_pose(args, shapes, params)
    try:
        with warnings.catch_warnings(), _notes_from("shapelib.pairwise"):  # the run's estimate, up front
            # the convergence summary is printed below with the specimens' ids instead
            warnings.simplefilter("ignore", GeodesicWarning)
            result = pairwise_distances(shapes, metric=args.metric, n_jobs=args.jobs, scheduler=args.scheduler,
                                        store=args.store, block_size=args.block_size, progress=not args.no_progress,
                                        rtol=args.rtol, return_result=True, callback=stop, **params)
    except PairError as exc:  # name the specimens, as every other input error does
        note = " (the metric counts landmarks from 0)" if exc.landmarks else ""
        raise CLIError(f"{args.file}: specimens {ids[exc.i]!r} (#{exc.i + 1}) and {ids[exc.j]!r} (#{exc.j + 1}), "
                       f"as u and v: {exc.reason}{note}") from None
    log = result.log or {}
    if not result.complete:  # --max-blocks stopped it: no matrix, the store is there to resume
        print(f"{PROG}: stopped after {log['blocks_computed']} block(s) (--max-blocks), {log['blocks_done']} of "
              f"{log['blocks_total']} in store {args.store}; -o not written: rerun the command (without "
              "--max-blocks to finish) to resume", file=sys.stderr)
        return EXIT_STOPPED
    frame = pd.DataFrame(result.matrix, index=pd.Index(ids, name="id"), columns=ids)
    _write_frame(frame, out, float_format=lambda v: repr(float(v)))
    bad = result.nonconverged_pairs()
    if diag is not None:
        pairs = result.to_frame()
        for col in ("i", "j"):
            if col in pairs:
                pairs.insert(pairs.columns.get_loc(col) + 1, f"id_{col}", [ids[int(t)] for t in pairs[col]])
        _write_frame(pairs, diag, index=False)
    resumed = ""
    if args.store and log.get("blocks_found_done"):
        resumed = (f", resumed: {log['blocks_found_done']} of {log.get('blocks_total', '?')} blocks were already "
                   "in the store")
    print(f"{args.metric}: {len(ids)} x {len(ids)} distance matrix -> {out}"
          + (f" (store {args.store}{resumed})" if args.store else ""))
    if bad:
        listed = ", ".join(f"{ids[i]}–{ids[j]}" for i, j in bad[:5]) + (", …" if len(bad) > 5 else "")
        more = "" if diag else " (--pairs FILE.csv writes every pair's bracket and status)"
        total = len(result.status())
        if args.rtol is not None:  # certified, only wider than asked: said as such, exit 0
            gap = result.rel_gap(*np.array(bad).T)
            print(f"{PROG}: warning: {len(bad)} of {total} pairs: the certified bracket is wider than --rtol "
                  f"{args.rtol:g} (relative gap median {100 * float(np.median(gap)):.3g} %, max "
                  f"{100 * float(np.max(gap)):.3g} %; {listed}): each distance lies in its bracket [lower, upper] "
                  f"and the matrix holds the upper end; the solver did not fail{more}", file=sys.stderr)
        else:
            print(f"{PROG}: warning: {len(bad)} of {total} pairs: solver failed (the geodesic solver stopped before "
                  f"its tolerance; their values are lengths of unconverged paths, upper bounds only): {listed}{more}; "
                  f"exit status {EXIT_UNCONVERGED}", file=sys.stderr)
            return EXIT_UNCONVERGED
    return 0


def cmd_geodesic(args) -> int:
    import pandas as pd

    from .distances import PATH_METRICS, path_result

    if args.metric not in PATH_METRICS:
        raise CLIError(f"--metric {args.metric}: geodesics exist for the path metrics {', '.join(PATH_METRICS)}")
    out = _output_path(args.output, suffixes=(".csv",), option="-o")
    plot = _output_path(args.plot, suffixes=(".png", ".pdf", ".svg"), option="--plot") if args.plot else None
    anim = _output_path(args.animate, suffixes=(".gif", ".mp4"), option="--animate") if args.animate else None
    if args.n_steps is not None and args.n_steps < 1:
        raise CLIError(f"--n-steps must be >= 1; got {args.n_steps}")
    if args.fps < 1:
        raise CLIError(f"--fps must be >= 1; got {args.fps}")
    if anim is not None and anim.suffix.lower() == ".mp4":
        import matplotlib.animation as manim

        if not manim.writers.is_available("ffmpeg"):
            raise CLIError(f"--animate {args.animate}: writing .mp4 needs ffmpeg, which is not installed; use a .gif")
    params = _metric_params(args)
    if args.n_steps is not None:
        if "n_steps" in params:
            raise CLIError("n_steps given twice: use --n-steps or --param n_steps=..., not both")
        params["n_steps"] = args.n_steps
    params.setdefault("n_steps", 16)
    shapes, spec = _read(args)
    params = _auto_sigma2(args, params, shapes)
    if (plot or anim) and shapes.shape[2] != 2:
        raise CLIError("--plot and --animate draw 2-D landmarks; this file is 3-D")
    links = []
    if args.links is not None:
        if not (plot or anim):
            raise CLIError("--links applies to --plot and --animate")
        from .plotting import parse_links

        try:
            links = parse_links(args.links, shapes.shape[1])
        except ValueError as exc:
            raise CLIError(f"--{exc}") from None
    i, j = _index_of(spec, args.source, "--from"), _index_of(spec, args.target, "--to")
    shapes = _align_pose(args, shapes, params)  # the whole file, as `shapelib distances` aligns it
    from .solver.geodesic import GeodesicWarning

    with warnings.catch_warnings():  # said below in the command line's words
        warnings.simplefilter("ignore", GeodesicWarning)
        result = path_result(shapes[i], shapes[j], metric=args.metric, **params)
    n1, k, d = result.path.shape
    t = np.repeat(np.linspace(0.0, 1.0, n1), k)
    frame = pd.DataFrame({"step": np.repeat(np.arange(n1), k), "t": t, "landmark": np.tile(np.arange(1, k + 1), n1),
                          **{a: result.path[:, :, c].ravel() for c, a in enumerate("xyz"[:d])}})
    _write_frame(frame, out, index=False, float_format=lambda v: repr(float(v)))
    print(f"{spec['id'].iloc[i]} -> {spec['id'].iloc[j]}: {result.summary()} -> {out}")
    if plot:
        _plot_path(result, plot, title=f"{args.metric} geodesic {spec['id'].iloc[i]} → {spec['id'].iloc[j]}",
                   links=links)
        print(f"figure -> {plot}")
    if anim:
        _animate_path(result, anim, title=f"{args.metric} geodesic {spec['id'].iloc[i]} → {spec['id'].iloc[j]}",
                      fps=args.fps, links=links)
        print(f"animation -> {anim}")
    if not result.converged:
        stopped = result.log.get("stopped_by")
        why = result.log.get("reason") or f"stopped by {stopped} after {result.n_iter} iterations"
        todo = ("bring the shapes to a scale that fits --sigma2 (shapelib align --size 20) or use a larger --sigma2"
                if stopped == "underflow" else "raise --param max_iter")
        print(f"{PROG}: warning: the {args.metric} geodesic did not converge ({why}): {out} holds the path it had, "
              f"whose length {result.length:.6g} is an upper bound only (lower bound {result.lower_bound:.6g}); "
              f"{todo}; exit status {EXIT_UNCONVERGED}", file=sys.stderr)
        return EXIT_UNCONVERGED
    return 0


def _plot_path(result, path, *, title, links):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plotting import plot_geodesic

    fig = plot_geodesic(result, links=links, title=title)
    fig.savefig(path, dpi=120, metadata={"Software": None} if Path(path).suffix == ".png" else None)
    plt.close(fig)


def _animate_path(result, path, *, title, fps, links=()):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter, PillowWriter

    from .plotting import animate_geodesic

    anim = animate_geodesic(result, title=title, links=list(links))
    writer = PillowWriter(fps=fps) if Path(path).suffix.lower() == ".gif" else FFMpegWriter(fps=fps)
    tmp = Path(path).with_name(f".{Path(path).stem}.tmp{Path(path).suffix}")
    try:
        anim.save(tmp, writer=writer)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
        plt.close(anim._fig)


# ---------------------------------------------------------------------------------------------
# intrinsic statistics: mean and pca (shapelib.population)
# ---------------------------------------------------------------------------------------------

INTRINSIC_METRICS = ("alpha", "fisher_rao")


def _intrinsic_input(args):
    """Shapes, specimens and the options shared by ``mean`` and ``pca``, checked."""
    if args.metric not in INTRINSIC_METRICS:
        raise CLIError(f"--metric {args.metric}: means and modes exist for {', '.join(INTRINSIC_METRICS)}")
    for name in ("sigma2", "tol"):
        value = getattr(args, name)
        if not (np.isfinite(value) and value > 0):
            raise CLIError(f"--{name.replace('_', '-')} must be a positive number; got {value}")
    if args.size is not None and not (np.isfinite(args.size) and args.size > 0):
        raise CLIError(f"--size must be a positive number; got {args.size}")
    if args.n_steps < 1:
        raise CLIError(f"--n-steps must be >= 1; got {args.n_steps}")
    if args.jobs is not None and args.jobs < 1 and args.jobs != -1:
        raise CLIError(f"--jobs must be a positive number of worker processes (or -1: all cores); got {args.jobs}")
    shapes, spec = _read(args)
    if len(shapes) < 2:
        raise CLIError(f"{args.file}: {len(shapes)} specimen; a mean needs at least two")
    if args.size is not None:
        from .geometry.scale import to_centroid_size

        shapes = to_centroid_size(shapes, args.size)
    options = {"tol": args.tol, "n_steps": args.n_steps, "n_jobs": args.jobs, "scheduler": args.scheduler}
    return shapes, spec, options


def cmd_mean(args) -> int:
    import pandas as pd

    from . import io
    from .population import frechet_mean

    out = _output_path(args.output, suffixes=(".tps", ".csv", ".npy", ".npz"), option="-o")
    plot = _output_path(args.plot, suffixes=(".png", ".pdf", ".svg"), option="--plot") if args.plot else None
    shapes, spec, options = _intrinsic_input(args)
    sigma2 = _auto_sigma2(args, {"sigma2": args.sigma2}, shapes)["sigma2"]
    res = frechet_mean(shapes, metric=args.metric, sigma2=sigma2, **options)
    io.write_landmarks(out, res.mean[None], pd.DataFrame({"id": ["frechet_mean"]}))  # reads back as written
    print(f"{res.summary()} -> {out}")
    if plot:
        _plot_mean(shapes, res, plot, title=f"{args.metric} Fréchet mean of {len(shapes)} specimens "
                                            f"(σ² = {sigma2:g})")
        print(f"figure -> {plot}")
    return 0


def _plot_mean(shapes, res, path, *, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plotting import plot_mean

    fig = plot_mean(shapes, res, title=title)
    fig.savefig(path, dpi=120, metadata={"Software": None} if Path(path).suffix == ".png" else None)
    plt.close(fig)


def cmd_pca(args) -> int:
    import pandas as pd

    from .population import tangent_pca

    out = _output_path(args.output, suffixes=(".csv",), option="-o")
    plot = _output_path(args.plot, suffixes=(".png", ".pdf", ".svg"), option="--plot") if args.plot else None
    if args.n_components is not None and args.n_components < 1:
        raise CLIError(f"--n-components must be >= 1; got {args.n_components}")
    shapes, spec, options = _intrinsic_input(args)
    sigma2 = _auto_sigma2(args, {"sigma2": args.sigma2}, shapes)["sigma2"]
    res = tangent_pca(shapes, metric=args.metric, sigma2=sigma2, n_components=args.n_components, modes=(),
                      **options)
    names = [f"PC{j + 1}" for j in range(res.n_components)]
    frame = pd.DataFrame(res.scores, columns=names, index=pd.Index(spec["id"].astype(str), name="id"))
    _write_frame(frame, out, float_format=lambda v: repr(float(v)))
    print(f"{res.frechet.summary() if res.frechet is not None else ''}")
    print(f"{res.summary()} -> {out}")
    print("component  variance      ratio   cumulative")
    cum = np.cumsum(res.explained_variance_ratio)
    for j in range(min(res.n_components, 10)):
        print(f"{names[j]:<9}  {res.explained_variance[j]:.6g}  {100 * res.explained_variance_ratio[j]:6.2f} %  "
              f"{100 * cum[j]:6.2f} %")
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from .plotting import plot_modes

        fig = plot_modes(res, components=tuple(range(min(3, res.n_components))), sd=(-2.0, 0.0, 2.0))
        fig.savefig(plot, dpi=120, metadata={"Software": None} if plot.suffix == ".png" else None)
        plt.close(fig)
        print(f"figure -> {plot}")
    return 0


def _intrinsic_options(p):
    p.add_argument("--metric", required=True, metavar="M", help=", ".join(INTRINSIC_METRICS))
    p.add_argument("--sigma2", type=float, required=True, metavar="S", help="σ² of the Gaussian mixture (eq. 5)")
    p.add_argument("--size", type=float, metavar="S",
                   help="align the specimens (generalized Procrustes) and scale them to centroid size S first "
                        "(the study uses 20); default: the coordinates as given, already aligned")
    p.add_argument("--tol", type=float, default=1e-3, metavar="T",
                   help="stop when |mean of the log maps| / their spread <= T (default 1e-3)")
    p.add_argument("--n-steps", type=int, default=4, metavar="N", help="segments of the discrete geodesics (default 4)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=int, metavar="N", help="worker processes on this machine (default: chosen "
                       "from the measured cost of one log map)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786")


def _add_intrinsic_commands(add):
    p = add("mean", "the Fréchet mean shape under the alpha or Fisher–Rao metric")
    _file_options(p)
    _intrinsic_options(p)
    p.add_argument("-o", "--output", required=True, metavar="mean.tps", help="the mean shape (.tps, .csv, .npy)")
    p.add_argument("--plot", metavar="mean.png", help="the specimens, the Procrustes start and the mean")
    p.set_defaults(func=cmd_mean)
    p = add("pca", "principal modes of variation at the Fréchet mean (tangent PCA in the metric)")
    _file_options(p)
    _intrinsic_options(p)
    p.add_argument("--n-components", type=int, metavar="K", help="components kept (default all)")
    p.add_argument("-o", "--output", required=True, metavar="scores.csv", help="scores: one row per specimen")
    p.add_argument("--plot", metavar="modes.png", help="shapes at -2, 0, +2 SD along the first three modes")
    p.set_defaults(func=cmd_pca)


def find_run_all() -> Path | None:
    """``run_all.py`` of the source checkout this package was imported from, or None."""
    from .study import is_checkout

    root = Path(__file__).resolve().parent.parent
    return root / "run_all.py" if is_checkout(root) else None


def cmd_study(run_all_args) -> int:
    """``shapelib study ARGS``: ``run_all.py ARGS`` of the source checkout, every option passed
    through unchanged (``shapelib study --help`` is run_all.py's help)."""
    script = find_run_all()
    if script is None:
        raise CLIError("`shapelib study` runs run_all.py from a source checkout, and this shapelib is installed "
                       f"from {Path(__file__).resolve().parent} without one; clone the repository, `pip install -e .` "
                       "there and run it from that checkout")
    argv = [sys.executable, str(script), *run_all_args]
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(sys.executable, argv)  # run_all.py's own signal handling sees Ctrl-C / SIGTERM directly


# ---------------------------------------------------------------------------------------------
# parser
# ---------------------------------------------------------------------------------------------

EXAMPLES = {
    "info": "example:\n  shapelib info fish.tps",
    "align": "examples:\n  shapelib align fish.tps -o aligned.tps --size 20\n  shapelib align fish.csv -o aligned.csv",
    "distances": ("examples:\n  shapelib distances aligned.tps --metric procrustes -o procrustes.csv\n"
                  "  shapelib distances aligned.tps --metric alpha --sigma2 0.5 \\\n"
                  "      --jobs 2 --store alpha.zarr -o alpha.csv        (rerun the same command to resume)\n"
                  "  shapelib distances aligned.tps --metric fisher_rao --sigma2 0.5 --rtol 1e-3 \\\n"
                  "      --scheduler tcp://127.0.0.1:8786 -o fr.csv"),
    "geodesic": ("example:\n  shapelib geodesic aligned.tps --from fish-1 --to Heart-1 \\\n"
                 "      --metric fisher_rao --sigma2 0.5 -o path.csv --plot path.png --links contour --animate path.gif"),
    "mean": ("example:\n  shapelib mean wings.tps --size 20 --metric alpha --sigma2 1.2 --jobs 2 -o mean.tps --plot mean.png"),
    "pca": ("example:\n  shapelib pca wings.tps --size 20 --metric alpha --sigma2 1.2 -o scores.csv --plot modes.png"),
}


def _file_options(p):
    p.add_argument("file", metavar="FILE", help="landmark file: .tps, .csv (wide or long), .npy or .npz")
    g = p.add_argument_group("reading the file")
    g.add_argument("--scale", action="store_true", help=".tps: multiply coordinates by each specimen's SCALE=")
    g.add_argument("--negative-coordinates", action="store_true",
                   help=".tps: negative values are coordinates (e.g. aligned shapes), not tpsDig's missing landmarks "
                        "(not needed for files shapelib wrote: they say so themselves)")
    g.add_argument("--pkn", action="store_true", help=".npy/.npz: the array is geomorph's p x k x n layout")


def _metric_options(p, *, metrics, required_sigma2=False):
    p.add_argument("--metric", required=True, metavar="M", help=", ".join(metrics) + " (listed below)")
    p.add_argument("--sigma2", type=_sigma2_arg, metavar="S", required=required_sigma2,
                   help="σ² of the Gaussian mixture (eq. 5), or 'auto': estimated from the landmarks' scatter "
                        "around the mean shape (`shapelib info` shows it); alpha and fisher_rao need it")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="any other option of the metric, e.g. --param n_steps=16 (repeatable)")
    p.add_argument("--no-align", action="store_true",
                   help="use the file's pose: by default the specimens are aligned first (rotations and "
                        "translations, sizes kept) for the metrics that depend on pose (alpha, fisher_rao, their "
                        "bounds, diffeomorphism, hausdorff)")


def build_parser() -> argparse.ArgumentParser:
    from ._version import __version__
    from .distances import METRICS, PATH_METRICS, metric_info

    parser = argparse.ArgumentParser(
        prog=PROG, description="Landmark shape analysis with information geometry (Peter & Rangarajan).",
        epilog="examples:\n  shapelib info fish.tps\n  shapelib align fish.tps -o aligned.tps --size 20\n"
               "  shapelib distances aligned.tps --metric alpha --sigma2 0.5 -o alpha.csv\n"
               "run `shapelib COMMAND --help` for each command's options.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def described(names):  # the registry's one-line descriptions, for the epilogs
        width = max(map(len, names))
        return "\n\nmetrics (--metric):\n" + "\n".join(f"  {n:<{width}}  {metric_info(n).description}" for n in names)

    epilogs = {"distances": EXAMPLES["distances"] + described(list(METRICS)),
               "geodesic": EXAMPLES["geodesic"] + described(list(PATH_METRICS))}

    def add(name, help_):
        sp = sub.add_parser(name, help=help_, description=help_, epilog=epilogs.get(name, EXAMPLES.get(name)),
                            formatter_class=argparse.RawDescriptionHelpFormatter)
        sp.set_defaults(subparser=sp)  # a stray option is reported with this command's usage
        return sp

    p = add("info", "specimens, landmarks, dimension, missing values, scale of a landmark file")
    _file_options(p)
    p.set_defaults(func=cmd_info)

    p = add("align", "generalized Procrustes alignment, written in the input's format")
    _file_options(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="aligned shapes (same format as FILE)")
    p.add_argument("--size", type=float, metavar="S",
                   help="centroid size of the aligned shapes (default 1; the paper's study uses 20)")
    p.add_argument("--scaling", action="store_true", help="full GPA: fit per-shape scales instead of unit size")
    p.set_defaults(func=cmd_align)

    p = add("distances", "the labelled distance matrix of every pair of specimens")
    _file_options(p)
    _metric_options(p, metrics=METRICS)
    p.add_argument("--rtol", type=float, metavar="R",
                   help="alpha/fisher_rao: certified bracket, stop when upper/lower - 1 <= R")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=int, metavar="N", help="worker processes on this machine (default: chosen "
                       "from the measured cost of one pair)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--store", metavar="D.zarr", help="zarr store of finished blocks; rerun the command to resume")
    p.add_argument("--max-blocks", type=int, metavar="N",
                   help=f"with --store: stop after computing N blocks, write no -o and exit with status {EXIT_STOPPED} "
                        "(rerun to resume)")
    p.add_argument("--block-size", type=int, metavar="B",
                   help="shapes per block side, the unit of work and of resuming (default: from the measured cost)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--pairs", metavar="PAIRS.csv", help="also write every pair's diagnostics (bounds, convergence)")
    p.add_argument("-o", "--output", required=True, metavar="D.csv",
                   help="square matrix with specimen ids as header row and first column")
    p.set_defaults(func=cmd_distances)

    p = add("geodesic", "the geodesic between two specimens: intermediate shapes, figure, animation")
    _file_options(p)
    p.add_argument("--from", dest="source", required=True, metavar="ID",
                   help="start specimen id (`shapelib info` lists them; a file without ids numbers them 0, 1, …)")
    p.add_argument("--to", dest="target", required=True, metavar="ID", help="end specimen id")
    _metric_options(p, metrics=PATH_METRICS)
    p.add_argument("--n-steps", type=int, metavar="N", help="time steps of the path (default 16)")
    p.add_argument("-o", "--output", required=True, metavar="path.csv",
                   help="long table step, t, landmark, x, y[, z] of the path")
    p.add_argument("--plot", metavar="path.png", help="landmark trajectories (Figs. 4 and 6 style)")
    p.add_argument("--animate", metavar="path.gif", help="animation of the deforming shape (.gif; .mp4 with ffmpeg)")
    p.add_argument("--fps", type=int, default=8, help="animation frames per second (default 8)")
    p.add_argument("--links", metavar="L", help="landmarks to join in --plot and --animate: pairs of landmark "
                   "numbers as in the file, e.g. 1-2,2-3,3-1 (geomorph's and Momocs' links), or 'contour' for a "
                   "closed outline in landmark order; default: points only")
    p.set_defaults(func=cmd_geodesic)

    _add_intrinsic_commands(add)

    # listed here for `shapelib --help`; main() hands everything after `study` to run_all.py
    add("study", "regenerate the study's figures and tables: run_all.py with the same options "
        "(needs a source checkout; `shapelib study --help` lists them)").set_defaults(func=lambda a: cmd_study([]))
    return parser


def _one_line_warnings(message, category, filename, lineno, file=None, line=None):
    text = " ".join(str(message).split())
    from .geometry.procrustes import PoseWarning

    if issubclass(category, PoseWarning):  # only --no-align gets here: say it in command-line terms
        text = text.split(" Align them first")[0] + " Drop --no-align to align them (rotations and translations, sizes kept)."
    print(f"{PROG}: warning: {text}", file=sys.stderr)


def _interrupted(exc: BaseException) -> bool:
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def main(argv=None) -> int:
    """Entry point of the ``shapelib`` console script and ``python -m shapelib``."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["study"]:  # run_all.py parses its own options
        run = lambda: cmd_study(argv[1:])  # noqa: E731
    else:
        args, extra = build_parser().parse_known_args(argv)
        if extra:
            args.subparser.error(f"unrecognized arguments: {' '.join(extra)}")
        run = lambda: args.func(args)  # noqa: E731
    warnings.showwarning = _one_line_warnings
    try:
        return int(run() or 0)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `shapelib info F | head`: the reader has gone, nothing to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except (ValueError, OSError) as exc:
        if os.environ.get("SHAPELIB_DEBUG"):
            raise
        msg = " ".join(str(exc).split()) or type(exc).__name__
        if isinstance(exc, OSError) and not isinstance(exc, CLIError) and getattr(exc, "filename", None):
            msg = f"{exc.filename}: {exc.strerror or msg}"
        print(f"{PROG}: error: {msg}", file=sys.stderr)
        return 1
    except Exception as exc:  # a bug, not bad input: still one line, traceback on request
        if _interrupted(exc):  # Ctrl-C inside compiled code surfaces as a SystemError around it
            print(f"{PROG}: interrupted", file=sys.stderr)
            return 130
        if os.environ.get("SHAPELIB_DEBUG"):
            raise
        print(f"{PROG}: internal error: {type(exc).__name__}: {' '.join(str(exc).split())} "
              "(set SHAPELIB_DEBUG=1 for the traceback, and please report it)", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
