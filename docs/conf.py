"""Sphinx configuration: the project's docs (MyST Markdown), its notebooks and its API reference.

``make docs`` builds the HTML site into ``docs/_build/html``. The notebooks live in
``rebar_notebooks/``; they are copied into ``docs/_notebooks/`` (git-ignored) at every build so
that Sphinx can read them. How they are executed: docs/decisions/012-docs-notebooks.md.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))  # the checkout's rebarlib, also when it is not installed


def _copy_notebooks() -> None:
    """Mirror rebar_notebooks/*.ipynb into docs/_notebooks/ (Sphinx reads only under docs/)."""
    target = DOCS / "_notebooks"
    target.mkdir(exist_ok=True)
    sources = sorted((ROOT / "rebar_notebooks").glob("*.ipynb"))
    for stale in set(target.glob("*.ipynb")) - {target / s.name for s in sources}:
        stale.unlink()
    for src in sources:
        dst = target / src.name
        if not dst.exists() or dst.read_bytes() != src.read_bytes():
            shutil.copyfile(src, dst)


_copy_notebooks()

project = "rebarlib"
author = "rebarlib contributors"
copyright = "2026, rebarlib contributors"

extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax", "sphinx.ext.viewcode"]
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "_notebooks/.ipynb_checkpoints", "Thumbs.db", ".DS_Store"]

# MyST: heading anchors so that links such as formats.md#design-files resolve.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath", "colon_fence"]

# Notebooks: executed once and cached (docs/_build/.jupyter_cache); CI passes
# -D nb_execution_mode=off because its slow test tier already executes every notebook.
nb_execution_mode = "cache"
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_timeout = 600
nb_execution_raise_on_error = True
# plotly: the notebooks' kernels (started from this process) render figures as HTML that loads
# plotly.js itself (the "sphinx_gallery" renderer); the JSON mime type JupyterLab reads is skipped.
os.environ.setdefault("PLOTLY_RENDERER", "sphinx_gallery")
nb_mime_priority_overrides = [("html", "application/vnd.plotly.v1+json", None)]

# Illustrative JSON with "..." in it does not lex strictly; Pygments then highlights it loosely.
suppress_warnings = ["misc.highlighting_failure"]

autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_google_docstring = False
napoleon_numpy_docstring = True

html_theme = "alabaster"
html_title = "rebarlib"
