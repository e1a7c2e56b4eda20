"""Large point sets: time and peak memory of ``shapelib.register`` (its defaults) on 10⁴ and 10⁵ points.

Cases (the source and a warped, rotated, noisy copy of it, shuffled; the truth is the source's warped
position):

* 2-D: ``n`` points at random positions on the closed curve ``r(t) = 1 + 0.3 cos 3t + 0.15 sin 5t``
  (no symmetry), moved by four Gaussian displacements of amplitude 0.1 (width 0.5, centres on the
  curve), turned by 30°, scaled by 1.3, with Gaussian noise of 0.005 per coordinate;
* 3-D: ``n`` points on the surface ``r(v) v`` over unit directions ``v``, ``r = 1 + 0.3 v_x + 0.2 v_y v_z
  + 0.15 v_z² + 0.2 v_y³``, stretched by (1.2, 1, 0.8) — an egg-like surface whose symmetries only its
  small odd terms break, so other poses fit it nearly as well — the same warp, turned by 30° about a
  random axis, scaled and noisy as in 2-D. Dense samples of a smooth surface also leave the
  correspondences along it poorly determined: a fit can slide over the surface at little cost.

Each case runs in its own Python process (``register`` once untimed on a small set first, so
compilation stays out of the time); the record keeps the wall time of the ``register`` call, the
process's peak resident memory (``ru_maxrss``, the interpreter and libraries included), the error
``mean_i |moved_i − truth_i|`` and the mean distance from each moved point to the nearest target point
(both in units of the target's RMS radius: the second does not count sliding along the curve or
surface), the ``reliable`` flag and ``converged``. The peers (pycpd, probreg) are not run at these
sizes: their non-rigid CPD forms dense (n, m) matrices (0.8 GB each at 10⁴ + 10⁴ points).

The 3-D cases run once more with ``--landmarks`` (default 3) known correspondences: source points spread
over the surface (farthest-point sampling), each with the target point that is its noisy true position.

    python benchmarks/bench_registration_large.py [--sizes 10000,100000] [--dims 2,3] [--landmarks 3] [--json out.json] [--record]

``--record`` writes ``docs/_data/benchmarks/bench_registration_large.json`` (machine, date, command).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from benchmarks._machine import loadavg, record  # noqa: E402

#: the warp: amplitude, width, number of Gaussian displacements; rotation (degrees), scale, noise
AMPLITUDE, WIDTH, N_BUMPS, DEGREES, SCALE, NOISE = 0.1, 0.5, 4, 30.0, 1.3, 0.005


def _unit_rms(a):
    a = a - a.mean(axis=0)
    return a / np.sqrt(np.mean(np.sum(a * a, axis=1)))


def make_case(n: int, d: int, seed: int = 0) -> dict:
    """The source ``x``, the shuffled target ``y`` and ``truth`` (x's true positions) of a case."""
    rng = np.random.default_rng([n, d, seed])
    if d == 2:
        t = rng.uniform(0.0, 2 * np.pi, n)
        r = 1 + 0.3 * np.cos(3 * t) + 0.15 * np.sin(5 * t)
        x = _unit_rms(np.column_stack([r * np.cos(t), r * np.sin(t)]))
        c, s = np.cos(np.radians(DEGREES)), np.sin(np.radians(DEGREES))
        rot = np.array([[c, -s], [s, c]])
    else:
        from benchmarks.bench_registration_3d import _rotation

        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        r = 1 + 0.3 * v[:, 0] + 0.2 * v[:, 1] * v[:, 2] + 0.15 * v[:, 2] ** 2 + 0.2 * v[:, 1] ** 3
        x = _unit_rms(r[:, None] * v * np.array([1.2, 1.0, 0.8]))
        rot = _rotation(rng.normal(size=3), DEGREES)
    centres = x[rng.choice(n, N_BUMPS, replace=False)]
    dirs = rng.normal(size=(N_BUMPS, d))
    dirs *= AMPLITUDE / np.linalg.norm(dirs, axis=1, keepdims=True)
    bump = np.zeros_like(x)
    for c0, a in zip(centres, dirs):
        bump += np.exp(-np.sum((x - c0) ** 2, axis=1) / (2 * WIDTH**2))[:, None] * a
    truth = SCALE * (x + bump) @ rot.T + 0.2
    y = truth + rng.normal(scale=NOISE, size=truth.shape)
    perm = rng.permutation(n)
    return {"x": x, "y": y[perm], "truth": truth, "perm": perm}


def case_landmarks(case: dict, k: int) -> np.ndarray:
    """``k`` known correspondences of a case: source points spread over it (farthest-point sampling),
    each with the target point that is its (noisy) true position."""
    from shapelib.pointsets.registration import farthest_points

    src = farthest_points(case["x"], k)
    where = np.argsort(case["perm"])  # where[i]: the target index of source point i
    return np.column_stack([src, where[src]])


def run_case(n: int, d: int, k: int = 0) -> dict:
    """One case in this process, with ``k`` known correspondences: time, peak memory, errors, flags."""
    import resource
    import time
    import warnings

    from scipy.spatial import cKDTree

    import shapelib as sl

    rng = np.random.default_rng(1)
    small = rng.normal(size=(40, d))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sl.register(small, 1.1 * small + 0.1)  # compile and import outside the timing
    case = make_case(n, d)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t0 = time.perf_counter()
        res = sl.register(case["x"], case["y"], landmarks=case_landmarks(case, k) if k else None)
        seconds = time.perf_counter() - t0
    truth = case["truth"]
    size = float(np.sqrt(np.mean(np.sum((truth - truth.mean(axis=0)) ** 2, axis=1))))
    to_target, _ = cKDTree(case["y"]).query(res.points)
    return {"points": n, "dim": d, "landmarks": k, "seconds": seconds,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "error": float(np.mean(np.linalg.norm(res.points - truth, axis=1))) / size,
            "distance_to_target": float(np.mean(to_target)) / size,
            "reliable": bool(res.reliable), "reasons": list(res.reasons), "converged": bool(res.converged),
            "stop_reason": res.stop_reason, "warnings": [str(w.message)[:160] for w in caught]}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="10000,100000", help="comma-separated set sizes (default 10000,100000)")
    ap.add_argument("--dims", default="2,3", help="comma-separated dimensions (default 2,3)")
    ap.add_argument("--landmarks", type=int, default=3,
                    help="3-D cases run once more with this many known correspondences (0: not; default 3)")
    ap.add_argument("--json", type=Path, help="write the report here")
    ap.add_argument("--record", action="store_true",
                    help="write docs/_data/benchmarks/bench_registration_large.json")
    ap.add_argument("--one", metavar="N,D", help=argparse.SUPPRESS)  # the child process of one case
    args = ap.parse_args(argv)
    if args.one:
        n, d, k = (int(v) for v in args.one.split(","))
        print(json.dumps(run_case(n, d, k)))
        return {}
    report = {"loadavg_start": loadavg(), "cases": []}
    runs = [(d, n, 0) for d in (int(v) for v in args.dims.split(",")) for n in (int(v) for v in args.sizes.split(","))]
    runs += [(d, n, args.landmarks) for d, n, _ in runs if d == 3 and args.landmarks]
    env = {**__import__("os").environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    for d, n, k in runs:
        out = subprocess.run([sys.executable, __file__, "--one", f"{n},{d},{k}"], capture_output=True, text=True,
                             check=True, env=env)
        case = json.loads(out.stdout.strip().splitlines()[-1])
        report["cases"].append(case)
        print(f"{d}-D, {n} + {n} points, {k} landmarks: {case['seconds']:.1f} s, peak {case['peak_rss_mb']:.0f} MB, "
              f"error {case['error']:.4f}, to target {case['distance_to_target']:.4f}, "
              f"reliable {case['reliable']}, converged {case['converged']}", flush=True)
    report["loadavg_end"] = loadavg()
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    if args.record:
        print(f"recorded {record('bench_registration_large', report, argv=argv)}")
    return report


if __name__ == "__main__":
    main()
