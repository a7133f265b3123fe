"""Sphinx configuration for veribattery's documentation (`make docs`).

The site builds offline: no intersphinx, no theme or extension fetched at build time.
The CLI, config and API references are generated while building, from the commands'
own help, the pydantic schema (with ``configs/example.yaml``'s comments) and the
docstrings (``docs/_ext/``).
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(DOCS.parent / "src"))

project = "veribattery"
author = "the veribattery authors"
copyright = "the veribattery authors"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "cli_reference",
    "config_reference",
    "api_reference",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# docs/reports/ is the example reports' folder (linked from the report page, not pages of
# the site); docs/_bench/ holds the tables `make bench` writes, included by performance.md.
exclude_patterns = ["_build", "reports", "_bench", "figures"]

myst_enable_extensions = ["deflist"]
# Blocks without a language are output, not code: shown as written.
highlight_language = "none"
myst_heading_anchors = 3

autodoc_member_order = "bysource"
autodoc_typehints = "signature"

html_theme = "alabaster"
html_theme_options = {"page_width": "1140px", "fixed_sidebar": True}
html_title = "veribattery"
html_static_path = ["_static"]
html_css_files = ["custom.css"]
html_show_sourcelink = False
