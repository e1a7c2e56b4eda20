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

With ``--registration`` it measures instead the registration distance
(``pairwise_distances(..., metric="registration")``, :func:`shapelib.pointsets.registration_distance.registration_distance`):

* the rate of :func:`shapelib.register` on ``--rate-pairs`` random pairs of the outlines (both
  directions each, in this process, one BLAS thread), and the projected core-hours of the full
  matrix (979,300 pairs, 1.96 M registrations) and of each query's ``--shortlist`` rigid nearest;
* unless ``--rate-only``: the matrix itself on the rigid shortlist, through the engine (``--workers``
  local processes, resumable from ``--store``: rerun the same command to continue), with the
  bull's-eye of the rigid bound and of the registration distance, raw and re-ranked
  (:func:`shapelib.rerank`, ``--rerank-k``, ``--rerank-mu``), in separate columns.

With ``--full --scores`` it computes every full-test figure the retrieval guide quotes, in one run, on
all 1,400 shapes (no engine, one process): the Fisher–Rao and α bound matrices modulo similarity at
σ² = 0.0025, 0.005, 0.01, 0.02 and 0.04 (100 points; spectra and pair search timed apart), the
Fisher–Rao bound with 200 points at σ² = 0.0025 and 0.005, Procrustes on the outlines, and for the
Fisher–Rao bound at σ² = 0.005 and 0.01 the bull's-eye raw and re-ranked (:func:`shapelib.rerank`,
``tpg`` k = 8, μ = 1.2, 20 steps; ``lcdp`` k = 10, μ = 0.8, 10 steps: the parameters chosen on classes
1–35) on all 70 classes and on classes 1–35 and 36–70 (each half its own collection, in the order of
:func:`shapelib.datasets.mpeg7_classes`), with the time of each re-ranking of the full matrix (one
BLAS thread). Recorded in ``bench_retrieval_full.json`` beside the subset record.

Not a test: numbers depend on the machine and its load (recorded).

    python benchmarks/bench_retrieval.py [--classes 20] [--full] [--sigma2 0.01] [--record]
    python benchmarks/bench_retrieval.py --full --scores --record
    python benchmarks/bench_retrieval.py --registration --rate-only --rate-pairs 150
    python benchmarks/bench_retrieval.py --registration --full --shortlist 80 --workers 16 --store reg.zarr
    python benchmarks/bench_retrieval.py --registration --full --backend jax --store reg.zarr   # a GPU machine

``--backend jax`` batches the registrations on the JAX device (:func:`shapelib.register_many`): the
rate over all ``--rate-pairs`` pairs in one batch, and the engine's blocks one batch each.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._machine import RECORD_DIR, loadavg, record  # noqa: E402

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
    ap.add_argument("--scores", action="store_true",
                    help="every full-test score the retrieval guide quotes: both bounds at five σ², 200 points, "
                         "Procrustes, raw and re-ranked on all classes and on each half (see above)")
    ap.add_argument("--registration", action="store_true", help="the registration distance instead (see above)")
    ap.add_argument("--rate-pairs", type=int, default=100, help="pairs timed for the rate (both directions each)")
    ap.add_argument("--rate-only", action="store_true", help="only the rate and the projections")
    ap.add_argument("--shortlist", type=int, default=80,
                    help="rigid nearest registered per query (0: all pairs); the bull's-eye counts the 40 nearest as a "
                         "set, so a shortlist of 40 or fewer only reorders them and cannot change the raw score")
    ap.add_argument("--store", default=None, help="zarr store of the registration matrix (resumable)")
    ap.add_argument("--backend", choices=("numpy", "jax"), default="numpy",
                    help="registrations one by one (numpy) or batched on the JAX device (jax: a GPU when JAX sees one)")
    ap.add_argument("--prepare", metavar="DIR", default=None,
                    help="write what bench_retrieval_device.py reads into DIR: the outlines, the rigid bound, "
                         "every pair in the order of its shortlist rank (see below)")
    ap.add_argument("--from-device", metavar="RUN", nargs="+", default=None,
                    help="score the registration matrix that bench_retrieval_device.py runs wrote (their --out "
                         "folders, in order; the last holds every pair done), with --prepare's DIR as --prepared")
    ap.add_argument("--prepared", metavar="DIR", default=None, help="the --prepare folder the runs read")
    ap.add_argument("--rerank-k", type=int, default=None,
                    help="--registration: re-rank with this k (and --rerank-mu) for both methods instead of the "
                         "parameters chosen on the rigid bound's classes 1–35 (FULL_RERANK)")
    ap.add_argument("--rerank-mu", type=float, default=None)
    args = ap.parse_args(argv)
    if args.prepare:
        return prepare_device(args)
    if args.from_device:
        return from_device(args)
    if args.registration:
        return registration(args)
    if args.scores:
        return scores(args)
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


#: the re-ranking parameters chosen on MPEG-7 classes 1–35 (bull's-eye of the rigid Fisher–Rao bound)
FULL_RERANK = {"tpg": {"k": 8, "mu": 1.2, "n_iter": 20}, "lcdp": {"k": 10, "mu": 0.8, "n_iter": 10}}


def class_halves(labels, classes) -> dict:
    """Each half of ``classes`` (in their order), to be scored as its own collection:
    ``{"classes 1–35": indices of its shapes in labels, "classes 36–70": ...}``."""
    labels, half = np.asarray(labels), len(classes) // 2
    return {f"classes 1–{half}": np.flatnonzero(np.isin(labels, classes[:half])),
            f"classes {half + 1}–{len(classes)}": np.flatnonzero(np.isin(labels, classes[half:]))}


def bullseye_results(D, labels, rerank=FULL_RERANK) -> dict:
    """The bull's-eye results (value and per class) of ``D``, raw and re-ranked by each method of ``rerank``
    (``{method: parameters}``): ``{"raw": result, method: result, ...}``, each re-ranking computed once."""
    return {"raw": sl.bullseye(D, labels),
            **{m: sl.bullseye(sl.rerank(D, method=m, **kw), labels) for m, kw in rerank.items()}}


def values_of(results: dict, prefix: str = "") -> dict:
    """The values of :func:`bullseye_results`, the re-ranked ones keyed ``prefix + method``."""
    return {("" if m == "raw" else prefix) + m: r.value for m, r in results.items()}


def bullseye_scores(D, labels, rerank=FULL_RERANK, prefix: str = "") -> dict:
    """The bull's-eye of ``D``, raw and re-ranked by each method of ``rerank`` (``{method: parameters}``),
    the re-ranked ones keyed ``prefix + method``."""
    return values_of(bullseye_results(D, labels, rerank), prefix)


#: σ² of the sweep (of each outline's RMS radius²); the re-ranked ones; the 200-point ones
FULL_SIGMA2 = (0.0025, 0.005, 0.01, 0.02, 0.04)
FULL_RERANKED = (0.005, 0.01)
FULL_200_POINTS = (0.0025, 0.005)


def scores(args) -> int:
    """``--scores``: every full-test figure the retrieval guide quotes (module docstring)."""
    from benchmarks._machine import RECORD_DIR

    every = mpeg7_classes()
    classes = every if args.full else [every[i] for i in np.round(np.linspace(0, 69, args.classes)).astype(int)]
    res = full_scores(classes, points=args.points, partial=Path("/tmp") / "bench_retrieval_scores.json"
                      if args.full else None)
    if args.record:
        print("recorded", record("bench_retrieval", res, path=RECORD_DIR / "bench_retrieval_full.json"))
    return 0


def full_scores(classes, *, points: int = 100, per_class: int | None = None, partial: Path | None = None) -> dict:
    """The ``--scores`` results on these MPEG-7 classes (``per_class``: their first shapes only, for a smoke
    test; ``partial``: a file rewritten after each matrix)."""
    import json

    from shapelib.solver.linalg import one_blas_thread

    res = {"loadavg_start": loadavg(), "mode": "scores", "classes": len(classes), "points": points}
    with Clock() as c:
        data = load_mpeg7(classes=classes, n_points=points, per_class=per_class)
    outlines, labels = list(data.shapes), np.asarray(data.labels)
    n = len(outlines)
    halves = class_halves(labels, classes)
    res.update(n_shapes=n, pairs=n * (n - 1) // 2, trace={"wall": c.wall, "cpu": c.cpu}, rerank=FULL_RERANK,
               rerank_chosen_on=next(iter(halves)), halves=list(halves))
    print(f"{n} outlines ({len(classes)} classes) traced in {c.wall:.1f} s wall, {c.cpu:.1f} s CPU", flush=True)

    def save():
        if partial is not None:
            partial.write_text(json.dumps(res, indent=1))

    def matrix(xs, metric, sigma2):
        row = {"metric": metric, "sigma2": sigma2, "points": len(xs[0])}
        with Clock() as c:
            sp = inv.polar_spectra(xs, sigma2=sigma2, kind=inv.spectrum_kind(metric))
        row["spectra"] = {"wall": c.wall, "cpu": c.cpu, "rings": sp.coefficients.shape[1],
                          "frequencies": sp.coefficients.shape[2]}
        with Clock() as c:
            D = inv.distances_from_spectra(xs, sp, metric=metric, exact=False)
        row["search"] = {"wall": c.wall, "cpu": c.cpu}
        row["cpu"] = row["spectra"]["cpu"] + row["search"]["cpu"]
        row["raw"] = sl.bullseye(D, labels).value
        print(f"{metric}, σ² = {sigma2}, {row['points']} points: {row['spectra']['cpu']:.1f} s CPU spectra + "
              f"{row['search']['cpu']:.1f} s CPU pairs; bull's-eye {100 * row['raw']:.2f} %", flush=True)
        return row, D

    xs = [inv.normalise_points(o)[0] for o in outlines]
    sweep = []
    res["sweep"] = sweep
    for metric in ("fisher_rao_bound", "alpha_bound"):
        for sigma2 in FULL_SIGMA2:
            row, D = matrix(xs, metric, sigma2)
            if metric == "fisher_rao_bound" and sigma2 in FULL_RERANKED:
                row["reranked"] = {}
                for method, kw in FULL_RERANK.items():
                    with Clock() as c, one_blas_thread():
                        R = sl.rerank(D, method=method, **kw)
                    row["reranked"][method] = {"all": sl.bullseye(R, labels).value, "wall": c.wall, "cpu": c.cpu}
                row["halves"] = {name: bullseye_scores(D[np.ix_(idx, idx)], labels[idx]) for name, idx in halves.items()}
                print(f"  re-ranked: {row['reranked']}; halves: {row['halves']}", flush=True)
            sweep.append(row)
            save()
    if points != 200:
        xs200 = [inv.normalise_points(o)[0] for o in load_mpeg7(classes=classes, n_points=200, per_class=per_class).shapes]
        res["points_200"] = [matrix(xs200, "fisher_rao_bound", sigma2)[0] for sigma2 in FULL_200_POINTS]
        save()
    with Clock() as c:
        P = sl.procrustes_outline_matrix(np.stack(outlines))
    res["procrustes"] = {"wall": c.wall, "cpu": c.cpu, "raw": sl.bullseye(P, labels).value}
    print(f"procrustes: {c.cpu:.1f} s CPU, bull's-eye {100 * res['procrustes']['raw']:.2f} %")
    res["loadavg_end"] = loadavg()
    save()
    return res


def registration(args) -> int:
    """``--registration``: the rate of the registrations, the projections, the shortlisted matrix."""
    from shapelib.pairwise._pointsets import fill_off_shortlist
    from shapelib.pointsets.registration_distance import ENERGY_WEIGHT, registration_misfits_many
    from shapelib.rerank import RERANK_METHODS
    from shapelib.solver.linalg import one_blas_thread

    every = mpeg7_classes()
    classes = every if args.full else [every[i] for i in np.round(np.linspace(0, 69, args.classes)).astype(int)]
    res = {"loadavg_start": loadavg(), "classes": len(classes), "points": args.points, "mode": "registration",
           "backend": args.backend}
    if args.backend == "jax":
        from benchmarks.bench_registration_batch import _device_info

        res["device"] = _device_info(None)
    data = load_mpeg7(classes=classes, n_points=args.points)
    outlines, labels = list(data.shapes), data.labels
    n = len(outlines)
    rng = np.random.default_rng(0)
    pairs = [tuple(rng.choice(n, size=2, replace=False)) for _ in range(args.rate_pairs)]
    if args.backend == "jax":  # compile the batch's programs outside the timing
        registration_misfits_many([(outlines[i], outlines[j]) for i, j in pairs[:2]], backend="jax")
    # on one core, as in a Dask worker (register's search then runs in one thread; on more cores it would
    # spread over them and its CPU time would count the threads' overhead too)
    cpus = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cpus)})
    try:
        with Clock() as c, one_blas_thread():
            out = registration_misfits_many([(outlines[i], outlines[j]) for i, j in pairs], backend=args.backend)
    finally:
        os.sched_setaffinity(0, cpus)
    n_iter = [m[3] for m in out]
    not_converged = sum(not m[2] for m in out)
    # CPU seconds (one thread: BLAS on one, no other work in this process) are what a loaded machine cannot
    # inflate; the wall time is recorded beside them
    per = c.cpu / (2 * len(pairs))
    rate = {"pairs": len(pairs), "registrations": 2 * len(pairs), "wall": c.wall, "cpu": c.cpu,
            "cpu_seconds_per_registration": per, "wall_seconds_per_registration": c.wall / (2 * len(pairs)),
            "registrations_per_cpu_second": 1 / per,
            "em_iterations_per_pair_median": float(np.median(n_iter)), "pairs_not_converged": not_converged}
    full_regs = 2 * 1400 * 1399 // 2
    rate["full_core_hours"] = full_regs * per / 3600
    if args.shortlist:  # the symmetric shortlist holds between N·K/2 and N·K pairs; N·K is the bound used
        rate["shortlist_core_hours_at_most"] = 2 * 1400 * args.shortlist * per / 3600
    res["rate"] = rate
    print(f"register, {args.points} points: {len(pairs)} pairs × 2 directions in {c.wall:.1f} s wall "
          f"({c.cpu:.1f} s CPU): {1e3 * per:.0f} ms CPU per registration, {1 / per:.2f} per second on one free core "
          f"(median {np.median(n_iter):.0f} EM iterations per pair, both directions; {not_converged} pairs with an EM "
          f"stopped at max_iter); "
          f"full MPEG-7 both directions ≈ {rate['full_core_hours']:.0f} core-hours"
          + (f", shortlist {args.shortlist} ≤ {rate['shortlist_core_hours_at_most']:.1f} core-hours" if args.shortlist else ""))
    if not args.rate_only:
        with Clock() as c:
            r = sl.pairwise_distances(outlines, metric="registration", n_jobs=args.workers, store=args.store,
                                      return_result=True, backend=args.backend,
                                      **({"shortlist": args.shortlist, "shortlist_sigma2": args.sigma2}
                                         if args.shortlist else {}))
        # the registrations' own seconds, summed over the pairs as each was computed (in this run or an earlier one
        # that wrote the store): what the matrix cost, whichever run computed it
        upper = np.triu(np.where(np.isfinite(r.seconds), r.seconds, 0.0), 1)
        res["matrix"] = {"wall": c.wall, "summary": r.summary(), "pair_seconds": float(upper.sum()),
                         "log": {k: v for k, v in r.log.items() if isinstance(v, (int, float, str, dict))}}
        print(r.summary(), f"({c.wall:.0f} s wall)")
        rigid = sl.pairwise_distances(outlines, metric="fisher_rao_bound", modulo="similarity", sigma2=args.sigma2,
                                      store=None if args.store is None else f"{args.store}.shortlist", progress=False)
        if args.rerank_k is None and args.rerank_mu is None:
            kws = FULL_RERANK
        else:
            kws = {m: {"k": args.rerank_k or 10, "mu": args.rerank_mu or 0.8} for m in RERANK_METHODS}
        # the product of the two on the registered pairs (chosen on classes 1–35 among eight combinations of the GPU
        # run's matrix, DEVICE_COMBINE), the pairs off the shortlist after them in the rigid bound's order
        off = ~np.isfinite(r.upper)
        product = fill_off_shortlist(np.where(off, np.inf, r.matrix * rigid), rigid)[0]
        results = {name: bullseye_results(d, labels, kws)
                   for name, d in (("rigid fisher_rao_bound", rigid), ("registration", r.matrix),
                                   ("registration × rigid bound", product))}
        table = {name: values_of(res_, "re-ranked ") for name, res_ in results.items()}
        # per class (raw and LCDP; the same re-ranked matrix as the table's), and each half of the classes scored as
        # its own collection (the registration distance's energy weight was chosen on ten classes among 1–35:
        # 36–70 is the held-out half)
        per_class = {"raw": results["registration"]["raw"].per_class,
                     "lcdp": results["registration"]["lcdp"].per_class}
        lab = np.asarray(labels)
        halves = {name: bullseye_scores(r.matrix[np.ix_(idx, idx)], lab[idx], kws, "re-ranked ")
                  for name, idx in class_halves(lab, classes).items()}
        res["bullseye"] = {"table": table, "rerank": kws, "per_class": per_class, "halves": halves,
                           "energy_weight": ENERGY_WEIGHT,
                           **({"rerank_chosen_on": "the rigid bound, classes 1–35"} if kws is FULL_RERANK else {})}
        print(f"bull's-eye ({n} shapes; re-ranking {kws}):")
        for name, row in table.items():
            print(f"  {name:24s} " + "  ".join(f"{col} {100 * v:.2f} %" for col, v in row.items()))
    res["loadavg_end"] = loadavg()
    if args.record:
        print("recorded", record("bench_retrieval", res, path=RECORD_DIR / "bench_retrieval_registration.json"))
    return 0


def _full_outlines(points):
    """The 1,400 MPEG-7 outlines and their labels, as every full-test figure uses them."""
    data = load_mpeg7(classes=mpeg7_classes(), n_points=points)
    return np.stack([np.asarray(o, dtype=np.float64) for o in data.shapes]), np.asarray(data.labels)


def shortlist_order(rigid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pair ``i < j`` ordered by its shortlist rank ``min(r_i(j), r_j(i))`` (``r_i(j)``: the place of
    ``j`` in row ``i`` of the rigid matrix, nearest 0; ties by ``i``, then ``j``), and those ranks. The
    pairs of rank below ``k`` are the pairs of ``pairwise_distances(..., shortlist=k)``, so every prefix
    of the order that ends where the rank changes is a shortlist."""
    n = len(rigid)
    r = np.array(rigid, dtype=np.float64)
    np.fill_diagonal(r, np.inf)
    place = np.empty((n, n), dtype=np.int64)
    place[np.arange(n)[:, None], np.argsort(r, axis=1, kind="stable")] = np.arange(n)[None, :]
    iu, ju = np.triu_indices(n, 1)
    rank = np.minimum(place, place.T)[iu, ju]
    order = np.lexsort((ju, iu, rank))
    return np.column_stack([iu[order], ju[order]]).astype(np.int32), rank[order].astype(np.int32)


def prepare_device(args) -> int:
    """``--prepare DIR``: the inputs of ``bench_retrieval_device.py`` (module docstring of that script)."""
    out = Path(args.prepare)
    out.mkdir(parents=True, exist_ok=True)
    outlines, labels = _full_outlines(args.points)
    with Clock() as c:
        rigid = sl.pairwise_distances(list(outlines), metric="fisher_rao_bound", modulo="similarity",
                                      sigma2=args.sigma2, n_jobs=args.workers, progress=False)
    pairs, rank = shortlist_order(rigid)
    for name, a in (("outlines", outlines), ("labels", labels), ("rigid", rigid), ("pairs", pairs),
                    ("pair_rank", rank)):
        np.save(out / f"{name}.npy", a)
    print(f"{len(outlines)} outlines, the rigid bound (σ² = {args.sigma2}) in {c.wall:.0f} s, {len(pairs):,} pairs "
          f"in shortlist order into {out}")
    return 0


#: the shortlist of the registration matrix that the retrieval guide reports (the benchmark's default
#: before the full matrix was run); the others are shown beside it
DEVICE_SHORTLIST = 80

#: how a pair's two directed misfits ``v`` (n, 2) and its rigid bound ``r`` become one dissimilarity; the
#: normalising medians are over the pairs registered (scale-free sums)
DEVICE_COMBINE = {
    "misfit": lambda v, r: v.mean(axis=1),  # registration_distance, combine="mean"
    "misfit max": lambda v, r: v.max(axis=1),  # combine="max"
    "misfit geometric": lambda v, r: np.sqrt(v[:, 0] * v[:, 1]),
    "misfit × rigid": lambda v, r: v.mean(axis=1) * r,
    "misfit + rigid": lambda v, r: v.mean(axis=1) / np.median(v.mean(axis=1)) + r / np.median(r),
    "misfit + rigid/2": lambda v, r: v.mean(axis=1) / np.median(v.mean(axis=1)) + 0.5 * r / np.median(r),
    "misfit + 2 rigid": lambda v, r: v.mean(axis=1) / np.median(v.mean(axis=1)) + 2 * r / np.median(r),
    "√misfit + rigid": lambda v, r: np.sqrt(v.mean(axis=1) / np.median(v.mean(axis=1))) + r / np.median(r),
}


def from_device(args) -> int:
    """``--from-device RUN ...``: the registration matrix of the device runs, scored and recorded."""
    import json

    from benchmarks._machine import RECORD_DIR
    from shapelib.pairwise._pointsets import fill_off_shortlist

    if args.prepared is None:
        raise SystemExit("--from-device needs --prepared DIR (the folder the runs read)")
    prep = Path(args.prepared)
    labels = np.load(prep / "labels.npy", allow_pickle=False)
    rigid, pairs, rank = (np.load(prep / f"{name}.npy") for name in ("rigid", "pairs", "pair_rank"))
    last = Path(args.from_device[-1])
    state = np.load(last / "progress.npz")
    done = int(state["done"])
    misfits = np.load(last / "misfits.npy")[:done]
    n = len(labels)
    complete = int(rank[done]) if done < len(rank) else n - 1  # every pair of rank below this is done
    runs = []
    for run in args.from_device:
        log = json.loads((Path(run) / "log.json").read_text())
        chunks = log["chunks"]
        timed = chunks[1:]  # the first chunk compiles the programs
        regs = 2 * sum(c["pairs"] for c in timed)
        runs.append({"date": log["date"], "command": log.get("argv"), "device": log["device"],
                     "batch_size": log["batch_size"],
                     "resumed_from": log["resumed_from"], "done": log["done"], "wall": log["wall_total"],
                     "first_chunk": {"pairs": chunks[0]["pairs"], "wall": chunks[0]["wall"]},
                     "registrations_per_second": regs / sum(c["wall"] for c in timed),
                     "device_share": sum(c["search"] for c in timed) / sum(c["wall"] for c in timed),
                     **({"check": log["check"]} if "check" in log else {})})
    rate = float(np.mean([r["registrations_per_second"] for r in runs]))
    res = {"mode": "registration on a device", "n_shapes": n, "points": int(np.load(prep / "outlines.npy").shape[1]),
           "shortlist_sigma2": args.sigma2, "runs": runs, "pairs_done": done, "registrations": 2 * done,
           "complete_shortlist": complete, "pairs_converged": float(state["ok"].mean()),
           "registrations_per_second": rate, "full_matrix_seconds": 2 * len(pairs) / rate,
           "rerank": FULL_RERANK, "rerank_chosen_on": "the rigid bound, classes 1–35",
           "reported_shortlist": DEVICE_SHORTLIST}
    halves = class_halves(labels, mpeg7_classes())

    def on_halves(D):
        return {name: bullseye_scores(D[np.ix_(i, i)], labels[i]) for name, i in halves.items()}

    def scored(D, results=None):
        return {**values_of(bullseye_results(D, labels) if results is None else results), "halves": on_halves(D)}

    rigid_results = bullseye_results(rigid, labels)
    res["rigid"] = scored(rigid, rigid_results)

    def matrix(k, combine):
        sel = rank[:done] < k
        i, j = pairs[:done][sel].T
        D = np.full((n, n), np.inf)
        np.fill_diagonal(D, 0.0)
        D[i, j] = D[j, i] = combine(misfits[sel], rigid[i, j])
        return fill_off_shortlist(D, rigid)[0], int(sel.sum())

    res["shortlists"] = []
    for k in sorted({40, DEVICE_SHORTLIST, 160, complete}):
        D, count = matrix(k, DEVICE_COMBINE["misfit"])
        results = bullseye_results(D, labels)
        row = {"k": k, "pairs": count, **scored(D, results)}
        if k == DEVICE_SHORTLIST:
            per, lc = results["raw"].per_class, results["lcdp"].per_class
            rig = rigid_results["raw"].per_class
            res["per_class"] = {str(c): {"raw": per[c], "lcdp": lc[c], "rigid": rig[c]} for c in per}
        res["shortlists"].append(row)
        print(f"shortlist {k} ({row['pairs']:,} pairs): bull's-eye raw {100 * row['raw']:.2f} %, "
              f"tpg {100 * row['tpg']:.2f} %, lcdp {100 * row['lcdp']:.2f} %", flush=True)
    # the misfit with the rigid bound: every combination at three shortlists scored on each half; the one
    # of largest bull's-eye on the first half (raw, and re-ranked by LCDP) reported on the second
    first, second = list(halves)
    combos = [{"k": k, "combine": name, "halves": on_halves(matrix(k, combine)[0])}
              for k in sorted({DEVICE_SHORTLIST, 160, complete}) for name, combine in DEVICE_COMBINE.items()]
    res["combinations"] = combos
    res["chosen"] = {}
    for column in ("raw", "lcdp"):
        best = max(combos, key=lambda c: c["halves"][first][column])
        full = bullseye_scores(matrix(best["k"], DEVICE_COMBINE[best["combine"]])[0], labels)
        res["chosen"][column] = {"by": f"the largest {column} bull's-eye on {first}", "k": best["k"],
                                 "combine": best["combine"], "chosen_on": best["halves"][first],
                                 "reported_on": best["halves"][second], "all": full}
        print(f"chosen by {column} on {first}: {best['combine']}, shortlist {best['k']}: on {second} raw "
              f"{100 * best['halves'][second]['raw']:.2f} %, lcdp {100 * best['halves'][second]['lcdp']:.2f} %; "
              f"all 70 raw {100 * full['raw']:.2f} %, tpg {100 * full['tpg']:.2f} %, lcdp {100 * full['lcdp']:.2f} %")
    print(f"rigid bound: raw {100 * res['rigid']['raw']:.2f} %, tpg {100 * res['rigid']['tpg']:.2f} %, "
          f"lcdp {100 * res['rigid']['lcdp']:.2f} %; {done:,} pairs registered at {rate:.0f} per second "
          f"(full matrix ≈ {res['full_matrix_seconds'] / 60:.0f} min)")
    if args.record:
        print("recorded", record("bench_retrieval", res, path=RECORD_DIR / "bench_retrieval_device.json"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
