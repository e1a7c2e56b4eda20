"""``shapelib mean`` and ``shapelib pca``: the Fréchet mean and tangent PCA in an information metric
(:mod:`shapelib.statistics`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import (CLIError, _auto_sigma2, _backend_options, _backend_params, _check_jobs, _check_size, _file_options,
                      _output_path, _read, _sigma2_arg, _where_options, _write_frame)

EXAMPLES = {
    "mean": ("example:\n  shapelib mean wings.tps --size 20 --metric alpha --sigma2 1.2 --jobs 2 -o mean.tps --plot mean.png"),
    "pca": ("example:\n  shapelib pca wings.tps --size 20 --metric alpha --sigma2 1.2 -o scores.csv --plot modes.png"),
}

INTRINSIC_METRICS = ("alpha", "fisher_rao")


def _intrinsic_input(args):
    """Shapes, specimens and the options shared by ``mean`` and ``pca``, checked."""
    if args.metric not in INTRINSIC_METRICS:
        raise CLIError(f"--metric {args.metric}: means and modes exist for {', '.join(INTRINSIC_METRICS)}")
    for name in ("sigma2", "tol"):
        value = getattr(args, name)
        if value == "auto":
            continue
        if not (np.isfinite(value) and value > 0):
            raise CLIError(f"--{name.replace('_', '-')} must be a positive number; got {value}")
    _check_size(args)
    if args.n_steps < 1:
        raise CLIError(f"--n-steps must be >= 1; got {args.n_steps}")
    _check_jobs(args)
    shapes, spec = _read(args)
    if shapes.shape[1] < 3:
        raise CLIError(f"{args.file}: {shapes.shape[1]} landmark(s): after alignment (position, orientation, size) "
                       "every such configuration is the same shape, so there is no shape variation to average or "
                       "decompose; a shape needs at least 3 landmarks")
    if len(shapes) < 2:
        raise CLIError(f"{args.file}: {len(shapes)} specimen; a mean needs at least two")
    if args.size is not None:
        from ..geometry.scale import to_centroid_size

        shapes = to_centroid_size(shapes, args.size)
    options = {"tol": args.tol, "n_steps": args.n_steps, "n_jobs": args.jobs, "scheduler": args.scheduler}
    args.link_pairs = None
    if args.links is not None:
        if not args.plot:
            raise CLIError("--links applies to --plot")
        from ..plotting import parse_links

        try:
            args.link_pairs = parse_links(args.links, shapes.shape[1])
        except ValueError as exc:
            raise CLIError(f"--{exc}") from None
    return shapes, spec, options


def cmd_mean(args) -> int:
    import pandas as pd

    from .. import io
    from ..statistics import frechet_mean

    out = _output_path(args.output, suffixes=(".tps", ".csv", ".npy", ".npz"), option="-o")
    plot = _output_path(args.plot, suffixes=(".png", ".pdf", ".svg"), option="--plot") if args.plot else None
    shapes, spec, options = _intrinsic_input(args)
    sigma2 = _auto_sigma2(args, {"sigma2": args.sigma2}, shapes)["sigma2"]
    options.update(_backend_params(args, args.metric))
    res = frechet_mean(shapes, metric=args.metric, sigma2=sigma2, **options)
    io.write_landmarks(out, res.mean[None], pd.DataFrame({"id": ["frechet_mean"]}))  # reads back as written
    print(f"{res.summary()} -> {out}")
    if plot:
        _plot_mean(shapes, res, plot, links=args.link_pairs, title=f"{args.metric} Fréchet mean of {len(shapes)} specimens "
                                            f"(σ² = {sigma2:g})")
        print(f"figure -> {plot}")
    return 0


def _plot_mean(shapes, res, path, *, title, links=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plotting import plot_mean

    fig = plot_mean(shapes, res, closed=None, links=links, title=title)
    fig.savefig(path, dpi=120, metadata={"Software": None} if Path(path).suffix == ".png" else None)
    plt.close(fig)


def cmd_pca(args) -> int:
    import pandas as pd

    from ..statistics import tangent_pca

    out = _output_path(args.output, suffixes=(".csv",), option="-o")
    plot = _output_path(args.plot, suffixes=(".png", ".pdf", ".svg"), option="--plot") if args.plot else None
    scores_plot = (_output_path(args.scores_plot, suffixes=(".png", ".pdf", ".svg"), option="--scores-plot")
                   if args.scores_plot else None)
    if bool(args.by) != bool(args.covariates):
        raise CLIError("--by and --covariates go together: the column, and the CSV file that holds it")
    if args.by and not scores_plot:
        raise CLIError("--by colours --scores-plot; give --scores-plot FILE.png")
    if scores_plot is not None and args.n_components is not None and args.n_components < 2:
        raise CLIError("--scores-plot draws PC1 against PC2: --n-components must be at least 2")
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
    if scores_plot:
        from ..plotting import plot_scores
        from ._common import save_figure, use_agg

        use_agg()
        groups = None
        if args.by:
            from .effects import _covariates

            groups = _covariates(args.covariates, spec, args.by, None).astype(str).to_numpy()
        save_figure(plot_scores(res.scores, groups, explained=res.explained_variance_ratio,
                                title=f"{args.metric} tangent PCA" + (f" by {args.by}" if args.by else "")),
                    scores_plot)
        print(f"figure -> {scores_plot}")
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from ..plotting import plot_modes

        fig = plot_modes(res, components=tuple(range(min(3, res.n_components))), sd=(-2.0, 0.0, 2.0), closed=None,
                         links=args.link_pairs)
        fig.savefig(plot, dpi=120, metadata={"Software": None} if plot.suffix == ".png" else None)
        plt.close(fig)
        print(f"figure -> {plot}")
    return 0


def _intrinsic_options(p):
    p.add_argument("--metric", required=True, metavar="M", help=", ".join(INTRINSIC_METRICS))
    p.add_argument("--sigma2", type=_sigma2_arg, required=True, metavar="S",
                   help="σ² of the Gaussian mixture (eq. 5), or 'auto': estimated from the landmarks' scatter around "
                        "the mean shape, after --size (`shapelib info` shows it)")
    p.add_argument("--size", type=float, metavar="S",
                   help="align the specimens (generalized Procrustes) and scale them to centroid size S first "
                        "(the study uses 20); default: the coordinates as given, already aligned")
    p.add_argument("--tol", type=float, default=1e-3, metavar="T",
                   help="stop when |mean of the log maps| / their spread <= T (default 1e-3)")
    p.add_argument("--n-steps", type=int, default=4, metavar="N", help="segments of the discrete geodesics (default 4)")
    p.add_argument("--links", metavar="L", help="landmarks to join in --plot: pairs of landmark numbers as in the file, "
                   "e.g. 1-2,2-3,3-1 (geomorph's and Momocs' links), or 'contour' for a closed outline in landmark "
                   "order; default: points only")
    _where_options(p, unit="one log map")


def register(add) -> None:
    """Add ``mean`` and ``pca`` to the parser (``add(name, help, epilog)`` returns the subparser)."""
    p = add("mean", "the Fréchet mean shape under the alpha or Fisher–Rao metric", EXAMPLES["mean"])
    _file_options(p)
    _intrinsic_options(p)
    p.add_argument("-o", "--output", required=True, metavar="mean.tps", help="the mean shape (.tps, .csv, .npy)")
    p.add_argument("--plot", metavar="mean.png", help="the specimens, the Procrustes start and the mean")
    _backend_options(p)
    p.set_defaults(func=cmd_mean)
    p = add("pca", "principal modes of variation at the Fréchet mean (tangent PCA in the metric)", EXAMPLES["pca"])
    _file_options(p)
    _intrinsic_options(p)
    p.add_argument("--n-components", type=int, metavar="K", help="components kept (default all)")
    p.add_argument("-o", "--output", required=True, metavar="scores.csv", help="scores: one row per specimen")
    p.add_argument("--plot", metavar="modes.png", help="shapes at -2, 0, +2 SD along the first three modes")
    p.add_argument("--scores-plot", metavar="scores.png", help="PC1 against PC2, coloured by --by with convex hulls")
    p.add_argument("--covariates", metavar="C.csv", help="CSV file with the specimens' groups (an id column first)")
    p.add_argument("--by", metavar="COLUMN", help="the column of --covariates that colours --scores-plot")
    p.set_defaults(func=cmd_pca)
