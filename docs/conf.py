"""Sphinx configuration of the jitterid documentation (``make docs``)."""

from __future__ import annotations

import os
import re
import sys
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
# Build from the working tree even when jitterid is not installed (e.g. PYTHONPATH unset).
sys.path.insert(0, str(ROOT / "src"))
os.environ.setdefault("MPLBACKEND", "Agg")

import jitterid

project = "jitterid"
author = "jitterid contributors"
copyright = "2026, jitterid contributors"
version = release = jitterid.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = [
    "_build",
    "Thumbs.db",
    ".DS_Store",
    # Not pages: the reproduction data and generated tables are linked, not rendered.
    "reproduction/*.csv",
    "reproduction/*.sqlite",
    "auto_examples/*.ipynb",
    "auto_examples/*.py",
    "auto_examples/*.zip",
    "auto_examples/*.json",
    "auto_examples/*.md5",
]

# -- MyST: the Markdown pages -------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
# tutorial.md links to its sections by GitHub-style slugs (#2-is-there-jitter).
myst_heading_anchors = 3

# -- autodoc / autosummary / numpydoc -----------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # numpydoc's Parameters sections say the types
# Autosummary already lists the members of a class; numpydoc would list them twice.
numpydoc_show_class_members = False
numpydoc_show_inherited_class_members = False
numpydoc_class_members_toctree = False
# The docstrings are numpydoc in spirit but not all conformant: validation stays off.
numpydoc_validation_checks: set[str] = set()
numpydoc_xref_param_type = False

# -- sphinx-gallery -----------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": str(HERE / "auto_examples"),
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "reset_modules": ("matplotlib",),
}

# -- HTML ---------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"jitterid {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
}
html_static_path: list[str] = []

# The Markdown tables in docs/reproduction jump from H1 to H3 by design.
suppress_warnings = ["myst.header"]

# numpydoc's "Unknown section Class Attributes" is a Python warning, not a Sphinx one.
warnings.filterwarnings("ignore", message="Unknown section", category=UserWarning)


# -- Docstrings in plain-text maths --------------------------------------------------------
# The docstrings write moduli as in plain text, |phi(f)| or |G(i 2 pi f)|, which reST reads
# as substitution references. Escape every "|" outside inline literals and roles before
# numpydoc and autosummary see the docstring (no docstring uses reST tables or line blocks).
_LITERAL = re.compile(r"(``.*?``|:\w+:`[^`]*`|`[^`]*`)")


def _escape_bars(line: str) -> str:
    parts = _LITERAL.split(line)
    return "".join(p if i % 2 else p.replace("|", r"\|") for i, p in enumerate(parts))


def _escape_docstring(app, what, name, obj, options, lines):
    lines[:] = [_escape_bars(line) for line in lines]


def setup(app):
    app.connect("autodoc-process-docstring", _escape_docstring, priority=100)
