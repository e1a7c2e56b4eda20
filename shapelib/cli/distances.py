"""``shapelib distances`` and ``shapelib geodesic``: the distance matrix of a file's specimens, and
the geodesic between two of them."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from ._common import (EXIT_STOPPED, EXIT_UNCONVERGED, PROG, CLIError, _align_pose, _auto_sigma2, _check_jobs,
                      _file_options, _index_of, _metric_options, _metric_params, _notes_from, _output_path,
                      _parse_params, _read, _where_options, _write_frame)

EXAMPLES = {
    "distances": ("examples:\n  shapelib distances aligned.tps --metric procrustes -o procrustes.csv\n"
                  "  shapelib distances aligned.tps --metric alpha --sigma2 0.5 \\\n"
                  "      --jobs 2 --store alpha.zarr -o alpha.csv        (rerun the same command to resume)\n"
                  "  shapelib distances aligned.tps --metric fisher_rao --sigma2 0.5 --rtol 1e-3 \\\n"
                  "      --scheduler tcp://127.0.0.1:8786 -o fr.csv\n"
                  "  shapelib distances outlines.csv --metric registration --param shortlist=10 \\\n"
                  "      --store reg.zarr -o registration.csv      (point sets; only each one's 10 rigid nearest)"),
    "geodesic": ("example:\n  shapelib geodesic aligned.tps --from fish-1 --to Heart-1 \\\n"
                 "      --metric fisher_rao --sigma2 0.5 -o path.csv --plot path.png --links contour --animate path.gif"),
}


def _point_set_distances(args) -> int:
    """``shapelib distances FILE --modulo similarity``: point sets of any sizes, no landmarks, compared
    by their mixture densities modulo translation, scale, rotation and reflection."""
    import pandas as pd

    from ..pairwise import pairwise_distances
    from ..io import read_point_sets

    out = _output_path(args.output, suffixes=(".csv",), option="-o")
    registration = args.metric == "registration"  # invariant to a similarity by construction: no --modulo needed
    if not registration and args.metric not in ("alpha_bound", "fisher_rao_bound"):
        raise CLIError(f"--modulo {args.modulo}: point sets are compared by --metric alpha_bound or fisher_rao_bound "
                       f"(the density distances; --metric registration needs no --modulo); got {args.metric}")
    if registration and args.sigma2 is not None:
        raise CLIError("--metric registration estimates σ² itself (the misfit it reports); drop --sigma2 "
                       "(the rigid shortlist's σ²: --param shortlist_sigma2=0.01)")
    if not registration and (args.sigma2 is None or args.sigma2 == "auto"):
        raise CLIError(f"--modulo {args.modulo}: give --sigma2 as a number, in units of each set's RMS radius "
                       "squared (e.g. 0.01)")
    for flag, value in (("--rtol", args.rtol), ("--pairs", args.pairs), ("--max-blocks", args.max_blocks)):
        if value is not None:
            raise CLIError(f"{flag} does not apply to point sets compared with --modulo or --metric registration")
    try:
        sets, ids = read_point_sets(args.file)
    except ValueError as exc:  # InputError: names the file and the set or point
        raise CLIError(str(exc)) from None
    if len(set(ids)) != len(ids):
        raise CLIError(f"{args.file}: a point-set id occurs more than once; the matrix needs unique ids")
    params = _parse_params(args.param)
    try:
        kw = {} if registration else {"modulo": args.modulo, "sigma2": float(args.sigma2)}
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = pairwise_distances(sets, metric=args.metric, n_jobs=args.jobs, scheduler=args.scheduler,
                                        store=args.store, block_size=args.block_size, progress=not args.no_progress,
                                        return_result=True, **kw, **params)
    except ValueError as exc:
        raise CLIError(f"{args.file}: {exc}") from None
    for w in caught:  # the engine's own words (e.g. EMs that stopped at max_iter), once each
        print(f"{PROG}: warning: {w.message}", file=sys.stderr)
    d = result.matrix
    _write_frame(pd.DataFrame(d, index=pd.Index(ids, name="id"), columns=ids), out,
                 float_format=lambda v: repr(float(v)))
    what = f"{args.metric} modulo {args.modulo}" if not registration else args.metric
    print(f"{what}: {len(ids)} x {len(ids)} distance matrix of point sets -> {out}"
          + (f" (store {args.store})" if args.store else ""))
    if registration and result.log.get("shortlist"):
        print(f"{PROG}: note: {result.summary().split('; ', 1)[1]}", file=sys.stderr)
    return 0


def cmd_distances(args) -> int:
    import pandas as pd

    if args.modulo is not None or args.metric == "registration":
        return _point_set_distances(args)

    from ..pairwise import pairwise_distances
    from ..pairwise import PairError
    from ..solver.geodesic import GeodesicWarning

    out = _output_path(args.output, suffixes=(".csv",), option="-o")
    diag = _output_path(args.pairs, suffixes=(".csv",), option="--pairs") if args.pairs else None
    if diag is not None and diag.resolve() == out.resolve():
        raise CLIError(f"--pairs {args.pairs}: the same file as -o; give the pair table its own name")
    params = _metric_params(args)
    _check_jobs(args)
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
    rechecked = _recheck(shapes, bad, args.metric, params, result.matrix) if args.rtol is None else []
    bad = [p for p in bad if p not in set(rechecked)]
    if diag is not None:
        pairs = result.to_frame()
        if rechecked:
            again = pairs.set_index(["i", "j"]).index.isin(rechecked)
            pairs.loc[again, "converged"] = True
            pairs.loc[again, "status"] = RECHECKED
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
    if rechecked:
        gap = result.rel_gap(*np.array(rechecked).T)
        listed = ", ".join(f"{ids[i]}–{ids[j]}" for i, j in rechecked[:5]) + (", …" if len(rechecked) > 5 else "")
        print(f"{PROG}: note: {len(rechecked)} of {len(result.status())} pairs ({listed}) stopped at or near the "
              f"straight path and were marked unconverged; solved again from a perturbed path, each converged back to "
              f"the same length (within {RECHECK_RTOL:g}): {RECHECKED}. Their certified brackets are wide (upper/lower "
              f"- 1 median {100 * float(np.median(gap)):.3g} %) because the closed-form lower bound, the L2 distance "
              f"of the two mixtures, saturates once landmarks move by more than sigma, while the geodesic length "
              f"keeps growing" + ("" if diag else " (--pairs FILE.csv writes every pair's bracket and status)"),
              file=sys.stderr)
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
            unchecked = (f"; {len(bad) + len(rechecked) - RECHECK_MAX} of them not solved again (more than "
                         f"{RECHECK_MAX})" if len(bad) + len(rechecked) > RECHECK_MAX else "")
            print(f"{PROG}: warning: {len(bad)} of {total} pairs: solver failed (the geodesic solver stopped before "
                  f"its tolerance{unchecked}; their values are lengths of unconverged paths, upper bounds only): "
                  f"{listed}{more}; "
                  f"exit status {EXIT_UNCONVERGED}", file=sys.stderr)
            return EXIT_UNCONVERGED
    return 0


#: a pair's status (``--pairs``) when the solver marked it unconverged but a second solve from a
#: perturbed path converged to the same length: a geodesic, found twice
RECHECKED = "converged (found again from a perturbed start)"
#: relative agreement of the two lengths for :data:`RECHECKED`
RECHECK_RTOL = 1e-4
#: pairs checked again at most (each costs a geodesic solve)
RECHECK_MAX = 200


def _recheck(shapes, pairs, metric, params, values) -> list:
    """The unconverged pairs whose geodesic, solved again from the straight path plus a random
    perturbation of half a σ, converges to the same length (within :data:`RECHECK_RTOL`).

    At σ well below the landmark spacing the Gaussians of different landmarks barely interact,
    the straight path is a geodesic to within their overlap, and the solver may stop at its first
    iterate and mark the pair unconverged (its energy gradient is tiny); a second solve from
    elsewhere that comes back to the same length shows the path is a local minimum of the energy.
    """
    from ..distances import PATH_METRICS, path_result
    from ..geometry.scale import ScaleWarning
    from ..solver.geodesic import GeodesicWarning

    if metric not in PATH_METRICS or "sigma2" not in params or not pairs:
        return []
    rng = np.random.default_rng(0)
    n_steps = int(params.get("n_steps", 16))
    t = np.linspace(0.0, 1.0, n_steps + 1)[:, None, None]
    found = []
    for i, j in pairs[:RECHECK_MAX]:
        u, v = shapes[i], shapes[j]
        init = u + t * (v - u)
        init[1:-1] += rng.normal(scale=0.5 * np.sqrt(params["sigma2"]), size=init[1:-1].shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", GeodesicWarning)
            warnings.simplefilter("ignore", ScaleWarning)  # said once for the whole file
            try:
                again = path_result(u, v, metric=metric, **{**params, "init": init})
            except (TypeError, ValueError):  # a metric without init
                return found
        if again.converged and abs(again.length - values[i, j]) <= RECHECK_RTOL * values[i, j]:
            found.append((i, j))
    return found


def cmd_geodesic(args) -> int:
    import pandas as pd

    from ..distances import PATH_METRICS, path_result

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
    if anim and shapes.shape[2] != 2:
        raise CLIError("--animate draws 2-D landmarks; this file is 3-D (--plot draws it in 3-D)")
    links = []
    if args.links is not None:
        if not (plot or anim):
            raise CLIError("--links applies to --plot and --animate")
        from ..plotting import parse_links

        try:
            links = parse_links(args.links, shapes.shape[1])
        except ValueError as exc:
            raise CLIError(f"--{exc}") from None
    i, j = _index_of(spec, args.source, "--from"), _index_of(spec, args.target, "--to")
    shapes = _align_pose(args, shapes, params)  # the whole file, as `shapelib distances` aligns it
    from ..solver.geodesic import GeodesicWarning

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
    if not result.converged and _recheck(np.stack([shapes[i], shapes[j]]), [(0, 1)], args.metric, params,
                                         np.array([[0.0, result.length], [result.length, 0.0]])):
        print(f"{PROG}: note: the solver stopped at or near the straight path and marked it unconverged; solved again "
              f"from a perturbed path it converged back to the same length (within {RECHECK_RTOL:g}): a geodesic. "
              f"Its bracket [{result.lower_bound:.6g}, {result.length:.6g}] is wide because the closed-form lower bound "
              "saturates once landmarks move by more than sigma", file=sys.stderr)
        return 0
    if not result.converged:
        stopped = result.log.get("stopped_by")
        why = result.log.get("reason") or f"stopped by {stopped} after {result.n_iter} iterations"
        todo = ("use a larger --sigma2 (`shapelib info` shows the landmark spacing)"
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

    from ..plotting import plot_geodesic

    fig = plot_geodesic(result, links=links, title=title)
    fig.savefig(path, dpi=120, metadata={"Software": None} if Path(path).suffix == ".png" else None)
    plt.close(fig)


def _animate_path(result, path, *, title, fps, links=()):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter, PillowWriter

    from ..plotting import animate_geodesic

    anim = animate_geodesic(result, title=title, links=list(links))
    writer = PillowWriter(fps=fps) if Path(path).suffix.lower() == ".gif" else FFMpegWriter(fps=fps)
    tmp = Path(path).with_name(f".{Path(path).stem}.tmp{Path(path).suffix}")
    try:
        anim.save(tmp, writer=writer)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
        plt.close(anim._fig)


def _described(names):
    """The metric registry's one-line descriptions, for the epilogs."""
    from ..distances import metric_info

    width = max(map(len, names))
    return "\n\nmetrics (--metric):\n" + "\n".join(f"  {n:<{width}}  {metric_info(n).description}" for n in names)


def register(add) -> None:
    """Add ``distances`` and ``geodesic`` to the parser (``add(name, help, epilog)`` returns the subparser)."""
    from ..distances import METRICS, PATH_METRICS

    p = add("distances", "the labelled distance matrix of every pair of specimens",
            EXAMPLES["distances"] + _described(list(METRICS)))
    _file_options(p)
    _metric_options(p, metrics=METRICS)
    p.add_argument("--rtol", type=float, metavar="R",
                   help="alpha/fisher_rao: certified bracket, stop when upper/lower - 1 <= R")
    p.add_argument("--modulo", choices=("similarity",),
                   help="FILE holds point sets of any sizes, without landmarks (read as by shapelib register): "
                        "alpha_bound or fisher_rao_bound minimised over translation, scale, rotation and "
                        "reflection; --sigma2 in units of each set's RMS radius squared")
    _where_options(p, unit="one pair")
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

    p = add("geodesic", "the geodesic between two specimens: intermediate shapes, figure, animation",
            EXAMPLES["geodesic"] + _described(list(PATH_METRICS)))
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
