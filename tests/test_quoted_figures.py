"""One number per fact: every measured figure the user pages quote has a source.

The pages are the README, ``docs/*.md``, ``docs/guide/*.md`` and the gallery examples' text (code blocks
and inline code left out). A *measured figure* is, as the pages write them:

* a percentage with decimals, or a range of percentages one of which has decimals (``78.89 %``,
  ``91.6–100 %``): bull's-eye scores, rates, shares;
* a number with a unit of time (``0.24 s``, ``11 ms``, ``39 minutes``, ``15 s``);
* a speed-up or cost ratio written ``21×`` or ``77 times faster``;
* on the pages that report the registration benchmark (the README and the point-set guide), a comparison
  of two mean errors, shapelib's against a peer's (``0.021 against 0.085``, ``0.021 against CPD's 0.085``).

Counts (``1,400 shapes``, ``56 levels``), σ² values, p-values and integer percentages of a table are not
measured figures in this sense. Each figure needs a source, one of:

1. a value of a benchmark record under ``docs/_data/benchmarks`` that the page draws on
   (:data:`PAGE_RECORDS`), rounded as printed (a fraction in ``[0, 1]`` as a percentage; a time in
   seconds as s, ms, µs, minutes or hours; a speed-up from a ``speedup``/``_over_`` entry; a comparison
   of errors from two entries of the same place in the record, shapelib's and one other method's);
2. a published figure of another method, ``docs/_data/published.toml``, each with its reference;
3. an entry of :data:`DERIVED`: a figure the page computes from a record or states as a setting of the
   library or a benchmark, each with the computation or the setting it must equal;
4. an entry of :data:`STUDY`: a finding of the study (``python run_all.py``; its values are written to the
   run's ``values.json`` and ``REPORT.md``, not to a committed record), quoted the same on every page.
   ``docs/reproduction.md`` is the study's report and is not scanned.

A figure without one fails with the page, the line and the figure.
"""
from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path

import pytest

from shapelib.geometry.procrustes import POSE_TOL
from tests.conftest import ROOT

DOCS = ROOT / "docs"
RECORDS = DOCS / "_data" / "benchmarks"
PUBLISHED = DOCS / "_data" / "published.toml"

#: the pages scanned: the README, the top pages (not the changelog, which is history, nor the study's
#: report), the guide, the gallery examples
PAGES = [ROOT / "README.md",
         *(p for p in sorted(DOCS.glob("*.md")) if p.name not in ("changelog.md", "reproduction.md")),
         *sorted((DOCS / "guide").glob("*.md")), *sorted((DOCS / "examples").glob("*/*.py"))]

#: the benchmark records each page may quote (a page not named here quotes none); on the performance page
#: (``"sections"``) each section quotes the records it renders (its ``{benchmark}`` directives)
PAGE_RECORDS = {
    "README.md": ["bench_retrieval_full", "bench_registration", "bench_retrieval_device",
                  "bench_retrieval_registration"],
    "docs/index.md": ["bench_retrieval_full", "bench_registration"],
    "docs/performance.md": "sections",
    "docs/guide/retrieval.md": ["bench_retrieval_full", "bench_retrieval_registration", "bench_retrieval_device",
                                "bench_articulation", "bench_energy_weight"],
    "docs/guide/pointsets.md": ["bench_registration", "bench_registration_3d", "bench_registration_large",
                                "bench_registration_batch", "bench_registration_landmarks"],
    "docs/guide/solver.md": ["bench_geodesic", "bench_solvers"],
}

#: the pages whose comparisons of registration errors (``0.021 against 0.085``) are measured figures
ERROR_PAGES = ("README.md", "docs/guide/pointsets.md")


def _record(name: str) -> dict:
    return json.loads((RECORDS / f"{name}.json").read_text())["results"]


def _geodesic_iteration(key: str, scale: float, fmt: str) -> str:
    row = _record("bench_geodesic")["rows"][key]
    return fmt.format(scale * row["seconds"] / row["iterations"])


def _setting(path: str, pattern: str) -> str:
    """The first group of ``pattern`` in a source file: a setting the page states."""
    return re.search(pattern, (ROOT / path).read_text()).group(1)


#: ``(page, figure as printed, what it is, the figure it must equal)``: figures a page computes from a record
#: or that state a setting; the last item is computed when the test runs
DERIVED = [
    ("docs/performance.md", "11 ms", "an α iteration: bench_geodesic's α row, seconds over iterations",
     lambda: _geodesic_iteration("alpha-default", 1000, "{:.0f} ms")),
    ("docs/performance.md", "0.4 s",
     "a Fisher–Rao iteration: bench_geodesic's Fisher–Rao row, seconds over iterations",
     lambda: _geodesic_iteration("fr-default", 1, "{:.1f} s")),
    ("docs/performance.md", "80 seconds", "the time bench_gpu.py gives its matrix row by default (a setting)",
     lambda: _setting("benchmarks/bench_gpu.py", r"else (\d+)\.0\)") + " seconds"),
    ("docs/guide/checks.md", "10 s", "the run time from which pairwise_distances estimates its cost (a setting)",
     lambda: _setting("shapelib/pairwise/_driver.py", r"LONG_RUN_SECONDS = (\d+)\.0") + " s"),
    ("docs/guide/checks.md", "0.1 %", "the share of a shape's size from which a pose difference warns (a setting)",
     lambda: "{:.1f} %".format(100 * POSE_TOL)),
    ("docs/guide/retrieval.md", "5.5 %", "a digitised length's excess, the page's formula "
     "4/π · (sin 45° + (√2 − 1)(1 − cos 45°)) − 1",
     lambda: "{:.1f} %".format(100 * (4 / math.pi * (math.sin(math.pi / 4) + (math.sqrt(2) - 1)
                                                     * (1 - math.cos(math.pi / 4))) - 1))),
]

#: ``(page, figure as printed, what it is)``: findings of the study that pages other than its report quote
STUDY = [
    ("README.md", "0.63 %", "the largest share of the shape variation diagnosis explains (also on the report page)"),
    ("docs/guide/group-tests.md", "0.07 %", "the share of the ADHD-200 shape variation age explains"),
    ("docs/guide/intrinsic.md", "2.3 %", "the log map at n = 4 against n = 32, ADHD-200, α, σ² = 1.2"),
    ("docs/guide/intrinsic.md", "1.1 %", "the log map at n = 8 against n = 32, ADHD-200, α, σ² = 1.2"),
    ("docs/guide/scale.md", "0.6–0.7 %", "the share of variation diagnosis explains across the σ sweep"),
]

_NUM = r"\d+(?:\.\d+)?"
PERCENT = re.compile(rf"(?<![\w.,·^-])({_NUM})(?:–({_NUM}))? ?%")
TIME = re.compile(rf"(?<![\w.,·^-])({_NUM})(?:–({_NUM}))? ?"
                  r"(ms|µs|s|seconds|min|minutes|h|hours|core-hours)(?![\w-])")
RATIO = re.compile(rf"(?<![\w.,·^-])({_NUM})(?:–({_NUM}))?(?:×| times (?:faster|slower|cheaper|longer))")
ERROR = re.compile(r"(?<![\w.,·^-])(0\.\d{3}) against (?:[\w-]+'s )?(0\.\d{3})(?!\d)")


def prose(text: str, suffix: str = ".md") -> list[tuple[int, str]]:
    """The lines of a page without its code (fenced blocks and directives, inline code); for a
    gallery example (``.py``), its docstring and comment lines only."""
    out, fenced = [], False
    if suffix == ".py":
        doc = re.match(r'\s*(?:#[^\n]*\n)*\s*"""(.*?)"""', text, flags=re.S)
        keep = set()
        if doc:
            first = text[:doc.start(1)].count("\n") + 1
            keep.update(range(first, first + doc.group(1).count("\n") + 1))
        for i, line in enumerate(text.splitlines(), 1):
            if i in keep or line.lstrip().startswith("#"):
                out.append((i, re.sub(r"``?[^`]*``?", "", line.lstrip("# "))))
        return out
    for i, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
            continue
        if not fenced:
            out.append((i, re.sub(r"`[^`]*`", "", line)))
    return out


def paragraphs(text: str, suffix: str = ".md") -> list[tuple[list[int], str]]:
    """The prose in paragraphs (a figure may be wrapped across lines): ``(line of each character, text)``."""
    out, lines, buf = [], [], ""
    last = None
    for i, line in [*prose(text, suffix), (None, "")]:
        if i is None or not line.strip() or (last is not None and i != last + 1):
            if buf:
                out.append((lines, buf))
            lines, buf = [], ""
        if i is not None and line.strip():
            piece = line.strip() + " "
            buf += piece
            lines += [i] * len(piece)
        last = i
    return out


def quoted_figures(text: str, page: str) -> list[tuple[int, str]]:
    """``(line, figure as printed)`` for every measured figure of a page (module docstring)."""
    found = []
    for lines, para in paragraphs(text, Path(page).suffix):
        for m in PERCENT.finditer(para):
            if "." in m.group(0):
                found.append((lines[m.start()], m.group(0)))
        for m in TIME.finditer(para):
            found.append((lines[m.start()], m.group(0)))
        for m in RATIO.finditer(para):
            found.append((lines[m.start()], m.group(1) + (f"–{m.group(2)}" if m.group(2) else "") + "×"))
        if page in ERROR_PAGES:
            found.extend((lines[m.start()], f"{m.group(1)} against {m.group(2)}") for m in ERROR.finditer(para))
    return sorted(found, key=lambda f: f[0])


def _leaves(obj, path=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaves(v, (*path, str(k)))
    elif isinstance(obj, list):
        for k, v in enumerate(obj):
            yield from _leaves(v, (*path, str(k)))
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool) and not path[-1].isdigit():
        yield path, float(obj)  # not an element of a list of numbers: raw samples are no quoted figure


_TIME_KEY = re.compile(r"wall|cpu|second|time|_s$|hours")
_RATIO_KEY = re.compile(r"speedup|_over_|ratio")
_SCALE = {"ms": 1e3, "µs": 1e6, "s": 1.0, "seconds": 1.0, "min": 1 / 60, "minutes": 1 / 60, "h": 1 / 3600,
          "hours": 1 / 3600, "core-hours": 1 / 3600}


def _matches(printed: str, value: float) -> bool:
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return f"{value:.{decimals}f}" == printed


def _error_pair_source(figure: str, names: list[str]) -> str | None:
    """``A against B``: shapelib's and another method's value at the same place of a record (the path with the
    method's name in it), rounded as printed."""
    a, b = figure.split(" against ")
    for name in names:
        rec = _record(name)
        methods = set(rec.get("methods", []))
        places: dict[tuple, dict[str, float]] = {}
        for path, v in _leaves(rec):
            if not any("error" in p for p in path):
                continue
            named = [p for p in path if p in methods]
            if len(named) == 1:
                place = tuple("*" if p in methods else p for p in path)
                places.setdefault(place, {})[named[0]] = v
        for place, values in places.items():
            if "shapelib" in values and _matches(a, values["shapelib"]) and any(
                    _matches(b, v) for m, v in values.items() if m != "shapelib"):
                return f"{name}: {'/'.join(place)}"
    return None


def record_source(figure: str, names: list[str]) -> str | None:
    """The record value (``name: key path``) a figure is, rounded as printed; ``None`` if there is none."""
    if " against " in figure:
        return _error_pair_source(figure, names)
    numbers = re.findall(_NUM, figure)
    unit = figure.rstrip().split(" ")[-1] if " " in figure else figure[-1]
    for name in names:
        for path, v in _leaves(_record(name)):
            key = "/".join(path)
            if unit == "%":
                # a rate or a score; not an error or a time that happens to lie in [0, 1]
                cands = [100 * v] if 0 <= v <= 1 and not _TIME_KEY.search(key) and "error" not in key else []
            elif unit == "×":
                cands = [v] if _RATIO_KEY.search(path[-1]) else []
            elif unit in _SCALE:
                if not _TIME_KEY.search(key):
                    continue
                # a leaf in hours (key *hours*) is already in hours
                cands = [v * (3600 * _SCALE[unit] if "hours" in path[-1] else _SCALE[unit])]
            else:
                cands = []
            if len(numbers) == 1 and any(_matches(numbers[0], c) for c in cands):
                return f"{name}: {key}"
    return None


def _published() -> set[str]:
    return {entry["figure"] for entries in tomllib.loads(PUBLISHED.read_text()).values() for entry in entries}


def section_records(text: str) -> dict[int, list[str]]:
    """``{line: the records of its section}``: the ``{benchmark}`` directives of each ``##`` section."""
    out, start, names = {}, 1, []
    lines = text.splitlines()
    for i, line in enumerate([*lines, "## end"], 1):
        if line.startswith("## "):
            out.update({j: names for j in range(start, i)})
            start, names = i, []
        names += re.findall(r"^```\{benchmark\} (\S+)", line)
    return out


def sources(page: str, figure: str, records: list[str] = ()) -> list[str]:
    """Where a figure on a page comes from (empty: nowhere); ``records``: those the page may quote there."""
    found = []
    if records:
        src = record_source(figure, list(records))
        if src:
            found.append(src)
    if figure in _published():
        found.append("published.toml")
    found += [what for p, f, what, _ in DERIVED if p == page and f == figure]
    found += [what for p, f, what in STUDY if p == page and f == figure]
    return found


def unsourced(text: str, page: str) -> list[str]:
    """``page:line: figure`` for every measured figure of a page without a source."""
    records = PAGE_RECORDS.get(page, [])
    by_line = section_records(text) if records == "sections" else {}
    return [f"{page}:{line}: {figure}" for line, figure in quoted_figures(text, page)
            if not sources(page, figure, by_line.get(line, []) if records == "sections" else records)]


def _rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


@pytest.mark.parametrize("path", PAGES, ids=_rel)
def test_every_quoted_figure_has_a_source(path):
    page = _rel(path)
    missing = unsourced(path.read_text(), page)
    assert not missing, "figures with no source (record it, list it, or remove it):\n" + "\n".join(missing)


def test_the_derived_figures_are_their_computation():
    """A derived figure is accepted only where the page prints it and it equals its computation now."""
    for page, figure, what, compute in DERIVED:
        assert compute() == figure, (page, figure, what, compute())
        assert figure in " ".join((ROOT / page).read_text().split()), (page, figure)


def test_a_study_finding_is_quoted_on_its_page():
    for page, figure, _ in STUDY:
        assert figure in (ROOT / page).read_text(), (page, figure)
    # a study finding quoted on the README is the one of the report page
    report = (DOCS / "reproduction.md").read_text()
    assert all(figure in report for page, figure, _ in STUDY if page == "README.md")


def test_every_published_figure_has_its_reference_and_is_quoted():
    entries = [e for entries in tomllib.loads(PUBLISHED.read_text()).values() for e in entries]
    text = "".join(p.read_text() for p in PAGES)
    for e in entries:
        assert e["method"] and re.search(r"\b(19|20)\d\d\b", e["reference"]), e
        assert e["figure"] in text, e  # no figure kept that no page quotes


# ---------------------------------------------------------------------------------------------
# the checker itself: it finds what it should, and a wrong figure fails


def test_the_scanner_finds_the_measured_figures_and_not_counts():
    text = ("On all 1,400 shapes (56 levels, 20 classes) it scores 78.89 % and 91.6–100 % with 64 % kept;\n"
            "a pair takes 0.24 s, the matrix 39 minutes, 21× CPD's time, 77 times faster; σ² = 0.005.\n"
            "```python\nx = 12.5  # 3.14 %\n```\n`sigma2s = 2s` and 0.021 against 0.085\n")
    assert [f for _, f in quoted_figures(text, "docs/guide/x.md")] == [
        "78.89 %", "91.6–100 %", "0.24 s", "39 minutes", "21×", "77×"]
    assert [f for _, f in quoted_figures(text, "docs/guide/pointsets.md")][-1] == "0.021 against 0.085"


def test_a_planted_wrong_figure_fails_with_its_page_line_and_number():
    """The contradictions the pages once had (four MPEG-7 scores, two costs of a solver iteration) fail."""
    full = {run["sigma2"]: run for run in _record("bench_retrieval_full")["sweep"]
            if run["metric"] == "fisher_rao_bound"}
    right = f"{100 * full[0.005]['raw']:.2f} %"
    page = "docs/guide/retrieval.md"
    assert not unsourced(f"The best scores {right}.\n", page)
    wrong = f"{100 * full[0.005]['raw'] + 0.1:.2f} %"
    assert unsourced(f"Intro.\nThe best scores {wrong}.\n", page) == [f"{page}:2: {wrong}"]
    assert unsourced("A subset scores 89.10 %.\n", page) == [f"{page}:1: 89.10 %"]
    # a Fisher–Rao iteration's cost, once quoted as ~1.2 s on one page and 0.41 s on another
    perf = (DOCS / "performance.md").read_text()
    assert not unsourced(perf, "docs/performance.md")
    for cost in ("1.2 s", "0.41 s"):
        planted = perf.replace("a Fisher–Rao iteration about 0.4 s", f"a Fisher–Rao iteration about {cost}")
        assert [m.split(": ")[1] for m in unsourced(planted, "docs/performance.md")] == [cost]
    # a registration error of the point-set guide that the record does not hold
    guide = (DOCS / "guide" / "pointsets.md").read_text()
    planted = re.sub(r"(\d\.\d{3}) against (\d\.\d{3}) for pycpd", lambda m: f"0.019 against {m.group(2)} for pycpd",
                     guide, count=1)
    assert not unsourced(guide, "docs/guide/pointsets.md")
    assert planted != guide and [m.split(": ")[1] for m in unsourced(planted, "docs/guide/pointsets.md")] == [
        "0.019 against " + re.search(r"0\.019 against (\d\.\d{3})", planted).group(1)]


def test_the_study_notebooks_quote_the_published_figures_of_the_list():
    """The MPEG-7 notebook's table and report text type other methods' scores in; they are those of the list."""
    published = _published()
    for path in sorted((ROOT / "notebooks").glob("*.py")):
        text = path.read_text()
        for figure in re.findall(r"(?<![\w.{])\d+\.\d+ %", text):
            assert figure in published, (path.name, figure)
        table = re.search(r"published = pd\.DataFrame\(\[(.*?)\], columns", text, flags=re.S)
        if table:
            numbers = re.findall(r",\s*(\d+\.\d+)(?=[,)])", table.group(1))
            assert len(numbers) >= 6 and all(f"{x} %" in published for x in numbers), (path.name, numbers)
