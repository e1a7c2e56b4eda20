#!/usr/bin/env python
"""Speed of the intrinsic statistics on ADHD-200 corpus callosum contours.

The 647 contours (50 landmarks), generalised-Procrustes aligned and scaled to centroid size 20
(:func:`shapelib.to_centroid_size`), σ² = 1.2 (σ = 2.6 landmark spacings, as in the study):

* the α Fréchet mean of all 647 shapes to its first-order certificate (``tol`` 1e-3), on 1 worker
  (this process) and on a ``LocalCluster`` of 2 single-threaded workers started beforehand (its
  start-up reported apart) — iterations, log maps, log maps per second, the 1 → 2 worker scaling;
* the Fisher–Rao Fréchet mean of the 180-shape subset balanced over diagnosis × sex (quadrature
  step 0.5σ, as the study), on the 2 workers;
* tangent PCA given the α mean (its log maps reused; three modes drawn at ±2 SD);
* geodesic regression of the 647 shapes on age (α), given the mean, on the 2 workers.

Targets (2-core machine): α mean ≤ 2 min, Fisher–Rao mean ≤ 15 min, tangent PCA ≤ 5 s,
regression ≤ 5 min. Not a test: the numbers depend on the machine and its load (recorded).

    python benchmarks/bench_intrinsic.py [--json out.json] [--record] [--quick] [--skip-serial]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._machine import loadavg, machine, record  # noqa: E402

import shapelib as sl  # noqa: E402
from shapelib.datasets import load_adhd200  # noqa: E402
from shapelib.statistics.frechet import frechet_mean  # noqa: E402

SIGMA2 = 1.2
TARGETS = {"alpha_mean_2": 120.0, "fisher_rao_mean_2": 900.0, "tangent_pca": 5.0, "regression_2": 300.0}


def balanced_subset(labels, n, seed=1):
    rng = np.random.default_rng(seed)
    diag = np.where(labels["phenotype"].to_numpy() == 0, "TD", "ADHD")
    sex = labels["gender"].astype(int).astype(str).to_numpy()
    idx = np.arange(len(labels))
    cells = [idx[(diag == d) & (sex == s)] for d in ("TD", "ADHD") for s in ("0", "1")]
    take = [n // 4 + (k < n % 4) for k in range(4)]
    return np.sort(np.concatenate([rng.choice(c, size=min(t, len(c)), replace=False) for c, t in zip(cells, take)]))


def mean_record(res, seconds, workers):
    return {"workers": workers, "seconds": seconds, "iterations": res.n_iter, "log_maps": res.n_log_maps,
            "log_maps_per_s": res.n_log_maps / seconds, "certificate": res.certificate, "converged": res.converged,
            "path_iterations": int(sum(h["path_iterations"] for h in res.log)), "n_shapes": len(res.logs)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", help="write the measurements here")
    ap.add_argument("--quick", action="store_true", help="a few shapes: a smoke test of the benchmark, not a measurement")
    ap.add_argument("--skip-serial", action="store_true", help="no 1-worker run of the α mean")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--record", action="store_true",
                    help="write the results, machine and date to docs/_data/benchmarks/bench_intrinsic.json (docs: Performance)")
    args = ap.parse_args(argv)
    if args.quick and args.record:
        ap.error("--record: a --quick run is a smoke test, not a measurement")
    n_all, n_sub = (12, 6) if args.quick else (647, 180)
    raw, labels = load_adhd200()
    pick = np.arange(len(raw)) if not args.quick else balanced_subset(labels, n_all, seed=0)
    x = sl.to_centroid_size(raw[pick])
    age = labels["age"].to_numpy()[pick]
    sub = sl.to_centroid_size(raw[balanced_subset(labels, n_sub)])
    report = {"machine": machine(), "loadavg_start": loadavg(), "sigma2": SIGMA2, "n_shapes": len(x),
              "n_subset": len(sub), "workers": args.workers, "quick": args.quick, "measurements": {}}
    out = report["measurements"]
    warnings.simplefilter("ignore", sl.ScaleWarning)
    # one-off costs (compiled kernels loaded from numba's cache) outside the timings
    frechet_mean(x[:3], sigma2=SIGMA2, max_iter=0, warn=False, n_jobs=1)
    frechet_mean(sub[:2], metric="fisher_rao", sigma2=SIGMA2, grid_spacing=0.5, max_iter=0, warn=False, n_jobs=1)

    if not args.skip_serial:
        t0 = time.perf_counter()
        res1 = frechet_mean(x, sigma2=SIGMA2, n_jobs=1)
        out["alpha_mean_1"] = mean_record(res1, time.perf_counter() - t0, 1)
        print(f"α mean, 1 worker: {out['alpha_mean_1']}", flush=True)

    from distributed import Client

    from shapelib.pairwise import local_cluster
    from shapelib.statistics.frechet import procrustes_mean

    t0 = time.perf_counter()
    with local_cluster(args.workers) as cluster, Client(cluster) as client:
        report["cluster_start_seconds"] = time.perf_counter() - t0
        # a first task on every worker loads shapelib and the compiled kernels there
        client.run(lambda: frechet_mean(np.stack([procrustes_mean(x[:3])] * 2 + [x[0]]), sigma2=SIGMA2, max_iter=0,
                                        warn=False, n_jobs=1) and None)
        t0 = time.perf_counter()
        res2 = sl.frechet_mean(x, sigma2=SIGMA2, client=client)
        out["alpha_mean_2"] = mean_record(res2, time.perf_counter() - t0, args.workers)
        print(f"α mean, {args.workers} workers: {out['alpha_mean_2']}", flush=True)
        if "alpha_mean_1" in out:
            eff = out["alpha_mean_1"]["seconds"] / (args.workers * out["alpha_mean_2"]["seconds"])
            out["alpha_mean_scaling_efficiency"] = eff
            print(f"  scaling 1 -> {args.workers} workers: efficiency {eff:.2f}", flush=True)

        t0 = time.perf_counter()
        pca = sl.tangent_pca(x, mean=res2, modes=(0, 1, 2), sd=(-2.0, 2.0), n_jobs=1)
        out["tangent_pca"] = {"seconds": time.perf_counter() - t0, "n_components": pca.n_components,
                              "ratio_1": float(pca.explained_variance_ratio[0])}
        print(f"tangent PCA given the mean: {out['tangent_pca']}", flush=True)

        t0 = time.perf_counter()
        reg = sl.geodesic_regression(x, age, sigma2=SIGMA2, mean=res2, client=client)
        sec = time.perf_counter() - t0
        n_logs = len(x) * (1 + sum(1 + h.get("backtracks", 0) for h in reg.log[:-1]))
        out["regression_2"] = {"workers": args.workers, "seconds": sec, "iterations": reg.n_iter,
                               "certificate": reg.certificate, "converged": reg.converged, "r2": reg.r2,
                               "log_maps": n_logs, "log_maps_per_s": n_logs / sec}
        print(f"geodesic regression, {args.workers} workers: {out['regression_2']}", flush=True)

        t0 = time.perf_counter()
        res_fr = sl.frechet_mean(sub, metric="fisher_rao", sigma2=SIGMA2, grid_spacing=0.5, client=client)
        out["fisher_rao_mean_2"] = mean_record(res_fr, time.perf_counter() - t0, args.workers)
        print(f"Fisher–Rao mean, {args.workers} workers: {out['fisher_rao_mean_2']}", flush=True)
    report["loadavg_end"] = loadavg()
    print("\n| measurement | seconds | target | iterations | log maps/s |\n|---|---|---|---|---|")
    for key, rec in out.items():
        if not isinstance(rec, dict):
            continue
        target = TARGETS.get(key)
        rate = rec.get("log_maps_per_s")
        print(f"| {key} | {rec['seconds']:.1f} | {'≤ %g' % target if target else ''} | {rec.get('iterations', '')} | "
              f"{'' if rate is None else f'{rate:.1f}'} |")
    print(f"machine: {report['machine']}; load average at the start {report['loadavg_start']}, at the end "
          f"{report['loadavg_end']}")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    if args.record:
        print(f"recorded {record('bench_intrinsic', report, argv=argv)}")
    return report


if __name__ == "__main__":
    main()
