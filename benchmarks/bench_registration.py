"""Point-set registration on the Chui–Rangarajan (TPS-RPM) benchmark: shapelib beside every peer that runs here.

For each of the 56 levels (fish and Chinese character × deformation 1–5, noise 1–6, outlier 1–5,
occlusion 1–6, rotation 1–6) and each sample, the template ``x1`` is registered onto the target
``y2a`` by

* ``shapelib.register(x1, y2a)`` with its defaults (no settings: what a user runs is reported), and
* the peers, each with its documented defaults on the same normalised inputs (zero mean, unit RMS
  radius; the result mapped back with the target's mean and scale): pycpd's
  ``DeformableRegistration`` and probreg's non-rigid CPD, FilterReg, GMMTree and BCPD
  (``benchmarks/_peers.py`` says which of them are rigid only and which needed a z = 0 embedding),

on the same inputs in the same run, BLAS on one thread. The error of a method is
``mean_i |moved_i − y2_i|`` over the first ``len(y2)`` points of ``x1``, whose ground-truth
positions ``y2`` the benchmark gives; a registration is a failure when its error exceeds 0.05 or
the method raised (its error is then that of the unmoved source, and the exception's class is
recorded); the wall time is that of the registration call. Where shapelib's result has a
``reliable`` flag it is recorded, with its catch rate (of the errors > 0.05, the share flagged
unreliable) and its false-alarm rate (of the errors < 0.02, the share flagged).

    python benchmarks/bench_registration.py [--samples 1-10] [--levels fish_rot,chinese_def_3] [--json out.json] [--record]

``--samples`` takes a count ``N`` (samples 1 to N) or a range ``A-B``; the default is sample 1.
Run on all ten, the summary reports samples 1–5 (where defaults are chosen), 6–10 (draws they
were not chosen on) and 1–10. ``--record`` writes ``docs/_data/benchmarks/bench_registration.json``
(machine, date and command included).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._machine import loadavg, record  # noqa: E402
from benchmarks._peers import DESCRIPTIONS, METHODS, run, warm_up  # noqa: E402

from shapelib.datasets import TPS_RPM_LEVELS, load_tps_rpm_case  # noqa: E402

#: an error above this is a failed registration
FAILURE = 0.05
#: an error below this is a good registration (for the flag's false-alarm rate)
GOOD = 0.02
#: the degradations, as the level names spell them
FAMILIES = ("def", "noise", "outlier", "occlusion", "rot")


def parse_samples(text: str) -> list[int]:
    """``"N"`` -> samples 1..N, ``"A-B"`` -> samples A..B, each within 1..10."""
    try:
        a, b = (text.split("-", 1) if "-" in text else ("1", text))
        a, b = int(a), int(b)
    except ValueError:
        raise ValueError(f"samples: expected N or A-B, got {text!r}") from None
    if not 1 <= a <= b <= 10:
        raise ValueError(f"samples: need 1 <= A <= B <= 10, got {text!r}")
    return list(range(a, b + 1))


def _level_stats(cell: dict, keep: list[int]) -> dict:
    errors = [cell["errors"][i] for i in keep]
    raised = [cell["exceptions"][i] for i in keep]
    return {"error": float(np.mean(errors)),
            "failures": int(sum(e > FAILURE or x is not None for e, x in zip(errors, raised))),
            "raised": int(sum(x is not None for x in raised)),
            "time_median_s": float(np.median([cell["times"][i] for i in keep]))}


def summarise_range(levels: dict, samples: list[int], methods=METHODS, families=FAMILIES,
                    shapes=("fish", "chinese")) -> dict:
    """Per method and per family × shape: mean error, failures, median time; shapelib against the peers.

    ``levels[name][method]`` holds per-sample lists ``samples``, ``errors``, ``times``,
    ``exceptions`` (and ``reliable`` for shapelib); only the samples in ``samples`` are counted.
    """
    names = list(levels)
    methods = [m for m in methods if all(m in levels[n] for n in names)]
    peers = [m for m in methods if m != "shapelib"]
    st = {}
    for n in names:
        st[n] = {}
        for m in methods:
            cell = levels[n][m]
            keep = [i for i, s in enumerate(cell["samples"]) if s in samples]
            if not keep:
                return {}
            st[n][m] = _level_stats(cell, keep)
    out = {"samples": f"{min(samples)}-{max(samples)}", "levels": len(names), "methods": {}}
    for m in methods:
        times = [t for n in names for s, t in zip(levels[n][m]["samples"], levels[n][m]["times"]) if s in samples]
        out["methods"][m] = {"mean_error": float(np.mean([st[n][m]["error"] for n in names])),
                             "failures": sum(st[n][m]["failures"] for n in names),
                             "raised": sum(st[n][m]["raised"] for n in names),
                             "registrations": len(times),
                             "median_time_s": float(np.median(times))}
    if "shapelib" in methods and peers:
        best = {n: min(st[n][p]["error"] for p in peers) for n in names}
        out["shapelib_le_peer"] = {p: sum(st[n]["shapelib"]["error"] <= st[n][p]["error"] for n in names)
                                   for p in peers}
        out["shapelib_le_every_peer"] = sum(st[n]["shapelib"]["error"] <= best[n] for n in names)
        out["shapelib_above_best_peer_plus_0.01"] = [n for n in names if st[n]["shapelib"]["error"] > best[n] + 0.01]
        t_sl = out["methods"]["shapelib"]["median_time_s"]
        out["shapelib_time_over_cpd"] = (t_sl / out["methods"]["cpd"]["median_time_s"]
                                         if "cpd" in methods else None)
    fam = {}
    for shape in shapes:
        for kind in families:
            group = [n for n in names if n.startswith(f"{shape}_{kind}_")]
            if not group:
                continue
            row = {m: float(np.mean([st[n][m]["error"] for n in group])) for m in methods}
            entry = {"levels": len(group), "mean_error": row,
                     "failures": {m: sum(st[n][m]["failures"] for n in group) for m in methods}}
            if peers:
                bp = min(peers, key=lambda p: row[p])
                entry["best_peer"], entry["best_peer_error"] = bp, row[bp]
            fam[f"{shape}_{kind}"] = entry
    out["families"] = fam
    if "shapelib" in methods:
        flags, errs, warned = [], [], []
        for n in names:
            cell = levels[n]["shapelib"]
            none = [None] * len(cell["errors"])
            for s, e, r, c in zip(cell["samples"], cell["errors"], cell.get("reliable", none),
                                  cell.get("converged", none)):
                if s in samples and r is not None:
                    flags.append(not r)
                    errs.append(e)
                    warned.append(None if c is None else (not r or not c))

        def rates(flagged):
            bad = [f for f, e in zip(flagged, errs) if e > FAILURE]
            good = [f for f, e in zip(flagged, errs) if e < GOOD]
            return {"registrations": len(flagged), "errors_above_0.05": len(bad),
                    "catch_rate": float(np.mean(bad)) if bad else None, "errors_below_0.02": len(good),
                    "false_alarm_rate": float(np.mean(good)) if good else None}

        if flags:
            out["reliable_flag"] = rates(flags)
        if warned and None not in warned:  # a RegistrationWarning: not reliable, or EM stopped at max_iter
            out["any_warning"] = rates(warned)
        for shape in shapes:
            base = f"{shape}_rot_1"
            if base in st:
                out[f"{shape}_rotation_error_over_level_1"] = {
                    n: st[n]["shapelib"]["error"] / max(st[base]["shapelib"]["error"], 1e-12)
                    for n in names if n.startswith(f"{shape}_rot_")}
    return out


def summarise(levels: dict, samples: list[int] | None = None, *, tuned=range(1, 6), **kw) -> dict:
    """The summary of every range: the samples the defaults were ``tuned`` on (1–5 here), the rest
    and all of them when every sample of ``tuned`` and some more ran (1–5, 6–10 and 1–10 for all
    ten), else the range that ran."""
    if samples is None:
        samples = sorted({s for n in levels for s in levels[n]["shapelib"]["samples"]}) if levels else []
    if not samples:
        return {}
    ranges = [samples]
    tuned = sorted(tuned)
    rest = sorted(set(samples) - set(tuned))
    if set(tuned) <= set(samples) and rest:
        ranges = [tuned, rest, sorted(samples)]
    return {f"{min(r)}-{max(r)}": summarise_range(levels, r, **kw) for r in ranges}


def parse_methods(ap, text: str) -> list[str]:
    """``--methods``: the comma-separated names (default every method), unknown ones an argparse error."""
    methods = [m for m in text.split(",") if m] or list(METHODS)
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        ap.error(f"--methods: unknown {', '.join(unknown)}; known: {', '.join(METHODS)}")
    return methods


def run_levels(levels, samples, methods, case_of, *, time_limit=None, dim=2, width=20) -> dict:
    """Every level × method × sample, BLAS on one thread: ``{level: {method: cell}}``.

    ``case_of(level, sample)`` gives ``(source, target, truth)``; a method's error is
    ``mean_i |moved_i − truth_i|`` over the first ``len(truth)`` points of the moved source. A cell
    holds per-sample ``samples``, ``errors``, ``times``, ``exceptions`` (shapelib also ``reliable``
    and ``converged``) and the level's statistics.
    """
    from threadpoolctl import threadpool_limits

    out = {}
    with threadpool_limits(limits=1, user_api="blas"):
        warm_up(methods, dim=dim, time_limit=time_limit)
        for name in levels:
            row = {m: {"samples": [], "errors": [], "times": [], "exceptions": []} for m in methods}
            if "shapelib" in row:
                row["shapelib"].update(reliable=[], converged=[])
            cases = [case_of(name, sample) for sample in samples]
            # method by method over the level's samples: a method runs after itself, so that one
            # whose threads linger after a call (probreg's) slows only its own timings
            for m in methods:
                for sample, (source, target, truth) in zip(samples, cases):
                    moved, seconds, info = run(m, source, target, time_limit)
                    cell = row[m]
                    cell["samples"].append(sample)
                    cell["errors"].append(float(np.mean(np.linalg.norm(moved[:len(truth)] - truth, axis=1))))
                    cell["times"].append(seconds)
                    cell["exceptions"].append(info["exception"])
                    if m == "shapelib":
                        cell["reliable"].append(info.get("reliable"))
                        cell["converged"].append(info.get("converged"))
            for m in methods:
                row[m].update(_level_stats(row[m], list(range(len(samples)))))
            out[name] = row
            print(f"{name:{width}s} " + "  ".join(f"{m} {row[m]['error']:.4f}/{row[m]['failures']}f/"
                                                 f"{row[m]['time_median_s']:.3f}s" for m in methods), flush=True)
    return out


def _tps_rpm_case(name, sample):
    case = load_tps_rpm_case(name, sample=sample)
    return case["x1"], case["y2a"], case["y2"]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default="1", help="N (samples 1 to N) or A-B, within 1 to 10 (default 1)")
    ap.add_argument("--levels", default="", help="comma-separated substrings of the levels to run (default all)")
    ap.add_argument("--methods", default="", help="comma-separated methods to run (default all: "
                    + ", ".join(METHODS) + ")")
    ap.add_argument("--time-limit", type=float, default=0,
                    help="seconds after which a registration is stopped and counted as a failure (0: none; "
                         "default 0)")
    ap.add_argument("--json", type=Path, help="write the report here")
    ap.add_argument("--record", action="store_true",
                    help="write docs/_data/benchmarks/bench_registration.json (all levels and methods only)")
    args = ap.parse_args(argv)
    try:
        samples = parse_samples(args.samples)
    except ValueError as exc:
        ap.error(str(exc))
    wanted = [w for w in args.levels.split(",") if w]
    methods = parse_methods(ap, args.methods)
    if args.record and (wanted or args.methods):
        ap.error("--record: a partial run is not the benchmark")
    levels = [lv for lv in TPS_RPM_LEVELS if not wanted or any(w in lv for w in wanted)]
    report = {"samples": samples, "methods": methods, "settings": {m: DESCRIPTIONS[m] for m in methods},
              "failure_threshold": FAILURE, "time_limit_s": args.time_limit or None,
              "normalisation": "peers: each set to zero mean and unit RMS radius, the result mapped back with the "
                               "target's mean and scale; shapelib: raw inputs",
              "on_exception": "a failure; its error is that of the unmoved source; the exception's class is recorded",
              "loadavg_before": loadavg()}
    report["levels"] = run_levels(levels, samples, methods, _tps_rpm_case, time_limit=args.time_limit or None)
    report["loadavg_after"] = loadavg()
    report["summary"] = summarise(report["levels"], samples, methods=methods)
    print(json.dumps(report["summary"], indent=1))
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")
    if args.record:
        print(f"recorded {record('bench_registration', report, argv=argv)}")
    return report


if __name__ == "__main__":
    main()
