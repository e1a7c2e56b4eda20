"""Certified distance brackets on the corpus callosum pairs of Table I (issue 13).

Measures, in one process, pairs per second for ``distance_bracket(rtol=1e-3)``:

* α at σ² = 0.5 (target ≥ 100 pairs/s per process),
* Fisher–Rao at σ² = 0.5 (target ≥ 5 pairs/s per process),
* α at σ² = 0.1, where the geodesic is longer than the L² chord and most pairs stop "stalled",

with the distribution of the certified gaps, the iterations and the final n_steps, and the
machine load (``os.getloadavg``) before and after: the machine may be shared, so numbers taken
under load are provisional.

    python benchmarks/bench_bracket.py [--quick] [--json out.json] [--repeat 3]
"""

from __future__ import annotations

import argparse
import itertools
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

from shapelib.solver.bracket import distance_bracket  # noqa: E402
from shapelib.datasets import load_corpus_callosum  # noqa: E402
from shapelib import to_centroid_size  # noqa: E402

#: (name, metric, σ², target pairs/s or None)
CASES = [
    ("alpha_s2_0.5", "alpha", 0.5, 100.0),
    ("fisher_rao_s2_0.5", "fisher_rao", 0.5, 5.0),
    ("alpha_s2_0.1", "alpha", 0.1, None),
]


def run_case(shapes, pairs, metric, sigma2, *, rtol, repeat):
    """Best-of-``repeat`` wall time over all pairs (after one warm-up pair), and the brackets of the last round."""
    with warnings.catch_warnings():  # warm-up: compiled kernels load on first use
        warnings.simplefilter("ignore")
        distance_bracket(shapes[pairs[0][0]], shapes[pairs[0][1]], metric=metric, sigma2=sigma2, rtol=rtol)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # stalled pairs are counted below
            out = [distance_bracket(shapes[i], shapes[j], metric=metric, sigma2=sigma2, rtol=rtol) for i, j in pairs]
        best = min(best, time.perf_counter() - t0)
    gaps = np.array([b.rel_gap for b in out])
    return {
        "pairs": len(pairs),
        "seconds": best,
        "pairs_per_second": len(pairs) / best,
        "converged": int(sum(b.converged for b in out)),
        "stopped_by": {k: int(sum(b.stopped_by == k for b in out)) for k in sorted({b.stopped_by for b in out})},
        "gap_median": float(np.median(gaps)),
        "gap_p90": float(np.quantile(gaps, 0.9)),
        "gap_max": float(gaps.max()),
        "n_iter_median": float(np.median([b.n_iter for b in out])),
        "n_iter_max": int(max(b.n_iter for b in out)),
        "n_steps": {str(n): int(sum(b.n_steps == n for b in out)) for n in sorted({b.n_steps for b in out})},
        "lower_le_upper": bool(all(b.lower <= b.upper for b in out)),
        "brackets": [{"lower": b.lower, "upper": b.upper, "rel_gap": b.rel_gap, "converged": b.converged,
                      "stopped_by": b.stopped_by, "n_iter": b.n_iter, "n_steps": b.n_steps} for b in out],
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="2 pairs, one round (smoke test)")
    ap.add_argument("--rtol", type=float, default=1e-3)
    ap.add_argument("--repeat", type=int, default=3, help="rounds per case; the best is reported")
    ap.add_argument("--fisher-rao-pairs", type=int, default=21, help="pairs for the (slow) Fisher-Rao case")
    ap.add_argument("--json", type=Path, help="write the report here")
    ap.add_argument("--record", action="store_true",
                    help="write the results, machine and date to docs/_data/benchmarks/bench_bracket.json (docs: Performance)")
    args = ap.parse_args(argv)
    if args.quick and args.record:
        ap.error("--record: a --quick run is a smoke test, not a measurement")

    shapes, _ = load_corpus_callosum()
    x = to_centroid_size(shapes)
    pairs = list(itertools.combinations(range(len(x)), 2))
    if args.quick:
        pairs, args.repeat, args.fisher_rao_pairs = pairs[:2], 1, 1
    report = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()},
              "rtol": args.rtol, "repeat": args.repeat, "loadavg_before": loadavg(), "cases": {}}
    for name, metric, s2, target in CASES:
        case_pairs = pairs[: args.fisher_rao_pairs] if metric == "fisher_rao" else pairs
        res = run_case(x, case_pairs, metric, s2, rtol=args.rtol, repeat=args.repeat)
        res["target_pairs_per_second"] = target
        res["loadavg_after"] = loadavg()
        report["cases"][name] = res
        print(f"{name:20s} {res['pairs_per_second']:8.2f} pairs/s (target {target or '-'}) | "
              f"{res['converged']}/{res['pairs']} <= {args.rtol:g}, stopped {res['stopped_by']} | "
              f"gap median {res['gap_median']:.2e} p90 {res['gap_p90']:.2e} max {res['gap_max']:.2e} | "
              f"iterations median {res['n_iter_median']:.0f} max {res['n_iter_max']} | n_steps {res['n_steps']} | "
              f"load {res['loadavg_after']}", flush=True)
    report["loadavg_after"] = loadavg()
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    if args.record:
        print(f"recorded {record('bench_bracket', report, argv=argv)}")
    return report


if __name__ == "__main__":
    main()
