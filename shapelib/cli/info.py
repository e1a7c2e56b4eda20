"""``shapelib info`` and ``shapelib align``: what a landmark file holds, and its shapes aligned
(semilandmarks slid first with ``--slide``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ._common import EXIT_UNCONVERGED, PROG, CLIError, _check_size, _file_options, _output_path, _read

EXAMPLES = {
    "info": "example:\n  shapelib info fish.tps",
    "align": "examples:\n  shapelib align fish.tps -o aligned.tps --size 20\n  shapelib align fish.csv -o aligned.csv\n"
             "  shapelib align wings.csv -o aligned.csv --slide curveslide.csv    # geomorph's define.sliders table\n"
             "  shapelib align wings.tps -o aligned.tps --slide curves           # the file's CURVES= blocks slide",
}


def cmd_info(args) -> int:
    from ..geometry.procrustes import centroid_size

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
              "semilandmarks (read apart; `shapelib align --slide curves` slides them)")
    ok = ~np.isnan(shapes).any(axis=(1, 2))
    if ok.any():
        lo, hi = np.nanmin(shapes, axis=(0, 1)), np.nanmax(shapes, axis=(0, 1))
        print("range       " + ", ".join(f"{a} {lo[i]:.6g} … {hi[i]:.6g}" for i, a in enumerate("xyz"[:d])))
        sizes = [centroid_size(s) for s in shapes[ok]]
        print(f"centroid    size {min(sizes):.6g} … {max(sizes):.6g}")
        if k >= 2:
            from ..geometry.scale import landmark_spacing

            h = landmark_spacing(shapes[ok])
            print(f"spacing     {h:.6g} mean nearest-landmark distance")
            if ok.sum() >= 2:
                from ..geometry.scale import estimate_sigma2

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


def _with_curves(shapes, curves, spec, path):
    """Landmarks followed by each specimen's curve points, and the sliders of those curves (each
    curve's interior points slide between their neighbours, its ends fixed)."""
    from ..geometry.semilandmarks import curve_sliders

    layout = [len(c) for c in curves[0]]
    if not layout:
        raise CLIError(f"--slide curves: {path} has no CURVES= blocks (for landmarks that are semilandmarks, give a "
                       "sliders table: --slide SLIDERS.csv)")
    for i, cs in enumerate(curves):
        if [len(c) for c in cs] != layout:
            raise CLIError(f"--slide curves: {path}: specimen {spec['id'].iloc[i]!r} (#{i + 1}) has curves of "
                           f"{[len(c) for c in cs]} points but specimen #1 has {layout}: every specimen needs the "
                           "same curves")
    starts = shapes.shape[1] + np.cumsum([0, *layout[:-1]])
    sliders = np.vstack([curve_sliders(int(a), m) for a, m in zip(starts, layout)])
    if not len(sliders):
        raise CLIError(f"--slide curves: {path}: no curve has a point between its ends (curves of {layout} points)")
    combined = np.stack([np.vstack([lm, *cs]) for lm, cs in zip(shapes, curves)])
    return combined, sliders, layout


def _slide(shapes, sliders, args):
    """:func:`shapelib.slide_semilandmarks` with the command's options."""
    from ..geometry.semilandmarks import slide_semilandmarks

    try:
        return slide_semilandmarks(shapes, sliders, criterion=args.slide_criterion or "bending_energy",
                                   max_iter=args.slide_max_iter or 20)
    except ValueError as exc:
        raise CLIError(f"--slide {args.slide}: {exc}") from None


def cmd_align(args) -> int:
    from .. import io
    from ..geometry.procrustes import generalized_procrustes

    fmt = io._format_of(args.file)
    out = Path(args.output)
    try:
        out_fmt = io._format_of(out)
    except ValueError:
        out_fmt = None
    if out_fmt != fmt:
        raise CLIError(f"-o {args.output}: align writes the input's format ({fmt}); name the output *.{fmt}")
    _output_path(out, suffixes=(f".{fmt}",), option="-o")
    _check_size(args)
    if args.sizes:
        _output_path(args.sizes, suffixes=(".csv",), option="--sizes")
    if args.slide is None and (args.slide_criterion or args.slide_max_iter is not None):
        raise CLIError(f"{'--slide-criterion' if args.slide_criterion else '--slide-max-iter'} needs --slide "
                       "SLIDERS.csv or --slide curves")
    if args.slide_max_iter is not None and args.slide_max_iter < 1:
        raise CLIError(f"--slide-max-iter must be a positive whole number; got {args.slide_max_iter}")
    by_curves = args.slide == "curves"
    if by_curves and fmt != "tps":
        raise CLIError(f"--slide curves: {args.file} is {fmt}; curves come from a .tps file's CURVES= blocks (for "
                       "another format give a sliders table: --slide SLIDERS.csv)")
    if args.slide is not None and not by_curves and not Path(args.slide).is_file():
        raise CLIError(f"--slide {args.slide}: no such file (a before,slide,after table, or 'curves')")
    read = _read(args, missing="nan" if args.estimate_missing else "error", curves=by_curves)
    shapes, spec = read[:2]
    sliders = None
    if by_curves:
        n_landmarks = shapes.shape[1]
        shapes, sliders, layout = _with_curves(shapes, read[2], spec, args.file)
    elif args.slide is not None:
        from ..io import read_sliders

        try:
            sliders = read_sliders(args.slide, n_landmarks=shapes.shape[1])
        except ValueError as exc:
            raise CLIError(f"--slide {exc}") from None
    if args.estimate_missing:
        from ..comparison.missing import estimate_missing

        try:
            est = estimate_missing(shapes, method=args.estimate_missing)
        except ValueError as exc:
            raise CLIError(f"--estimate-missing {args.estimate_missing}: {args.file}: {exc}") from None
        shapes = est.shapes
        if est.estimated.any():
            rows = np.flatnonzero(est.estimated.any(axis=1))
            listed = "; ".join(f"{spec['id'].iloc[r]}: landmark(s) "
                               f"{', '.join(str(j + 1) for j in np.flatnonzero(est.estimated[r]))}" for r in rows[:5])
            print(f"{PROG}: note: {est.summary()} ({listed}{'; …' if len(rows) > 5 else ''}); the aligned file holds "
                  "the estimates", file=sys.stderr)
    slid = _slide(shapes, sliders, args) if sliders is not None else None
    aligned, _ = generalized_procrustes(shapes if slid is None else slid.shapes, scaling=args.scaling)
    aligned = aligned * (1.0 if args.size is None else args.size)
    spec = spec.copy()
    if "scaled" in spec:
        spec["scaled"] = True  # SCALE= no longer describes aligned coordinates
    kw = {}
    if fmt == "csv" and spec.attrs.get("layout") == "long":
        kw["layout"] = "long"
    if fmt == "csv" and spec.attrs.get("landmarks"):
        kw["landmarks"] = spec.attrs["landmarks"]
    if by_curves:  # written back as the file had them: landmarks, then CURVES= blocks
        ends = n_landmarks + np.cumsum(layout)
        kw["curves"] = [[a[e - m:e] for e, m in zip(ends, layout)] for a in aligned]
        aligned = aligned[:, :n_landmarks]
    io.write_landmarks(out, aligned, spec, **kw)
    if args.sizes:
        import pandas as pd

        from .._files import write_text_atomic
        from ..geometry.procrustes import centroid_size

        sizes = pd.DataFrame({"id": spec["id"].astype(str), "centroid_size": [centroid_size(s) for s in shapes]})
        write_text_atomic(Path(args.sizes), sizes.to_csv(index=False, lineterminator="\n",
                                                         float_format=lambda v: repr(float(v))))
        print(f"centroid sizes of the specimens as read -> {args.sizes} (shapelib regress ALIGNED --covariates "
              f"{Path(args.sizes).name} --by centroid_size --log: allometry)")
    print(f"aligned {len(aligned)} specimen{'s' if len(aligned) != 1 else ''} (generalized Procrustes, {'full' if args.scaling else 'unit-size'} "
          f"scaling, centroid size {args.size or 1:g}) -> {out}")
    if slid is not None:
        state = "converged in" if slid.converged else "did not converge in"
        print(f"slid {len(slid.sliders)} semilandmarks by minimum {slid.criterion.replace('_', ' ')}: {state} "
              f"{slid.n_iter} iteration{'s' if slid.n_iter != 1 else ''}")
    if fmt == "tps" and (aligned < 0).any():
        print(f"{PROG}: note: aligned coordinates are centred, so some are negative: each specimen of {out.name} says "
              f"so in a COMMENT= line, which shapelib reads back as coordinates (tpsDig itself reads negative values "
              f"as missing landmarks)", file=sys.stderr)
    if slid is not None and not slid.converged:
        iterations = f"{slid.n_iter} iteration{'s' if slid.n_iter != 1 else ''}"
        print(f"{PROG}: warning: sliding did not converge: after {iterations} "
              f"the Procrustes sum of squares around the mean still changed by more than 1e-4 of itself; {out} holds "
              f"the shapes as slid so far (raise --slide-max-iter); exit status {EXIT_UNCONVERGED}", file=sys.stderr)
        return EXIT_UNCONVERGED
    return 0


def register(add) -> None:
    """Add ``info`` and ``align`` to the parser (``add(name, help, epilog)`` returns the subparser)."""
    p = add("info", "specimens, landmarks, dimension, missing values, scale of a landmark file", EXAMPLES["info"])
    _file_options(p)
    p.set_defaults(func=cmd_info)

    p = add("align", "generalized Procrustes alignment, written in the input's format", EXAMPLES["align"])
    _file_options(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="aligned shapes (same format as FILE)")
    p.add_argument("--size", type=float, metavar="S",
                   help="centroid size of the aligned shapes (default 1; the paper's study uses 20)")
    p.add_argument("--scaling", action="store_true", help="full GPA: fit per-shape scales instead of unit size")
    p.add_argument("--estimate-missing", choices=("tps", "regression"), metavar="METHOD",
                   help="estimate missing landmarks (NA, or tpsDig's negative coordinates) from the complete specimens "
                        "first: 'tps' (thin-plate spline from their mean) or 'regression'; a note lists them")
    p.add_argument("--sizes", metavar="SIZES.csv", help="also write each specimen's centroid size as read (id, "
                   "centroid_size), the size that alignment removes: a covariate for `shapelib regress --log`")
    g = p.add_argument_group("sliding semilandmarks")
    g.add_argument("--slide", metavar="SLIDERS.csv|curves",
                   help="slide semilandmarks along their curves before the alignment, as geomorph's gpagen(curves=): "
                        "a table of rows before,slide,after (landmark numbers from 1, as geomorph's define.sliders "
                        "writes it), or 'curves': a .tps file's CURVES= points slide between their neighbours, each "
                        "curve's ends fixed, and are written back as CURVES= blocks")
    g.add_argument("--slide-criterion", choices=("bending_energy", "procrustes"), metavar="C",
                   help="bending_energy (default, as geomorph) or procrustes (geomorph's ProcD=TRUE)")
    g.add_argument("--slide-max-iter", type=int, metavar="N",
                   help="most slide-and-align iterations (default 20); not converging by then exits with status "
                        f"{EXIT_UNCONVERGED}")
    p.set_defaults(func=cmd_align)
