#!/usr/bin/env python
"""Fisher–Rao geodesics on an accelerator against the compiled CPU path, in one run on one machine.

One prepared command for a machine with a GPU (it needs nothing but shapelib with its ``gpu``
extra, ``pip install "shapelib[gpu]"``, and the datasets, which it reads through
``SHAPELIB_DATA_DIR`` or the package's cache); it refuses in one line when JAX sees no GPU:

    python benchmarks/bench_gpu.py                 # ≤ 5 minutes on a GPU; writes docs/_data/benchmarks/bench_gpu.json
    python benchmarks/bench_gpu.py --cpu-check     # a tiny version on JAX's CPU backend (a test runs it)

Rows (Fisher–Rao, ``backend="cpu"``: the compiled Levenberg–Marquardt solver; ``backend="jax"``:
the same discrete energy by L-BFGS on the device, :mod:`shapelib.solver.batched`):

* ``geodesic``: the corpus callosum pair 1–2 of the speed targets (K = 63, σ² = 0.5, centroid size
  20, n_steps = 16, default tol) on the CPU path, and per geodesic on the device in a batch of 1 and
  of ``--batch`` (128) corpus callosum pairs; the lengths of the pairs solved on both paths;
* ``brackets``: certified brackets (rtol 1e-3) of the same ``--batch`` pairs on the device
  (:func:`shapelib.distance_brackets`), pairs per second and the fraction certified, against
  :func:`shapelib.distance_bracket` on the CPU for a few of them;
* ``matrix``: the Fisher–Rao certified-bracket matrix of the 180-shape balanced ADHD-200 subset
  (diagnosis × sex, seed 0, centroid size 20, σ² = 1.2 as in the study: 16,110 pairs), as much of it as
  fits ``--budget`` seconds, extrapolated to the whole subset and to all 647 shapes (208,981 pairs).

Compilation (the first call of each program) is timed apart from the rates. Not a test: the numbers
depend on the machine; the record carries the device's name, the machine and the date.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._machine import loadavg, record  # noqa: E402

PAIRS_180 = 180 * 179 // 2
PAIRS_647 = 647 * 646 // 2


def _refuse(message: str) -> int:
    print(f"bench_gpu: {message}", file=sys.stderr)
    return 2


def _device_info(jax, platform):
    dev = jax.devices(platform)[0]
    return {"platform": dev.platform, "device_kind": getattr(dev, "device_kind", str(dev)), "name": str(dev),
            "count": len(jax.devices(platform)), "jax": jax.__version__}


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _cc(args):
    import shapelib
    from shapelib.datasets import load_corpus_callosum
    shapes, ids = load_corpus_callosum()
    x = shapelib.to_centroid_size(shapes)
    order = [list(ids).index(1), list(ids).index(2)] + [i for i in range(len(x)) if ids[i] not in (1, 2)]
    x = x[order]
    if args.cpu_check:
        x = x[:, ::9]  # 7 landmarks
    pairs = list(itertools.combinations(range(len(x)), 2))[: args.batch]
    return x, pairs


def _adhd(args):
    import pandas as pd

    import shapelib
    from shapelib.datasets import load_adhd200
    from shapelib.study import stratified_sample
    raw, clinical = load_adhd200()
    labels = pd.DataFrame({"diagnosis": np.where(clinical["phenotype"].to_numpy() == 0, "TD", "ADHD"),
                           "sex": clinical["gender"].astype(int).astype(str).to_numpy()})
    cells = [(labels.diagnosis.to_numpy() == d) & (labels.sex.to_numpy() == s) for d in ("TD", "ADHD") for s in ("0", "1")]
    sel = stratified_sample(np.arange(len(raw)), 180, cells, np.random.default_rng(0))
    x = raw[sel]
    if args.cpu_check:
        x = x[:3, ::10]  # 3 shapes of 5 landmarks
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return shapelib.to_centroid_size(x)  # GPA over the analysed shapes, as the study does


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cpu-check", action="store_true", help="a tiny version on JAX's CPU backend (no GPU needed)")
    ap.add_argument("--batch", type=int, default=None, help="pairs of the batched rows (default 128; 4 with --cpu-check)")
    ap.add_argument("--budget", type=float, default=None,
                    help="seconds for the ADHD-200 matrix row (default 80; 10 with --cpu-check)")
    ap.add_argument("--cpu-pairs", type=int, default=None, help="pairs solved on the CPU path (default 3)")
    ap.add_argument("--json", type=Path, default=None,
                    help="write the record here (default on a GPU: docs/_data/benchmarks/bench_gpu.json; "
                         "--cpu-check writes only with --json)")
    args = ap.parse_args(argv)
    args.batch = args.batch or (2 if args.cpu_check else 128)
    args.budget = args.budget if args.budget is not None else (10.0 if args.cpu_check else 80.0)
    args.cpu_pairs = args.cpu_pairs or (2 if args.cpu_check else 3)
    try:
        import jax
    except ImportError:
        return _refuse('JAX is not installed: pip install "shapelib[gpu]" on a CUDA 12 machine '
                       '(or "shapelib[jax]" for --cpu-check)')
    if args.cpu_check:
        platform, device = "cpu", "cpu"
    else:
        try:
            gpus = jax.devices("gpu")
        except RuntimeError:
            gpus = []
        if not gpus:
            return _refuse(f"no GPU visible to JAX {jax.__version__} (devices: {', '.join(map(str, jax.devices()))}); "
                           'run it on a CUDA 12 machine with pip install "shapelib[gpu]", or --cpu-check for the tiny CPU version')
        platform, device = "gpu", "gpu"

    import shapelib
    from shapelib.solver.batched import batched_geodesics

    info = _device_info(jax, platform)
    sigma2, n_steps = 0.5, (4 if args.cpu_check else 16)
    print(f"bench_gpu{' --cpu-check' if args.cpu_check else ''}: {info['device_kind']} ({info['name']}), "
          f"JAX {jax.__version__}, {os.cpu_count()} CPU cores [load {loadavg()}]")
    report = {"mode": "cpu-check" if args.cpu_check else "gpu", "device": info, "cpus": os.cpu_count(),
              "sigma2": sigma2, "n_steps": n_steps, "batch": args.batch, "rows": {}}
    rows = report["rows"]
    record_to = args.json if args.json is not None else (None if args.cpu_check else "default")
    argv_used = sys.argv[1:] if argv is None else list(argv)

    def save(final=False):
        # after every row, so that a run stopped at its time limit keeps the rows it measured
        report["complete"] = final
        if record_to is not None:
            return record("bench_gpu", report, argv=argv_used, path=None if record_to == "default" else record_to)

    warnings.simplefilter("ignore", shapelib.GeodesicWarning)
    warnings.simplefilter("ignore", shapelib.ScaleWarning)

    # --- one Fisher–Rao geodesic: CPU path, device batch 1, device batch B -------------------------
    x, pairs = _cc(args)
    k = x.shape[1]
    if args.cpu_check:  # few landmarks: σ at 2.6 landmark spacings, as the study chooses it
        sigma2 = report["sigma2"] = float(f"{(2.6 * shapelib.landmark_spacing(x)) ** 2:.2g}")
    kw = dict(metric="fisher_rao", sigma2=sigma2, n_steps=n_steps)
    shapelib.geodesic(x[0][:3], x[1][:3], metric="fisher_rao", sigma2=sigma2, n_steps=2)  # numba kernels load
    cpu = []
    for i, j in pairs[: args.cpu_pairs]:
        r, s = _timed(lambda: shapelib.geodesic(x[i], x[j], **kw))
        cpu.append((r, s))
    cpu_s = float(np.median([s for _, s in cpu]))
    us, vs = x[[i for i, _ in pairs]], x[[j for _, j in pairs]]
    _, compile1 = _timed(lambda: batched_geodesics(us[:1], vs[:1], **kw, device=device))
    one, s1 = _timed(lambda: batched_geodesics(us[:1], vs[:1], **kw, device=device))
    _, compile_b = _timed(lambda: batched_geodesics(us, vs, **kw, device=device))
    many, sb = _timed(lambda: batched_geodesics(us, vs, **kw, device=device))
    rows["geodesic"] = [{"pair": [int(i), int(j)], "lower": r.lower_bound, "length_cpu": r.length,
                         "length_jax": many[p].length, "iterations_cpu": r.n_iter, "iterations_jax": many[p].n_iter,
                         "cpu_seconds": s} for p, ((i, j), (r, s)) in enumerate(zip(pairs, cpu))]
    rows["geodesic_timing"] = {
        "K": int(k), "cpu_seconds_per_geodesic": cpu_s, "jax_batch1_seconds": s1, "jax_batch1_iterations": one[0].n_iter,
        "jax_batch_seconds": sb, "jax_batch_pairs": len(pairs), "jax_seconds_per_geodesic": sb / len(pairs),
        "speedup_batch1": cpu_s / s1, "speedup_batch": cpu_s / (sb / len(pairs)),
        "jax_batch_converged": sum(r.converged for r in many), "compile_seconds": {"batch1": compile1 - s1,
                                                                                   "batch": compile_b - sb},
        "max_rel_length_difference": max(abs(row["length_jax"] / row["length_cpu"] - 1) for row in rows["geodesic"])}
    g = rows["geodesic_timing"]
    print(f"FR geodesic, CC K = {k}, sigma2 = {sigma2}, n_steps = {n_steps}: CPU {cpu_s:.3g} s; "
          f"{platform} batch 1 {s1:.3g} s ({cpu_s / s1:.3g}x); batch {len(pairs)} {sb:.3g} s = "
          f"{sb / len(pairs) * 1e3:.3g} ms per geodesic ({g['speedup_batch']:.3g}x); "
          f"lengths agree to {g['max_rel_length_difference']:.1e}")

    save()

    # --- certified brackets ------------------------------------------------------------------------
    # --cpu-check: one level at the geodesics' n_steps and grid, so the programs compiled above serve
    # (each n_steps, batch size and grid size is another compiled program)
    small = dict(n_steps=n_steps, max_n_steps=n_steps, grid_spacing=0.35) if args.cpu_check else {}
    bkw = dict(metric="fisher_rao", sigma2=sigma2, rtol=1e-3, **small)
    _, b_compile = _timed(lambda: shapelib.distance_brackets(us, vs, **bkw, device=device))
    brs, bs = _timed(lambda: shapelib.distance_brackets(us, vs, **bkw, device=device))
    cpu_b = [_timed(lambda: shapelib.distance_bracket(us[p], vs[p], **bkw)) for p in range(args.cpu_pairs)]
    cpu_bs = sum(s for _, s in cpu_b)
    rows["brackets"] = {"pairs": len(brs), "rtol": 1e-3, "seconds": bs, "pairs_per_second": len(brs) / bs,
                        "certified_rate": float(np.mean([b.converged for b in brs])),
                        "stopped_by": {w: sum(b.stopped_by == w for b in brs) for w in {b.stopped_by for b in brs}},
                        "cpu_pairs": len(cpu_b), "cpu_pairs_per_second": len(cpu_b) / cpu_bs,
                        "cpu_certified_rate": float(np.mean([b.converged for b, _ in cpu_b])),
                        "contains_cpu_upper": all(brs[p].lower <= b.upper for p, (b, _) in enumerate(cpu_b)),
                        "warmup_seconds": b_compile}
    b = rows["brackets"]
    print(f"FR brackets (rtol 1e-3), {b['pairs']} CC pairs: {platform} {b['pairs_per_second']:.3g} pairs/s, "
          f"certified {b['certified_rate']:.1%}; CPU {b['cpu_pairs_per_second']:.3g} pairs/s on {b['cpu_pairs']}")

    save()

    # --- a batch of --batch Fisher–Rao geodesics of ADHD-200 pairs (the corpus callosum has only 21) --
    xa = _adhd(args)
    s2a = float(f"{(2.6 * shapelib.landmark_spacing(xa)) ** 2:.2g}") if args.cpu_check else 1.2
    all_pairs = list(itertools.combinations(range(len(xa)), 2))
    ii = np.array(all_pairs)
    gp = ii[: args.batch]
    akw = dict(metric="fisher_rao", sigma2=s2a, n_steps=n_steps)
    cpu_a = [_timed(lambda: shapelib.geodesic(xa[i], xa[j], **akw)) for i, j in gp[: min(2, args.cpu_pairs)]]
    _, a_compile = _timed(lambda: batched_geodesics(xa[gp[:, 0]], xa[gp[:, 1]], **akw, device=device))
    many_a, sa = _timed(lambda: batched_geodesics(xa[gp[:, 0]], xa[gp[:, 1]], **akw, device=device))
    cpu_as = float(np.median([t for _, t in cpu_a]))
    rows["geodesic_batch"] = {
        "data": "ADHD-200", "K": int(xa.shape[1]), "sigma2": s2a, "pairs": len(gp), "seconds": sa,
        "seconds_per_geodesic": sa / len(gp), "converged": sum(r.converged for r in many_a),
        "iterations_max": max(r.n_iter for r in many_a), "cpu_pairs": len(cpu_a), "cpu_seconds_per_geodesic": cpu_as,
        "speedup": cpu_as / (sa / len(gp)), "compile_seconds": a_compile - sa,
        "max_rel_length_difference": max(abs(many_a[p].length / r.length - 1) for p, (r, _) in enumerate(cpu_a))}
    ga = rows["geodesic_batch"]
    print(f"FR geodesics, ADHD-200 K = {ga['K']}, sigma2 = {s2a}: batch {len(gp)} {sa:.3g} s = "
          f"{ga['seconds_per_geodesic'] * 1e3:.3g} ms per geodesic ({ga['converged']} converged); CPU {cpu_as:.3g} s "
          f"({ga['speedup']:.3g}x); lengths agree to {ga['max_rel_length_difference']:.1e}")
    save()

    # --- the 180-shape ADHD-200 matrix, as much as fits the budget --------------------------------
    mkw = dict(metric="fisher_rao", sigma2=s2a, rtol=1e-3, **small)
    chunk = len(all_pairs) if args.cpu_check else args.batch
    _, m_warm = _timed(lambda: shapelib.distance_brackets(xa[ii[:chunk, 0]], xa[ii[:chunk, 1]], **mkw, device=device))
    done, certified, t0 = 0, 0, time.perf_counter()
    while done < len(all_pairs) and time.perf_counter() - t0 < args.budget:
        block = ii[done:done + chunk]
        out = shapelib.distance_brackets(xa[block[:, 0]], xa[block[:, 1]], **mkw, device=device)
        certified += sum(r.converged for r in out)
        done += len(block)
    ms = time.perf_counter() - t0
    rate = done / ms
    rows["matrix"] = {"shapes": len(xa), "K": int(xa.shape[1]), "sigma2": s2a, "rtol": 1e-3, "pairs_total": len(all_pairs),
                      "pairs_done": done, "seconds": ms, "pairs_per_second": rate,
                      "certified_rate": certified / max(done, 1), "warmup_seconds": m_warm,
                      "extrapolated_hours_180": PAIRS_180 / rate / 3600, "extrapolated_hours_647": PAIRS_647 / rate / 3600}
    m = rows["matrix"]
    print(f"ADHD-200 FR bracket matrix ({m['shapes']} shapes, K = {m['K']}, sigma2 = {s2a}): {done} of {len(all_pairs)} "
          f"pairs in {ms:.3g} s ({rate:.3g} pairs/s, certified {m['certified_rate']:.1%}); "
          f"extrapolated: 180 shapes {m['extrapolated_hours_180']:.3g} h, 647 shapes {m['extrapolated_hours_647']:.3g} h")

    written = save(final=True)
    if written is not None:
        print(f"record: {written}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
