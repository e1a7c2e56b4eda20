#!/usr/bin/env python
"""Throughput of the pairwise engine on ADHD-200 shapes (issue 12, "Benchmark").

For each metric, a random subset of the 647 ADHD-200 corpus callosum contours (50 landmarks,
generalised-Procrustes aligned and scaled to centroid size 20 as in the study:
:func:`shapelib.to_centroid_size`) is run through :func:`shapelib.pairwise.compute_pairwise`
with 1 worker (in this process, as ``n_jobs=1`` does) and on a ``LocalCluster`` of 2 (or
``--workers``) single-threaded processes started once beforehand (its start-up is reported
separately, not charged to any metric); before timing a metric, one pair is computed in this process
and on every worker (numba compilation and other first-call costs are reported as ``warmup_seconds``,
not charged to the rate). Reported per metric and worker count: pairs, wall seconds,
pairs/s, and the scaling efficiency ``rate_w / (w · rate_1)``; then the projected wall-clock of the
full 647-shape matrices (208,981 pairs) of the α and Fisher–Rao geodesic distances on N workers,
from the mean measured seconds per pair and the measured 2-worker efficiency.

The geodesic metrics use the certified bracket (``--rtol``, :func:`shapelib.solver.bracket.distance_bracket`).

Then the closed-form bound matrices of the whole population as matrix products
(:mod:`shapelib.geometry.bound_matrices`), at ``--bound-sigma2`` (1.2, the population study's σ²):
the Fisher–Rao and α bound matrices of all 647 shapes, each directly and through
``pairwise_distances(..., n_jobs=1)`` (the engine's batched path, one block in this process); for
the α bound the time per Gaussian against a bare ``numpy.exp`` over as many numbers (the floor); the
per-pair functions on a sample of pairs, projected to all pairs (what the matrix cost before); and
a ``--sweep-points``-value σ² sweep of both bounds (σ from 0.2 to 10 mean landmark spacings,
:func:`shapelib.bound_matrix_sweep`), best of ``--repeat`` runs each.
Not a test: numbers depend on the machine and its load (the load average, ``os.getloadavg``, is recorded).

    python benchmarks/bench_pairwise.py [--sigma2 0.5] [--workers 1 2] [--json out.json] [--quick]
    python benchmarks/bench_pairwise.py --metrics --bound-sigma2 1.2      # the bound matrices only
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._machine import loadavg, record  # noqa: E402

from shapelib import bound_matrix_sweep, landmark_spacing, pairwise_distances  # noqa: E402
from shapelib.datasets import load_adhd200  # noqa: E402
from shapelib.geometry.bound_matrices import alpha_bound_matrix, fisher_rao_bound_matrix  # noqa: E402
from shapelib.distances import pair_record  # noqa: E402
from shapelib.pairwise import compute_pairwise  # noqa: E402
from shapelib import to_centroid_size  # noqa: E402

#: shapes per metric (full run): 10-60 s of work each on one core, so task and store overheads show
#: at their real share; the cheap metrics and the α bound use the whole population
SIZES = {"procrustes": 647, "tps": 300, "hausdorff": 647, "alpha_bound": 647, "fisher_rao_bound": 200,
         "alpha": 40, "fisher_rao": 20}
QUICK_SIZES = {"procrustes": 8, "tps": 6, "hausdorff": 8, "alpha_bound": 8, "fisher_rao_bound": 4,
               "alpha": 3, "fisher_rao": 2}
FULL_N = 647
PROJECT_WORKERS = (1, 2, 8, 32, 128)


def metric_params(metric: str, args) -> dict:
    if metric in ("alpha", "fisher_rao"):
        kw = {"sigma2": args.sigma2, "rtol": args.rtol}
        if args.quick:  # a smoke test of the machinery, not a distance anyone should use
            kw.update({"n_steps": 4, "max_n_steps": 4, "level_iter": 2, "rtol": 0.5})
        return kw
    if metric in ("alpha_bound", "fisher_rao_bound"):
        return {"sigma2": args.sigma2}
    return {}


def warm_up(x, metric, params, clients) -> float:
    """One pair in this process and on every worker before timing: the first call of a process pays
    one-off costs (numba compiles the α kernels, imports) that a long run amortises."""
    t0 = time.perf_counter()
    _quiet_pair(x[0], x[1], metric=metric, **params)
    for client in clients:
        client.run(_quiet_pair, x[0], x[1], metric=metric, **params)
    return time.perf_counter() - t0


def _quiet_pair(u, v, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pair_record(u, v, **kw)


def run(x, metric, params, *, workers, client):
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # non-converged pairs are counted below instead
        if workers == 1:
            r = compute_pairwise(x, metric=metric, n_jobs=1, progress=False, **params)
        else:
            r = compute_pairwise(x, metric=metric, client=client, progress=False, **params)
    wall = time.perf_counter() - t0
    frame = r.to_frame()
    return {"pairs": len(frame), "wall_seconds": wall, "pairs_per_second": len(frame) / wall,
            "mean_seconds_per_pair": float(frame.seconds.mean()), "block_size": r.log["block_size"],
            "blocks": r.log["blocks_total"], "nonconverged": len(r.nonconverged_pairs())}


def _best_of(fn, repeat):
    """Fastest wall time of ``repeat`` calls and the last result."""
    times, out = [], None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), times, out


def bound_rows(x, *, sigma2, sweep_points, repeat, sample_pairs, seed):
    """The bound-matrix rows of the report (module docstring)."""
    n, k, d = x.shape
    out = {"n_shapes": n, "sigma2": sigma2}
    # warm (thread pool, grids, imports) on a few shapes
    alpha_bound_matrix(x[:8], sigma2=sigma2)
    fisher_rao_bound_matrix(x[:8], sigma2=sigma2)
    for name, fn in (("fisher_rao_bound", fisher_rao_bound_matrix), ("alpha_bound", alpha_bound_matrix)):
        best, runs, mat = _best_of(lambda: fn(x, sigma2=sigma2), repeat)
        eng, eng_runs, res = _best_of(lambda: pairwise_distances(x, metric=name, sigma2=sigma2, n_jobs=1, progress=False,
                                                                return_result=True), repeat)
        rng = np.random.default_rng(seed)
        pairs = [tuple(rng.choice(n, 2, replace=False)) for _ in range(sample_pairs)]
        t0 = time.perf_counter()
        per_pair = [pair_record(x[i], x[j], metric=name, sigma2=sigma2)["value"] for i, j in pairs]
        per_pair_s = (time.perf_counter() - t0) / len(pairs)
        agree = max(abs(mat[i, j] / v - 1) for (i, j), v in zip(pairs, per_pair))
        out[name] = {"matrix_seconds": best, "matrix_runs": runs, "engine_seconds": eng, "engine_runs": eng_runs,
                     "engine_blocks": res.log["blocks_total"], "per_pair_seconds": per_pair_s,
                     "per_pair_projected_seconds": per_pair_s * n * (n - 1) / 2,
                     "max_rel_diff_per_pair": agree}
    gaussians = n * (n - 1) // 2 * k * k  # one cross Gaussian per landmark pair of every pair of shapes
    arg = -np.random.default_rng(seed).random(gaussians) * 30.0
    floor, _, _ = _best_of(lambda: np.exp(arg, out=arg), repeat)
    del arg
    a = out["alpha_bound"]
    out["alpha_bound"].update({"gaussians": gaussians, "ns_per_gaussian": a["matrix_seconds"] / gaussians * 1e9,
                               "bare_exp_seconds": floor, "bare_exp_ns": floor / gaussians * 1e9,
                               "times_bare_exp": a["matrix_seconds"] / floor})
    spacing = landmark_spacing(x)
    s2s = (np.geomspace(0.2, 10.0, sweep_points) * spacing) ** 2
    sweep = {"sigma2": s2s.tolist(), "sigma_over_spacing": [0.2, 10.0]}
    for name in ("alpha_bound", "fisher_rao_bound"):
        best, runs, _ = _best_of(lambda: bound_matrix_sweep(x, metric=name, sigma2s=s2s), repeat)
        sweep[name] = {"seconds": best, "runs": runs}
    sweep["both_seconds"] = sweep["alpha_bound"]["seconds"] + sweep["fisher_rao_bound"]["seconds"]
    out["sweep"] = sweep
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma2", type=float, default=0.5)
    ap.add_argument("--rtol", type=float, default=1e-3)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--metrics", nargs="*", default=list(SIZES), choices=list(SIZES))
    ap.add_argument("--bound-sigma2", type=float, default=1.2, help="sigma2 of the bound-matrix rows")
    ap.add_argument("--sweep-points", type=int, default=20, help="sigma2 values of the sweep row")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each bound-matrix row (the fastest counts)")
    ap.add_argument("--no-bounds", action="store_true", help="skip the bound-matrix rows")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="tiny subsets, n_steps=4 (smoke test)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--record", action="store_true",
                    help="write the results, machine and date to docs/_data/benchmarks/bench_pairwise.json (docs: Performance)")
    args = ap.parse_args(argv)
    if args.quick and args.record:
        ap.error("--record: a --quick run is a smoke test, not a measurement")
    sizes = QUICK_SIZES if args.quick else SIZES
    contours, _ = load_adhd200()
    x_all = to_centroid_size(contours)
    order = np.random.default_rng(args.seed).permutation(len(x_all))
    report = {"machine_cores": os.cpu_count(), "loadavg_start": loadavg(), "sigma2": args.sigma2,
              "date": time.strftime("%Y-%m-%d %H:%M %Z"), "machine": platform.platform(),
              "geodesics": f"bracket rtol={args.rtol}",
              "quick": args.quick, "metrics": {}}
    print(f"ADHD-200, centroid size 20, sigma2={args.sigma2}; geodesics: {report['geodesics']}; "
          f"load {report['loadavg_start']}")
    clusters = {}
    try:
        from distributed import Client

        from shapelib.pairwise import local_cluster  # the cluster n_jobs=w starts, malloc settings included

        for w in args.workers:
            if w > 1 and args.metrics:
                t0 = time.perf_counter()
                cluster = local_cluster(w)
                client = Client(cluster)
                client.run(lambda: __import__("shapelib.pairwise"))  # workers import shapelib once, up front
                clusters[w] = (cluster, client)
                report[f"cluster_startup_seconds_{w}"] = time.perf_counter() - t0
                print(f"LocalCluster({w}) started in {report[f'cluster_startup_seconds_{w}']:.1f} s")
        for metric in args.metrics:
            x = x_all[order[: sizes[metric]]]
            params = metric_params(metric, args)
            out = {"n_shapes": len(x), "params": params,
                   "warmup_seconds": warm_up(x, metric, params, [c for _, c in clusters.values()])}
            for w in args.workers:
                out[w] = run(x, metric, params, workers=w, client=clusters.get(w, (None, None))[1])
            base = out[args.workers[0]]["pairs_per_second"] / args.workers[0]
            for w in args.workers:
                out[w]["efficiency"] = out[w]["pairs_per_second"] / (w * base)
            report["metrics"][metric] = out
            print(f"{metric:>17} ({len(x):3d} shapes, warm-up {out['warmup_seconds']:.1f} s): " + "  ".join(
                f"{w} worker(s): {out[w]['pairs']} pairs {out[w]['wall_seconds']:7.2f} s "
                f"{out[w]['pairs_per_second']:9.2f} pairs/s eff {out[w]['efficiency']:.2f}" for w in args.workers))
    finally:
        for cluster, client in clusters.values():
            client.close()
            cluster.close()
    full_pairs = FULL_N * (FULL_N - 1) // 2
    report["projection"] = {}
    for metric in ("alpha", "fisher_rao"):
        if metric not in report["metrics"]:
            continue
        out = report["metrics"][metric]
        per_pair = out[args.workers[0]]["mean_seconds_per_pair"]
        eff = min(1.0, out[max(args.workers)]["efficiency"]) if len(args.workers) > 1 else 1.0
        proj = {n: full_pairs * per_pair / (n * (eff if n > 1 else 1.0)) / 3600 for n in PROJECT_WORKERS}
        report["projection"][metric] = {"seconds_per_pair": per_pair, "efficiency_used": eff, "hours": proj}
        print(f"full {FULL_N}-shape {metric} matrix ({full_pairs} pairs, {per_pair:.2f} s/pair, efficiency "
              f"{eff:.2f}): " + ", ".join(f"{n} workers {h:.1f} h" for n, h in proj.items()))
    if not args.no_bounds:
        xb = x_all[order[:40]] if args.quick else x_all
        b = report["bound_matrices"] = bound_rows(xb, sigma2=args.bound_sigma2, sweep_points=3 if args.quick else
                                                  args.sweep_points, repeat=1 if args.quick else args.repeat,
                                                  sample_pairs=10 if args.quick else 200, seed=args.seed)
        print(f"bound matrices of {b['n_shapes']} shapes, sigma2 = {b['sigma2']:g} (fastest of the runs; load "
              f"{loadavg()}):")
        for name in ("fisher_rao_bound", "alpha_bound"):
            r = b[name]
            print(f"  {name:>16}: matrix {r['matrix_seconds']:.2f} s, through pairwise_distances(n_jobs=1) "
                  f"{r['engine_seconds']:.2f} s ({r['engine_blocks']} block); pair by pair {r['per_pair_seconds'] * 1e3:.2f} "
                  f"ms/pair = {r['per_pair_projected_seconds']:.0f} s projected; max rel. difference to the per-pair "
                  f"function {r['max_rel_diff_per_pair']:.1e}")
        a = b["alpha_bound"]
        print(f"  alpha_bound per Gaussian: {a['ns_per_gaussian']:.2f} ns ({a['gaussians']:,} Gaussians) against a bare "
              f"numpy.exp of as many numbers {a['bare_exp_ns']:.2f} ns: {a['times_bare_exp']:.1f}x the floor")
        sw = b["sweep"]
        print(f"  {len(sw['sigma2'])}-value sigma2 sweep (sigma 0.2-10 spacings): alpha {sw['alpha_bound']['seconds']:.1f} s, "
              f"Fisher-Rao {sw['fisher_rao_bound']['seconds']:.1f} s, both {sw['both_seconds']:.1f} s")
    report["loadavg_end"] = loadavg()
    print(f"load at the end {report['loadavg_end']}")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1, default=str))
    if args.record:
        print(f"recorded {record('bench_pairwise', report, argv=argv)}")
    return report


if __name__ == "__main__":
    main()
