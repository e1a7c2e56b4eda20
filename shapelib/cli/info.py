"""``shapelib info`` and ``shapelib align``: what a landmark file holds, and its shapes aligned."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ._common import PROG, CLIError, _check_size, _file_options, _output_path, _read

EXAMPLES = {
    "info": "example:\n  shapelib info fish.tps",
    "align": "examples:\n  shapelib align fish.tps -o aligned.tps --size 20\n  shapelib align fish.csv -o aligned.csv",
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
              "semilandmarks (read apart; not used by the other commands)")
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
    shapes, spec = _read(args, missing="nan" if args.estimate_missing else "error")
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
    if fmt == "tps" and (aligned < 0).any():
        print(f"{PROG}: note: aligned coordinates are centred, so some are negative: each specimen of {out.name} says "
              f"so in a COMMENT= line, which shapelib reads back as coordinates (tpsDig itself reads negative values "
              f"as missing landmarks)", file=sys.stderr)
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
    p.set_defaults(func=cmd_align)
