"""The documentation's sources, without running Sphinx: every public name has an API entry, every
command a help page, the README is a short landing page whose example runs, the benchmark records
render as the performance page's tables, and the study notebooks become pages."""
import importlib
import importlib.util
import json
import re
import sys

import numpy as np
import pytest

import run_all
import shapelib
from tests.conftest import ROOT, needs, requires_data

DOCS = ROOT / "docs"
#: modules documented under their own name (``shapelib.io.read_landmarks``); they load on first use
DOCUMENTED_MODULES = ("io", "pairwise", "statistics", "datasets", "plotting")


@pytest.fixture(scope="module")
def docs_ext():
    """docs/_ext/shapelib_docs.py, the Sphinx extension's plain functions."""
    spec = importlib.util.spec_from_file_location("shapelib_docs", DOCS / "_ext" / "shapelib_docs.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["shapelib_docs"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("shapelib_docs", None)


def test_every_public_name_has_an_api_reference_entry(docs_ext):
    entries = docs_ext.api_entries()
    missing = sorted(set(shapelib.__all__) - entries.get("shapelib", set()))
    assert not missing, f"add these names of shapelib.__all__ to an autosummary list in docs/api/index.rst: {missing}"
    for name in DOCUMENTED_MODULES:
        module = getattr(shapelib, name)
        top = entries.get("shapelib", set())
        # a name also served from the top level (the same object) is documented there
        missing = sorted(n for n in set(module.__all__) - entries.get(f"shapelib.{name}", set())
                         if not (n in top and getattr(shapelib, n, None) is getattr(module, n)))
        assert not missing, f"add these names of shapelib.{name}.__all__ to docs/api/index.rst: {missing}"


def test_every_api_entry_is_a_public_name(docs_ext):
    for module_name, names in docs_ext.api_entries().items():
        module = importlib.import_module(module_name)
        public = set(module.__all__)
        stale = sorted(n for n in names if n not in public or not hasattr(module, n))
        assert not stale, f"docs/api: {module_name} does not export {stale}"


def test_the_command_line_reference_shows_every_command(docs_ext):
    text = (DOCS / "api" / "cli.rst").read_text()
    shown = set(re.findall(r"^\.\. cli-help:: (\S+)$", text, flags=re.M))
    assert "\n.. cli-help::\n" in text  # the top-level help
    assert shown == set(docs_ext.cli_commands())
    help_text = docs_ext.cli_help("distances")
    assert help_text.startswith("usage: shapelib distances") and "--metric M" in help_text
    assert "--record-timings" in docs_ext.cli_help("study")  # run_all.py's own help
    with pytest.raises(ValueError, match="no command 'nope'"):
        docs_ext.cli_help("nope")


def test_readme_is_a_short_landing_page():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 120
    for section in ("## Install", "## The two commands", "## Example", "## What the study found", "## Documentation"):
        assert section in text
    assert "make results" in text and "make test" in text
    figure = re.search(r"!\[[^\]]*\]\(([^)]+\.png)\)", text).group(1)
    assert (ROOT / figure).is_file()
    for link in re.findall(r"\]\(((?:docs/|CHANGELOG|CITATION)[^)#]+)\)", text):
        assert (ROOT / link).is_file(), link


USER_DOCS = [ROOT / "README.md", ROOT / "docs" / "index.md", *sorted((ROOT / "docs").glob("*.md")),
             *sorted((ROOT / "docs" / "guide").glob("*.md")), ROOT / "docs" / "notebooks" / "index.md"]


@pytest.mark.parametrize("path", USER_DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_user_facing_text_has_no_issue_numbers_dates_or_load_averages(path):
    """Measurements with their date and load live in the generated performance tables."""
    text = path.read_text()
    for pattern in (r"\bissue[s]? \d", r"#\d{2,}\b", r"\b20\d\d-\d\d-\d\d\b", r"load average", r"\bsession \d"):
        found = re.findall(pattern, text, flags=re.I)
        assert not found, f"{path.name}: {found}"


@requires_data
def test_readme_example_runs():
    text = (ROOT / "README.md").read_text()
    code = re.search(r"## Example\s+```python\n(.*?)```", text, flags=re.S).group(1)
    assert 10 <= len(code.strip().splitlines()) <= 20
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)
    r, b, D = ns["r"], ns["b"], ns["D"]
    assert r.path.shape == (17, 63, 2)
    np.testing.assert_allclose(r.path[0], ns["u"])
    np.testing.assert_allclose(r.path[-1], ns["v"])
    assert r.lower_bound <= r.length
    assert b.lower <= b.upper <= b.lower * (1 + 1e-3)
    assert D.shape == (7, 7)
    np.testing.assert_array_equal(D, D.T)
    np.testing.assert_array_equal(np.diag(D), 0)
    # the matrix holds the same α distance as the single geodesic, within the bracket's tolerance
    assert D[0, 3] == pytest.approx(r.length, rel=2e-3)


def test_every_benchmark_record_renders_with_its_machine_and_date(docs_ext):
    records = sorted((DOCS / "_data" / "benchmarks").glob("*.json"))
    stems = {p.stem for p in records}
    assert set(docs_ext.RENDERERS) - set(docs_ext.OPTIONAL) <= stems <= set(docs_ext.RENDERERS)
    for path in records:
        data = json.loads(path.read_text())
        assert data["machine"]["date"] and data["machine"]["cpus"] and data["command"]
        rendered = docs_ext.benchmark_tables(path.stem)
        assert rendered.provenance.startswith("Measured ") and data["command"] in rendered.provenance
        assert rendered.tables
        for table in rendered.tables:
            assert table.rows and all(len(row) == len(table.header) for row in table.rows), (path.stem, table.title)
    # every record is shown on the performance page
    page = (DOCS / "performance.md").read_text()
    assert set(re.findall(r"```\{benchmark\} (\S+)", page)) == set(docs_ext.RENDERERS)


@requires_data
def test_a_recorded_benchmark_run_renders_as_its_table(docs_ext, tmp_path):
    spec = importlib.util.spec_from_file_location("bench_bracket", ROOT / "benchmarks" / "bench_bracket.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    machine = importlib.import_module("benchmarks._machine")
    with pytest.raises(SystemExit):  # a smoke test is not a measurement
        bench.main(["--quick", "--record"])
    report = bench.main(["--quick"])
    path = machine.record("bench_bracket", report, argv=["--quick"], path=tmp_path / "bench_bracket.json")
    data = json.loads(path.read_text())
    assert data["command"] == "python benchmarks/bench_bracket.py --quick"
    assert data["machine"]["cpus"] and data["machine"]["shapelib"] == shapelib.__version__
    (table,) = docs_ext.benchmark_tables("bench_bracket", data_dir=tmp_path).tables
    assert [row[0] for row in table.rows] == [docs_ext.BRACKET_CASES[c] for c in report["cases"]]
    for row, case in zip(table.rows, report["cases"].values()):
        assert row[2].startswith(f"{case['converged']}/{case['pairs']}")


@requires_data
def test_the_full_retrieval_scores_are_the_library_s_and_render_as_tables(docs_ext, tmp_path):
    """``bench_retrieval.py --scores`` on a few shapes: each recorded score is the bull's-eye of the library's own
    matrix (``invariant_distance_matrix``, ``procrustes_outline_matrix``; a half of the classes scored on its
    rows and columns), and the performance page's tables show every one as recorded."""
    from shapelib.datasets import load_mpeg7

    spec = importlib.util.spec_from_file_location("bench_retrieval", ROOT / "benchmarks" / "bench_retrieval.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    machine = importlib.import_module("benchmarks._machine")
    classes = ["apple", "bat", "fork", "spoon"]
    res = bench.full_scores(classes, per_class=6)
    machine.record("bench_retrieval", res, argv=["--scores"], path=tmp_path / "bench_retrieval_full.json")
    tables = {t.key: t for t in docs_ext.benchmark_tables("bench_retrieval_full", data_dir=tmp_path).tables}

    data = load_mpeg7(classes=classes, per_class=6, n_points=100)
    labels = np.asarray(data.labels)
    rows = {(r["metric"], r["points"], r["sigma2"]): r for r in [*res["sweep"], *res["points_200"]]}
    assert len(rows) == 12 and res["n_shapes"] == 24
    for metric, sigma2 in (("fisher_rao_bound", 0.005), ("alpha_bound", 0.04)):
        D = shapelib.invariant_distance_matrix(list(data.shapes), metric=metric, sigma2=sigma2)
        assert rows[metric, 100, sigma2]["raw"] == shapelib.bullseye(D, labels).value
    D = shapelib.invariant_distance_matrix(list(data.shapes), metric="fisher_rao_bound", sigma2=0.01)
    first = np.isin(labels, classes[:2])
    assert rows["fisher_rao_bound", 100, 0.01]["halves"]["classes 1–2"]["raw"] == shapelib.bullseye(
        D[np.ix_(first, first)], labels[first]).value
    tpg = shapelib.rerank(D, method="tpg", **bench.FULL_RERANK["tpg"])
    assert rows["fisher_rao_bound", 100, 0.01]["reranked"]["tpg"]["all"] == shapelib.bullseye(tpg, labels).value
    P = shapelib.procrustes_outline_matrix(np.stack(data.shapes))
    assert res["procrustes"]["raw"] == shapelib.bullseye(P, labels).value

    # the tables: one score row per distance, one column per σ², the re-ranked rows per σ² and half
    scores = tables["scores"]
    assert scores.header[1:] == [f"σ² = {s:g}" for s in bench.FULL_SIGMA2]
    assert len(scores.rows) == 3 and f"{100 * res['procrustes']['raw']:.2f} %" in scores.note
    shown = {cell for row in scores.rows for cell in row[1:] if cell}
    assert shown == {f"{100 * r['raw']:.2f} %" for r in rows.values()}
    assert len(tables["rerank"].rows) == 3 * len(bench.FULL_RERANKED)
    assert len(tables["times"].rows) == 3


@pytest.mark.processes
@requires_data
def test_an_executed_notebook_becomes_a_page_with_its_parameters_and_no_build_paths(docs_ext, tmp_path):
    name = "fig04_line_bending"
    _, status, _, msg = run_all.run_one(name, quick=True, force=True, results_dir=tmp_path)
    assert status == "ok", msg
    info = json.loads((tmp_path / name / ".inputs.json").read_text())
    raw = (tmp_path / name / f"{name}.ipynb").read_text()
    assert str(tmp_path) in raw  # papermill recorded the run's folders
    nb = docs_ext.notebook_page(name, tmp_path / name / f"{name}.ipynb", info, tmp_path)
    text = json.dumps(nb)
    assert str(tmp_path) not in text
    assert nb["cells"][0]["source"][0].startswith("# Figures 4 and 5")  # the title stays first
    note = nb["cells"][1]["source"]
    assert "quick parameters" in note and "`n_steps=6`" in note and f"--only {name}" in note
    (injected,) = [c for c in nb["cells"] if "injected-parameters" in c["metadata"].get("tags", [])]
    assert not any(line.startswith("output_dir") for line in injected["source"])
    # the plumbing is hidden: the parameter cells and the cell that records values for the report
    tags = {"".join(c["source"]).strip().split("\n")[0]: c["metadata"].get("tags", []) for c in nb["cells"]
            if c["cell_type"] == "code"}
    assert all("remove-cell" in t for t in tags.values() if {"parameters", "injected-parameters"} & set(t))
    recording = [t for line, t in tags.items() if line.startswith("spacing = ")]  # computes, then records
    assert recording == [["hide-input"]]
    assert not any("remove-cell" in t or "hide-input" in t for line, t in tags.items() if line.startswith("k = 21"))
    shown = [o for c in nb["cells"] for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert shown  # the figures stay


# ---------------------------------------------------------------------------------------------
# the built site (docs/_build/html, written by `make docs`; CI builds it before the tests)

HTML = DOCS / "_build" / "html"
requires_html = needs((HTML / "api" / "index.html").is_file(),
                      f"the documentation is not built: no {HTML / 'api' / 'index.html'} (make docs)")

#: what every API page shows: a function its Parameters (if it takes any, as tests/test_docstrings.py
#: asks), Returns and an Example; a class its Parameters or Attributes and an Example; a page of a
#: name that implements an equation of the paper (docs/_ext/shapelib_api.py) a rendered formula
SECTIONS = {"function": (("Parameters",), ("Returns", "Yields"), ("Examples",)),
            "function without parameters": (("Returns", "Yields"), ("Examples",)),
            "class": (("Parameters", "Attributes"), ("Examples",))}

#: pages that do not show a section yet, by section, each with the reason beside it (none: every
#: API page shows its sections). A page listed here that shows its section fails, so that this
#: table never lags behind the docstrings.
PENDING: dict[str, set[str]] = {}


def _api_pages(docs_ext) -> dict[str, tuple[str, str]]:
    """``{qualified name: (kind, equations)}`` of the documented functions and classes."""
    import inspect

    out = {}
    for e in docs_ext._api_table().entries():
        obj = getattr(importlib.import_module(e.module), e.name)
        if inspect.isclass(obj):
            out[e.qualname] = ("class", e.equations)
        elif callable(obj):
            takes = bool(inspect.signature(obj).parameters)  # a loader like load_beijing() takes nothing
            out[e.qualname] = ("function" if takes else "function without parameters", e.equations)
    return out


def _rendered(html: str) -> set[str]:
    """The numpydoc sections a built API page shows, and "formula" if it renders math."""
    shown = set(re.findall(r'<dt class="field-\w+">(\w+)<span class="colon">', html))
    shown |= set(re.findall(r'<p class="rubric">(\w+)</p>', html))
    if re.search(r'class="math[ "]', html):
        shown.add("formula")
    return shown


def api_page_report(docs_ext) -> dict[str, set[str]]:
    """``{section: names whose built page lacks it}`` over every function and class page."""
    missing: dict[str, set[str]] = {}
    for name, (kind, equations) in _api_pages(docs_ext).items():
        path = HTML / "api" / "generated" / f"{name}.html"
        shown = _rendered(path.read_text()) if path.is_file() else set()
        wanted = [*SECTIONS[kind], *((("formula",),) if equations else ())]
        for alternatives in wanted:
            if not shown & set(alternatives):
                missing.setdefault(alternatives[0], set()).add(name)
    return missing


@requires_html
def test_every_api_page_shows_parameters_returns_an_example_and_its_formula(docs_ext):
    missing = api_page_report(docs_ext)
    for section in sorted(set(missing) | set(PENDING)):
        lacking, pending = missing.get(section, set()), PENDING.get(section, set())
        assert not lacking - pending, f"API pages without {section}: {sorted(lacking - pending)}"
        assert not pending - lacking, (f"these pages show {section} now: remove them from PENDING[{section!r}] "
                                       f"in tests/test_docs.py: {sorted(pending - lacking)}")


def test_the_page_check_reads_numpydoc_sections_and_math():
    html = ('<dl class="field-list simple"><dt class="field-odd">Parameters<span class="colon">:</span></dt>'
            '<p class="rubric">Examples</p><div class="math notranslate nohighlight">\\[x\\]</div>')
    assert _rendered(html) == {"Parameters", "Examples", "formula"}
    assert _rendered("<p>Parameters</p>") == set()


@requires_html
def test_every_equation_of_the_map_links_its_function_and_module():
    page = (HTML / "api" / "reference" / "equations.html").read_text()
    for name in ("shapelib.gmm_density", "shapelib.alpha_metric", "shapelib.geodesic", "shapelib.extrinsic_warp"):
        assert f'href="../generated/{name}.html' in page
    assert 'href="modules/shapelib.geometry.metrics.html' in page


@requires_html
def test_the_gallery_has_every_example_executed_with_its_figures():
    sources = sorted((DOCS / "examples").glob("*/plot_*.py"))
    assert len(sources) >= 8
    assert not list((DOCS / "examples").glob("plot_*.py")), "every example belongs to a topic folder"
    for source in sources:
        topic, stem = source.parent.name, source.stem
        page = HTML / "auto_examples" / topic / f"{stem}.html"
        assert page.is_file(), f"docs/examples/{topic}/{stem}.py has no gallery page"
        assert re.search(r'<img [^>]*src="\.\./\.\./_images/sphx_glr_' + stem + r'_\d+\.png"', page.read_text()), \
            f"{stem}: no figure on its page"


def test_the_gallery_lists_every_topic_and_example_in_reading_order(docs_ext):
    topics = sorted(p.parent.name for p in (DOCS / "examples").glob("*/README.txt"))
    assert sorted(docs_ext.GALLERY_ORDER) == topics
    for topic, names in docs_ext.GALLERY_ORDER.items():
        assert sorted(names) == sorted(p.name for p in (DOCS / "examples" / topic).glob("plot_*.py")), topic
    assert next(iter(docs_ext.GALLERY_ORDER.values()))[0] == "plot_first_geodesic.py"
    order = docs_ext.ExampleOrder("examples/landmarks")
    assert sorted(["plot_own_tps_file.py", "/x/plot_first_geodesic.py"], key=order)[0].endswith("first_geodesic.py")


@requires_html
def test_the_gallery_page_shows_the_topics_in_reading_order():
    page = (HTML / "auto_examples" / "index.html").read_text()
    where = [page.find(f">{title}<") for title in ("Landmarks", "Point sets and retrieval", "Statistics", "The study")]
    assert -1 not in where and where == sorted(where), where
    assert page.find("A first geodesic") < page.find("Fisher–Rao vs α")


@requires_html
def test_api_pages_show_the_examples_that_use_their_name():
    page = (HTML / "api" / "generated" / "shapelib.geodesic.html").read_text()
    assert "Examples using" in page and "plot_first_geodesic.html" in page
    assert re.search(r"<h1>geodesic<", page), "the page title is the function's name"



#: the widest code line that fits a code block of the site at 1280 px without a scroll bar
CODE_WIDTH = 88
_FENCE = re.compile(r"^```(?P<info>[^\n]*)\n(?P<code>.*?)^```[ \t]*$", flags=re.M | re.S)


def long_code_lines(text: str) -> list[tuple[int, int]]:
    """``[(line number, length)]`` of the code lines wider than :data:`CODE_WIDTH` in a Markdown
    page's fenced code blocks; directives (```{image}) and printed output (```text) are not code."""
    out = []
    for m in _FENCE.finditer(text):
        info = m.group("info").strip()
        if info.startswith("{") or info == "text":
            continue
        first = text.count("\n", 0, m.start("code")) + 1
        out += [(first + i, len(line)) for i, line in enumerate(m.group("code").splitlines())
                if len(line) > CODE_WIDTH]
    return out


def test_the_code_line_check_finds_wide_lines_in_code_blocks_only():
    wide = "x = " + "1" * 90
    text = f"{wide}\n```python\nok = 1\n{wide}\n```\n```text\n{wide}\n```\n```{{image}} a.png\n:alt: {wide}\n```\n"
    assert long_code_lines(text) == [(4, len(wide))]


@needs(importlib.util.find_spec("sphinx_gallery") is not None,
       "sphinx-gallery splits the gallery examples into blocks: the docs extra (pip install -e '.[docs]')")
def test_code_lines_of_the_pages_and_examples_fit_their_blocks():
    from sphinx_gallery.py_source_parser import split_code_and_text_blocks

    wide = []
    for page in sorted([*DOCS.glob("*.md"), *(DOCS / "guide").glob("*.md"), ROOT / "CONTRIBUTING.md"]):
        wide += [f"{page.relative_to(ROOT)}:{n} ({width})" for n, width in long_code_lines(page.read_text())]
    for example in sorted((DOCS / "examples").rglob("*.py")):
        for block in split_code_and_text_blocks(str(example))[1]:
            if block.type == "code":
                wide += [f"{example.relative_to(ROOT)}:{block.lineno + i} ({len(line)})"
                         for i, line in enumerate(block.content.splitlines()) if len(line) > CODE_WIDTH]
    assert not wide, f"code lines over {CODE_WIDTH} characters (wrap them): {wide}"

@requires_html
def test_the_header_links_the_paper():
    page = (HTML / "index.html").read_text()
    assert "https://doi.org/10.1109/TPAMI.2008.76" in page


@requires_html
def test_notebook_pages_hide_the_study_plumbing():
    page = (HTML / "notebooks" / "fig04_line_bending.html").read_text()

    def called(name, html):
        return re.search(name + r'</span>\s*<span class="p">\(', html) is not None

    assert called("plot_metric_panels", page)  # the notebook's own code is shown
    assert not called("record_values", re.sub(r"<details.*?</details>", "", page, flags=re.S))  # folded at most
    assert not called("default_output_dir", page)  # the parameter cell is removed


#: a script or stylesheet the page loads from another host (the site is read from a local build)
REMOTE_ASSET = re.compile(r"<(?:script|link)\b[^>]*\b(?:src|href)=[\"'](?:https?:)?//[^\"']+[\"'][^>]*>", re.I)


def test_the_remote_asset_check_tells_loaded_files_from_links():
    assert REMOTE_ASSET.search('<script defer src="https://cdn.example.org/mathjax/tex-chtml.js"></script>')
    assert REMOTE_ASSET.search('<link rel="stylesheet" href="//cdn.example.org/a.css" />')
    assert not REMOTE_ASSET.search('<script src="../_static/mathjax/tex-chtml.js"></script>')
    assert not REMOTE_ASSET.search('<a class="reference external" href="https://doi.org/10.1109/TPAMI.2008.76">')


@requires_html
def test_no_page_loads_a_script_or_stylesheet_from_the_network():
    pages = sorted(HTML.rglob("*.html"))
    assert len(pages) > 100
    remote = {str(p.relative_to(HTML)): REMOTE_ASSET.findall(p.read_text()) for p in pages}
    remote = {page: found for page, found in remote.items() if found}
    assert not remote, f"pages that load files from another host: {remote}"


@requires_html
def test_pages_with_math_load_mathjax_from_the_site():
    with_math = 0
    for page in sorted(HTML.rglob("*.html")):
        html = page.read_text()
        if not re.search(r'class="math[ "]', html):
            continue
        with_math += 1
        scripts = re.findall(r'<script[^>]*\bsrc="([^"]*mathjax[^"]*)"', html)
        assert scripts, f"{page.relative_to(HTML)} shows math but loads no MathJax"
        for src in scripts:
            path = src.split("?")[0]  # Sphinx may add ?v=<checksum>
            assert (page.parent / path).resolve().is_file(), f"{page.relative_to(HTML)}: {src} is not in the site"
    assert with_math >= 50  # the guide, the theory pages and the API reference
    fonts = HTML / "_static" / "mathjax" / "output" / "chtml" / "fonts" / "woff-v2"
    assert len(list(fonts.glob("MathJax_*.woff"))) >= 20  # the CHTML output's fonts come with it


def test_the_reference_has_no_page_for_a_private_module(docs_ext):
    modules = docs_ext._api_table().all_modules()
    assert not [m for m in modules if any(part.startswith("_") for part in m.split("."))]
    pages = docs_ext._api_table().pages()
    # a name defined in a private module is listed on its public parent's page
    assert "   compute_pairwise" in pages["modules/shapelib.pairwise.rst"]  # defined in pairwise._driver
    assert "   InputError" in pages["modules/shapelib.rst"]  # defined in shapelib._validate


@requires_html
def test_the_top_pages_have_no_empty_left_sidebar():
    for page in ("index", "installation", "getting-started", "performance", "license"):
        html = (HTML / f"{page}.html").read_text()
        assert 'class="bd-sidebar-primary' not in html or "hide-on-wide" in html, page
