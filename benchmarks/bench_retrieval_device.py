#!/usr/bin/env python
"""The MPEG-7 registration matrix on a JAX device (a GPU), in the order of the rigid shortlist,
within a time limit, resumable.

Run where the data are not (a GPU machine with JAX, no network, no dask or zarr): it reads what
``bench_retrieval.py --registration --prepare DIR`` wrote here (the 1,400 outlines of 100 points and
every pair ordered by its rank in the rigid Fisher–Rao bound's shortlist: pairs where one shape is
among the other's 40 nearest first, then 80, ...) and registers the pairs in that order, both
directions each, by :func:`shapelib.pointsets.registration_distance.registration_misfits_many`
(``backend="jax"``: batched on the device), in chunks of whole device batches sized to about 40 s
from the rate measured (the first chunk, which compiles the programs, is timed apart). After each chunk it writes
``misfits.npy`` (the two directed misfits of each pair done so far, in order), ``progress.npz``
(how many are done, their convergence and EM iterations) and ``log.json`` (the device, the compile
time, each chunk's wall seconds) into ``--out``, each replaced whole (a run killed at any point
leaves the last chunk's files), and it starts no chunk that the previous one's rate says would end
past ``--deadline`` seconds. ``--resume DIR`` continues from a previous run's files.
Before the matrix, ``--check`` pairs of the first chunk are registered one by one with the numpy backend too (the
batched path equals one by one: the largest difference is logged).

``bench_retrieval.py --registration --from-device DIR`` then builds the matrix (the pairs not
reached take the rigid bound, ranked after the registered ones: as ``shortlist=k`` does), scores
it raw and re-ranked, and records it with the device and the times.

    python benchmarks/bench_retrieval_device.py --data DIR --out OUT [--deadline 480] [--resume PREVIOUS_OUT]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _save(path: Path, array) -> None:
    """``np.save`` to a temporary name, then renamed over ``path`` (never half written)."""
    tmp = path.with_name(path.stem + ".tmp.npy")
    np.save(tmp, array)
    os.replace(tmp, path)


def _digest(pairs) -> str:
    return hashlib.sha256(np.ascontiguousarray(pairs, dtype=np.int64).tobytes()).hexdigest()


def _save_json(path: Path, obj) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(obj, indent=1))
    os.replace(tmp, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="folder with outlines.npy and pairs.npy (from --prepare)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--deadline", type=float, default=480.0, help="seconds: no chunk is started that would end later")
    ap.add_argument("--batch-size", type=int, default=1024,
                    help="registrations per device call (default 1024); the chunks are whole batches, sized to about 40 s")
    ap.add_argument("--check", type=int, default=8, help="pairs also registered one by one with numpy")
    ap.add_argument("--limit", type=int, default=None, help="at most this many pairs (a trial run)")
    ap.add_argument("--resume", default=None, help="a previous run's --out folder")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    import jax

    from shapelib.pointsets.registration_distance import registration_misfits_many

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    data = Path(args.data)
    outlines = np.load(data / "outlines.npy")
    pairs = np.load(data / "pairs.npy")
    if args.limit is not None:
        pairs = pairs[:args.limit]
    total = len(pairs)
    res = np.full((total, 2), np.nan)
    ok = np.zeros(total, bool)
    iters = np.zeros(total, np.int32)
    done = 0
    if args.resume:
        prev = Path(args.resume)
        state = np.load(prev / "progress.npz")
        done = int(state["done"])
        if str(state["digest"]) != _digest(pairs[:done]):
            raise ValueError(f"{prev}: its pairs are not this run's")
        res[:done] = np.load(prev / "misfits.npy")[:done]
        ok[:done], iters[:done] = state["ok"][:done], state["iters"][:done]
    dev = jax.devices()[0]
    log = {"device": {"platform": dev.platform, "device_kind": getattr(dev, "device_kind", str(dev)),
                      "jax": jax.__version__, "host": platform.node(), "cpus": os.cpu_count(),
                      "python": platform.python_version(), "numpy": np.__version__},
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "pairs_total": total,
           "resumed_from": done, "chunks": [], "batch_size": args.batch_size,
           "argv": " ".join(["python3", "benchmarks/bench_retrieval_device.py", *(sys.argv[1:] if argv is None else argv)])}
    kw = dict(backend="jax", batch_size=args.batch_size)

    def run(idx, **extra):
        return registration_misfits_many([(outlines[i], outlines[j]) for i, j in pairs[idx]], **kw, **extra)

    # one device batch a chunk until a rate is measured: the first compiles the programs (its time is
    # logged apart, not in the rate), the second measures it
    step = max(1, args.batch_size // 2)
    chunk, rate = step, None
    while done < total:
        elapsed = time.perf_counter() - t_start
        if rate is not None:  # pairs per second: chunks of about 40 s, none started that would end late
            chunk = int(np.clip(rate * 40 // step, 1, 128) * step)
            if elapsed + chunk / rate > args.deadline:
                chunk = int((args.deadline - elapsed) * rate // step) * step
                if chunk < step:
                    print(f"stopping before the deadline: {elapsed:.0f} s gone", flush=True)
                    break
        idx = np.arange(done, min(done + chunk, total))
        t = {}
        t0 = time.perf_counter()
        fit = run(idx, timings=t)
        wall = time.perf_counter() - t0
        res[idx] = [(a, b) for a, b, _, _ in fit]
        ok[idx] = [c for _, _, c, _ in fit]
        iters[idx] = [n for _, _, _, n in fit]
        first = not log["chunks"]
        if first and args.check:  # the batched path against one by one (numpy) on the first pairs
            k = min(args.check, len(idx))
            ref = registration_misfits_many([(outlines[i], outlines[j]) for i, j in pairs[idx[:k]]], backend="numpy")
            diff = max(abs(a[c] - b[c]) / max(b[c], 1e-12) for a, b in zip(fit[:k], ref) for c in (0, 1))
            log["check"] = {"pairs": k, "max_relative_difference": float(diff),
                            "same_convergence": all(a[2] == b[2] for a, b in zip(fit[:k], ref))}
            print(f"check: {k} pairs, device against numpy one by one: largest relative difference {diff:.2e}",
                  flush=True)
        elif not first:  # the first chunk's time is the compilation's: no rate from it
            rate = len(idx) / wall if rate is None else 0.5 * (rate + len(idx) / wall)
        done = int(idx[-1]) + 1
        log["chunks"].append({"pairs": len(idx), "wall": wall, "compiles": first,
                              **{k: v for k, v in t.items() if k != "device"}})
        log["done"] = done
        log["wall_total"] = time.perf_counter() - t_start
        # the misfits first, then the count that says how many of them are done (a run killed between
        # the two leaves more misfits than the count: the extra ones are computed again)
        _save(out / "misfits.npy", res[:done])
        tmp = out / "progress.tmp.npz"
        np.savez(tmp, ok=ok[:done], iters=iters[:done], done=np.int64(done), digest=_digest(pairs[:done]))
        os.replace(tmp, out / "progress.npz")
        _save_json(out / "log.json", log)
        print(f"{done:,}/{total:,} pairs ({2 * len(idx):,} registrations in {wall:.1f} s: "
              f"{2 * len(idx) / wall:.0f} per second; prep {t['prep']:.1f} s, device {t['search']:.1f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
