"""The comparison report: every stored reference value of the paper against ours.

Reference values live in ``data/reference/*.csv`` (one row per printed number, with its
provenance: item, row, column, printed text, scale, decimals); ``regression_<name>.csv`` files
there hold our own checked values instead (same columns plus ``rel_tol``) and are never counted
as paper comparisons. Our values come from each notebook's ``results/<name>/values.json``. For
each reference value the report gives the paper's value, ours, their ratio, the relative error,
the tolerance and a status. With ``abs_tol`` = half a unit of the last printed digit (in the
quantity's units) and ``rel_tol`` (default 1 %):

``match``
    ``|ours − paper| ≤ abs_tol``: equal to print precision.
``close``
    not a match, but ``|ours − paper| ≤ rel_tol · |paper|``.
``proportional``
    "proportional (one constant per metric)": not match or close, but the notebook recorded a
    constant ``k`` for the column (value ``constant/<item>/<column>``) and ``k · ours`` passes
    the match or close test: ``|k · ours − paper| ≤ max(abs_tol, rel_tol · |paper|)``. The
    constant is one fit per metric (pooled over the metric's columns, least squares on log
    ratios), times a power of ten for a column whose printed scale is shown to be misprinted;
    the notebook states how it was fitted ("Fitted conventions" in ``REPORT.md``). ``ratio`` and
    ``rel_err`` stay those of ``ours`` itself.
``differs``
    anything else.
``not computed``
    no value of ours (e.g. Table I rows involving shapes 4 and 5, whose landmarks are not public).

Other sections of ``REPORT.md``, all generated from what the notebooks recorded:

* "Failed notebooks": the ``failures`` passed to :func:`write_report` (``[(notebook, message)]``;
  ``run_all.py`` passes the failing cell in the message).
* "Fitted conventions": per column with a note ``convention/<item>/<column>`` (a dict with
  ``column``, ``convention``, ``k`` and a generated ``sentence``), the fit statistics recorded as
  values ``fit/<item>/<column>/<convention>/<statistic>_<n pairs>``.
* "Figures": every verdict recorded with :func:`shapelib.study.record_verdict`
  (notes ``verdict/<item>``).
* "Regression checks": ``regression_*.csv`` against our values; status ``ok`` when
  ``|ours − value| ≤ rel_tol · |value|``, ``regressed`` otherwise, ``quick run`` when the
  notebook ran with its quick (CI) parameters (not comparable), ``not computed`` if missing.
* A notebook's ``report_section.md`` (markdown it generated from its numbers) goes under
  "Beyond the paper" when the notebook recorded no reference value and no verdict, otherwise
  under "Notes from <notebook>".
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .._files import write_text_atomic

__all__ = ["fit_constant", "load_reference", "load_regression", "collect_values", "collect_sections", "compare",
           "compare_regression", "render_report", "write_report", "REL_TOL", "STATUSES", "SECTION_FILE"]

REL_TOL = 0.01
STATUSES = ("match", "close", "proportional", "differs")
SECTION_FILE = "report_section.md"
REGRESSION_PREFIX = "regression_"


def fit_constant(paper, ours, *, abs_tol=None) -> dict:
    """Fit ``paper ≈ k · ours`` with one constant and measure how well it fits.

    ``k`` is the least-squares fit on log ratios, ``k = exp(mean log(paper / ours))`` (the
    geometric mean of the ratios: every pair weighs the same, whatever its size).

    A printed value is only known to half a unit of its last digit, so a column printed with few
    digits has a ratio spread that no constant can remove. With ``abs_tol`` (that half unit, per
    value) the fit also gives the spread that print rounding does *not* explain: each ratio may
    move anywhere in its rounding interval ``[(paper − abs_tol) / ours, (paper + abs_tol) / ours]``,
    and ``cv_beyond_rounding`` is the smallest CV of the moved ratios over every constant, i.e.
    ``min_c CV(clip(c, lo_i, hi_i))``. It is 0 exactly when one constant reproduces every printed
    value to its last digit, and never exceeds ``cv``.

    Parameters
    ----------
    paper, ours : array_like
        Positive values, pair by pair.
    abs_tol : float or array_like, optional
        Half a unit of each printed value's last digit, in the units of ``paper`` (non-negative).

    Returns
    -------
    dict
        ``k``; ``median`` of the ratios paper/ours; ``cv`` = std/mean of the ratios (population
        std); ``max_min`` = max/min − 1 of the ratios; ``n`` pairs; with ``abs_tol`` also
        ``cv_beyond_rounding`` and ``k_rounding``, the constant attaining it.

    Raises
    ------
    ValueError
        If the arrays differ in shape, are empty, or hold a non-positive or non-finite value, or
        ``abs_tol`` is negative, non-finite or of another shape.
    """
    paper = np.asarray(paper, dtype=np.float64)
    ours = np.asarray(ours, dtype=np.float64)
    if paper.shape != ours.shape or paper.ndim != 1 or not len(paper):
        raise ValueError(f"paper and ours must be non-empty 1-d arrays of one shape; got {paper.shape} and {ours.shape}")
    if not (np.all(np.isfinite(paper)) and np.all(np.isfinite(ours)) and np.all(paper > 0) and np.all(ours > 0)):
        raise ValueError("fit_constant needs finite positive values")
    r = paper / ours
    out = {"k": float(np.exp(np.mean(np.log(r)))), "median": float(np.median(r)), "cv": float(r.std() / r.mean()),
           "max_min": float(r.max() / r.min() - 1), "n": int(len(r))}
    if abs_tol is not None:
        try:
            tol = np.broadcast_to(np.asarray(abs_tol, dtype=np.float64), paper.shape)
        except ValueError:
            raise ValueError(f"abs_tol must be a scalar or match paper's shape {paper.shape}; got "
                             f"{np.shape(abs_tol)}") from None
        if not (np.all(np.isfinite(tol)) and np.all(tol >= 0)):
            raise ValueError("abs_tol must be finite and non-negative")
        out["cv_beyond_rounding"], out["k_rounding"] = _cv_beyond_rounding(r, tol / ours)
    return out


def _cv_beyond_rounding(r, half_width) -> tuple[float, float]:
    """``min_c CV(clip(c, r − w, r + w))`` and its ``c`` (see :func:`fit_constant`).

    The CV is smooth between the interval ends, so it is scanned on a grid spanning them and the
    best grid point refined by a bounded scalar minimisation.
    """
    from scipy.optimize import minimize_scalar

    lo, hi = np.maximum(r - half_width, np.finfo(float).tiny), r + half_width

    def cv(c):
        moved = np.clip(c, lo, hi)
        return moved.std() / moved.mean()

    grid = np.linspace(lo.min(), hi.max(), 4001)
    moved = np.clip(grid[:, None], lo, hi)
    cvs = moved.std(axis=1) / moved.mean(axis=1)
    i = int(np.argmin(cvs))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    res = minimize_scalar(cv, bounds=(a, b), method="bounded", options={"xatol": 1e-12 * max(abs(b), 1.0)})
    best, c = (float(res.fun), float(res.x)) if res.fun <= cvs[i] else (float(cvs[i]), float(grid[i]))
    return min(best, float(r.std() / r.mean())), c


def _read_csvs(paths) -> pd.DataFrame:
    frames = [pd.read_csv(p, comment="#", dtype={"printed": str}) for p in paths]
    ref = pd.concat(frames, ignore_index=True)
    dup = ref["key"][ref["key"].duplicated()]
    if len(dup):
        raise ValueError(f"duplicate reference keys: {sorted(dup)[:5]}")
    return ref.set_index("key")


def load_reference(reference_dir) -> pd.DataFrame:
    """The paper's values: ``reference_dir/*.csv`` except ``regression_*.csv``, indexed by ``key``."""
    paths = [p for p in sorted(Path(reference_dir).glob("*.csv")) if not p.name.startswith(REGRESSION_PREFIX)]
    if not paths:
        raise FileNotFoundError(f"no reference CSV files in {reference_dir}")
    return _read_csvs(paths)


def load_regression(reference_dir) -> pd.DataFrame:
    """Our own checked values: ``reference_dir/regression_*.csv`` (columns of the reference files plus
    ``rel_tol``), indexed by ``key``; empty if there are none.

    Raises
    ------
    ValueError
        If a file lacks ``rel_tol`` or a ``rel_tol`` is not a positive number (the file is named).
    """
    paths = sorted(Path(reference_dir).glob(f"{REGRESSION_PREFIX}*.csv"))
    if not paths:
        return pd.DataFrame(columns=["item", "row", "column", "value", "rel_tol"]).rename_axis("key")
    for p in paths:
        head = pd.read_csv(p, comment="#")
        if "rel_tol" not in head or not (pd.to_numeric(head["rel_tol"], errors="coerce") > 0).all():
            raise ValueError(f"{p}: every row needs a positive rel_tol")
    return _read_csvs(paths)


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


def paper_notebooks_in(results_dir, reference: pd.DataFrame) -> set:
    """Notebooks that recorded a reference value of the paper or a figure verdict."""
    out = set()
    for path in sorted(Path(results_dir).glob("*/values.json")):
        data = json.loads(path.read_text())
        if set(data.get("values", {})) & set(reference.index) or any(k.startswith("verdict/") for k in data.get("notes", {})):
            out.add(path.parent.name)
    return out


def collect_sections(results_dir) -> dict:
    """``{notebook: markdown}`` of every ``results_dir/<notebook>/report_section.md``."""
    return {p.parent.name: p.read_text().strip() for p in sorted(Path(results_dir).glob(f"*/{SECTION_FILE}"))}


def constants_from(values: dict) -> dict:
    """``{(item, column): k}`` from the values ``constant/<item>/<column>``."""
    out = {}
    for key, (v, _) in values.items():
        if key.startswith("constant/"):
            parts = key.split("/")
            if len(parts) != 3 or not (np.isfinite(v) and v > 0):
                raise ValueError(f"{key!r}: constants are named constant/<item>/<column> and positive; got {v!r}")
            out[(parts[1], parts[2])] = float(v)
    return out


def compare(reference: pd.DataFrame, values: dict, *, rel_tol: float = REL_TOL, constants: dict | None = None) -> pd.DataFrame:
    """One row per reference value with ours, ratio, relative error, tolerance and status.

    ``constants`` maps ``(item, column)`` to the fitted constant ``k`` (see the module docstring,
    status ``proportional``); by default they are read from the ``constant/…`` entries of ``values``.
    """
    constants = constants_from(values) if constants is None else constants
    rows = []
    for key, ref in reference.iterrows():
        paper = float(ref["value"])
        abs_tol = 0.5 * 10.0 ** (-int(ref["decimals"])) * float(ref["scale"])
        k = constants.get((ref["item"], ref["column"]), np.nan)
        row = dict(key=key, item=ref["item"], row=ref["row"], column=ref["column"], printed=ref["printed"],
                   scale=float(ref["scale"]), paper=paper, abs_tol=abs_tol, ours=np.nan, notebook="",
                   ratio=np.nan, rel_err=np.nan, constant=k, status="not computed")
        if key in values:
            ours, nb = values[key]
            row.update(ours=ours, notebook=nb)
            row["ratio"] = ours / paper if paper != 0 else np.nan
            row["rel_err"] = abs(ours - paper) / abs(paper) if paper != 0 else np.nan
            # a hair of slack so that a value printed from the exact same number is a match
            slack = 1 + 1e-9
            if abs(ours - paper) <= abs_tol * slack + 1e-15:
                row["status"] = "match"
            elif row["rel_err"] <= rel_tol:
                row["status"] = "close"
            elif np.isfinite(k) and abs(k * ours - paper) <= max(abs_tol, rel_tol * abs(paper)) * slack + 1e-15:
                row["status"] = "proportional"
            else:
                row["status"] = "differs"
        rows.append(row)
    return pd.DataFrame(rows)


def compare_regression(regression: pd.DataFrame, values: dict, runs: dict) -> pd.DataFrame:
    """One row per regression value: reference, ours, relative difference, ``rel_tol`` and status."""
    rows = []
    for key, ref in regression.iterrows():
        want, tol = float(ref["value"]), float(ref["rel_tol"])
        row = dict(key=key, value=want, rel_tol=tol, ours=np.nan, rel_diff=np.nan, notebook="", status="not computed")
        if key in values:
            ours, nb = values[key]
            diff = abs(ours - want) / abs(want) if want != 0 else abs(ours)
            row.update(ours=ours, rel_diff=diff, notebook=nb)
            if runs.get(nb, {}).get("mode") == "quick":
                row["status"] = "quick run"
            else:
                row["status"] = "ok" if diff <= tol else "regressed"
        rows.append(row)
    return pd.DataFrame(rows, columns=["key", "value", "rel_tol", "ours", "rel_diff", "notebook", "status"])


@dataclass
class _ColumnSummary:
    item: str
    column: str
    n_ref: int
    n: int
    counts: dict
    constant: float
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
        k = float(g["constant"].iloc[0]) if "constant" in g else np.nan
        out.append(_ColumnSummary(item, column, len(g), len(got), counts, k, med, spread, cv, rho, tau))
    return out


def _fmt(x, spec=".4g"):
    return "—" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


def _cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


_FIT_KEY = re.compile(r"^fit/(?P<item>[^/]+)/(?P<column>[^/]+)/(?P<conv>[^/]+)/(?P<stat>[a-z_]+)_(?P<n>\d+)$")


def _conventions(notes: dict, values: dict) -> list[str]:
    """The "Fitted conventions" section (empty if no notebook recorded one)."""
    fits = {}  # (item, column) -> {convention: {(stat, n): value}}
    ks = {}
    for key, (v, _) in values.items():
        m = _FIT_KEY.match(key)
        if m:
            fits.setdefault((m["item"], m["column"]), {}).setdefault(m["conv"], {})[(m["stat"], int(m["n"]))] = v
        elif key.startswith("fit/") and key.endswith("/k") and key.count("/") == 4:
            _, item, column, conv, _ = key.split("/")
            ks[(item, column, conv)] = v
    out = []
    for note_key, conv in sorted(notes.items()):
        if not note_key.startswith("convention/") or not isinstance(conv, dict):
            continue
        _, item, ref_column = note_key.split("/", 2)
        column, best = conv.get("column", ref_column), conv.get("convention")
        out += [f"### {item} — {ref_column}", ""]
        table = fits.get((item, column), {})
        sets = sorted({n for stats in table.values() for (_, n) in stats}, reverse=True)
        if table:
            rounding = any(s == "cv_beyond_rounding" for stats in table.values() for (s, _) in stats)
            labels = ("median", "CV", "max/min − 1") + (("CV beyond print rounding",) if rounding else ())
            head = ["convention", "k (fit on log ratios)"] + [f"{s} ({n} pairs)" for n in sets for s in labels]
            out += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
            for name, stats in table.items():
                cells = [f"**{name}** (fitted)" if name == best else name, _fmt(ks.get((item, column, name)))]
                for n in sets:
                    cells += [_fmt(stats.get(("median", n))), _fmt(stats.get(("cv", n)), ".2%"),
                              _fmt(stats.get(("max_min", n)), ".2%")]
                    if rounding:
                        cells.append(_fmt(stats.get(("cv_beyond_rounding", n)), ".2%"))
                out.append("| " + " | ".join(cells) + " |")
            out.append("")
        if conv.get("sentence"):
            out += [str(conv["sentence"]), ""]
    if out:
        out = ["## Fitted conventions", "",
               "For each column with a fitted convention: one constant k (paper ≈ k × ours) per convention tried, "
               "the spread of the ratios paper/ours over each set of pairs (and the part of it that rounding the "
               "printed values to their last digit cannot explain), and the convention used for the values above (bold). The sentences are generated by the notebook from the same numbers.", ""] + out
    return out


def _figures(notes: dict) -> list[str]:
    verdicts = {k.split("/", 1)[1]: v for k, v in notes.items() if k.startswith("verdict/") and isinstance(v, dict)}
    if not verdicts:
        return []
    counts = {s: sum(v.get("status") == s for v in verdicts.values())
              for s in ("reproduced", "reproduced with a difference", "not reproduced")}
    out = ["## Figures", "", "Verdict on each figure or section against the paper's caption and text, measured by its "
           "notebook: " + ", ".join(f"{n} {s}" for s, n in counts.items()) + ".", "",
           "| item | verdict | what was measured |", "|---|---|---|"]
    for item in sorted(verdicts):
        v = verdicts[item]
        out.append(f"| {item} | {_cell(v.get('status', '?'))} | {_cell(v.get('text', ''))} |")
    return out + [""]


def render_report(table: pd.DataFrame, notes: dict, runs: dict, *, rel_tol: float = REL_TOL, values: dict | None = None,
                  failures=None, sections: dict | None = None, regression: pd.DataFrame | None = None,
                  paper_notebooks=None) -> str:
    """Markdown text of ``REPORT.md`` (sections described in the module docstring)."""
    values = values or {}
    lines = ["# shapelib: reproduction report", ""]
    lines.append(
        "Every stored reference value of the paper compared with ours. Status: **match** = within print "
        "precision (half a unit of the last printed digit); **close** = relative error ≤ "
        f"{rel_tol:.0%}; **proportional** (one constant per metric) = neither, but k × ours is within print "
        f"precision or {rel_tol:.0%} of the paper's value, k being the column's recorded constant (fitted once per "
        "metric, see 'Fitted conventions'); **differs** = otherwise; **not computed** = we have no value (e.g. "
        "Table I rows with shapes 4 and 5, whose landmarks are not public). Ours are shown in the paper's printed "
        "units. The ratio CV (std/mean of ours/paper over the pairs) measures proportionality: a column with a "
        "constant factor has a median ratio ≠ 1 but a small CV."
    )
    lines.append("")
    if failures:
        lines += ["## Failed notebooks", "",
                  "These notebooks failed in the last run; their previous results (if any) are used below.", "",
                  "| notebook | error |", "|---|---|"]
        for name, msg in failures:
            lines.append(f"| {_cell(name)} | {_cell(msg)} |")
        lines.append("")
    if runs:
        lines += ["## Runs", "", "| notebook | mode | seconds |", "|---|---|---|"]
        for name, info in sorted(runs.items()):
            lines.append(f"| {name} | {info.get('mode', '?')} | {_fmt(info.get('seconds'), '.1f')} |")
        if any(info.get("mode") == "quick" for info in runs.values()):
            lines += ["", "**Some notebooks ran with quick (CI) parameters: their numbers are not the full study's.**"]
        lines.append("")
    summaries = _summaries(table)
    lines += ["## Summary", "",
              "| item | column | compared | match | close | proportional | differs | not computed | constant k (paper ≈ k × ours) | "
              "median ratio (ours/paper) | ratio CV | ratio max/min − 1 | Spearman | Kendall |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        lines.append(
            f"| {s.item} | {s.column} | {s.n} | {s.counts['match']} | {s.counts['close']} | {s.counts['proportional']} | "
            f"{s.counts['differs']} | {s.n_ref - s.n} | {_fmt(s.constant)} | {_fmt(s.median_ratio)} | {_fmt(s.ratio_cv, '.2%')} | "
            f"{_fmt(s.ratio_spread, '.2%')} | {_fmt(s.spearman, '.3f')} | {_fmt(s.kendall, '.3f')} |"
        )
    lines.append("")
    lines += _conventions(notes, values)
    lines += _figures(notes)
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
    if regression is not None and len(regression):
        counts = regression["status"].value_counts().to_dict()
        lines += ["## Regression checks", "",
                  "Our own earlier values (`data/reference/regression_*.csv`), not the paper's: they catch changes in our "
                  "results and are never counted as paper comparisons. Statuses: "
                  + ", ".join(f"{s} {n}" for s, n in sorted(counts.items())) + " (\"quick run\": not compared).", "",
                  "| key | stored | ours | rel. difference | rel. tolerance | status |", "|---|---|---|---|---|---|"]
        for _, r in regression.iterrows():
            lines.append(f"| {r['key']} | {_fmt(r['value'], '.6g')} | {_fmt(r['ours'], '.6g')} | {_fmt(r['rel_diff'], '.2e')} | "
                         f"{_fmt(r['rel_tol'], '.1e')} | {r['status']} |")
        lines.append("")
    sections = sections or {}
    paper_notebooks = set(paper_notebooks or ())
    for nb, text in sections.items():
        if nb in paper_notebooks:
            lines += [f"## Notes from {nb}", "", text, ""]
    beyond = {nb: text for nb, text in sections.items() if nb not in paper_notebooks}
    if beyond:
        lines += ["## Beyond the paper", ""]
        for nb, text in beyond.items():
            lines += [f"### {nb}", "", text, ""]
    return "\n".join(lines) + "\n"


def write_report(results_dir, reference_dir, *, rel_tol: float = REL_TOL, failures=None) -> Path:
    """Compare everything in ``results_dir`` with ``reference_dir`` and write ``results_dir/REPORT.md``.

    Parameters
    ----------
    results_dir, reference_dir : path-like
    rel_tol : float
        Relative tolerance of the statuses ``close`` and ``proportional``.
    failures : list of (notebook, message), optional
        Notebooks that failed in this run (``run_all.py`` passes them); listed in the report.

    Returns
    -------
    pathlib.Path
        ``results_dir/REPORT.md`` (``comparison.csv`` is written beside it).
    """
    results_dir = Path(results_dir)
    values, notes, runs = collect_values(results_dir)
    reference = load_reference(reference_dir)
    table = compare(reference, values, rel_tol=rel_tol)
    regression = compare_regression(load_regression(reference_dir), values, runs)
    text = render_report(table, notes, runs, rel_tol=rel_tol, values=values, failures=list(failures or []),
                         sections=collect_sections(results_dir), regression=regression,
                         paper_notebooks=paper_notebooks_in(results_dir, reference))
    path = results_dir / "REPORT.md"
    write_text_atomic(path, text)
    write_text_atomic(results_dir / "comparison.csv", table.to_csv(index=False))
    return path
