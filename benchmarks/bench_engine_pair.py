#!/usr/bin/env python
"""What the pairwise engine adds to one cheap pair: a 50-landmark Procrustes pair, bare and through
the engine.

Three numbers, each the best of 7 repeats of CPU seconds (``time.process_time``, so that other
processes on a shared machine count less than in wall time) per pair:

* ``bare``: :func:`shapelib.procrustes_distance` of two (50, 2) arrays;
* ``pair_record``: :func:`shapelib.distances.pair_record` (the one-pair door: options and shapes
  checked, then the record's unchecked core);
* ``engine``: one 40 × 40 diagonal block of :func:`shapelib.pairwise.compute_block` (780 pairs,
  what a task computes), per pair.

Usage::

    python benchmarks/bench_engine_pair.py
"""

from __future__ import annotations

import platform
import time

import numpy as np


def per_call(f, n, reps=7) -> float:
    best = np.inf
    for _ in range(reps):
        t0 = time.process_time()
        for _ in range(n):
            f()
        best = min(best, (time.process_time() - t0) / n)
    return best


def main() -> dict:
    from shapelib import procrustes_distance
    from shapelib.distances import pair_record
    from shapelib.pairwise import compute_block

    x = np.random.default_rng(0).normal(size=(40, 50, 2))
    u, v = x[0], x[1]
    out = {
        "bare_us": 1e6 * per_call(lambda: procrustes_distance(u, v), 3000),
        "pair_record_us": 1e6 * per_call(lambda: pair_record(u, v, metric="procrustes"), 3000),
        "engine_us": 1e6 * per_call(lambda: compute_block(x, x, diagonal=True, symmetric=True, metric="procrustes",
                                                          rtol=None, params={}), 5) / (40 * 39 / 2),
    }
    print(f"50-landmark Procrustes pair, CPU µs per pair: bare {out['bare_us']:.1f}, pair_record "
          f"{out['pair_record_us']:.1f}, engine {out['engine_us']:.1f} ({platform.machine()}, Python "
          f"{platform.python_version()}, NumPy {np.__version__})")
    return out


if __name__ == "__main__":
    main()
