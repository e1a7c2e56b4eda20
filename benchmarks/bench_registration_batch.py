"""Many non-rigid registrations at once: ``shapelib.register_many`` with ``backend="numpy"`` (register
one pair at a time, compiled CPU EM) and ``backend="jax"`` (pairs × starts batched in one array
program: the GPU when JAX sees one, else the CPU), on the same pairs in the same run.

The pairs are MPEG-7 outlines resampled to ``--points`` points (``shapelib.datasets.load_mpeg7``),
drawn at random among ``--classes`` classes × ``--per-class`` shapes. Recorded per backend: wall
seconds per registration (JAX: after a first call on the same shapes that compiles the programs,
which is not charged) and, for JAX, how that time splits between the host's preparation
(normalisation, the target's leave-one-out σ² once per distinct target), the batched search (EM on
the device, transfers included) and the results' assembly on the host (the numpy code of
``register``: reliability, pose, correspondences). Recorded between the backends: the largest difference of the
moved points in units of the target's RMS radius, and the pairs where the chosen start, the
reliability flag or the EM's iteration count differ.

    python benchmarks/bench_registration_batch.py [--pairs 64] [--numpy-pairs 64] [--batch-size N]
        [--device cpu|gpu] [--record]

Runs as is on a machine with a GPU (``pip install "shapelib[gpu]"``); the device is printed and
recorded. ``--record`` writes ``docs/_data/benchmarks/bench_registration_batch.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._machine import loadavg, record  # noqa: E402

import shapelib as sl  # noqa: E402
from shapelib.datasets import load_mpeg7, mpeg7_classes  # noqa: E402


def make_pairs(n_pairs, classes, per_class, points, seed=0):
    every = mpeg7_classes()
    chosen = [every[i] for i in np.round(np.linspace(0, len(every) - 1, classes)).astype(int)]
    data = load_mpeg7(classes=chosen, per_class=per_class, n_points=points)
    shapes = list(data.shapes)
    rng = np.random.default_rng(seed)
    idx = [tuple(rng.choice(len(shapes), size=2, replace=False)) for _ in range(n_pairs)]
    return [(shapes[i], shapes[j]) for i, j in idx], chosen


def _device_info(device):
    import jax

    from shapelib.solver.batched import jax_device

    dev = jax_device(device)
    return {"platform": dev.platform, "device_kind": getattr(dev, "device_kind", str(dev)), "name": str(dev),
            "jax": jax.__version__}


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=64, help="pairs registered with backend='jax' (default 64)")
    p.add_argument("--numpy-pairs", type=int, default=None,
                   help="of them, registered with backend='numpy' too (default: all; the agreement is over these)")
    p.add_argument("--points", type=int, default=100)
    p.add_argument("--classes", type=int, default=8)
    p.add_argument("--per-class", type=int, default=4)
    p.add_argument("--batch-size", type=int, default=None, help="pairs per device call (default: from its memory)")
    p.add_argument("--device", choices=("cpu", "gpu"), default=None, help="JAX device (default: JAX's default)")
    p.add_argument("--record", action="store_true")
    args = p.parse_args(argv)
    res = {"loadavg_start": loadavg(), "points": args.points}
    pairs, classes = make_pairs(args.pairs, args.classes, args.per_class, args.points)
    n_np = len(pairs) if args.numpy_pairs is None else min(args.numpy_pairs, len(pairs))
    res.update(pairs=len(pairs), numpy_pairs=n_np, data=f"MPEG-7 outlines, {len(classes)} classes × {args.per_class}")
    info = _device_info(args.device)
    res["device"] = info
    print(f"bench_registration_batch: {len(pairs)} pairs of {args.points}-point MPEG-7 outlines; JAX device "
          f"{info['device_kind']} ({info['name']}, JAX {info['jax']}); load {res['loadavg_start']}")
    rows = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.RegistrationWarning)
        # JAX: a first call compiles the programs for these shapes (not charged), then the timed call
        t0 = time.perf_counter()
        sl.register_many(pairs, backend="jax", device=args.device, batch_size=args.batch_size)
        compile_s = time.perf_counter() - t0
        tm = {}
        t0 = time.perf_counter()
        got = sl.register_many(pairs, backend="jax", device=args.device, batch_size=args.batch_size, timings=tm)
        wall = time.perf_counter() - t0
        rows["jax"] = {"registrations": len(pairs), "wall_s": wall, "seconds_per_registration": wall / len(pairs),
                       "prep_seconds_per_registration": tm["prep"] / len(pairs),
                       "search_seconds_per_registration": tm["search"] / len(pairs),
                       "assembly_seconds_per_registration": tm["assembly"] / len(pairs),
                       "first_call_s": compile_s, "batch_size": args.batch_size, "device": tm["device"]}
        print(f"  jax   ({tm['device']}): {1e3 * wall / len(pairs):.1f} ms per registration (host prep "
              f"{1e3 * tm['prep'] / len(pairs):.2f} ms, device search {1e3 * tm['search'] / len(pairs):.2f} ms, host "
              f"assembly {1e3 * tm['assembly'] / len(pairs):.2f} ms); "
              f"first call {compile_s:.1f} s")
        sl.register(*pairs[0])  # the compiled CPU kernels loaded before timing
        t0 = time.perf_counter()
        ref = sl.register_many(pairs[:n_np], backend="numpy")
        wall = time.perf_counter() - t0
    rows["numpy"] = {"registrations": n_np, "wall_s": wall, "seconds_per_registration": wall / max(n_np, 1)}
    print(f"  numpy (register one by one, CPU): {1e3 * wall / max(n_np, 1):.1f} ms per registration")
    res["rows"] = rows
    diff = [float(np.abs(a.points - b.points).max() / a._frame[1]) for a, b in zip(ref, got)]
    res["agreement"] = {
        "pairs": n_np,
        "max_points_difference": max(diff) if diff else None,
        "median_points_difference": float(np.median(diff)) if diff else None,
        "start_differs": int(sum(not np.allclose(a._start[0], b._start[0]) for a, b in zip(ref, got))),
        "reliable_differs": int(sum(a.reliable != b.reliable for a, b in zip(ref, got))),
        "n_iter_differs": int(sum(a.n_iter != b.n_iter for a, b in zip(ref, got))),
        "reliable_share": float(np.mean([r.reliable for r in got])),
    }
    a = res["agreement"]
    print(f"  agreement over {n_np} pairs: moved points differ by at most {a['max_points_difference']:.2g} "
          f"(target RMS radius units); start differs in {a['start_differs']}, reliable in {a['reliable_differs']}, "
          f"iterations in {a['n_iter_differs']}")
    res["speedup"] = rows["numpy"]["seconds_per_registration"] / rows["jax"]["seconds_per_registration"]
    res["loadavg_end"] = loadavg()
    if args.record:
        print("recorded", record("bench_registration_batch", res, argv=argv))
    return res


if __name__ == "__main__":
    main()
