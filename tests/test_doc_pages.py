"""Every code block of the hand-written documentation pages runs, as a reader would run it.

Each page's ```python blocks are executed in order in one namespace, in an empty folder, with the
datasets of ``SHAPELIB_DATA_DIR``; the ``shapelib ...`` and ``python ...`` lines of its shell
blocks (```bash, ```console) run in the same folder, after the Python blocks above them. A page
therefore has to make the files its commands read (from a dataset loader, or with the writers of
:mod:`shapelib.io`), as the reader would. A Python block whose first line is ``# name.py`` is a file
the reader saves: it is written to the folder as well as executed.

A block that cannot run here (a Dask scheduler at an example address, ``make results``) is marked
in the page by a MyST comment on the line just above its fence, which the site does not show::

    % doc: skip-run (needs a Dask scheduler at that address)

The marks are counted below (``SKIPPED``), so that skipping stays rare and visible. A block that
shows an error on purpose is marked ``% doc: raises (InputError)``: it must raise that error.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys

import matplotlib
import pytest

from tests.conftest import ROOT, requires_data

matplotlib.use("Agg")

DOCS = ROOT / "docs"
#: the hand-written pages (the gallery is executed by the docs build, the notebooks by run_all.py)
PAGES = sorted([*DOCS.glob("*.md"), *(DOCS / "guide").glob("*.md")])

FENCE = re.compile(r"^(?:% doc: (?P<mark>[^\n]*)\n)?```(?P<lang>python|bash|console|shell|sh)[ \t]*\n"
                   r"(?P<code>.*?)^```[ \t]*$", flags=re.M | re.S)
SKIP = re.compile(r"skip-run \((?P<reason>[^)]+)\)$")
RAISES = re.compile(r"raises \((?P<error>\w+)\)$")

#: blocks marked ``% doc: skip-run (...)``, page by page: a new mark must be added here too
SKIPPED = {
    "getting-started.md": 2,  # make setup; SHAPELIB_DATA_DIR (the test suite runs in that environment)
    "installation.md": 2,  # pip install into the environment; python -m build
    "performance.md": 1,  # the benchmarks themselves (a quarter of an hour and more)
    "guide/population.md": 3,  # a Dask scheduler and workers on other machines
    "guide/study.md": 1,  # make results, make test, make docs
    "guide/semilandmarks.md": 2,  # sliding does not converge on the example files (procrustes; tps curves)
}


def code_blocks(text: str) -> list[tuple[int, str, str, str | None]]:
    """``[(line, language, code, skip reason or None)]`` of a page's Python and shell blocks."""
    return [(line, lang, code, reason) for line, lang, code, reason, _ in _blocks(text)]


def _blocks(text: str) -> list[tuple[int, str, str, str | None, str | None]]:
    """``[(line, language, code, skip reason, expected error)]``, the last two None when unmarked."""
    blocks = []
    for m in FENCE.finditer(text):
        reason = error = None
        if m.group("mark") is not None:
            mark = m.group("mark").strip()
            skip, raises = SKIP.fullmatch(mark), RAISES.fullmatch(mark)
            if not (skip or raises):
                raise ValueError(f"unknown mark '% doc: {mark}' (use '% doc: skip-run (reason)' or "
                                 "'% doc: raises (ErrorName)')")
            reason = skip.group("reason") if skip else None
            error = raises.group("error") if raises else None
        line = text.count("\n", 0, m.start("lang")) + 1
        blocks.append((line, m.group("lang"), m.group("code"), reason, error))
    return blocks


def shell_commands(code: str) -> list[list[str]]:
    """The commands of a shell block: continuation lines joined, ``$ `` prompts and comments removed."""
    commands = []
    for line in code.replace("\\\n", " ").splitlines():
        line = line.strip()
        if line.startswith("$ "):
            line = line[2:]
        argv = shlex.split(line, comments=True)
        if argv:
            commands.append(argv)
    return commands


def run_shell(argv: list[str], where: str) -> None:
    """Run one documented command in the current folder: ``shapelib`` in this process, ``python`` in a child."""
    from shapelib.cli import main

    if argv[0] == "shapelib":
        try:
            status = main(argv[1:])
        except SystemExit as stop:  # --help
            status = stop.code
        assert status == 0, f"{where}: `{shlex.join(argv)}` exited with {status}"
    elif argv[0] == "python":
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.getcwd(), str(ROOT), os.environ.get("PYTHONPATH", "")])}
        proc = subprocess.run([sys.executable, *argv[1:]], capture_output=True, text=True, env=env)
        assert proc.returncode == 0, f"{where}: `{shlex.join(argv)}` failed:\n{proc.stdout}\n{proc.stderr}"
    else:
        raise AssertionError(f"{where}: `{shlex.join(argv)}` is neither a shapelib nor a python command; "
                             "mark the block '% doc: skip-run (reason)' if it cannot run in the tests")


def test_the_page_reader_finds_blocks_marks_and_commands():
    text = ("Text\n\n```python\nx = 1\n```\n\n% doc: skip-run (needs a cluster)\n```bash\ndask worker a\n```\n"
            "```console\n$ shapelib info a.tps \\\n    --json  # a comment\n\n```\n```text\nnot code\n```\n")
    blocks = code_blocks(text)
    assert [(line, lang, reason) for line, lang, _, reason in blocks] == [
        (3, "python", None), (8, "bash", "needs a cluster"), (11, "console", None)]
    assert shell_commands(blocks[2][2]) == [["shapelib", "info", "a.tps", "--json"]]
    with pytest.raises(ValueError, match="unknown mark"):
        code_blocks("% doc: skip this\n```python\nx\n```\n")
    assert _blocks("% doc: raises (InputError)\n```python\nx\n```\n") == [(2, "python", "x\n", None, "InputError")]


def test_every_page_with_code_is_executed_and_skips_are_counted():
    marked = {}
    for page in PAGES:
        n = sum(reason is not None for *_, reason in code_blocks(page.read_text()))
        if n:
            marked[str(page.relative_to(DOCS))] = n
    assert marked == SKIPPED


#: the pages whose code starts a Dask cluster: run by `make test-processes` (CI) and `make test-all`
STARTS_PROCESSES = {"guide/intrinsic.md", "guide/long-runs.md", "guide/population.md"}


@requires_data
@pytest.mark.parametrize("page", [pytest.param(p, marks=[pytest.mark.processes]
                                               if str(p.relative_to(DOCS)) in STARTS_PROCESSES else [])
                                  for p in PAGES if code_blocks(p.read_text())],
                         ids=lambda p: str(p.relative_to(DOCS)))
def test_every_code_block_of_the_page_runs(page, tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    from shapelib.distances import _REGISTRY

    registered = set(_REGISTRY)  # a page may register a metric (docs/guide/long-runs.md)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.syspath_prepend(str(tmp_path))  # a module the page writes (mymetrics.py) imports
    namespace: dict = {"__name__": "__main__"}
    name = str(page.relative_to(DOCS))
    try:
        for line, lang, code, reason, error in _blocks(page.read_text()):
            if reason is not None:
                continue
            where = f"docs/{name}, line {line}"
            if error is not None:
                with pytest.raises(Exception) as raised:
                    exec(compile(code, where, "exec"), namespace)
                assert type(raised.value).__name__ == error, f"{where}: raised {raised.value!r}, not {error}"
                continue
            if lang == "python":
                module = re.match(r"# (\w+\.py)\n", code)  # a file the reader saves ("# mymetrics.py")
                if module:
                    (tmp_path / module.group(1)).write_text(code)
                exec(compile(code, where, "exec"), namespace)
            else:
                for argv in shell_commands(code):
                    run_shell(argv, where)
    finally:
        plt.close("all")
        for metric in set(_REGISTRY) - registered:
            del _REGISTRY[metric]


# ---------------------------------------------------------------------------------------------
# one number per fact: figures quoted in the prose are those of their source


def test_the_quoted_iteration_costs_are_the_benchmark_records():
    """docs/performance.md quotes the cost of a solver iteration: the record's seconds over its iterations."""
    import json

    rows = json.loads((DOCS / "_data" / "benchmarks" / "bench_geodesic.json").read_text())["results"]["rows"]
    alpha_ms = 1000 * rows["alpha-default"]["seconds"] / rows["alpha-default"]["iterations"]
    fr_s = rows["fr-default"]["seconds"] / rows["fr-default"]["iterations"]
    text = " ".join((DOCS / "performance.md").read_text().split())
    assert f"an α iteration costs about {alpha_ms:.0f} ms" in text
    assert f"a Fisher–Rao iteration about {fr_s:.1f} s" in text
    solver = (ROOT / "shapelib" / "solver" / "geodesic.py").read_text()
    assert not re.search(r"~?\d(\.\d+)? s against", solver)  # no second figure for the same cost


def test_the_quoted_mpeg7_scores_are_the_full_test_record():
    """The README and the retrieval guide quote the full 1,400-shape bull's-eye of the Fisher–Rao bound
    (σ² = 0.005 and 0.01, raw and re-ranked) as ``bench_retrieval.py --full --scores`` recorded it."""
    import json

    data = json.loads((DOCS / "_data" / "benchmarks" / "bench_retrieval_full.json").read_text())
    r = data["results"]
    assert r["n_shapes"] == 1400 and r["classes"] == 70 and "--full" in data["command"]
    runs = {run["sigma2"]: {"raw": run["raw"], **{f"re-ranked {m}": v["all"] for m, v in run.get("reranked", {}).items()}}
            for run in r["sweep"] if run["metric"] == "fisher_rao_bound" and run["points"] == 100}
    best = runs[0.005]
    readme = " ".join((ROOT / "README.md").read_text().split())
    guide = " ".join((DOCS / "guide" / "retrieval.md").read_text().split())
    assert f"bull's-eye: {100 * best['raw']:.1f} % rigid" in readme
    # the σ² table: the best cell in bold, the σ² = 0.01 cell beside it
    row = re.search(r"\| Fisher–Rao bound modulo similarity \|([^\n]*)", (DOCS / "guide" / "retrieval.md").read_text())
    cells = [c.strip() for c in row.group(1).split("|")]
    assert cells[1] == f"**{100 * best['raw']:.2f} %**" and cells[2] == f"{100 * runs[0.01]['raw']:.2f} %"
    assert f"scores {100 * best['raw']:.2f} %" in guide
    # the re-ranking table's all-70 row (σ² = 0.01) and the sentence on σ² = 0.005
    at01 = runs[0.01]
    assert (f"| all 70 classes | {100 * at01['raw']:.2f} % | {100 * at01['re-ranked tpg']:.2f} % | "
            f"{100 * at01['re-ranked lcdp']:.2f} % |") in guide
    assert (f"σ² = 0.005 ({100 * best['raw']:.2f} %), the same parameters give {100 * best['re-ranked tpg']:.2f} % "
            f"(TPG) and {100 * best['re-ranked lcdp']:.2f} % (LCDP) on all 1,400 shapes") in guide
    assert r["rerank"] == {"tpg": {"k": 8, "mu": 1.2, "n_iter": 20}, "lcdp": {"k": 10, "mu": 0.8, "n_iter": 10}}
    # the subset pages compute their own scores and say so, quoting none
    gallery = (DOCS / "examples" / "pointsets" / "plot_retrieval.py").read_text()
    assert "not comparable" in gallery and not re.search(r"\d\d\.\d+ %", gallery)
    assert "about 89 %" not in guide


@requires_data
def test_the_quoted_landmark_spacings_of_sigma2_are_computed_ones():
    """σ² = 0.1, 0.5, 1.5 at the corpus callosum's centroid size 20 are σ = 1.1, 2.6 and 4.5
    spacings (and σ² = 1.2 for the ADHD-200 outlines 2.6), wherever a page says so."""
    import shapelib as sl
    from shapelib.datasets import load_adhd200, load_corpus_callosum

    cc = sl.to_centroid_size(load_corpus_callosum()[0])
    ratios = [f"{sl.sigma_ratio(cc, sigma2=s):.1f}" for s in (0.1, 0.5, 1.5)]
    assert ratios == ["1.1", "2.6", "4.5"]
    one_line = {p: " ".join(p.read_text().split()) for p in (DOCS / "getting-started.md", DOCS / "guide" / "scale.md")}
    assert "σ² = 0.1, 0.5 and 1.5 are 1.1, 2.6 and 4.5 landmark spacings" in one_line[DOCS / "getting-started.md"]
    assert "σ is 1.1, 2.6 and 4.5 times the mean nearest-landmark spacing" in one_line[DOCS / "guide" / "scale.md"]
    assert "σ² = 0.5 is about 2.6 landmark spacings" in (DOCS / "examples" / "landmarks" / "plot_first_geodesic.py").read_text()
    adhd = sl.to_centroid_size(load_adhd200()[0])
    assert f"{sl.sigma_ratio(adhd, sigma2=1.2):.1f}" == "2.6"
    assert "At σ² = 1.2 (σ = 2.6 landmark spacings" in (DOCS / "reproduction.md").read_text()


def test_the_quoted_registration_scores_are_the_cpu_record():
    """The README and the retrieval guide quote the registration distance's full-test bull's-eye on the
    shortlist of 80 (raw and LCDP, the distance as it is now) and the guide's CPU table as
    ``bench_retrieval.py --registration --full`` recorded it: all 1,400 shapes, the shortlist of 80, the
    re-ranking parameters chosen on the rigid bound's classes 1–35, the library's energy weight."""
    import json

    from shapelib.pointsets.registration_distance import ENERGY_WEIGHT

    data = json.loads((DOCS / "_data" / "benchmarks" / "bench_retrieval_registration.json").read_text())
    r = data["results"]
    assert r["classes"] == 70 and "--full" in data["command"] and "--shortlist 80" in data["command"]
    b = r["bullseye"]
    assert b["energy_weight"] == ENERGY_WEIGHT and r["matrix"]["log"]["shortlist"]["shortlist"] == 80
    assert b["rerank"] == {"tpg": {"k": 8, "mu": 1.2, "n_iter": 20}, "lcdp": {"k": 10, "mu": 0.8, "n_iter": 10}}
    reg = b["table"]["registration"]
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert f"{100 * reg['raw']:.2f} % ({100 * reg['re-ranked lcdp']:.2f} % re-ranked)" in readme
    guide = (DOCS / "guide" / "retrieval.md").read_text()
    for name, label, bold in (("rigid fisher_rao_bound", "rigid Fisher–Rao bound (σ² = 0.01)", (False, False)),
                              ("registration", "registration distance, shortlist 80", (True, True)),
                              ("registration × rigid bound", "registration distance × rigid bound, shortlist 80",
                               (False, True))):
        row = b["table"][name]
        cell = [f"{100 * row[k]:.2f} %" for k in ("raw", "re-ranked tpg", "re-ranked lcdp")]
        cell[0], cell[2] = (f"**{c}**" if on else c for c, on in zip((cell[0], cell[2]), bold))
        assert f"| {label} | " + " | ".join(cell) + " |" in guide, name
    for half, row in b["halves"].items():
        cell = " | ".join(f"{100 * row[k]:.2f} %" for k in ("raw", "re-ranked tpg", "re-ranked lcdp"))
        assert f"| registration distance, {half} alone | {cell} |" in guide, half


def test_the_quoted_registration_scores_are_the_device_record():
    """The retrieval guide quotes the GPU run's full-test bull's-eye of σ² alone (the shortlist fixed before
    the run, raw and LCDP) and its table rows as ``bench_retrieval.py --from-device`` recorded them; the
    record covers all 1,400 shapes and at least that shortlist, and says which device ran it."""
    import json

    r = json.loads((DOCS / "_data" / "benchmarks" / "bench_retrieval_device.json").read_text())["results"]
    assert r["n_shapes"] == 1400 and r["complete_shortlist"] >= r["reported_shortlist"]
    assert all(run["device"]["platform"] == "gpu" for run in r["runs"])
    row = next(s for s in r["shortlists"] if s["k"] == r["reported_shortlist"])
    guide = (DOCS / "guide" / "retrieval.md").read_text()
    assert (f"| registration misfit | {row['k']} | **{100 * row['raw']:.2f} %** | {100 * row['tpg']:.2f} % | "
            f"**{100 * row['lcdp']:.2f} %** |") in guide
    rigid = r["rigid"]
    assert (f"| rigid Fisher–Rao bound (σ² = {r['shortlist_sigma2']:g}) | — | {100 * rigid['raw']:.2f} % | "
            f"{100 * rigid['tpg']:.2f} % | {100 * rigid['lcdp']:.2f} % |") in guide
    chosen = r["chosen"]["lcdp"]
    assert (f"| {chosen['combine']} bound | {chosen['k']} | {100 * chosen['all']['raw']:.2f} % | "
            f"{100 * chosen['all']['tpg']:.2f} % | {100 * chosen['all']['lcdp']:.2f} % |") in guide
