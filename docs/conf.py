"""Sphinx configuration of pedmesh's documentation.

    pip install -e ".[docs]"
    python -m sphinx -W -b html docs OUTDIR

pedmesh is imported from this checkout, not from wherever it is installed. Three kinds of
page are generated at every build, so that they cannot drift from what they describe (see
docs/development.md): the API reference (autosummary, into docs/api/), the command-line
reference (render_cli.py) and the measured figures (render_figures.py, from the benchmarks'
JSON in docs/data/); the last two write into docs/_generated/. Both directories are
git-ignored.
"""

from __future__ import annotations

import sys
import types
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS))

import pedmesh  # noqa: E402
import render_cli  # noqa: E402
import render_figures  # noqa: E402
import render_parameters  # noqa: E402

# autosummary's walk over the package imports every submodule, and importing
# pedmesh/__main__.py runs the command line (on Sphinx's own arguments): stand in an empty
# module for it.
sys.modules.setdefault("pedmesh.__main__", types.ModuleType("pedmesh.__main__"))

render_cli.main()
render_figures.main()
render_parameters.main()

project = "pedmesh"
author = "the pedmesh developers"
copyright = "the pedmesh developers"
version = release = pedmesh.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = [
    "_build",
    "_generated",  # included into pages, not pages of their own
    "data",
    "**/runs",
    # written by benchmarks/dense_crowds.py without a title; validation/probes.md includes it
    "validation/dense_crowds_probes.md",
]

# API reference: autosummary walks the package (``:recursive:`` in api.rst), so it follows
# modules as they are added or renamed. Each module page documents the members defined in
# that module (_templates/autosummary/module.rst: ``:ignore-module-all:``), so an object
# that a package re-exports is documented once, where it is defined.
autosummary_generate = True
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "description"

# Docstrings are NumPy style.
napoleon_google_docstring = False
napoleon_numpy_docstring = True

myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = f"pedmesh {release}"


#: what autodoc calls the objects whose docstrings are prose for napoleon's purposes
_PROSE_KINDS = ("attribute", "data", "property")
_prose: dict[str, list[str]] = {}


def _stash_prose(app, what, name, obj, options, lines):
    """napoleon reads the first line of an attribute's docstring as ``type: description``
    when it holds a colon, and pedmesh's attribute comments are prose that often does
    (``#: [m] corridors this narrow ... (Adrian et al. 2020: 1.2 m)``). Such docstrings are
    kept as written: stashed before napoleon runs and put back after it. napoleon still
    parses the sections of modules, classes and functions; autodoc adds the types from the
    annotations itself."""
    if what in _PROSE_KINDS:
        _prose[name] = list(lines)


def _restore_prose(app, what, name, obj, options, lines):
    if what in _PROSE_KINDS and name in _prose:
        lines[:] = _prose.pop(name)


def setup(app):
    # napoleon's handler has the default priority, 500
    app.connect("autodoc-process-docstring", _stash_prose, priority=400)
    app.connect("autodoc-process-docstring", _restore_prose, priority=600)
