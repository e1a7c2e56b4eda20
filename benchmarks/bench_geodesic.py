#!/usr/bin/env python
"""Speed of the geodesic solver and of the Fisher–Rao metric (issue: core, "Speed").

Times, on the corpus callosum pair (paper shapes 1 and 2; K = 63, σ² = 0.5, GPA-aligned at
centroid size 20, default n_steps), one α geodesic and one Fisher–Rao geodesic, and reports
seconds, iterations, energy, length, lower bound and whether they converged; the Fisher–Rao/α
time ratio (the paper claims close to an order of magnitude); and the speed of our
Fisher–Rao metric tensor against a straightforward evaluation on an N×N grid over a fixed
box, at equal accuracy. Not a test: numbers depend on the machine.

    python benchmarks/bench_geodesic.py [--sigma2 0.5] [--n-steps 16] [--tol 1e-9] [--json out.json]

The issue's targets (2-core machine): α < 1 s, Fisher–Rao < 10 s, both converged to a relative
energy change below 1e-9 (``--tol``, the default here).
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

from shapelib.datasets import load_corpus_callosum  # noqa: E402
from shapelib.geodesic import geodesic  # noqa: E402
from shapelib.metrics import fisher_rao_metric  # noqa: E402
from shapelib.study import paper_scale  # noqa: E402


def naive_fisher_rao(theta, s2, n, half_width):
    """Eq. (6) on an n×n grid over [-half_width, half_width]², densities in linear space."""
    ax = np.linspace(-half_width, half_width, n)
    h = ax[1] - ax[0]
    x = np.stack(np.meshgrid(ax, ax, indexing="ij"), -1).reshape(-1, 2)
    k = len(theta)
    r = x[:, None, :] - theta[None]
    nk = np.exp(-(r**2).sum(-1) / (2 * s2)) / (2 * np.pi * s2)
    p = nk.mean(1)
    dp = (nk[..., None] * r / (k * s2)).reshape(len(x), -1)
    keep = p > 1e-300
    return h * h * (dp[keep] / p[keep, None]).T @ dp[keep]


def timed(f, repeat=1):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t0)
    return out, best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma2", type=float, default=0.5)
    ap.add_argument("--n-steps", type=int, default=16)
    ap.add_argument("--tol", type=float, default=1e-9)
    ap.add_argument("--max-iter", type=int, default=1000)
    ap.add_argument("--metrics", nargs="+", default=["alpha", "fisher_rao"], choices=["alpha", "fisher_rao"])
    ap.add_argument("--json", type=Path)
    ap.add_argument("--skip-geodesics", action="store_true", help="only time the Fisher–Rao metric tensor")
    args = ap.parse_args(argv)
    shapes, ids = load_corpus_callosum()
    x = paper_scale(shapes)
    u, v = x[list(ids).index(1)], x[list(ids).index(2)]
    report = {"sigma2": args.sigma2, "n_steps": args.n_steps, "tol": args.tol, "K": len(u)}
    for metric in () if args.skip_geodesics else args.metrics:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r, sec = timed(lambda: geodesic(u, v, metric=metric, sigma2=args.sigma2, n_steps=args.n_steps,
                                            tol=args.tol, max_iter=args.max_iter))
        report[metric] = {"seconds": sec, "iterations": r.n_iter, "converged": r.converged, "energy": r.energy,
                          "length": r.length, "lower_bound": r.lower_bound,
                          "length_over_bound_minus_1": r.length / r.lower_bound - 1,
                          "stopped_by": r.log["stopped_by"], "newton_decrement": r.log["newton_decrement"]}
        print(f"{metric:>10}: {sec:8.2f} s  {r.n_iter:4d} it  converged={r.converged}  energy={r.energy:.8e}  "
              f"length={r.length:.8e}  bound={r.lower_bound:.8e}  (length/bound − 1 = {r.length / r.lower_bound - 1:.2e})"
              f"  stopped by {r.log['stopped_by']}")
    if {"alpha", "fisher_rao"} <= set(report):
        report["fisher_rao_over_alpha_time"] = report["fisher_rao"]["seconds"] / report["alpha"]["seconds"]
        print(f"Fisher–Rao / α time: {report['fisher_rao_over_alpha_time']:.1f}×")

    # Fisher–Rao metric tensor: ours vs a plain N×N grid, both against a very fine reference
    s2 = args.sigma2
    theta = u
    ref = fisher_rao_metric(theta, s2, spacing=0.1, margin=10)
    scale = np.abs(ref).max()
    ours, t_ours = timed(lambda: fisher_rao_metric(theta, s2), repeat=3)
    err_ours = np.abs(ours - ref).max() / scale
    half = np.abs(theta).max() + 8 * np.sqrt(s2)  # a square box with a generous margin
    rows = []
    for n in (50, 75, 100, 150, 200, 300, 400, 600):
        g, t = timed(lambda: naive_fisher_rao(theta, s2, n, half))
        rows.append((n, t, np.abs(g - ref).max() / scale))
    # the cheapest naive grid at least as accurate as ours (or the most accurate one tried)
    match = next(((n, t, e) for n, t, e in rows if e <= err_ours), min(rows, key=lambda r: r[2]))
    report["fisher_rao_metric"] = {"ours_seconds": t_ours, "ours_rel_error": err_ours,
                                   "naive": [{"N": n, "seconds": t, "rel_error": e} for n, t, e in rows],
                                   "naive_at_equal_accuracy": {"N": match[0], "seconds": match[1], "rel_error": match[2]},
                                   "speedup": match[1] / t_ours}
    print(f"FR metric, ours: {t_ours * 1e3:.1f} ms, rel. error {err_ours:.1e}")
    for n, t, e in rows:
        print(f"  naive {n}×{n} grid: {t * 1e3:8.1f} ms, rel. error {e:.1e}")
    reached = match[2] <= err_ours
    print(f"speed-up {'at equal accuracy' if reached else 'against the most accurate naive grid (less accurate than ours)'}"
          f" (naive N = {match[0]}): {match[1] / t_ours:.1f}×")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
