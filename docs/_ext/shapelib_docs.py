"""Sphinx extension of the shapelib documentation.

The API reference comes from one table, ``docs/_ext/shapelib_api.py`` (its pages are written when
the build starts; references to shapelib's names resolve through it). Two more build steps, both
run by ``make docs`` (and by any ``sphinx-build docs ...``):

* ``.. benchmark:: NAME`` renders the measurements in ``docs/_data/benchmarks/NAME.json`` as
  tables, headed by the machine, the date and the command they come from. The benchmarks
  (``python benchmarks/bench_*.py --record``) and ``python run_all.py --record-timings`` write
  those files; the renderers below are plain functions (:func:`benchmark_tables`), tested without
  Sphinx in ``tests/test_docs.py``.
* The study notebooks are executed by ``run_all.py`` (papermill) into ``docs/_build/notebook-runs``
  — the paper's figures (:data:`FULL_IN_DOCS`, seconds each) with their full parameters, the
  others with their quick ones; notebooks whose inputs are unchanged are not re-run — and the
  executed ``.ipynb`` files are copied to ``docs/notebooks/`` for myst-nb to render with their
  figures. ``SHAPELIB_DOCS_NOTEBOOKS=results`` renders the notebooks of a full
  ``python run_all.py`` from ``results/`` instead (one without a full run there is executed as
  above). Their plumbing is hidden on the pages: the parameter cells and the cells that record
  values for the report (:func:`plumbing_tags`).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
DATA = DOCS / "_data" / "benchmarks"
NOTEBOOK_PAGES = DOCS / "notebooks"
NOTEBOOK_RUNS = DOCS / "_build" / "notebook-runs"
NOTEBOOKS_ENV = "SHAPELIB_DOCS_NOTEBOOKS"


# ---------------------------------------------------------------------------------------------
# the example gallery's reading order

#: ``{topic folder of docs/examples: its examples' file names}``, in reading order: the gallery
#: shows the topics and, within each, the examples in this order (a file not listed comes last)
GALLERY_ORDER = {
    "landmarks": ["plot_first_geodesic.py", "plot_fisher_rao_vs_alpha.py", "plot_certified_distances.py",
                  "plot_choosing_sigma2.py", "plot_own_tps_file.py"],
    "pointsets": ["plot_pointset_registration.py", "plot_retrieval.py"],
    "statistics": ["plot_mean_shape_modes.py", "plot_regression_on_age.py"],
    "study": ["plot_distance_matrix_dask.py"],
}


class ExampleOrder:
    """sphinx-gallery's ``within_subsection_order``: the examples of a topic folder in the order
    :data:`GALLERY_ORDER` lists them, then any other file by name."""

    def __init__(self, src_dir):
        self.src_dir = src_dir

    def __call__(self, filename) -> tuple[int, str]:
        name = Path(filename).name
        order = [n for names in GALLERY_ORDER.values() for n in names]
        return (order.index(name) if name in order else len(order), name)

    def __repr__(self) -> str:  # part of the configuration Sphinx compares between builds
        return "ExampleOrder"


# ---------------------------------------------------------------------------------------------
# benchmark tables (no Sphinx needed)

@dataclass
class Table:
    """One rendered table: a title, column names, rows of strings and an optional note below."""

    title: str
    header: list[str]
    rows: list[list[str]]
    note: str = ""
    key: str = ""


@dataclass
class Rendered:
    provenance: str
    tables: list[Table] = field(default_factory=list)


def load_benchmark(name: str, data_dir: Path = DATA) -> dict:
    path = data_dir / f"{name}.json"
    if not path.is_file():
        raise ValueError(f"no benchmark record {path}; run the benchmark with --record")
    return json.loads(path.read_text())


def _num(x, fmt: str = "{:,.3g}") -> str:
    if x is None:
        return "—"
    if isinstance(x, (list, tuple)):
        return "–".join(_num(v, fmt) for v in x)
    return fmt.format(x)


def _rate(x) -> str:
    """Three significant digits, thousands separated: ``15,400``, ``146``, ``20.2``; a range as ``118–126``."""
    if x is None:
        return "—"
    if isinstance(x, (list, tuple)):
        return "–".join(_rate(v) for v in x)
    if x >= 100:
        digits = len(str(int(x))) - 3
        return f"{round(x, -digits):,.0f}"
    return f"{x:.3g}"


def _sci(x, digits: int = 1) -> str:
    """``1e-9``, ``6.2e-4`` (no zero-padded exponent)."""
    if x is None:
        return "—"
    mant, exp = f"{x:.{digits}e}".split("e")
    mant = mant.rstrip("0").rstrip(".") if "." in mant else mant
    return f"{mant}e{int(exp)}"


def _date(text) -> str:
    import datetime

    try:
        if "T" not in text:  # a date without a time, or a description
            return text
        d = datetime.datetime.fromisoformat(text)
    except (TypeError, ValueError):
        return text or "(date not recorded)"
    return d.astimezone(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def _seconds(x) -> str:
    """``0.30 s``, ``13.0 s``; a pair of values (a range over runs) as ``1.69–1.81 s``."""
    if x is None:
        return "—"
    if isinstance(x, (list, tuple)):
        return "–".join(_seconds(v)[:-2] for v in x) + " s"
    return f"{x:.2f} s" if x < 1 else (f"{x:.3g} s" if x < 100 else f"{x:.0f} s")


def provenance(data: dict) -> str:
    """One sentence: where, when and how the numbers were measured."""
    m = data.get("machine", {})
    cpu = m.get("processor") or m.get("machine") or "?"
    load = m.get("loadavg")
    parts = [f"Measured {_date(m.get('date'))} on {m.get('cpus', '?')} CPUs ({cpu})",
             f"Python {m.get('python', '?')}"]
    if m.get("gpu"):
        parts.append(f"GPU {m['gpu']}")
    if m.get("shapelib"):
        parts.append(f"shapelib {m['shapelib']}")
    if load:
        parts.append(f"load average {load}")
    text = ", ".join(parts) + f", with ``{data.get('command', '?')}``."
    if data.get("transcribed"):
        text += " " + data["transcribed"]
    return text


GEODESIC_ROWS = {
    "alpha-default": "α, default tolerance",
    "fr-default": "Fisher–Rao, default tolerance",
    "alpha-1e-9": "α, certified at 1e-9",
    "fr-1e-9": "Fisher–Rao, certified at 1e-9",
}


def _geodesic(r: dict) -> list[Table]:
    rows, parts = [], []
    for key, row in r["rows"].items():
        label = GEODESIC_ROWS.get(key, key)
        runs = row.get("runs", 1)
        wall = _seconds(row.get("seconds"))
        if runs > 1:
            median = f"; median {_seconds(row['median_seconds'])}" if row.get("median_seconds") else ""
            wall += f" (fastest of {runs}{median})"
        rows.append([label, wall, _seconds(row.get("cpu_seconds")), _num(row.get("iterations"), "{}"),
                     row.get("stopped_by", "—"), _sci(row.get("length_over_bound_minus_1"))])
        p = row.get("per_iteration_cpu_ms")
        if p:
            chol = _num(p.get("cholesky"), "{:.2g}")
            per_it = row.get("cholesky_per_iteration")
            if per_it is None and row.get("calls", {}).get("n_cholesky") and row.get("iterations"):
                per_it = row["calls"]["n_cholesky"] / row["iterations"]
            if per_it is not None:
                chol += f" ({per_it:.1f} per iteration)"
            total = sum(v for v in p.values() if v is not None)
            parts.append([label, _num(p.get("energy_grad_hessian"), "{:.3g}"), chol, _num(p.get("solve"), "{:.2g}"),
                          _num(p.get("trial_energy"), "{:.2g}"), _num(p.get("rest"), "{:.2g}"), f"{total:.3g}"])
    setup = (f"Corpus callosum shapes 1 and 2 (K = {r.get('K', 63)}), σ² = {r.get('sigma2')}, "
             f"n_steps = {r.get('n_steps')}; Fisher–Rao quadrature step {r.get('grid_spacing')}σ.")
    first = r.get("first_call_cpu_seconds")
    tables = [Table("Single geodesics", ["geodesic", "wall time", "CPU time", "iterations", "stopped by",
                                         "length / bound − 1"], rows, setup, key="rows")]
    if parts:
        note = ("CPU milliseconds per iteration. The first geodesic of a process also loads the compiled "
                f"kernels: {first:.2f} s CPU." if first is not None else "CPU milliseconds per iteration.")
        tables.append(Table("Where an iteration's time goes", ["geodesic", "energy + gradient + Hessian",
                                                                "block Cholesky", "solves", "trial energies",
                                                                "rest", "total"], parts, note, key="iteration"))
    return tables


BRACKET_CASES = {"alpha_s2_0.5": "α, σ² = 0.5", "fisher_rao_s2_0.5": "Fisher–Rao, σ² = 0.5",
                 "alpha_s2_0.1": "α, σ² = 0.1"}


def _bracket(r: dict) -> list[Table]:
    rtol = r.get("rtol", 1e-3)
    rows = []
    for key, c in r["cases"].items():
        steps = ", ".join(f"{n} ({k})" for n, k in c.get("n_steps", {}).items())
        stalled = c.get("stopped_by", {}).get("stalled")
        reached = f"{c.get('converged')}/{c.get('pairs')}" + (f" ({stalled} stalled)" if stalled else "")
        rows.append([BRACKET_CASES.get(key, key), _rate(c.get("pairs_per_second")), reached, f"{_sci(c.get('gap_median'))} / {_sci(c.get('gap_max'))}",
                     f"{_num(c.get('n_iter_median'), '{:g}')} / {_num(c.get('n_iter_max'), '{}')}", steps or "—"])
    return [Table(f"Certified distance brackets, rtol = {_sci(rtol)}",
                  ["case", "pairs/s", f"gap ≤ {_sci(rtol)}", "gap median / max",
                   "iterations median / max", "final n_steps (pairs)"], rows,
                  "The corpus callosum pairs of Table I at centroid size 20, one process; best of "
                  f"{r.get('repeat', 'several')} rounds.", key="cases")]


PAIRWISE_METRICS = {"procrustes": "Procrustes", "hausdorff": "Hausdorff", "tps": "TPS bending energy",
                    "alpha_bound": "α lower bound", "fisher_rao_bound": "Fisher–Rao lower bound",
                    "alpha": "α geodesic (bracket)", "fisher_rao": "Fisher–Rao geodesic (bracket)"}


def _pairwise(r: dict) -> list[Table]:
    metrics = r["metrics"]
    workers = sorted({int(w) for m in metrics.values() for w in m if str(w).isdigit()})
    rows = []
    for name, m in metrics.items():
        row = [PAIRWISE_METRICS.get(name, name), _num(m.get("n_shapes"), "{:,}"),
               _num(m.get(str(workers[0]), {}).get("pairs"), "{:,}")]
        row += [_rate(m.get(str(w), {}).get("pairs_per_second")) for w in workers]
        row.append(_num(m.get(str(workers[-1]), {}).get("efficiency"), "{:.2f}") if len(workers) > 1 else "—")
        rows.append(row)
    header = ["metric", "shapes", "pairs"] + [f"pairs/s, {w} worker{'s' if w > 1 else ''}" for w in workers]
    header.append(f"efficiency, {workers[-1]} workers")
    tables = [Table("Pairwise engine throughput", header, rows,
                    f"ADHD-200 contours (K = 50) at centroid size 20, σ² = {r.get('sigma2')}; geodesics as "
                    f"{r.get('geodesics', 'certified brackets')}. Efficiency: pairs/s on w workers over w times "
                    "the one-worker rate.", key="metrics")]
    proj = r.get("projection", {})
    if proj:
        counts = sorted({int(n) for p in proj.values() for n in p["hours"]})
        prow = [[PAIRWISE_METRICS.get(k, k), f"{p['seconds_per_pair']:.3g}"] +
                [_num(p["hours"].get(str(n), p["hours"].get(n)), "{:.2g}") for n in counts] for k, p in proj.items()]
        tables.append(Table("Projected wall-clock hours for all 647 ADHD-200 shapes (208,981 pairs)",
                            ["metric", "s per pair"] + [f"{n} worker{'s' if n > 1 else ''}" for n in counts], prow,
                            "From the mean measured seconds per pair and the measured two-worker efficiency.",
                            key="projection"))
    bounds = r.get("bound_matrices")
    if bounds:
        brow = [[PAIRWISE_METRICS.get(k, k), _seconds(b.get("matrix_seconds")), _seconds(b.get("engine_seconds")),
                 _seconds(b.get("per_pair_projected_seconds")), _sci(b.get("max_rel_diff_per_pair"))]
                for k, b in bounds.items() if k in PAIRWISE_METRICS]
        a, sw = bounds.get("alpha_bound", {}), bounds.get("sweep", {})
        note = (f"All {bounds.get('n_shapes')} ADHD-200 shapes at σ² = {bounds.get('sigma2')}, one process, fastest of "
                "the runs: the closed-form bounds of a whole population as matrix products "
                "(``fisher_rao_bound_matrix``, ``alpha_bound_matrix``), and the same through ``pairwise_distances``.")
        if a.get("ns_per_gaussian"):
            note += (f" The α bound evaluates {a['gaussians']:,} Gaussians at {a['ns_per_gaussian']:.2f} ns each, "
                     f"{a['times_bare_exp']:.1f}× a bare ``numpy.exp`` of as many numbers.")
        if sw:
            note += (f" A {len(sw['sigma2'])}-value σ² sweep (σ from {sw['sigma_over_spacing'][0]:g} to "
                     f"{sw['sigma_over_spacing'][-1]:g} landmark spacings, ``bound_matrix_sweep``): α "
                     f"{_seconds(sw['alpha_bound']['seconds'])}, Fisher–Rao {_seconds(sw['fisher_rao_bound']['seconds'])}.")
        when = bounds.get("measured")
        if when:
            note += f" Measured {_date(when.get('date'))} with ``{when.get('command')}``."
        tables.append(Table("Whole bound matrices", ["bound", "matrix", "through pairwise_distances",
                                                     "pair by pair (projected)", "max rel. difference to per pair"],
                            brow, note, key="bound_matrices"))
    return tables


SOLVER_METHODS = {
    "lm": "Levenberg–Marquardt, exact block-tridiagonal Hessian (the library)",
    "coarse_to_fine": "the library, coarse to fine n = 2 → 4 → 8 → 16",
    "trust_exact": "SciPy trust-exact, dense exact Hessian",
    "saddle_free": "saddle-free Newton (|eigenvalues|, line search)",
    "polynomial": "Levenberg–Marquardt on polynomial paths in time",
}


def _solvers(r: dict) -> list[Table]:
    rows = [[SOLVER_METHODS.get(k, k), _num(m.get("iterations"), "{}"), _seconds(m.get("seconds")),
             _sci(m.get("energy_over_bound_squared_minus_1"), 2)] for k, m in r["methods"].items()]
    return [Table("Second-order methods to the same certificate",
                  ["method", "iterations", "seconds", "E / bound² − 1"], rows,
                  f"α geodesic of corpus callosum shapes 1 and 2, σ² = {r.get('sigma2')}, n_steps = {r.get('n_steps')}, "
                  f"from the straight line until the exact Hessian is positive definite and the Newton decrement is "
                  f"below {_sci(r.get('tol', 1e-9))}·E.", key="methods")]


def _run_times(r: dict) -> list[Table]:
    runs = r["notebooks"]
    total = sum(n["seconds"] for n in runs.values())
    rows = [[f"``{name}``", f"{n['seconds'] / 60:.1f}"]
            for name, n in sorted(runs.items(), key=lambda kv: -kv[1]["seconds"])]
    jobs = sorted({n.get("jobs", 1) for n in runs.values()})
    return [Table("Run time of every study notebook", ["notebook", "minutes"], rows,
                  f"{total / 60:.1f} min of notebook time in all, {' or '.join(map(str, jobs))} notebook(s) at a time "
                  "(notebooks that start a worker per core run alone).", key="notebooks")]


INTRINSIC_ROWS = {
    "alpha_mean_1": "α Fréchet mean of all shapes, to its certificate",
    "alpha_mean_2": "α Fréchet mean of all shapes, to its certificate",
    "fisher_rao_mean_2": "Fisher–Rao Fréchet mean of the balanced subset",
    "tangent_pca": "tangent PCA given the α mean (three modes drawn at ±2 SD)",
    "regression_2": "geodesic regression on age, given the α mean",
}


def _intrinsic(r: dict) -> list[Table]:
    rows = []
    for key, label in INTRINSIC_ROWS.items():
        m = r["measurements"].get(key)
        if m is None:
            continue
        shapes = r.get("n_subset") if key.startswith("fisher_rao") else r.get("n_shapes")
        rows.append([label, _num(shapes, "{:,}"), _num(m.get("workers"), "{}"), _seconds(m.get("seconds")),
                     _num(m.get("iterations"), "{}"), _num(m.get("log_maps"), "{:,}"), _rate(m.get("log_maps_per_s"))])
    eff = r["measurements"].get("alpha_mean_scaling_efficiency")
    note = (f"ADHD-200 contours (K = 50) at centroid size 20, σ² = {r.get('sigma2')}, discrete geodesics of 4 segments, "
            "first-order certificate 1e-3; several workers: a LocalCluster started beforehand (its start-up not "
            "counted). Iterations: Karcher or Gauss–Newton steps.")
    if eff is not None:
        note += f" One to {r.get('workers', 2)} workers: efficiency {eff:.2f} on the α mean."
    return [Table("Mean shapes, modes and regression", ["statistic", "shapes", "workers", "seconds", "iterations",
                                                        "log maps", "log maps/s"], rows, note, key="measurements")]


def _gpu(r: dict) -> list[Table]:
    dev = r.get("device", {})
    where = f"{dev.get('device_kind', '?')} (JAX {dev.get('jax', '?')})"
    g = r["rows"]["geodesic_timing"]
    b = r["rows"]["brackets"]
    m = r["rows"]["matrix"]
    geo = Table(f"Fisher–Rao geodesic, corpus callosum (K = {g.get('K')}, σ² = {r.get('sigma2')}, n_steps = {r.get('n_steps')})",
                ["path", "seconds per geodesic", "speed-up"],
                [["CPU (compiled kernels, Levenberg–Marquardt)", _seconds(g["cpu_seconds_per_geodesic"]), "1"],
                 [f"{where}, batch of 1", _seconds(g["jax_batch1_seconds"]), f"{_rate(g['speedup_batch1'])}×"],
                 [f"{where}, batch of {g['jax_batch_pairs']}", _seconds(g["jax_seconds_per_geodesic"]),
                  f"{_rate(g['speedup_batch'])}×"]],
                f"Lengths of the pairs solved on both paths agree to {_sci(g.get('max_rel_length_difference'))} "
                "(relative). Compilation (first call) is not charged.", key="geodesic")
    tables = [geo]
    ga = r["rows"].get("geodesic_batch")
    if ga:
        tables.append(Table(
            f"Fisher–Rao geodesics, {ga['data']} (K = {ga['K']}, σ² = {ga['sigma2']}, n_steps = {r.get('n_steps')})",
            ["path", "seconds per geodesic", "speed-up"],
            [[f"CPU (compiled kernels), {ga['cpu_pairs']} pairs", _seconds(ga["cpu_seconds_per_geodesic"]), "1"],
             [f"{where}, batch of {ga['pairs']}", _seconds(ga["seconds_per_geodesic"]), f"{_rate(ga['speedup'])}×"]],
            f"{ga['converged']} of {ga['pairs']} converged; the batch runs until its slowest pair stops "
            f"({ga['iterations_max']} L-BFGS iterations). Lengths agree with the CPU path to "
            f"{_sci(ga.get('max_rel_length_difference'))} (relative).", key="geodesic_batch"))
    rates = Table("Certified Fisher–Rao brackets (rtol 1e-3) and the ADHD-200 matrix",
                  ["row", "pairs/s", "certified", "note"],
                  [[f"brackets, {b['pairs']} corpus callosum pairs, {where}", _rate(b["pairs_per_second"]),
                    f"{b['certified_rate']:.0%}", ""],
                   [f"brackets, {b['cpu_pairs']} of them on the CPU", _rate(b["cpu_pairs_per_second"]),
                    f"{b['cpu_certified_rate']:.0%}", ""],
                   [f"ADHD-200 matrix, {m['shapes']} shapes (K = {m['K']}, σ² = {m['sigma2']})", _rate(m["pairs_per_second"]),
                    f"{m['certified_rate']:.0%}",
                    f"{m['pairs_done']:,} of {m['pairs_total']:,} pairs; extrapolated: {_num(m['extrapolated_hours_180'])} h "
                    f"for the {m['shapes']}, {_num(m['extrapolated_hours_647'])} h for all 647 shapes"]],
                  m.get("run", {}).get("note", "") and f"The matrix row: {m['run']['note']} ({m['run']['date']}).",
                  key="rates")
    return tables + [rates]


def _registration_two_methods(r: dict) -> list[Table]:
    """A record of the first benchmark, shapelib beside pycpd only (before the probreg peers joined)."""
    rows = []
    for name, row in r["levels"].items():
        a, b = row["shapelib"], row["cpd"]
        rows.append([name.replace("_", " "), f"{a['error']:.4f}", f"{b['error']:.4f}",
                     "yes" if a["error"] < b["error"] else "no", _seconds(a["time_median_s"]),
                     _seconds(b["time_median_s"])])
    s = r.get("summary", {})
    note = (f"Mean error |moved − truth| over the template points with a ground truth, {r.get('samples')} sample(s) per "
            f"level; shapelib {r['settings']['shapelib']}, pycpd: {r['settings']['cpd']}. shapelib below CPD at "
            f"{s.get('shapelib_below_cpd')} of {s.get('levels')} levels; median time per registration "
            f"{_seconds(s.get('shapelib_median_time_s'))} (shapelib), {_seconds(s.get('cpd_median_time_s'))} (CPD).")
    return [Table("Registration on the Chui–Rangarajan benchmark", ["level", "shapelib error", "CPD error",
                                                                   "shapelib below", "shapelib time", "CPD time"],
                  rows, note, key="levels")]


_REG_LABELS = {"shapelib": "shapelib", "cpd": "pycpd CPD", "probreg_cpd": "probreg CPD", "probreg_filterreg": "FilterReg",
               "probreg_gmmtree": "GMMTree", "probreg_bcpd": "BCPD"}
_REG_FAMILIES = {"def": "deformation", "noise": "noise", "outlier": "outliers", "occlusion": "occlusion",
                 "rot": "rotation"}


def _ms(x) -> str:
    return "—" if x is None else (f"{1000 * x:.0f} ms" if x < 1 else _seconds(x))


def _registration_peers(r: dict, title: str, cases: str) -> list[Table]:
    """shapelib beside every peer: per level, per family × shape and per range of samples."""
    methods = r["methods"]
    header = [_REG_LABELS.get(m, m) for m in methods]
    samples = r["samples"]
    lv_rows = [[name.replace("_", " ")] + [f"{row[m]['error']:.4f} · {row[m]['failures']} · {_ms(row[m]['time_median_s'])}"
                                           for m in methods] for name, row in r["levels"].items()]
    settings = "; ".join(f"{_REG_LABELS.get(m, m)}: {r['settings'][m]}" for m in methods)
    tables = [Table(f"{title}: every level", ["level", *header], lv_rows,
                    f"Each cell: mean error |moved − truth| over {cases} · registrations that failed (error > "
                    f"{r.get('failure_threshold', 0.05)}, or the method raised or ran past the time limit, when it scores the "
                    f"error of the unmoved source) of {len(samples)} · median time per "
                    f"registration; samples {min(samples)}–{max(samples)}, the same inputs in the same run, BLAS on one "
                    f"thread. {settings}.", key="levels")]
    above = _above_best_peer(r)
    if above:
        tables.append(Table(f"{title}: the levels where shapelib's mean error is above the best peer's", [
            "level", "best peer", "shapelib − best peer", "95 % interval", "samples where shapelib is lower"], above,
            "The difference of the two methods' errors on the same inputs, sample by sample (paired), its mean and "
            "Student's t interval over the samples; the best peer is the peer of least mean error at the level "
            "(the least of several peers' means, itself a low estimate).", key="above"))
    summary = r.get("summary", {})
    if not summary:
        return tables
    whole = summary[max(summary, key=lambda k: int(k.split("-")[1]) - int(k.split("-")[0]))]  # the widest range
    fam_rows = []
    for key, f in whole.get("families", {}).items():
        shape, kind = key.rsplit("_", 1)
        best = f.get("best_peer")
        fam_rows.append([f"{shape}: {_REG_FAMILIES.get(kind, kind)}"]
                        + [f"{f['mean_error'][m]:.4f} · {f['failures'][m]}" for m in methods]
                        + [f"{_REG_LABELS.get(best, best)} {f['best_peer_error']:.4f}" if best else "—"])
    if fam_rows:
        tables.append(Table(f"{title}: per degradation", ["family", *header, "best peer"], fam_rows,
                            f"Mean error over the family's levels · failed registrations; samples {whole['samples']}.",
                            key="families"))
    rng_rows = []
    for rng, s in summary.items():
        flag, warn = s.get("reliable_flag"), s.get("any_warning")

        def pct(rates, key):
            return "—" if not rates or rates[key] is None else f"{100 * rates[key]:.0f} %"

        rng_rows.append([rng, f"{s.get('shapelib_le_every_peer', '—')} of {s['levels']}",
                         str(len(s.get("shapelib_above_best_peer_plus_0.01", []))),
                         pct(flag, "catch_rate"), pct(flag, "false_alarm_rate"),
                         f"{pct(warn, 'catch_rate')} / {pct(warn, 'false_alarm_rate')}"]
                        + [f"{s['methods'][m]['mean_error']:.4f} · {s['methods'][m]['failures']} · "
                           f"{_ms(s['methods'][m]['median_time_s'])}" for m in methods])
    tables.append(Table(f"{title}: summary by samples", ["samples", "shapelib ≤ every peer", "levels above best peer + 0.01",
                                                          "flag catch rate", "flag false alarms",
                                                          "any warning: catch / false alarms", *header], rng_rows,
                        "Levels where shapelib's mean error is at most every peer's; levels where it exceeds the best "
                        "peer's by more than 0.01; shapelib's reliable flag: of the registrations with error > 0.05 the "
                        "share flagged unreliable, of those below 0.02 the share flagged (— where the result has no "
                        "flag); the same for any RegistrationWarning (not reliable, or EM stopped at max_iter; — where "
                        "the record has no convergence); then each method's mean error over the levels · failed "
                        "registrations · median time.",
                        key="summary"))
    return tables


def _above_best_peer(r: dict) -> list[list[str]]:
    """Rows of the levels where shapelib's mean error exceeds the best peer's, with the paired difference's
    mean, its 95 % Student's t interval and the samples where shapelib is lower."""
    import numpy as np
    from scipy import stats

    rows = []
    for name, row in r["levels"].items():
        if "shapelib" not in row or "errors" not in row["shapelib"]:
            continue
        peers = [m for m in row if m != "shapelib" and row[m].get("errors")]
        if not peers:
            continue
        best = min(peers, key=lambda m: row[m]["error"])
        if row["shapelib"]["error"] <= row[best]["error"]:
            continue
        d = np.array(row["shapelib"]["errors"], float) - np.array(row[best]["errors"], float)
        half = stats.t.ppf(0.975, len(d) - 1) * d.std(ddof=1) / np.sqrt(len(d))
        rows.append([name.replace("_", " "), _REG_LABELS.get(best, best), f"{d.mean():+.4f}",
                     f"[{d.mean() - half:+.4f}, {d.mean() + half:+.4f}]", f"{int(np.sum(d < 0))} of {len(d)}"])
    return rows


def _registration(r: dict) -> list[Table]:
    if "methods" not in r:
        return _registration_two_methods(r)
    return _registration_peers(r, "Registration on the Chui–Rangarajan benchmark",
                               "the template points with a ground truth")


def _registration_3d(r: dict) -> list[Table]:
    return _registration_peers(r, f"3-D registration ({r.get('points')} points per surface)",
                               "the source points (their warped, rotated positions)")


def _retrieval(r: dict) -> list[Table]:
    n, pairs = r.get("n_shapes"), r.get("pairs")
    rows = [["tracing the outlines", _seconds(r["trace"]["wall"]), _seconds(r["trace"]["cpu"]), "—", "—"]]
    for metric, label in (("alpha_bound", "α bound"), ("fisher_rao_bound", "Fisher–Rao bound")):
        m = r.get(metric)
        if not m:
            continue
        sp = m["spectra"]

        def full(stage):  # the 1,400-shape matrix: spectra linear, pairs quadratic in the number of shapes
            return f"{(sp['cpu'] / n * 1400 + stage['cpu'] / pairs * 979_300) / 60:.1f}"

        rows.append([f"{label}: polar spectra ({sp['rings']} rings × {sp['frequencies']} frequencies, once per outline)",
                     _seconds(sp["wall"]), _seconds(sp["cpu"]), "—", "—"])
        rows.append([f"{label}: angle search (FFT over angles, Newton) and quadrature values", _seconds(m["search"]["wall"]),
                     _seconds(m["search"]["cpu"]), _num(1e6 * m["search"]["cpu"] / pairs, "{:.0f}"), full(m["search"])])
        if "search_and_exact" in m:
            e = m["search_and_exact"]
            rows.append([f"{label}: the same with closed-form values (exact=True)", _seconds(e["wall"]), _seconds(e["cpu"]),
                         _num(1e6 * e["cpu"] / pairs, "{:.0f}"), full(e)])
    p = r.get("procrustes")
    if p:
        rows.append(["Procrustes on the outlines (FFT over start points)", _seconds(p["wall"]), _seconds(p["cpu"]),
                     _num(1e6 * p["cpu"] / pairs, "{:.0f}"), "—"])
    e = r.get("engine")
    note = (f"{n:,} MPEG-7 outlines of {r.get('classes')} classes, {r.get('points')} points each, σ² = {r.get('sigma2')} "
            f"of the RMS radius², {pairs:,} pairs, in one process; the full 1,400-shape matrix (979,300 pairs) "
            "projected from the CPU seconds (spectra linear, pairs quadratic in the number of shapes).")
    if e:
        note += (f" Through the engine on {e['workers']} local workers ({e['mode']}): {_seconds(e['wall'])} wall "
                 f"for the α matrix, blocks of {e['block_size']}, equal to the in-process matrix within "
                 f"{_sci(e['max_abs_diff_vs_in_process'])}.")
    scores = [f"{label} {100 * r[k]['bullseye']:.2f} %" for k, label in (
        ("alpha_bound", "α bound"), ("fisher_rao_bound", "Fisher–Rao bound"), ("procrustes", "Procrustes")) if k in r]
    note += " Bull's-eye on these shapes: " + ", ".join(scores) + "."
    return [Table("Similarity-invariant distance matrices of MPEG-7 outlines",
                  ["stage", "wall", "CPU", "CPU µs per pair", "full matrix, CPU min"], rows, note, key="trace")]





def _mutation(r: dict) -> list[Table]:
    mods = r.get("modules", [])
    # a run of some functions only (mutation.py --only) says which
    part = lambda m: f" ({', '.join(m['only'])} only)" if m.get("only") else ""  # noqa: E731
    rows = [[f"``{m['module']}``{part(m)}", _date(m["date"]), m["tool"], str(m["mutants"]), str(m["killed"]),
             str(m["survived"]), f"{m['score']:.1f} %"] for m in mods]
    note = ("Killed: a test of the module's test files (benchmarks/mutation_targets.toml) failed or ran past the time "
            "limit. Each module's load average at its start is in the record.")
    tables = [Table("Mutation score per module", ["module", "date", "tool", "mutants", "killed", "survived", "score"],
                    rows, note, key="modules")]
    killed, total = sum(m["killed"] for m in mods), sum(m["mutants"] for m in mods)
    if total:
        rows.append(["all recorded modules", "", "", str(total), str(killed), str(total - killed),
                     f"{100 * killed / total:.1f} %"])
    groups: dict = {}
    for m in mods:
        for sv in m["survivors"]:
            key = (m["module"], sv["why"] or "(no note yet)")
            groups.setdefault(key, []).append(sv["mutant"].rsplit(".", 1)[-1])
    left = [[f"``{mod}``", str(len(names)), f"``{names[0]}``" + (f" and {len(names) - 1} more" if len(names) > 1 else ""),
             why] for (mod, why), names in groups.items()]
    if left:
        tables.append(Table("Surviving mutants, by reason", ["module", "mutants", "for example", "why they survive"],
                            left, "Every survivor with its diff is in docs/_data/benchmarks/mutation.json.",
                            key="survivors"))
    return tables


_FULL_ROWS = {("fisher_rao_bound", 100): "Fisher–Rao bound modulo similarity",
              ("alpha_bound", 100): "α bound modulo similarity",
              ("fisher_rao_bound", 200): "Fisher–Rao bound modulo similarity, 200 points"}


def _retrieval_full(r: dict) -> list[Table]:
    """``bench_retrieval.py --full --scores``: the full-test bull's-eye over σ², raw and re-ranked, with times."""
    rows = [*r["sweep"], *r.get("points_200", [])]
    sigma2s = sorted({row["sigma2"] for row in rows})
    kinds = list(dict.fromkeys((row["metric"], row["points"]) for row in rows))

    def cells(kind, value):
        at = {row["sigma2"]: row for row in rows if (row["metric"], row["points"]) == kind}
        return [value(at[s]) if s in at else "" for s in sigma2s]

    def label(kind):
        return _FULL_ROWS.get(kind, f"{kind[0]}, {kind[1]} points")

    p = r.get("procrustes")
    score_rows = [[label(k), *cells(k, lambda row: f"{100 * row['raw']:.2f} %")] for k in kinds]
    time_rows = [[label(k), *cells(k, lambda row: f"{row['spectra']['cpu']:.1f} + {row['search']['cpu']:.1f}")]
                 for k in kinds]
    header = ["distance", *(f"σ² = {s:g}" for s in sigma2s)]
    n, points = r["n_shapes"], r["points"]
    scores = Table(f"MPEG-7 bull's-eye, all {n:,} shapes", header, score_rows,
                   f"{n:,} MPEG-7 outlines ({r['classes']} classes), {points} points each unless said, σ² in units of "
                   "each outline's RMS radius², mirror images allowed; raw: no post-processing, the published protocol."
                   + (f" Procrustes on the outlines (best cyclic start point, direction and mirror image; no σ²): "
                      f"{100 * p['raw']:.2f} %." if p else ""), key="scores")
    times = Table("CPU seconds per matrix: polar spectra + pairs", header, time_rows,
                  f"One process; {r['pairs']:,} pairs per matrix; the spectra once per outline, the pairs by the "
                  f"batched angle search." + (f" Procrustes on the outlines: {_seconds(p['cpu'])} CPU." if p else ""),
                  key="times")
    kw = r.get("rerank", {})
    methods = list(kw)
    rr_rows, rr_times = [], []
    for row in r["sweep"]:
        if "reranked" not in row:
            continue
        for name, h in row.get("halves", {}).items():
            rr_rows.append([f"{row['sigma2']:g}", name, f"{100 * h['raw']:.2f} %",
                            *(f"{100 * h[m]:.2f} %" for m in methods)])
        rr_rows.append([f"{row['sigma2']:g}", f"all {r['classes']} classes", f"{100 * row['raw']:.2f} %",
                        *(f"{100 * row['reranked'][m]['all']:.2f} %" for m in methods)])
        rr_times.append(f"σ² = {row['sigma2']:g}: " + ", ".join(
            f"{m.upper()} {_seconds(row['reranked'][m]['cpu'])}" for m in methods))
    tables = [scores, times]
    if rr_rows:
        tables.append(Table(
            "Re-ranked bull's-eye (Fisher–Rao bound, 100 points)",
            ["σ²", "shapes scored", "raw", *(f"{m.upper()} (k = {kw[m]['k']}, μ = {kw[m]['mu']}, {kw[m]['n_iter']} steps)"
                                              for m in methods)], rr_rows,
            f"``shapelib.rerank`` on the finished matrix, a separate, labelled post-processing; parameters chosen on "
            f"{r.get('rerank_chosen_on', 'classes 1–35')}. A half of the classes is scored as its own collection (its "
            f"rows and columns of the matrix, re-ranked on their own), in the order of ``mpeg7_classes()``. "
            f"CPU seconds to re-rank the full matrix (one BLAS thread): " + "; ".join(rr_times) + ".", key="rerank"))
    return tables


def _retrieval_registration(r: dict) -> list[Table]:
    """``bench_retrieval.py --registration``: the registration distance's rate on MPEG-7 outlines, the
    projected cost of the full test, and the shortlisted matrix's bull's-eye when it was run."""
    rate = r["rate"]
    where = "one CPU core" if r.get("backend", "numpy") == "numpy" else (
        f"{r.get('device', {}).get('device_kind', 'the JAX device')} (batched)")
    rows = [[f"{rate['pairs']} random pairs × 2 directions ({r['points']} points)", where,
             f"{1e3 * rate['cpu_seconds_per_registration']:.0f} ms CPU, "
             f"{1e3 * rate['wall_seconds_per_registration']:.0f} ms wall",
             f"{rate['em_iterations_per_pair_median']:.0f}",
             f"{rate['full_core_hours']:,.0f}",
             _num(rate.get("shortlist_core_hours_at_most"), "{:,.1f}")]]
    note = ("Per registration: ``register`` with the registration distance's options (mirror images searched, w = 0). "
            "Projections: the full 1,400 × 1,400 matrix both directions (1,958,600 registrations), and a symmetric "
            "shortlist of the rigid bound's nearest (at most 1,400 × k pairs), in core-hours at the measured CPU rate.")
    out = [Table("Registration distance on MPEG-7 outlines: rate and projected cost",
                 ["pairs", "on", "per registration", "EM iterations per pair", "full test (core-hours)",
                  "shortlist (core-hours, at most)"], rows, note, key="rate")]
    if "bullseye" in r:
        b = r["bullseye"]
        rows = [[name, *[f"{100 * v:.2f} %" for v in row.values()]] for name, row in b["table"].items()]
        header = ["distance", *next(iter(b["table"].values())).keys()]
        note = (f"{r['matrix']['summary']} Registrations: {r['matrix']['pair_seconds']:,.0f} s of worker time, "
                "summed over the pairs. Re-ranking: "
                + "; ".join(f"{m.upper()} k = {p['k']}, μ = {p['mu']}" + (f", {p['n_iter']} steps" if "n_iter" in p else "")
                            for m, p in b["rerank"].items())
                + (f" (chosen on {b['rerank_chosen_on']})." if "rerank_chosen_on" in b else "."))
        if "energy_weight" in b:
            note += (f" Registration distance with the deformation's price κ = {b['energy_weight']} "
                     "(chosen on ten classes among 1–35).")
        out.append(Table(f"Bull's-eye, {r['classes']} classes", header, rows, note, key="bullseye"))
        if b.get("halves"):
            rows = [[half, *[f"{100 * v:.2f} %" for v in row.values()]] for half, row in b["halves"].items()]
            out.append(Table("Registration distance, each half of the classes as its own collection",
                             ["classes", *next(iter(b["halves"].values())).keys()], rows,
                             "Classes 36–70 were not used to choose the distance's price on the deformation.",
                             key="halves"))
        if b.get("per_class"):
            raw, lcdp = b["per_class"]["raw"], b["per_class"].get("lcdp", {})
            worst = sorted(raw, key=raw.get)[:10]
            rows = [[c, f"{100 * raw[c]:.2f} %", _num(100 * lcdp[c] if c in lcdp else None, "{:.2f} %")]
                    for c in worst]
            out.append(Table("Registration distance: the ten worst classes (raw)", ["class", "raw", "re-ranked lcdp"],
                             rows, "Per-class bull's-eye of the whole matrix.", key="worst"))
    return out


def _energy_weight(r: dict) -> list[Table]:
    """``bench_energy_weight.py``: the registration distance's price on the deformation, chosen on some
    MPEG-7 classes and checked on others, and how much the misfit moves when the target is turned."""
    weights = [str(w) for w in r["weights"]]
    rows = [[f"{name} ({c['shapes']} outlines: {', '.join(c['classes'])})",
             *[f"{100 * c['bullseye'][w]:.2f} %" for w in weights], _seconds(c["wall"])]
            for name, c in r["collections"].items()]
    t = r["turns"]
    note = (f"Raw bull's-eye of each collection (class-mates among each query's 40 nearest) with the registration "
            f"distance at each κ, from one registration of every ordered pair; chosen on the tuning collection: "
            f"κ = {r['chosen']} (the library's ENERGY_WEIGHT: {r['energy_weight']}). Turned targets ({t['pairs']} pairs "
            f"of the tuning collection, the target turned by {', '.join(f'{d:g}°' for d in t['degrees'])}): the misfit "
            f"moves by at most {100 * t['spread_priced']:.2f} % (σ² alone: {100 * t['spread_sigma2']:.2f} %), the energy "
            f"by at most {t['energy_spread_per_point']:.4f} nats per point.")
    return [Table("The registration distance's price on the deformation, chosen and checked",
                  ["collection", *[f"κ = {w}" for w in weights], "registrations (wall)"], rows, note, key="weights")]


def _registration_batch(r: dict) -> list[Table]:
    """``bench_registration_batch.py``: ``register_many`` with both backends on the same pairs."""
    dev = r.get("device", {})
    where = f"{dev.get('device_kind', '?')} (JAX {dev.get('jax', '?')})"
    rn, rj = r["rows"]["numpy"], r["rows"]["jax"]
    a = r["agreement"]

    def ms(x):  # a GPU's share of a millisecond shows
        return "—" if x is None else (f"{1e3 * x:.3g} ms" if x < 1 else _seconds(x))

    rows = [[f"``backend=\"numpy\"`` (``register`` one by one, CPU), {rn['registrations']} pairs",
             ms(rn["seconds_per_registration"]), "—", "—", "—", "1"],
            [f"``backend=\"jax\"`` on {where}, {rj['registrations']} pairs",
             ms(rj["seconds_per_registration"]), ms(rj.get("prep_seconds_per_registration")),
             ms(rj["search_seconds_per_registration"]),
             ms(rj["assembly_seconds_per_registration"]), f"{_rate(r['speedup'])}×"]]
    note = (f"{r['data']}, {r['points']} points each. Wall time per registration; JAX's first call on the same pairs (compilation and a first run, "
            f"{_seconds(rj['first_call_s'])}) is not charged. Preparation, on the host: normalisation and the target's leave-one-out σ² (once per "
            f"distinct target); search: the batched EM on the device, transfers included; assembly, on the host: the "
            f"results built by the numpy code of ``register``. Over the "
            f"{a['pairs']} pairs run on both backends the moved points differ by at most "
            f"{_sci(a['max_points_difference'])} target RMS radii; the chosen start differs in {a['start_differs']}, "
            f"the reliability flag in {a['reliable_differs']}, the EM's iteration count in {a['n_iter_differs']}.")
    return [Table("Many registrations at once (``register_many``)",
                  ["backend", "per registration", "preparation", "search", "assembly", "speed-up"], rows, note, key="batch")]


def _registration_large(r: dict) -> list[Table]:
    """``bench_registration_large.py``: ``register``'s defaults on 10⁴–10⁵ points, time and peak memory."""
    rows = [[f"{c['dim']}-D", f"{c['points']:,} + {c['points']:,}", str(c.get("landmarks", 0)),
             _seconds(c["seconds"]),
             f"{c['peak_rss_mb']:,.0f} MB", f"{c['error']:.3f}", f"{c['distance_to_target']:.4f}",
             "yes" if c["reliable"] else "no: " + "; ".join(c["reasons"]), "yes" if c["converged"] else "no"]
            for c in r["cases"]]
    note = ("Wall time of the ``register`` call (compilation excluded) and the process's peak resident memory "
            "(interpreter and libraries included). Error: mean distance of each moved point to its true position; "
            "to target: mean distance to the nearest target point (sliding along the curve or surface not counted); "
            "both in target RMS radii. Converged: the EM of the subsets' fit reached its tolerance within "
            "``max_iter``. Landmarks: known correspondences given (``landmarks=``), source points spread over the "
            "set, each with the target point at its true position.")
    return [Table("Large point sets (farthest-point subsets, the warp carrying every point)",
                  ["set", "points", "landmarks", "time", "peak memory", "error", "to target", "reliable", "converged"],
                  rows, note, key="large")]


def _registration_landmarks(r: dict) -> list[Table]:
    """``bench_registration_landmarks.py``: ``register``'s defaults with 0, 2 and 3 known correspondences."""
    rows = []
    for rng, by_k in r["summary"].items():
        for k, c in by_k.items():
            fam = ", ".join(f"{f} {n}" for f, n in sorted(c["failures_by_family"].items())) or "—"
            given = "—" if k == "0" else f"{c['with_all_landmarks']} of {c['registrations']}"
            rows.append([rng, k, given, f"{c['failures']} of {c['registrations']}", f"{c['mean_error']:.4f}",
                         f"{c['failures_flagged']} of {c['failures']}", fam])
    note = (f"Landmarks: {r['landmarks']} (noise levels move every target point and get none; occlusion levels "
            f"only the points that remain). Failure: error above {r['failure_threshold']:g}; flagged: "
            "``reliable`` False. Nothing was tuned on these runs: the landmarks only add information.")
    return [Table("Known correspondences (``landmarks=``) on the Chui–Rangarajan benchmark",
                  ["samples", "landmarks", "registrations given them", "failures", "mean error", "failures flagged",
                   "failures by degradation"], rows, note, key="landmarks")]


def _published_mpeg7() -> list[dict]:
    """The published MPEG-7 figures of ``docs/_data/published.toml`` (the pages quote them beside ours)."""
    import tomllib

    return tomllib.loads((DATA.parent / "published.toml").read_text())["mpeg7"]


def _retrieval_device(r: dict) -> list[Table]:
    """``bench_retrieval.py --from-device``: the MPEG-7 registration matrix run on a GPU, its runs and
    its bull's-eye raw and re-ranked, beside the published columns of the same kind."""
    runs = r["runs"]
    run_rows = [[run["date"], f"{run['device']['device_kind']} (JAX {run['device']['jax']})",
                 f"{run['resumed_from']:,}–{run['done']:,}", _seconds(run["wall"]),
                 _seconds(run["first_chunk"]["wall"]), _rate(run["registrations_per_second"]),
                 f"{100 * run['device_share']:.0f} %"] for run in runs]
    check = next((run["check"] for run in runs if "check" in run), None)
    note = (f"``benchmarks/bench_retrieval_device.py``: the pairs in the order of their rank in the rigid "
            f"shortlist (Fisher–Rao bound, σ² = {r['shortlist_sigma2']:g}), {runs[0]['batch_size']:,} registrations "
            f"per device call, saved after each chunk; the second run continued from the first's files. "
            f"{r['pairs_done']:,} pairs ({r['registrations']:,} registrations): every pair of the shortlist "
            f"k = {r['complete_shortlist']} and part of the next. The first chunk of a run compiles the programs "
            f"(its time is not in the rate); device share: the batched EM on the device, the rest is the host's "
            f"preparation. At the rate, the full matrix (both directions of all 979,300 pairs) would take "
            f"{r['full_matrix_seconds'] / 60:.0f} minutes. {100 * r['pairs_converged']:.1f} % of the pairs had both EMs "
            f"converged within ``max_iter``; the others' misfits are those of the last iteration.")
    if check:
        note += (f" On the first {check['pairs']} pairs the device's misfits equal ``backend=\"numpy\"`` (one by one on "
                 f"the host) to {_sci(check['max_relative_difference'])} relative.")
    out = [Table("The MPEG-7 registration matrix on a GPU", ["run", "device", "pairs", "wall", "first chunk",
                                                             "registrations per second", "on the device"],
                 run_rows, note, key="runs")]

    def pct(x):
        return f"{100 * x:.2f} %"

    kw = r["rerank"]
    header = ["distance", "shortlist", "raw", f"TPG (k = {kw['tpg']['k']}, μ = {kw['tpg']['mu']})",
              f"LCDP (k = {kw['lcdp']['k']}, μ = {kw['lcdp']['mu']})"]
    rows = [["rigid Fisher–Rao bound", "—", pct(r["rigid"]["raw"]), pct(r["rigid"]["tpg"]), pct(r["rigid"]["lcdp"])]]
    for row in r["shortlists"]:
        rows.append(["registration misfit" + (" (reported)" if row["k"] == r["reported_shortlist"] else ""),
                     f"{row['k']} ({row['pairs']:,} pairs)", pct(row["raw"]), pct(row["tpg"]), pct(row["lcdp"])])
    for column, c in r["chosen"].items():
        rows.append([f"{c['combine']} (chosen by {'raw' if column == 'raw' else column.upper()} on classes 1–35)",
                     str(c["k"]), pct(c["all"]["raw"]), pct(c["all"]["tpg"]), pct(c["all"]["lcdp"])])
    for pub in _published_mpeg7():
        if pub["protocol"] == "raw" and pub["method"].startswith(("Inner-distance", "Shape tree", "Height")):
            rows.append([f"published: {pub['method']}", "—", pub["figure"], "", ""])
        elif pub["protocol"] == "re-ranked" and "LCDP" in pub["method"]:
            rows.append([f"published: {pub['method']}", "—", "", "", pub["figure"]])
    scores = Table(f"MPEG-7 bull's-eye with the registration distance, all {r['n_shapes']:,} shapes", header, rows,
                   "Raw: no post-processing (the published protocol); TPG, LCDP: ``shapelib.rerank`` on the finished "
                   f"matrix, parameters chosen on the rigid bound's classes 1–35. Misfit: the EM σ² left after the "
                   f"non-rigid registration, mean of both directions, on the pairs of the shortlist; the other pairs "
                   f"take the rigid bound, ranked after them. The combinations with the rigid bound were scored at "
                   f"three shortlists on each half of the classes; the one of largest score on classes 1–35 is "
                   f"shown on all 70 here and on classes 36–70 in the next table.", key="scores")
    half_rows = []
    for column, c in r["chosen"].items():
        for name, h in (("classes 1–35 (chosen here)", c["chosen_on"]), ("classes 36–70", c["reported_on"])):
            half_rows.append([f"{c['combine']}, shortlist {c['k']}", name, pct(h["raw"]), pct(h["tpg"]),
                              pct(h["lcdp"])])
    for row in r["shortlists"]:
        if row["k"] == r["reported_shortlist"]:
            for name, h in row["halves"].items():
                half_rows.append([f"misfit, shortlist {row['k']}", name, pct(h["raw"]), pct(h["tpg"]), pct(h["lcdp"])])
    for name, h in r["rigid"]["halves"].items():
        half_rows.append(["rigid Fisher–Rao bound", name, pct(h["raw"]), pct(h["tpg"]), pct(h["lcdp"])])
    halves = Table("Each half of the classes scored as its own collection", ["distance", "shapes scored", *header[2:]],
                   half_rows, "Classes in the order of ``mpeg7_classes()``; a half's rows and columns of the matrix, "
                   "re-ranked on their own.", key="halves")
    worst = sorted(r["per_class"].items(), key=lambda kv: kv[1]["lcdp"])[:8]
    worst_rows = [[c, pct(v["rigid"]), pct(v["raw"]), pct(v["lcdp"])] for c, v in worst]
    per_class = Table(f"The eight worst classes (misfit, shortlist {r['reported_shortlist']})",
                      ["class", "rigid bound, raw", "misfit, raw", "misfit, LCDP"], worst_rows,
                      "Per-class bull's-eye: the class-mates among each of its shapes' 40 nearest.", key="worst")
    return [*out, scores, halves, per_class]


def _articulation(r: dict) -> list[Table]:
    """``bench_articulation.py``: a part-aware registration distance beside the smooth one."""
    classes = r["classes"]
    rows = [[name, f"{100 * row['raw']:.2f} %", *(f"{100 * row['per_class'][c]:.0f} %" for c in classes)]
            for name, row in r["table"].items()]
    cpu = r["cpu_seconds"]
    note = (f"{r['per_class']} shapes of each class ({r['n_shapes']} shapes, {r['pairs']} pairs), {r['points']} outline "
            f"points; bull's-eye: class-mates among each query's {r['top']} nearest. Part misfit: each outline split "
            f"at its {r['parts']} most concave points, every arc registered onto the whole other outline with its own "
            f"similarity pose, the mean of the arcs' σ², both directions; nothing tuned. CPU seconds for all pairs "
            f"both ways: smooth {_seconds(cpu['smooth'])}, parts {_seconds(cpu['parts'])}.")
    return [Table("Articulated classes: a part-aware registration distance beside the smooth one",
                  ["distance", "bull's-eye", *classes], rows, note, key="articulation")]


RENDERERS = {"bench_registration": _registration, "bench_registration_landmarks": _registration_landmarks,
             "bench_registration_large": _registration_large, "bench_registration_3d": _registration_3d, "bench_geodesic": _geodesic, "bench_bracket": _bracket, "bench_pairwise": _pairwise,
             "bench_solvers": _solvers, "run_times": _run_times, "bench_intrinsic": _intrinsic, "bench_gpu": _gpu,
             "bench_retrieval": _retrieval, "bench_retrieval_full": _retrieval_full,
             "bench_retrieval_registration": _retrieval_registration, "mutation": _mutation,
             "bench_registration_batch": _registration_batch, "bench_retrieval_device": _retrieval_device,
             "bench_articulation": _articulation, "bench_energy_weight": _energy_weight}
#: records that may be absent (measured on hardware that is not always at hand): the page says so
OPTIONAL = {"bench_gpu": "Pending a measurement on a GPU: run ``python benchmarks/bench_gpu.py`` on a machine "
                         "with an NVIDIA GPU and ``pip install \"shapelib[gpu]\"``, which writes the record this "
                         "section is rendered from.",
            "bench_registration_3d": "Pending a measurement: ``python benchmarks/bench_registration_3d.py --record`` "
                                     "writes the record this section is rendered from."}

def benchmark_tables(name: str, data_dir: Path = DATA) -> Rendered:
    """The tables of ``docs/_data/benchmarks/<name>.json``, with their provenance sentence."""
    if name not in RENDERERS:
        raise ValueError(f"unknown benchmark {name!r}; choose from {sorted(RENDERERS)}")
    data = load_benchmark(name, data_dir)
    return Rendered(provenance(data), RENDERERS[name](data["results"]))


def _rst_inline(text: str):
    """Paragraph children for text with ``literal`` spans (the only markup the tables use)."""
    from docutils import nodes

    out = []
    for i, part in enumerate(re.split(r"``(.+?)``", text)):
        if part:
            out.append(nodes.literal(part, part) if i % 2 else nodes.Text(part))
    return out


def _table_node(t: Table):
    from docutils import nodes

    table = nodes.table(classes=["benchmark-table"])
    table += nodes.title(t.title, t.title)
    group = nodes.tgroup(cols=len(t.header))
    table += group
    for _ in t.header:
        group += nodes.colspec(colwidth=1)
    head = nodes.thead()
    group += head
    body = nodes.tbody()
    group += body
    for parent, rows in ((head, [t.header]), (body, t.rows)):
        for cells in rows:
            row = nodes.row()
            for cell in cells:
                entry = nodes.entry()
                entry += nodes.paragraph("", "", *_rst_inline(str(cell)))
                row += entry
            parent += row
    return table


def _benchmark_directive():
    from docutils import nodes
    from docutils.parsers.rst import directives
    from sphinx.util.docutils import SphinxDirective

    class BenchmarkDirective(SphinxDirective):
        """``.. benchmark:: NAME`` (``:tables: key, ...`` to show some tables only)."""

        required_arguments = 1
        option_spec = {"tables": directives.unchanged}

        def run(self):
            name = self.arguments[0]
            self.env.note_dependency(str(DATA / f"{name}.json"))
            if name in OPTIONAL and not (DATA / f"{name}.json").is_file():
                return [nodes.paragraph("", "", *_rst_inline(OPTIONAL[name]), classes=["benchmark-provenance"])]
            try:
                rendered = benchmark_tables(name)
            except (ValueError, KeyError) as exc:
                raise self.error(f"benchmark {name}: {exc}") from None
            keep = [k.strip() for k in self.options.get("tables", "").split(",") if k.strip()]
            out = [nodes.paragraph("", "", *_rst_inline(rendered.provenance), classes=["benchmark-provenance"])]
            for t in rendered.tables:
                if keep and t.key not in keep:
                    continue
                out.append(_table_node(t))
                if t.note:
                    out.append(nodes.paragraph("", "", *_rst_inline(t.note), classes=["benchmark-note"]))
            return out

    return BenchmarkDirective


# ---------------------------------------------------------------------------------------------
# command-line help

def cli_help(command: str | None = None, *, width: int = 100) -> str:
    """What ``shapelib --help`` (or ``shapelib COMMAND --help``) prints, at ``width`` columns."""
    import argparse

    from shapelib.cli import build_parser

    if command == "study":  # `shapelib study ARGS` is `python run_all.py ARGS`
        env = {**os.environ, "COLUMNS": str(width)}
        proc = subprocess.run([sys.executable, str(ROOT / "run_all.py"), "--help"], capture_output=True, text=True,
                              env=env, cwd=ROOT, check=True)
        return proc.stdout
    parser = build_parser()
    if command is not None:
        (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if command not in sub.choices:
            raise ValueError(f"no command {command!r}; the commands are {sorted(sub.choices)}")
        parser = sub.choices[command]
    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)  # argparse wraps help to the terminal width
    try:
        return parser.format_help()
    finally:
        if previous is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = previous


def cli_commands() -> list[str]:
    import argparse

    from shapelib.cli import build_parser

    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return list(sub.choices)


def _cli_help_directive():
    from docutils import nodes
    from sphinx.util.docutils import SphinxDirective

    class CliHelpDirective(SphinxDirective):
        """``.. cli-help::`` (the top-level help) or ``.. cli-help:: COMMAND``."""

        optional_arguments = 1

        def run(self):
            command = self.arguments[0] if self.arguments else None
            try:
                text = cli_help(command)
            except ValueError as exc:
                raise self.error(str(exc)) from None
            block = nodes.literal_block(text, text)
            block["language"] = "none"
            return [block]

    return CliHelpDirective


# ---------------------------------------------------------------------------------------------
# study notebooks

def _run_all():
    sys.path.insert(0, str(ROOT))
    import run_all

    return run_all


#: notebooks the documentation executes with their full parameters: the paper's figures, whose
#: full runs take seconds each; the others run with their quick parameters
FULL_IN_DOCS = ("fig01_gmm_representation", "fig02_intrinsic_extrinsic", "fig04_line_bending",
                "fig06_square_rotation", "fig07_fish_deformations", "fig10_corpus_callosum",
                "sec3e_extrinsic_warp")


def _run_record(folder: Path) -> dict:
    path = folder / ".inputs.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def _executed(name: str, mode: str, run_all) -> tuple[Path, Path, dict]:
    """The executed notebook to render, the results folder of its run, and its run record."""
    if mode == "results" and _run_record(run_all.RESULTS_DIR / name).get("mode") == "full":
        return run_all.RESULTS_DIR / name / f"{name}.ipynb", run_all.RESULTS_DIR, _run_record(run_all.RESULTS_DIR / name)
    return NOTEBOOK_RUNS / name / f"{name}.ipynb", NOTEBOOK_RUNS, _run_record(NOTEBOOK_RUNS / name)


def _clean_paths(text: str, run_dir: Path, name: str) -> str:
    """Show the folders a run by hand writes to (``results/<name>``), not the build's temporary ones."""
    text = re.sub(re.escape(str(run_dir)) + r"/\.tmp-" + re.escape(name) + r"-[A-Za-z0-9_]+", f"results/{name}", text)
    text = text.replace(str(run_dir) + "/.stores", "results/.stores").replace(str(run_dir), "results")
    return text.replace(str(ROOT) + "/", "")


#: the study's recording calls (results/<name>/values.json, verdicts): plumbing of the study, not
#: something a reader of the page needs to see
RECORDING_CALLS = ("record_values", "record_verdict")


def plumbing_tags(source: str) -> list[str]:
    """myst-nb tags that hide a code cell's plumbing on its page: ``remove-cell`` for the
    papermill parameter cells and for cells that only record values or verdicts (and the imports
    they need), ``hide-input`` (the code folded, its output shown) for cells that also compute."""
    import ast

    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []

    def recording(stmt) -> bool:
        return isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Call) and \
            getattr(stmt.value.func, "id", getattr(stmt.value.func, "attr", None)) in RECORDING_CALLS

    calls = [st for st in tree.body if recording(st)]
    if not calls:
        return []
    rest = [st for st in tree.body if not recording(st) and not isinstance(st, (ast.Import, ast.ImportFrom))]
    return ["hide-input"] if rest else ["remove-cell"]


def notebook_page(name: str, source: Path, info: dict, run_dir: Path) -> dict:
    """The executed notebook as a documentation page: a note on the parameters it ran with after
    its title cell, no absolute paths, and the plumbing hidden: the parameter cells (the note says
    which parameters ran) and the cells that record values for the report (:func:`plumbing_tags`)."""
    nb = json.loads(source.read_text())
    output_dir = nb["metadata"].get("papermill", {}).get("parameters", {}).get("output_dir")
    if output_dir:  # the results folder the notebook ran in (run_dir/.tmp-<name>-*), wherever it is now
        run_dir = Path(output_dir).parent
    nb["metadata"].pop("papermill", None)
    for cell in nb["cells"]:
        cell.get("metadata", {}).pop("papermill", None)
        cell.get("metadata", {}).pop("execution", None)
        tags = cell.setdefault("metadata", {}).get("tags", [])
        if cell["cell_type"] == "code":
            text = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
            hidden = ["remove-cell"] if {"parameters", "injected-parameters"} & set(tags) else plumbing_tags(text)
            if hidden:
                cell["metadata"]["tags"] = [*tags, *hidden]
        if "injected-parameters" in tags:  # not shown, but no build path in the page's source either
            lines = cell["source"] if isinstance(cell["source"], list) else cell["source"].splitlines(True)
            cell["source"] = [ln for ln in lines if not ln.startswith(("output_dir", "store_dir"))]
        for out in cell.get("outputs", []):
            if "text" in out:
                out["text"] = [_clean_paths(t, run_dir, name) for t in out["text"]] if isinstance(out["text"], list) \
                    else _clean_paths(out["text"], run_dir, name)
            for mime in ("text/plain", "text/html"):
                if mime in out.get("data", {}):
                    v = out["data"][mime]
                    out["data"][mime] = [_clean_paths(t, run_dir, name) for t in v] if isinstance(v, list) \
                        else _clean_paths(v, run_dir, name)
    overrides = {k: v for k, v in info.get("overrides", {}).items() if k not in ("output_dir", "store_dir")}
    if info.get("mode") == "full":
        how = "This page shows the notebook executed with its full parameters, as `python run_all.py` runs it"
    else:
        shown = ", ".join(f"`{k}={v!r}`" for k, v in overrides.items()) or "its defaults"
        how = (f"This page shows the notebook executed with its quick parameters ({shown}) when the documentation "
               "was built, so figures and numbers are coarser than a full run's")
    note = (f":::{{note}}\n{how}. Source: `notebooks/{name}.py`; run it with "
            f"`python run_all.py --only {name}` (see {{doc}}`/guide/study`).\n:::\n")
    nb["cells"].insert(1, {"cell_type": "markdown", "id": "shapelib-docs-run-note", "metadata": {}, "source": note})
    return nb


def prepare_notebooks(app, config) -> None:
    """Execute the study notebooks (cached by their inputs) and copy them into docs/notebooks/."""
    from sphinx.errors import ExtensionError
    from sphinx.util import logging

    log = logging.getLogger(__name__)
    mode = os.environ.get(NOTEBOOKS_ENV, "build")
    if mode not in ("build", "results"):
        raise ExtensionError(f"{NOTEBOOKS_ENV} must be 'build' (execute them now) or 'results' (a full run's "
                             f"from results/); got {mode!r}")
    run_all = _run_all()
    names = list(run_all.NOTEBOOKS)
    if mode == "results":
        names_to_run = [n for n in names if _run_record(run_all.RESULTS_DIR / n).get("mode") != "full"]
    else:
        names_to_run = names
    full = [n for n in names_to_run if n in FULL_IN_DOCS]
    quick = [n for n in names_to_run if n not in FULL_IN_DOCS]
    for selected, options in ((full, []), (quick, ["--quick"])):
        if not selected:
            continue
        log.info(f"[shapelib] executing {len(selected)} study notebook(s) {'with their quick parameters ' * bool(options)}"
                 "(run_all.py; notebooks whose inputs are unchanged are not re-run)")
        cmd = [sys.executable, str(ROOT / "run_all.py"), *options, "--no-progress", "--results-dir", str(NOTEBOOK_RUNS)]
        cmd += [a for n in selected for a in ("--only", n)]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        if proc.returncode != 0:
            raise ExtensionError(f"{' '.join(cmd[1:])} failed (exit {proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
        log.info(proc.stdout.strip())
    NOTEBOOK_PAGES.mkdir(exist_ok=True)
    for name in names:
        source, run_dir, info = _executed(name, mode, run_all)
        text = json.dumps(notebook_page(name, source, info, run_dir), indent=1, ensure_ascii=False) + "\n"
        target = NOTEBOOK_PAGES / f"{name}.ipynb"
        if not target.is_file() or target.read_text() != text:  # unchanged pages are not re-read
            target.write_text(text)


def _api_table():
    """docs/_ext/shapelib_api.py, the API reference's one table (loaded by path: the tests import
    this module without Sphinx's sys.path)."""
    import importlib.util

    name = "shapelib_api"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name("shapelib_api.py"))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up
        spec.loader.exec_module(module)
    return sys.modules[name]


def api_entries() -> dict[str, set[str]]:
    """``{module: names}`` of the API reference (the table of docs/_ext/shapelib_api.py)."""
    return _api_table().api_entries()


def prune_api_stubs(app, config) -> None:
    """Remove autosummary pages of names no longer in the API reference (a renamed module's stubs
    would otherwise stay in docs/api/generated and be built as orphans)."""
    wanted = {f"{module}.{name}.rst" for module, names in api_entries().items() for name in names}
    for stub in (DOCS / "api" / "generated").glob("*.rst"):
        if stub.name not in wanted:
            stub.unlink()


def setup(app):
    app.add_directive("benchmark", _benchmark_directive())
    app.add_directive("cli-help", _cli_help_directive())
    app.add_directive("module-docstring", _api_table().module_docstring_directive())
    app.connect("config-inited", lambda app, config: _api_table().write_pages())
    app.connect("config-inited", prune_api_stubs)
    app.connect("missing-reference", lambda app, env, node, contnode: _api_table().resolve_reference(app, env, node, contnode))
    app.connect("config-inited", prepare_notebooks)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
