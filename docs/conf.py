"""Sphinx configuration of the documentation site: `make docs` builds it into docs/_build/html,
and tests/test_docs.py fails on any warning (a broken link or reference, a docstring Sphinx
cannot read)."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

project = "rsfbench"
author = "the rsfbench developers"
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.mathjax"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "examples"]
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
html_theme = "furo"
html_title = "rsfbench"
autodoc_member_order = "bysource"
autodoc_typehints = "description"
