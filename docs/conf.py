"""Sphinx configuration of the shapelib documentation (``make docs``)."""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(ROOT))  # run_all.py (the study notebooks' runner)

import shapelib  # noqa: E402
import shapelib_docs  # noqa: E402  (docs/_ext)

project = "shapelib"
author = "the shapelib developers"
copyright = "the shapelib developers"  # noqa: A001 (Sphinx's name)
release = version = shapelib.__version__

# The paper whose methods shapelib implements, and the repository: one home each, pyproject.toml's
# [project.urls]; the header shows them on every page, the landing page and docs/citing.md link them.
try:
    import tomllib
except ImportError:  # Python 3.10: Sphinx brings tomli
    import tomli as tomllib

_URLS = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"].get("urls", {})
PAPER_URL = _URLS["Paper"]
REPOSITORY_URL = _URLS.get("Repository")


extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    # MathJax 3 (tex-chtml and its fonts) copied into the built site's _static/mathjax, and the pages
    # load it from there: the site is read from a local build, without a network
    "sphinx-mathjax-offline",
    "sphinx.ext.intersphinx",
    "numpydoc",
    "myst_nb",
    "sphinx_copybutton",
    "sphinx_gallery.gen_gallery",
    "shapelib_docs",  # docs/_ext: benchmark tables from docs/_data, the study notebooks
]

root_doc = "index"
exclude_patterns = ["_build", "_data", "_scripts", "_templates", "_intersphinx", "**.ipynb_checkpoints",
                    "notebooks/.runs", "examples/**", "auto_examples/**.ipynb", "auto_examples/**.py",
                    "auto_examples/**.zip", "auto_examples/**.json", "sg_execution_times.rst",
                    "auto_examples/sg_execution_times.rst"]
templates_path = ["_templates"]
html_static_path = ["_static"]

# -- cross-references ----------------------------------------------------------------------------
# Every reference must resolve (warnings are errors in `make docs`). References to the other
# projects go through intersphinx, with inventories kept in docs/_intersphinx/: the build has no
# internet (CI and the developers' machines reach package registries only), so Sphinx cannot
# download the projects' objects.inv. `python docs/_intersphinx/make_inventories.py` writes them
# from the installed packages (every public name of the modules shapelib refers to, at the page
# each project's site gives it); the links lead to the projects' own stable documentation.
nitpicky = True
_INV = DOCS / "_intersphinx"
intersphinx_mapping = {
    "python": ("https://docs.python.org/3/", str(_INV / "python.inv")),
    "numpy": ("https://numpy.org/doc/stable/", str(_INV / "numpy.inv")),
    "scipy": ("https://docs.scipy.org/doc/scipy/", str(_INV / "scipy.inv")),
    "sklearn": ("https://scikit-learn.org/stable/", str(_INV / "sklearn.inv")),
    "pandas": ("https://pandas.pydata.org/docs/", str(_INV / "pandas.inv")),
    "dask": ("https://docs.dask.org/en/stable/", str(_INV / "dask.inv")),
    "distributed": ("https://distributed.dask.org/en/stable/", str(_INV / "distributed.inv")),
    "matplotlib": ("https://matplotlib.org/stable/", str(_INV / "matplotlib.inv")),
    "pooch": ("https://www.fatiando.org/pooch/latest/", str(_INV / "pooch.inv")),
    "skbio": ("https://scikit.bio/docs/latest/", str(_INV / "skbio.inv")),
}
intersphinx_timeout = 1
intersphinx_disabled_reftypes = ["std:doc"]
# Private names (``_kernels``, ``_alpha_qform_grad``) are not documented: a docstring may name one,
# which then shows as code without a link.
nitpick_ignore_regex = [(r"py:.*", r"(.*\.)?_[A-Za-z]\w*(\..*)?")]
# Helpers of private modules (shapelib._validate, _executor, pairwise._driver) that the docstrings
# of their public names mention: private modules have no reference page, so these show as code.
nitpick_ignore = [("py:data", "LIBRARY_WORDS"), ("py:func", "literal"), ("py:class", "Interrupts"),
                  ("py:func", "ignore_sigint")]

# -- API reference -------------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_typehints = "none"  # numpydoc docstrings carry the types
autodoc_default_options = {"member-order": "bysource"}
numpydoc_show_class_members = False  # the class template lists members itself
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# The summaries in the API tables are the docstrings' first sentences; "eq. (5)", "Fig. 10" do not end one.
import sphinx.ext.autosummary as _autosummary  # noqa: E402

_autosummary.WELL_KNOWN_ABBREVIATIONS = (*_autosummary.WELL_KNOWN_ABBREVIATIONS, "eq.", "eqs.", "Fig.", "Figs.")

# -- notebooks and Markdown ----------------------------------------------------------------------
# The study notebooks are executed by run_all.py (papermill, with their parameters) when the docs
# are built, and rendered from the executed .ipynb: myst-nb never executes them itself.
nb_execution_mode = "off"
nb_merge_streams = True
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
# outputs without an HTML rendering (none so far) fall back to their text
suppress_warnings = ["mystnb.unknown_mime_type"]

# -- example gallery -------------------------------------------------------------------------------
# Every docs/examples/<topic>/plot_*.py is executed when the documentation is built (sphinx-gallery)
# and becomes a page of docs/auto_examples/<topic>/ with its figures and output; a failing example
# fails the build. The topics (each a folder with a README.txt) and the examples within each come
# in reading order: shapelib_docs.GALLERY_ORDER. Each API page lists the examples that use its name
# ("backreferences", written to docs/api/backreferences/ and shown by the page's minigallery).
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"__init__\.py",
    "subsection_order": [f"examples/{topic}" for topic in shapelib_docs.GALLERY_ORDER],
    "within_subsection_order": "shapelib_docs.ExampleOrder",
    "doc_module": ("shapelib",),
    "backreferences_dir": "api/backreferences",
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "min_reported_time": 5,
    "show_memory": False,
    "only_warn_on_example_error": False,
    "abort_on_example_error": False,
    # no page of run times: sphinx-gallery renders it with scripts from a CDN, and the site is read offline
    "write_computation_times": False,
}

# -- HTML ----------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"shapelib {release}"
html_logo = None
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 5,  # the top menu on one line; the other pages under "More"
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
    "icon_links": [
        {"name": "The paper: Peter & Rangarajan, IEEE TPAMI 31(2), 2009", "url": PAPER_URL,
         "icon": "fa-solid fa-file-lines", "type": "fontawesome"},
        *([{"name": "Source repository", "url": REPOSITORY_URL, "icon": "fa-brands fa-git-alt",
            "type": "fontawesome"}] if REPOSITORY_URL else []),
    ],
}
html_context = {"default_mode": "light"}
# pages that stand alone: no left sidebar (it would be empty), the page's own contents on the right
html_sidebars = {page: [] for page in ("index", "installation", "getting-started", "reproduction",
                                        "performance", "contributing", "changelog", "citing",
                                        "license")}
html_show_sourcelink = False
html_copy_source = False
