"""The comparison report: every stored reference value of the paper against ours.

Reference values live in ``data/reference/*.csv`` (one row per printed number, with its
provenance: item, row, column, printed text, scale). Our values come from each notebook's
``results/<name>/values.json``. For each reference value the report gives the paper's
value, ours, their ratio, the relative error, the tolerance and a status:

``match``
    ``|ours − paper|`` is within print precision (half a unit of the last printed digit).
``close``
    not within print precision, but within the relative tolerance (default 1 %).
``differs``
    anything else.
``not computed``
    no value of ours (e.g. Table I rows involving shapes 4 and 5, whose landmarks are not public).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["load_reference", "collect_values", "compare", "render_report", "write_report", "REL_TOL"]

REL_TOL = 0.01
STATUSES = ("match", "close", "differs")


def load_reference(reference_dir) -> pd.DataFrame:
    """All reference values in ``reference_dir/*.csv`` as one frame indexed by ``key``."""
    frames = [pd.read_csv(p, comment="#", dtype={"printed": str}) for p in sorted(Path(reference_dir).glob("*.csv"))]
    if not frames:
        raise FileNotFoundError(f"no reference CSV files in {reference_dir}")
    ref = pd.concat(frames, ignore_index=True)
    dup = ref["key"][ref["key"].duplicated()]
    if len(dup):
        raise ValueError(f"duplicate reference keys: {sorted(dup)[:5]}")
    return ref.set_index("key")


def collect_values(results_dir) -> tuple[dict, dict, dict]:
    """Merge ``values``, ``notes`` and per-notebook run info from ``results_dir/*/values.json``."""
    values, notes, runs = {}, {}, {}
    for path in sorted(Path(results_dir).glob("*/values.json")):
        data = json.loads(path.read_text())
        name = path.parent.name
        for k, v in data.get("values", {}).items():
            if k in values:
                raise ValueError(f"value {k!r} recorded by two notebooks ({values[k][1]} and {name})")
            values[k] = (float(v), name)
        notes.update(data.get("notes", {}))
        info_path = path.parent / ".inputs.json"
        runs[name] = json.loads(info_path.read_text()) if info_path.exists() else {}
    return values, notes, runs


def compare(reference: pd.DataFrame, values: dict, *, rel_tol: float = REL_TOL) -> pd.DataFrame:
    """One row per reference value with ours, ratio, relative error, tolerance and status."""
    rows = []
    for key, ref in reference.iterrows():
        paper = float(ref["value"])
        abs_tol = 0.5 * 10.0 ** (-int(ref["decimals"])) * float(ref["scale"])
        row = dict(key=key, item=ref["item"], row=ref["row"], column=ref["column"], printed=ref["printed"],
                   scale=float(ref["scale"]), paper=paper, abs_tol=abs_tol, ours=np.nan, notebook="",
                   ratio=np.nan, rel_err=np.nan, status="not computed")
        if key in values:
            ours, nb = values[key]
            row.update(ours=ours, notebook=nb)
            row["ratio"] = ours / paper if paper != 0 else np.nan
            row["rel_err"] = abs(ours - paper) / abs(paper) if paper != 0 else np.nan
            # a hair of slack so that a value printed from the exact same number is a match
            if abs(ours - paper) <= abs_tol * (1 + 1e-9) + 1e-15:
                row["status"] = "match"
            elif row["rel_err"] <= rel_tol:
                row["status"] = "close"
            else:
                row["status"] = "differs"
        rows.append(row)
    return pd.DataFrame(rows)


@dataclass
class _ColumnSummary:
    item: str
    column: str
    n_ref: int
    n: int
    counts: dict
    median_ratio: float
    ratio_spread: float
    ratio_cv: float
    spearman: float
    kendall: float


def _summaries(table: pd.DataFrame) -> list[_ColumnSummary]:
    from scipy.stats import kendalltau, spearmanr

    out = []
    for (item, column), g in table.groupby(["item", "column"], sort=False):
        got = g[g["status"] != "not computed"]
        counts = {s: int((got["status"] == s).sum()) for s in STATUSES}
        med = spread = cv = rho = tau = np.nan
        if len(got):
            r = got["ratio"].to_numpy()
            med = float(np.median(r))
            spread = float(r.max() / r.min() - 1) if r.min() > 0 else np.nan
            cv = float(r.std() / r.mean()) if len(r) > 1 and r.mean() != 0 else np.nan
        if len(got) >= 3:
            rho = float(spearmanr(got["ours"], got["paper"]).statistic)
            tau = float(kendalltau(got["ours"], got["paper"]).statistic)
        out.append(_ColumnSummary(item, column, len(g), len(got), counts, med, spread, cv, rho, tau))
    return out


def _fmt(x, spec=".4g"):
    return "—" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


def render_report(table: pd.DataFrame, notes: dict, runs: dict, *, rel_tol: float = REL_TOL) -> str:
    """Markdown text of ``REPORT.md``."""
    lines = ["# shapelib: reproduction report", ""]
    lines.append(
        "Every stored reference value of the paper compared with ours. Status: **match** = within print "
        "precision (half a unit of the last printed digit); **close** = relative error ≤ "
        f"{rel_tol:.0%}; **differs** = otherwise; **not computed** = we have no value (e.g. Table I rows "
        "with shapes 4 and 5, whose landmarks are not public). Ours are shown in the paper's printed units. "
        "The ratio CV (std/mean of ours/paper over the pairs) measures proportionality: a column with an "
        "unexplained constant factor has a median ratio ≠ 1 but a small CV."
    )
    lines.append("")
    if runs:
        lines += ["## Runs", "", "| notebook | mode | seconds |", "|---|---|---|"]
        for name, info in sorted(runs.items()):
            lines.append(f"| {name} | {info.get('mode', '?')} | {_fmt(info.get('seconds'), '.1f')} |")
        if any(info.get("mode") == "quick" for info in runs.values()):
            lines += ["", "**Some notebooks ran with quick (CI) parameters: their numbers are not the full study's.**"]
        lines.append("")
    summaries = _summaries(table)
    lines += ["## Summary", "", "| item | column | compared | match | close | differs | not computed | median ratio | ratio CV | ratio max/min − 1 | Spearman | Kendall |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        lines.append(
            f"| {s.item} | {s.column} | {s.n} | {s.counts['match']} | {s.counts['close']} | {s.counts['differs']} | "
            f"{s.n_ref - s.n} | {_fmt(s.median_ratio)} | {_fmt(s.ratio_cv, '.2%')} | {_fmt(s.ratio_spread, '.2%')} | {_fmt(s.spearman, '.3f')} | {_fmt(s.kendall, '.3f')} |"
        )
    lines.append("")
    for s in summaries:
        g = table[(table["item"] == s.item) & (table["column"] == s.column)]
        got = g[g["status"] != "not computed"]
        if not len(got):
            continue
        lines += [f"## {s.item} — {s.column}", ""]
        note = notes.get(f"{s.item}/{s.column}") or notes.get(s.item)
        if note:
            lines += [str(note), ""]
        lines += ["| row | paper (printed) | ours (printed units) | ratio | rel. error | tolerance (abs, printed units) | status |",
                  "|---|---|---|---|---|---|---|"]
        for _, r in got.iterrows():
            sc = r["scale"]
            lines.append(
                f"| {r['row']} | {r['printed']} | {r['ours'] / sc:.4f} | {r['ratio']:.5f} | {r['rel_err']:.3%} | "
                f"{r['abs_tol'] / sc:.3g} | {r['status']} |"
            )
        lines.append("")
    return "\n".join(lines) + "\n"


def write_report(results_dir, reference_dir, *, rel_tol: float = REL_TOL) -> Path:
    """Compare everything in ``results_dir`` with ``reference_dir`` and write ``results_dir/REPORT.md``."""
    from .study import _atomic_write_text

    results_dir = Path(results_dir)
    values, notes, runs = collect_values(results_dir)
    table = compare(load_reference(reference_dir), values, rel_tol=rel_tol)
    path = results_dir / "REPORT.md"
    _atomic_write_text(path, render_report(table, notes, runs, rel_tol=rel_tol))
    _atomic_write_text(results_dir / "comparison.csv", table.to_csv(index=False))
    return path
