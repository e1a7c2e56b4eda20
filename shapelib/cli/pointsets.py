"""``shapelib register``: one point set registered onto another (any sizes, no correspondence needed)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ._common import EXIT_UNCONVERGED, PROG, CLIError, _output_path, save_figure, use_agg

EXAMPLES = {
    "register": "examples:\n  shapelib register template.csv outline.csv -o moved.csv --plot fig.png\n"
                "  shapelib register a.tps b.tps --source-id fish-1 --target-id fish-7 --transform rigid -o moved.csv",
}


def _one_set(path, ident, option):
    from ..io import read_point_sets

    sets, ids = read_point_sets(path)
    if ident is None:
        if len(sets) > 1:
            raise CLIError(f"{path} holds {len(sets)} point sets ({', '.join(ids[:5])}{', …' if len(ids) > 5 else ''}); "
                           f"choose one with {option} ID")
        return sets[0]
    if ident not in ids:
        raise CLIError(f"{option} {ident}: {path} has no point set with that id (it has {', '.join(ids[:8])}"
                       f"{', …' if len(ids) > 8 else ''})")
    return sets[ids.index(ident)]


def _sigma2(text: str):
    if text is None or text == "auto":
        return "auto"
    try:
        s2 = float(text)
    except ValueError:
        raise CLIError(f"--sigma2 must be a positive number or 'auto'; got {text!r}") from None
    if not s2 > 0 or not np.isfinite(s2):
        raise CLIError(f"--sigma2 must be a positive number or 'auto'; got {text!r}")
    return s2


def _w(text: str):
    if text == "auto":
        return "auto"
    try:
        w = float(text)
    except ValueError:
        raise CLIError(f"--w must be a number in [0, 1) or 'auto'; got {text!r}") from None
    return w


def _progress_bar(off):
    """A tqdm bar on standard error for :func:`~shapelib.register`'s ``progress`` (None when ``off``;
    tqdm draws nothing where standard error is not a terminal)."""
    if off:
        return None
    from tqdm.auto import tqdm

    bar = tqdm(total=1, desc="register", unit="fit", leave=False, disable=None, file=sys.stderr)

    def update_to(done, total):
        bar.total = total
        bar.n = done
        bar.refresh()

    bar.update_to = update_to
    return bar


def _landmarks(path):
    """``--landmarks CSV``: rows ``source,target`` of known correspondences (0-based indices; a header line
    and lines starting with # are skipped), as an int array (k, 2); None without the option."""
    if path is None:
        return None
    import re

    f = Path(path)
    if not f.is_file():
        raise CLIError(f"--landmarks: no such file: {path}")
    rows = []
    for k, line in enumerate(f.read_text().splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = [q.strip() for q in line.split(",")]
        if not rows and not re.fullmatch(r"[+-]?\d+", parts[0]):
            continue  # the header
        if len(parts) != 2 or not all(re.fullmatch(r"[+-]?\d+", q) for q in parts):
            raise CLIError(f"--landmarks {path}, line {k}: expected two integers, source,target; got {line!r}")
        rows.append((int(parts[0]), int(parts[1])))
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def cmd_register(args) -> int:
    from ..io import write_point_set
    from ..pointsets.registration import register

    out = _output_path(args.output, suffixes=(".csv", ".npy"), option="-o")
    if args.plot:
        _output_path(args.plot, suffixes=(".png", ".pdf", ".svg"), option="--plot")
    if args.correspondence:
        _output_path(args.correspondence, suffixes=(".csv",), option="--correspondence")
    source = _one_set(args.source, args.source_id, "--source-id")
    target = _one_set(args.target, args.target_id, "--target-id")
    landmarks = _landmarks(args.landmarks)
    import warnings

    from ..pointsets.registration import RegistrationWarning

    bar = _progress_bar(args.no_progress)
    with warnings.catch_warnings():  # the summary says it, once: not a warning beside it
        warnings.simplefilter("ignore", RegistrationWarning)
        try:
            res = register(source, target, transform=args.transform, metric=args.metric,
                           sigma2=_sigma2(args.sigma2), w=_w(args.w), reflection=args.reflection,
                           max_iter=args.max_iter, tol=args.tol, landmarks=landmarks, pose_prior=args.pose_prior,
                           progress=None if bar is None else bar.update_to)
        finally:
            if bar is not None:
                bar.close()
    write_point_set(out, res.points)
    print(res.summary())
    print(f"moved source -> {out}")
    if args.correspondence:
        from .._files import write_text_atomic

        rows = "\n".join(f"{i},{j}" for i, j in enumerate(res.correspondence))
        write_text_atomic(Path(args.correspondence), f"source,target\n{rows}\n")
        print(f"correspondence (target index per source point, -1: none) -> {args.correspondence}")
    if args.plot:
        use_agg()
        import matplotlib.pyplot as plt

        d = source.shape[1]
        fig = plt.figure(figsize=(5, 5))
        ax = fig.add_subplot(projection="3d" if d == 3 else None)
        ax.plot(*target.T, ".", color="0.6", ms=3, label="target")
        ax.plot(*res.rigid_points.T, ".", color="tab:blue", ms=2, alpha=0.5, label="source, posed")
        ax.plot(*res.points.T, ".", color="tab:red", ms=3, label="source, registered")
        for i, j in enumerate(res.correspondence):
            if j >= 0:
                ax.plot(*np.stack([res.points[i], target[j]]).T, "-", color="k", lw=0.3)
        if d == 2:
            ax.set_aspect("equal")
        ax.legend(fontsize=8)
        ax.set_title(f"{res.transform} registration ({res.metric})", fontsize=9)
        save_figure(fig, args.plot)
        print(f"figure -> {args.plot}")
    if not (res.converged and res.reliable):
        why = "; ".join([*res.reasons] + ([] if res.converged else
                                          ["EM stopped before its tolerance: raise --max-iter or loosen --tol"]))
        print(f"{PROG} register: the registration probably failed ({why}); exit status {EXIT_UNCONVERGED}",
              file=sys.stderr)
        return EXIT_UNCONVERGED
    return 0


def register(add) -> None:
    """Add ``register`` to the parser (``add(name, help, epilog)`` returns the subparser)."""
    p = add("register", "register one point set onto another (any sizes, no correspondence needed): pose over "
                        "every rotation, then a deformation by the information geometry", EXAMPLES["register"])
    p.add_argument("source", metavar="SOURCE", help="point set to move: .csv (x, y[, z]), .npy, .npz or .tps")
    p.add_argument("target", metavar="TARGET", help="point set to move it onto (same formats)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="the moved source points (.csv or .npy)")
    p.add_argument("--plot", metavar="FIG", help="draw target, posed and registered source (.png, .pdf or .svg)")
    p.add_argument("--correspondence", metavar="CSV", help="write the target index of each source point (-1: none)")
    p.add_argument("--source-id", metavar="ID", help="the set to use when SOURCE holds several")
    p.add_argument("--target-id", metavar="ID", help="the set to use when TARGET holds several")
    p.add_argument("--transform", choices=("rigid", "similarity", "affine", "nonrigid"), default="nonrigid",
                   help="what may change (default nonrigid: a smooth deformation, whose similarity part is "
                        "reported as the pose)")
    p.add_argument("--metric", choices=("alpha", "fisher_rao"), default="alpha",
                   help="density distance of the pose search and metric of the deformation (default alpha)")
    p.add_argument("--sigma2", default="auto", metavar="S2",
                   help="fixed sigma2, or 'auto' (default): estimated by EM")
    p.add_argument("--w", default="auto", metavar="W",
                   help="outlier weight in [0, 1), or 'auto' (default): chosen from the data")
    p.add_argument("--reflection", action="store_true", help="also try mirror images of the source")
    p.add_argument("--max-iter", type=int, default=150, metavar="N",
                   help="EM iterations of each fit (default 150)")
    p.add_argument("--tol", type=float, default=1e-5, metavar="TOL",
                   help="EM stops when sigma2 changes by less than TOL, relative (default 1e-5)")
    p.add_argument("--pose-prior", type=float, default=0.12, metavar="K",
                   help="nats per source point that a quarter turn of the source costs in the choice among the "
                        "nonrigid fits (default 0.12); 0: no price, the fit that explains the target best")
    p.add_argument("--landmarks", metavar="CSV",
                   help="known correspondences (nonrigid): rows source,target of 0-based point indices, as "
                        "--correspondence writes them")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (drawn on a terminal only)")
    p.set_defaults(func=cmd_register)
