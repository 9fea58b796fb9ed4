"""Sphinx configuration of the tli-verify docs: ``make docs`` (warnings are errors).

Pages are Markdown (MyST) except the API reference (reST, autodoc + numpydoc). The CLI page is
generated from ``tli_verify.cli:build_parser`` (sphinx-argparse), the file-format tables from
the JSON Schemas in ``tli_verify/schemas/`` and the public API from ``tli_verify.__all__``
(``docs/_ext/tli_docs.py``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))
os.environ.setdefault("MPLBACKEND", "Agg")

import tli_verify  # noqa: E402

project = "tli-verify"
author = "the tli-verify authors"
copyright = "the tli-verify authors, MIT License"
release = version = tli_verify.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "numpydoc",
    "sphinxarg.ext",
    "tli_docs",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "img", "Thumbs.db", ".DS_Store"]

# MyST: anchors for headings (links like page.md#section), fences with colons.
myst_enable_extensions = ["colon_fence"]
myst_heading_anchors = 4

# autodoc + numpydoc
autodoc_member_order = "bysource"
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

html_theme = "alabaster"
html_title = f"tli-verify {release}"
html_static_path: list[str] = []
html_theme_options = {
    "description": "Temporal Logic Imitation (LTL-DS) with certificates anyone can re-check",
    "fixed_sidebar": True,
    "page_width": "1180px",
    "sidebar_width": "240px",
}
html_sidebars = {"**": ["about.html", "navigation.html", "relations.html", "searchbox.html"]}

# numpydoc turns a docstring's "References" into citations; most docstrings list their
# sources without citing them inline, which Sphinx would report as unreferenced.
suppress_warnings = ["ref.citation"]
