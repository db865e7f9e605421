"""Sphinx configuration: MyST Markdown pages, the env's docstrings and the CLI's parser.

``make docs`` builds it with warnings as errors (``-W``), as CI does.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

project = "maniskill-tidy"
author = "maniskill-tidy contributors"
copyright = "2026, maniskill-tidy contributors"  # noqa: A001
extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinxarg.ext",
]
source_suffix = {".md": "markdown"}
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
html_theme = "furo"
html_title = "maniskill-tidy"
autodoc_member_order = "bysource"
autodoc_typehints = "description"
nitpicky = False
