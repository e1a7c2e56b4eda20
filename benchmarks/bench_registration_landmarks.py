"""Known correspondences on the Chui–Rangarajan benchmark: ``register``'s defaults with 0, 2 and 3 landmarks.

For each of the 56 levels and each sample, the template ``x1`` is registered onto the target ``y2a`` by
``shapelib.register(x1, y2a, landmarks=...)``, its other settings the defaults, with ``k`` known
correspondences: the ``k`` template points spread over its ground-truth part (farthest-point sampling of
the first ``len(y2)`` points, the same for every level) whose true position ``y2[i]`` is a point of the
target (exactly: noise levels move every target point, so they get none, and occlusion levels only those
that remain), each paired with that target point. ``k = 0`` is the plain registration. The error, the
failure line (0.05) and the ``reliable`` flag are those of ``benchmarks/bench_registration.py``; the
peers have no such input and are not run.

    python benchmarks/bench_registration_landmarks.py [--samples 1-10] [--counts 0,2,3] [--json out.json] [--record]

Run on all ten samples the summary reports samples 1–5, 6–10 and 1–10 (nothing here was tuned: the
landmarks only add information). ``--record`` writes
``docs/_data/benchmarks/bench_registration_landmarks.json`` (machine, date and command included).
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
from benchmarks._machine import loadavg, record  # noqa: E402
from benchmarks.bench_registration import FAILURE, parse_samples  # noqa: E402

from shapelib.datasets import TPS_RPM_LEVELS, load_tps_rpm_case  # noqa: E402


def landmarks_of(x, y, truth, k):
    """The ``k`` known correspondences of a case (rows ``(source, target)``), or None: the farthest-point
    sample of the template's first ``len(truth)`` points whose true position is a target point."""
    from shapelib.pointsets.registration import farthest_points

    if k == 0:
        return None
    src = farthest_points(x[:len(truth)], k)
    dist = np.linalg.norm(y[None, :, :] - truth[src][:, None, :], axis=2)
    near = np.argmin(dist, axis=1)
    exact = dist[np.arange(k), near] == 0.0
    return np.column_stack([src[exact], near[exact]]) if exact.any() else None


def run(samples, counts, levels=TPS_RPM_LEVELS) -> dict:
    """Every level × sample × count: ``{count: {level: cell}}`` with per-sample errors, landmarks given,
    reliability and times."""
    import shapelib as sl
    from threadpoolctl import threadpool_limits

    out = {str(k): {} for k in counts}
    with threadpool_limits(limits=1, user_api="blas"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rng = np.random.default_rng(0)
        small = rng.normal(size=(30, 2))
        sl.register(small, 1.1 * small, landmarks=[[0, 0]])  # compilation outside the timing
        for name in levels:
            for k in counts:
                cell = {"samples": [], "errors": [], "given": [], "reliable": [], "times": []}
                for sample in samples:
                    case = load_tps_rpm_case(name, sample=sample)
                    x, y, truth = case["x1"], case["y2a"], case["y2"]
                    lm = landmarks_of(x, y, truth, k)
                    t0 = time.perf_counter()
                    res = sl.register(x, y, landmarks=lm)
                    cell["times"].append(time.perf_counter() - t0)
                    cell["samples"].append(sample)
                    cell["errors"].append(float(np.mean(np.linalg.norm(res.points[:len(truth)] - truth, axis=1))))
                    cell["given"].append(0 if lm is None else len(lm))
                    cell["reliable"].append(bool(res.reliable))
                out[str(k)][name] = cell
            print(f"{name:20s} " + "  ".join(
                f"k={k}: {np.mean(out[str(k)][name]['errors']):.4f}/"
                f"{sum(e > FAILURE for e in out[str(k)][name]['errors'])}f" for k in counts), flush=True)
    return out


def summarise_range(runs: dict, samples: list[int]) -> dict:
    """Per count: registrations, those given every landmark asked for, failures, mean error, failures
    flagged, per family failures; over the samples in ``samples``."""
    out = {}
    for k, levels in runs.items():
        errs, given, rel, fam = [], [], [], {}
        for name, cell in levels.items():
            for s, e, g, r in zip(cell["samples"], cell["errors"], cell["given"], cell["reliable"]):
                if s in samples:
                    errs.append(e), given.append(g), rel.append(r)
                    if e > FAILURE:
                        f = name.split("_")[1]
                        fam[f] = fam.get(f, 0) + 1
        errs, rel = np.array(errs), np.array(rel)
        bad = errs > FAILURE
        out[k] = {"registrations": len(errs), "with_all_landmarks": int(sum(g == int(k) for g in given)),
                  "with_some_landmarks": int(sum(g > 0 for g in given)), "failures": int(bad.sum()),
                  "mean_error": float(errs.mean()), "failures_flagged": int((bad & ~rel).sum()),
                  "failures_by_family": fam}
    return out


def summarise(runs: dict, samples: list[int]) -> dict:
    tuned, rest = [s for s in samples if s <= 5], [s for s in samples if s > 5]
    ranges = [tuned, rest, samples] if tuned and rest else [samples]
    return {f"{min(r)}-{max(r)}": summarise_range(runs, r) for r in ranges}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default="1", help="N (samples 1 to N) or A-B, within 1 to 10 (default 1)")
    ap.add_argument("--counts", default="0,2,3", help="comma-separated numbers of landmarks (default 0,2,3)")
    ap.add_argument("--levels", default="", help="comma-separated substrings of the levels to run (default all)")
    ap.add_argument("--json", type=Path, help="write the report here")
    ap.add_argument("--record", action="store_true",
                    help="write docs/_data/benchmarks/bench_registration_landmarks.json (all levels only)")
    args = ap.parse_args(argv)
    try:
        samples = parse_samples(args.samples)
        counts = [int(c) for c in args.counts.split(",") if c]
    except ValueError as exc:
        ap.error(str(exc))
    if any(c < 0 for c in counts) or not counts:
        ap.error("--counts: non-negative integers")
    wanted = [w for w in args.levels.split(",") if w]
    if args.record and wanted:
        ap.error("--record: a partial run is not the benchmark")
    levels = [lv for lv in TPS_RPM_LEVELS if not wanted or any(w in lv for w in wanted)]
    report = {"samples": samples, "counts": counts, "failure_threshold": FAILURE,
              "landmarks": "the farthest-point sample of the template's ground-truth points whose true position is "
                           "a target point, paired with it", "loadavg_before": loadavg()}
    report["runs"] = run(samples, counts, levels)
    report["loadavg_after"] = loadavg()
    report["summary"] = summarise(report["runs"], samples)
    print(json.dumps(report["summary"], indent=1))
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")
    if args.record:
        print(f"recorded {record('bench_registration_landmarks', report, argv=argv)}")
    return report


if __name__ == "__main__":
    main()
