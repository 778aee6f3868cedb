"""Sphinx configuration of xcheck's documentation (``make docs``: warnings are errors)."""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import xcheck  # noqa: E402

project = "xcheck"
author = "the xcheck authors"
copyright = "the xcheck authors, MIT licence"
release = version = xcheck.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "xcheck_docs",  # docs/_ext/xcheck_docs.py: the engines' tables from the registry
]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build", "examples", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = f"xcheck {release}"
html_static_path: list[str] = []

# the API reference: numpydoc docstrings through napoleon
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
nitpicky = False
