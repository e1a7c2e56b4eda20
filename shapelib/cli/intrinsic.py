"""``shapelib mean`` and ``shapelib pca``: the Fréchet mean and tangent PCA in an information metric
(:mod:`shapelib.population`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import CLIError, _auto_sigma2, _file_options, _output_path, _read, _write_frame

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
        from ..geometry.scale import to_centroid_size

        shapes = to_centroid_size(shapes, args.size)
    options = {"tol": args.tol, "n_steps": args.n_steps, "n_jobs": args.jobs, "scheduler": args.scheduler}
    return shapes, spec, options


def cmd_mean(args) -> int:
    import pandas as pd

    from .. import io
    from ..population import frechet_mean

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

    from ..plotting import plot_mean

    fig = plot_mean(shapes, res, title=title)
    fig.savefig(path, dpi=120, metadata={"Software": None} if Path(path).suffix == ".png" else None)
    plt.close(fig)


def cmd_pca(args) -> int:
    import pandas as pd

    from ..population import tangent_pca

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

        from ..plotting import plot_modes

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


def register(add) -> None:
    """Add ``mean`` and ``pca`` to the parser (``add(name, help, epilog)`` returns the subparser)."""
    p = add("mean", "the Fréchet mean shape under the alpha or Fisher–Rao metric", EXAMPLES["mean"])
    _file_options(p)
    _intrinsic_options(p)
    p.add_argument("-o", "--output", required=True, metavar="mean.tps", help="the mean shape (.tps, .csv, .npy)")
    p.add_argument("--plot", metavar="mean.png", help="the specimens, the Procrustes start and the mean")
    p.set_defaults(func=cmd_mean)
    p = add("pca", "principal modes of variation at the Fréchet mean (tangent PCA in the metric)", EXAMPLES["pca"])
    _file_options(p)
    _intrinsic_options(p)
    p.add_argument("--n-components", type=int, metavar="K", help="components kept (default all)")
    p.add_argument("-o", "--output", required=True, metavar="scores.csv", help="scores: one row per specimen")
    p.add_argument("--plot", metavar="modes.png", help="shapes at -2, 0, +2 SD along the first three modes")
    p.set_defaults(func=cmd_pca)
