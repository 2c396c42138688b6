"""Sphinx settings of the imgform-rs documentation (``make docs``).

The stack is the one NumPy, SciPy and scikit-image use: pydata-sphinx-theme,
numpydoc for the docstrings, autosummary for one page per public name and
sphinx-gallery for the examples, which run at every build so that each figure
comes from the current code. Equations are typeset by MathJax from a copy
installed with the docs dependencies (sphinx-mathjax-offline), so the pages
render their equations without a network.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
# The gallery scripts draw without a display.
matplotlib.use("Agg")

project = "imgform-rs"
author = "the imgform-rs authors"
copyright = "the imgform-rs authors, MIT licence"
try:
    from importlib.metadata import version as _version

    release = _version("imgform-rs")
except Exception:
    release = ""
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "benchmark_tables",
]

exclude_patterns = ["_build", "examples"]
templates_path = ["_templates"]
default_role = "code"
nitpicky = False

# One page per public name, generated from the lists in api.rst.
autosummary_generate = True
autosummary_imported_members = True
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
# Docstrings use ``Returns`` headings without names in places; numpydoc's
# validation would turn style points into build errors, so it only parses.
numpydoc_validation_checks: set[str] = set()

intersphinx_mapping: dict[str, tuple[str, None]] = {}

sphinx_gallery_conf = {
    "examples_dirs": str(DOCS / "examples"),
    "gallery_dirs": str(DOCS / "auto_examples"),
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("matplotlib",),
    # A failing example fails the build.
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "show_memory": False,
    # Every build runs every example, changed or not: the figures must come
    # from the current code, not from a cache of an older build.
    "run_stale_examples": True,
}

html_theme = "pydata_sphinx_theme"
html_title = "imgform-rs"
html_static_path: list[str] = []
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_context = {"default_mode": "light"}
# Pages without sub-pages need no section navigation: their text gets the width.
html_sidebars = {page: [] for page in ("index", "install", "benchmarks", "conventions", "api")}

# Where the benchmark extension finds the committed results.
benchmark_results = str(ROOT / "benchmarks" / "results")


def _skip_tuple_fields(app, what, name, obj, skip, options):
    """A NamedTuple's fields are described in its Attributes section; autodoc
    would list each again as "Alias for field number N"."""
    doc = getattr(obj, "__doc__", None) or ""
    if what == "class" and doc.startswith("Alias for field number"):
        return True
    return None


def setup(app):
    app.connect("autodoc-skip-member", _skip_tuple_fields)
