#!/usr/bin/env python
"""A part-aware registration distance on MPEG-7's articulated classes, beside the smooth one.

A smooth warp bends a limb only as far as its kernel allows; an articulated shape moves its parts
each with its own pose. This experiment splits each outline at its ``--parts`` most concave points
(the most negative turning angles of the counter-clockwise outline, over ±3 points, split points at least
an eighth of the outline apart) into arcs, registers every arc onto the whole other outline with its
own similarity pose (:func:`shapelib.register`, ``transform="similarity"``, mirror images searched,
the outlier weight the share of the target the arc does not cover, ``w = 1 − n_arc / n``), and takes
the mean of the arcs' EM σ² (both outlines at unit RMS radius) as the directed part misfit,
symmetrised by the mean of both directions. Nothing was tuned: the number of parts, the smoothing
and the outlier weight were set before the run.

Compared on the same shapes (``--per-class`` shapes of each of ``--classes``, default the six
articulated classes among the twelve worst under the rigid bound on the full test): the rigid
Fisher–Rao bound (σ² = 0.01), the smooth registration distance (``metric="registration"``), the part
misfit, and the mean of the two misfits, each by its bull's-eye (class-mates among each query's
``2 × per_class`` nearest). One process, the registrations one by one on the CPU.

    python benchmarks/bench_articulation.py [--per-class 6] [--parts 4] [--record]
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
from shapelib.datasets import load_mpeg7  # noqa: E402
from shapelib.pointsets.registration_distance import _unit, registration_misfits  # noqa: E402

#: the articulated classes among the twelve worst under the rigid bound on the full test
ARTICULATED = ("tree", "octopus", "lizzard", "fly", "beetle", "horse")


def split_at_concavities(x: np.ndarray, parts: int, smooth: int = 3) -> list[np.ndarray]:
    """Index arrays of the ``parts`` arcs of the closed outline ``x`` between its most concave points."""
    n = len(x)
    area = 0.5 * np.sum(x[:, 0] * np.roll(x[:, 1], -1) - np.roll(x[:, 0], -1) * x[:, 1])
    ccw = x if area > 0 else x[::-1]
    idx = np.arange(n) if area > 0 else np.arange(n)[::-1]
    a = ccw - np.roll(ccw, smooth, axis=0)  # arriving from the point `smooth` before
    b = np.roll(ccw, -smooth, axis=0) - ccw  # leaving for the point `smooth` after
    turn = np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.sum(a * b, axis=1))  # < 0: a right turn, concave
    cuts = []
    for i in np.argsort(turn, kind="stable"):
        if all(min(abs(i - c), n - abs(i - c)) >= n // 8 for c in cuts):
            cuts.append(int(i))
        if len(cuts) == parts:
            break
    cuts.sort()
    return [idx[np.arange(c, cuts[(k + 1) % len(cuts)] + (n if k + 1 == len(cuts) else 0)) % n]
            for k, c in enumerate(cuts)]


def part_misfit(x: np.ndarray, y: np.ndarray, parts: int) -> float:
    """Mean EM σ² of ``x``'s arcs, each registered onto the whole of ``y`` with its own similarity pose."""
    out = []
    for arc in split_at_concavities(x, parts):
        w = float(np.clip(1.0 - len(arc) / len(x), 0.05, 0.95))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sl.RegistrationWarning)
            out.append(sl.register(x[arc], y, transform="similarity", w=w, reflection=True).sigma2)
    return float(np.mean(out))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--classes", nargs="+", default=list(ARTICULATED))
    ap.add_argument("--per-class", type=int, default=6)
    ap.add_argument("--parts", type=int, default=4)
    ap.add_argument("--points", type=int, default=100)
    ap.add_argument("--record", action="store_true")
    args = ap.parse_args(argv)
    data = load_mpeg7(classes=args.classes, per_class=args.per_class, n_points=args.points)
    xs = [_unit(o, "outline") for o in data.shapes]
    labels = np.asarray(data.labels)
    n = len(xs)
    res = {"loadavg_start": loadavg(), "classes": list(args.classes), "per_class": args.per_class,
           "parts": args.parts, "points": args.points, "n_shapes": n, "pairs": n * (n - 1) // 2}
    rigid = sl.pairwise_distances(xs, metric="fisher_rao_bound", modulo="similarity", sigma2=0.01, n_jobs=1,
                                  progress=False)
    smooth, directed = np.zeros((n, n)), np.zeros((n, n))
    t_smooth = t_parts = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            t0 = time.process_time()
            m_ij, m_ji, _, _ = registration_misfits(xs[i], xs[j])
            t1 = time.process_time()
            directed[i, j], directed[j, i] = part_misfit(xs[i], xs[j], args.parts), part_misfit(xs[j], xs[i], args.parts)
            t2 = time.process_time()
            smooth[i, j] = smooth[j, i] = 0.5 * (m_ij + m_ji)
            t_smooth, t_parts = t_smooth + t1 - t0, t_parts + t2 - t1
        print(f"{i + 1}/{n} shapes", flush=True)
    parts = 0.5 * (directed + directed.T)
    top = 2 * args.per_class
    both = smooth / np.median(smooth[np.triu_indices(n, 1)]) + parts / np.median(parts[np.triu_indices(n, 1)])
    table = {}
    for name, d in (("rigid Fisher–Rao bound", rigid), ("smooth registration misfit", smooth),
                    ("part misfit", parts), ("smooth + part misfits", both)):
        b = sl.bullseye(d, labels, top=top)
        table[name] = {"raw": b.value, "per_class": b.per_class}
        print(f"{name:28s} bull's-eye {100 * b.value:.2f} %  " +
              "  ".join(f"{c} {100 * v:.0f}" for c, v in b.per_class.items()))
    res.update(table=table, top=top, cpu_seconds={"smooth": t_smooth, "parts": t_parts}, loadavg_end=loadavg())
    print(f"CPU: smooth {t_smooth:.0f} s, parts {t_parts:.0f} s for {res['pairs']} pairs (both directions)")
    if args.record:
        print("recorded", record("bench_articulation", res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
