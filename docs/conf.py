"""Sphinx configuration of the stringcontact site (MyST markdown). Build: `make docs` (docs/_build/html).

The reference tables (scene keys, command line, exit codes, output folder, API) are generated from the code
(`_ext/reference_pages.py`), the demos are run and rendered as pages (`_ext/demo_pages.py`), both when the
build starts. Nothing is downloaded: no intersphinx, MathJax is loaded by the reader's browser.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE / "_ext"))

import demo_pages
import reference_pages

project = "stringcontact"
author = "stringcontact developers"
copyright = "stringcontact developers"
release = version = "0.1.0"

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.mathjax"]
source_suffix = {".md": "markdown"}
root_doc = "index"
# The site's pages live in its four sections; a markdown file at the top of docs/ besides index.md is not part of it.
exclude_patterns = ["_build", "_generated", "_ext", *(p.name for p in HERE.glob("*.md") if p.name != "index.md")]
myst_enable_extensions = ["dollarmath", "amsmath", "deflist", "colon_fence"]
myst_heading_anchors = 3
# every internal link must resolve: MyST's cross-reference warnings are errors under -W
suppress_warnings = []
nitpicky = True
# types from other packages in the API's signatures: not in this site, and no intersphinx (no network)
nitpick_ignore_regex = [
    ("py:class", r"(numpy|np|dolfinx|ufl|petsc4py|PETSc|mpi4py|MPI|pathlib|os|collections|typing|importlib)\..*"),
    ("py:class", r"(Path|Callable|Iterable|Sequence|Mapping|NDArray|ndarray|Function|Form|Constant|Expr|Comm)"),
    ("py:class", r"(optional|callable|array|float|int|str|bool|dict|tuple|list)( .*)?"),
    ("py:class", r"stringcontact\..*\._.*"),
    ("py:mod", r"stringcontact\..*"),  # the internal modules a docstring names are not pages of the site
]
default_role = "code"  # the docstrings' `name`: code, as in the rest of the project
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_preserve_defaults = True  # a Model shows `penalty=penalty`, not a function repr
autodoc_default_options = {"undoc-members": False}
html_theme = "pydata_sphinx_theme"  # the dolfinx documentation's theme; its fonts and icons are bundled
html_title = "stringcontact"
html_static_path = []
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2, "header_links_before_dropdown": 4}
# figures stay in docs/ (the README shows them too); the pages refer to them as ../NAME.png


def _generate(app) -> None:
    reference_pages.write_all(HERE / "_generated")
    work = Path(os.environ.get("STRINGCONTACT_DOCS_DEMO_WORK", Path(app.outdir).parent / "demo-runs"))
    demo_pages.write_pages(ROOT / "demos", HERE / "tutorial" / "demos", work, ROOT / "src" / "stringcontact",
                           "../../../demos")


def setup(app):
    app.connect("builder-inited", _generate)
    return {"parallel_read_safe": True}
