"""Point-set registration on the Chui–Rangarajan (TPS-RPM) benchmark: shapelib beside Coherent Point Drift.

For each of the 56 levels (fish and Chinese character × deformation 1–5, noise 1–6, outlier 1–5,
occlusion 1–6, rotation 1–6) and each sample, the template ``x1`` is registered onto the target
``y2a`` by

* ``shapelib.register(x1, y2a, w="auto")`` (non-rigid: pose over every rotation, EM, the metric's
  kernel; defaults otherwise), and
* ``pycpd.DeformableRegistration`` (Coherent Point Drift, pycpd's defaults: λ = 2, β = 2, w = 0),
  with the inputs normalised as MATLAB CPD does (each set to zero mean and unit RMS radius; the
  result mapped back with the target's mean and scale),

on the same inputs in the same run, BLAS on one thread for both. The error of a method is
``mean_i |moved_i − y2_i|`` over the first ``len(y2)`` points of ``x1``, whose ground-truth
positions ``y2`` the benchmark gives; the wall time is that of the registration call.

    python benchmarks/bench_registration.py [--samples N] [--levels fish_rot,chinese_def_3] [--json out.json] [--record]

``--samples 1`` (default) registers sample 1 of each level (about 5 minutes on a 2-core machine);
``--samples 10`` is the whole benchmark. ``--record`` writes
``docs/_data/benchmarks/bench_registration.json`` (machine, date and command included).
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

import shapelib as sl  # noqa: E402
from shapelib.datasets import TPS_RPM_LEVELS, load_tps_rpm_case  # noqa: E402

#: the settings of shapelib's run (recorded with the results)
SHAPELIB_SETTINGS = {"transform": "nonrigid", "metric": "alpha", "w": "auto"}


def _normalise(a):
    m = a.mean(axis=0)
    s = float(np.sqrt(np.sum((a - m) ** 2) / len(a)))
    return (a - m) / s, m, s


def run_shapelib(x1, y2a):
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an EM that stops at max_iter is counted by its error
        res = sl.register(x1, y2a, **SHAPELIB_SETTINGS)
    return res.points, time.perf_counter() - t0, {"converged": bool(res.converged), "w": res.w}


def run_cpd(x1, y2a):
    from pycpd import DeformableRegistration

    yn, my, sy = _normalise(y2a)
    xn, _, _ = _normalise(x1)
    t0 = time.perf_counter()
    moved, _ = DeformableRegistration(X=yn, Y=xn).register()
    return moved * sy + my, time.perf_counter() - t0, {}


METHODS = {"shapelib": run_shapelib, "cpd": run_cpd}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1, help="samples per level, 1 to 10 (default 1)")
    ap.add_argument("--levels", default="", help="comma-separated substrings of the levels to run (default all)")
    ap.add_argument("--json", type=Path, help="write the report here")
    ap.add_argument("--record", action="store_true",
                    help="write docs/_data/benchmarks/bench_registration.json (all levels only)")
    args = ap.parse_args(argv)
    if not 1 <= args.samples <= 10:
        ap.error("--samples must be 1 to 10")
    wanted = [w for w in args.levels.split(",") if w]
    if args.record and wanted:
        ap.error("--record: a partial run is not the benchmark")
    levels = [lv for lv in TPS_RPM_LEVELS if not wanted or any(w in lv for w in wanted)]
    from threadpoolctl import threadpool_limits

    report = {"samples": args.samples, "settings": {"shapelib": SHAPELIB_SETTINGS,
                                                     "cpd": "pycpd DeformableRegistration defaults, MATLAB-CPD normalisation"},
              "loadavg_before": loadavg(), "levels": {}}
    with threadpool_limits(limits=1, user_api="blas"):
        for name in levels:
            row = {m: {"errors": [], "times": []} for m in METHODS}
            for sample in range(1, args.samples + 1):
                case = load_tps_rpm_case(name, sample=sample)
                n = len(case["y2"])
                for m, fn in METHODS.items():
                    moved, seconds, _ = fn(case["x1"], case["y2a"])
                    row[m]["errors"].append(float(np.mean(np.linalg.norm(moved[:n] - case["y2"], axis=1))))
                    row[m]["times"].append(seconds)
            for m in METHODS:
                row[m]["error"] = float(np.mean(row[m]["errors"]))
                row[m]["time_median_s"] = float(np.median(row[m]["times"]))
            report["levels"][name] = row
            print(f"{name:22s} shapelib {row['shapelib']['error']:.4f} ({row['shapelib']['time_median_s']:.2f} s)   "
                  f"cpd {row['cpd']['error']:.4f} ({row['cpd']['time_median_s']:.2f} s)", flush=True)
    report["loadavg_after"] = loadavg()
    report["summary"] = summarise(report["levels"])
    print(json.dumps(report["summary"], indent=1))
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")
    if args.record:
        print(f"recorded {record('bench_registration', report, argv=argv)}")
    return report


def summarise(levels: dict) -> dict:
    """Levels where shapelib's error is below CPD's, rotation robustness, median times."""
    names = list(levels)
    below = [n for n in names if levels[n]["shapelib"]["error"] < levels[n]["cpd"]["error"]]
    out = {"levels": len(names), "shapelib_below_cpd": len(below),
           "shapelib_not_below_cpd": [n for n in names if n not in below]}
    for m in METHODS:
        times = [t for n in names for t in levels[n][m]["times"]]
        out[f"{m}_median_time_s"] = float(np.median(times)) if times else None
        out[f"{m}_mean_error"] = float(np.mean([levels[n][m]["error"] for n in names])) if names else None
    for shape in ("fish", "chinese"):
        rot = {n: levels[n] for n in names if n.startswith(f"{shape}_rot_")}
        if f"{shape}_rot_1" in rot:
            base = {m: rot[f"{shape}_rot_1"][m]["error"] for m in METHODS}
            out[f"{shape}_rotation_error_over_level_1"] = {
                m: {n: levels[n][m]["error"] / max(base[m], 1e-12) for n in rot} for m in METHODS}
    return out


if __name__ == "__main__":
    main()
