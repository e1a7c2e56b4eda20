#!/usr/bin/env python
"""MPEG-7 bull's-eye retrieval: where the time of a similarity-invariant distance matrix goes.

Outlines of MPEG-7 CE-Shape-1 silhouettes (``--points`` per outline, arc-length resampled,
:func:`shapelib.trace_outline`) of ``--classes`` classes (default 20, spread over the 70; ``--full``:
all 70, 1,400 shapes, 979,300 pairs) compared by the α and Fisher–Rao density distances modulo
the similarity group (:func:`shapelib.invariant_distance_matrix`) at ``--sigma2``. Reported, each
as wall and CPU seconds of this process (the CPU time is what the machine's load cannot inflate):

* tracing the outlines;
* the polar spectra (once per outline) and the angle search (per pair: one batched product per
  frequency, one inverse FFT, Newton on the trigonometric polynomial), in process;
* the closed-form α values at the poses found (``exact=True``; the default takes the quadrature's);
* the bull's-eye score of each matrix and of the Procrustes baseline on the outlines;
* the whole α matrix through the engine (``pairwise_distances(..., modulo="similarity")``) with
  ``--workers`` local worker processes;
* the projection to the full 1,400 × 1,400 matrix (linear spectra + quadratic pairs).

Not a test: numbers depend on the machine and its load (recorded).

    python benchmarks/bench_retrieval.py [--classes 20] [--full] [--sigma2 0.01] [--record]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._machine import loadavg, record  # noqa: E402

import shapelib as sl  # noqa: E402
from shapelib.datasets import load_mpeg7, mpeg7_classes  # noqa: E402
from shapelib.pointsets import invariant as inv  # noqa: E402

FULL_PAIRS = 1400 * 1399 // 2


class Clock:
    """Wall and CPU seconds of a block."""

    def __enter__(self):
        self.w, self.c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall, self.cpu = time.perf_counter() - self.w, time.process_time() - self.c


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--classes", type=int, default=20)
    ap.add_argument("--full", action="store_true", help="all 70 classes (1,400 shapes)")
    ap.add_argument("--points", type=int, default=100)
    ap.add_argument("--sigma2", type=float, default=0.01)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--record", action="store_true")
    args = ap.parse_args(argv)
    every = mpeg7_classes()
    classes = every if args.full else [every[i] for i in np.round(np.linspace(0, 69, args.classes)).astype(int)]
    res = {"loadavg_start": loadavg(), "classes": len(classes), "points": args.points, "sigma2": args.sigma2}
    with Clock() as c:
        data = load_mpeg7(classes=classes, n_points=args.points)
    outlines, labels = list(data.shapes), data.labels
    n = len(outlines)
    pairs = n * (n - 1) // 2
    res.update(n_shapes=n, pairs=pairs, trace={"wall": c.wall, "cpu": c.cpu})
    print(f"{n} outlines ({len(classes)} classes), {pairs:,} pairs; traced in {c.wall:.1f} s wall, {c.cpu:.1f} s CPU")
    xs = [inv.normalise_points(o)[0] for o in outlines]
    for metric in ("alpha_bound", "fisher_rao_bound"):
        m = {}
        with Clock() as c:
            sp = inv.polar_spectra(xs, sigma2=args.sigma2, kind=inv.spectrum_kind(metric))
        m["spectra"] = {"wall": c.wall, "cpu": c.cpu, "rings": sp.coefficients.shape[1], "frequencies": sp.coefficients.shape[2]}
        with Clock() as c:
            D = inv.distances_from_spectra(xs, sp, metric=metric, exact=False)
        m["search"] = {"wall": c.wall, "cpu": c.cpu}
        if metric == "alpha_bound":
            with Clock() as c:
                D = inv.distances_from_spectra(xs, sp, metric=metric, exact=True)
            m["search_and_exact"] = {"wall": c.wall, "cpu": c.cpu}
        m["bullseye"] = sl.bullseye(D, labels).value
        if metric == "alpha_bound":
            d_alpha = D
        m["full_cpu_projection"] = m["spectra"]["cpu"] / n * 1400 + m["search"]["cpu"] / pairs * FULL_PAIRS
        res[metric] = m
        print(f"{metric}: spectra {m['spectra']['cpu']:.1f} s CPU ({m['spectra']['rings']} rings × "
              f"{m['spectra']['frequencies']} frequencies), search {m['search']['cpu']:.1f} s CPU "
              f"({1e6 * m['search']['cpu'] / pairs:.0f} µs/pair)"
              + (f", with closed-form values {m['search_and_exact']['cpu']:.1f} s" if "search_and_exact" in m else "")
              + f"; bull's-eye {100 * m['bullseye']:.2f} %; full matrix ≈ {m['full_cpu_projection'] / 60:.1f} min CPU")
    with Clock() as c:
        P = sl.procrustes_outline_matrix(np.stack(outlines))
    res["procrustes"] = {"wall": c.wall, "cpu": c.cpu, "bullseye": sl.bullseye(P, labels).value}
    print(f"procrustes: {c.cpu:.1f} s CPU, bull's-eye {100 * res['procrustes']['bullseye']:.2f} %")
    with Clock() as c:
        r = sl.pairwise_distances(outlines, metric="alpha_bound", modulo="similarity", sigma2=args.sigma2,
                                  n_jobs=args.workers, progress=False, return_result=True)
    res["engine"] = {"workers": args.workers, "wall": c.wall, "mode": r.log["mode"], "block_size": r.log["block_size"],
                     "blocks": r.log["blocks_total"], "spectra_seconds": r.log.get("spectra_seconds"),
                     "estimated_seconds": r.log.get("estimated_seconds"),
                     "max_abs_diff_vs_in_process": float(np.abs(r.matrix - d_alpha).max())}
    print(f"engine, {args.workers} workers ({r.log['mode']}): {c.wall:.1f} s wall, blocks of {r.log['block_size']}")
    res["loadavg_end"] = loadavg()
    print("load average", res["loadavg_start"], "->", res["loadavg_end"])
    if args.record:
        print("recorded", record("bench_retrieval", res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
