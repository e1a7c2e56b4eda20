"""Sphinx configuration of the shapelib documentation (``make docs``)."""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(ROOT))  # run_all.py (the study notebooks' runner)

import shapelib  # noqa: E402

project = "shapelib"
author = "the shapelib developers"
copyright = "the shapelib developers"  # noqa: A001 (Sphinx's name)
release = version = shapelib.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_nb",
    "sphinx_copybutton",
    "shapelib_docs",  # docs/_ext: benchmark tables from docs/_data, the study notebooks
]

root_doc = "index"
exclude_patterns = ["_build", "_data", "_scripts", "_templates", "**.ipynb_checkpoints", "notebooks/.runs"]
templates_path = ["_templates"]
html_static_path = ["_static"]

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
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
# outputs without an HTML rendering (none so far) fall back to their text
suppress_warnings = ["mystnb.unknown_mime_type"]

# -- HTML ----------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"shapelib {release}"
html_logo = None
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 8,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_context = {"default_mode": "light"}
html_show_sourcelink = False
html_copy_source = False
