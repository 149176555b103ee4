"""Sphinx configuration of the stringcontact site (MyST markdown). Build: `make docs` (docs/_build/html).

The reference pages' tables and API (scene keys, command line, exit codes, output folder, API) are generated from
the code into the committed pages docs/reference/*.md (`_ext/reference_pages.py`: `make reference`, and again when
the build starts, so that the site never shows a stale page); the demos are run and rendered as pages
(`_ext/demo_pages.py`) when the build starts. Nothing is downloaded, and the site loads nothing from the network: no intersphinx, and the
formulas are typeset by Debian's MathJax 2 (libjs-mathjax, installed by `scripts/setup --docs`), the part of it the
site needs copied into `_static/mathjax` when the build ends.
"""

from __future__ import annotations

import os
import shutil
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

extensions = ["myst_parser", "sphinx.ext.mathjax"]
source_suffix = {".md": "markdown"}
root_doc = "index"
# The site's pages live in its four sections; a markdown file at the top of docs/ besides index.md is not part of it.
exclude_patterns = ["_build", "_ext", *(p.name for p in HERE.glob("*.md") if p.name != "index.md")]
myst_enable_extensions = ["dollarmath", "amsmath", "deflist", "colon_fence"]
myst_heading_anchors = 4  # the API page's methods (####) get anchors too
# every internal link must resolve: MyST's cross-reference warnings are errors under -W
suppress_warnings = []
nitpicky = True
html_theme = "pydata_sphinx_theme"  # the dolfinx documentation's theme; its fonts and icons are bundled
html_title = "stringcontact"
html_static_path = ["_static"]
html_css_files = ["custom.css"]  # wide tables wrap their cells, long signatures and code lines stay in the page
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2, "header_links_before_dropdown": 4}

# MathJax from Debian (libjs-mathjax), not from a CDN: a cluster without internet shows the formulas too
MATHJAX = Path(os.environ.get("STRINGCONTACT_MATHJAX", "/usr/share/javascript/mathjax"))
#: the files of MathJax 2 that TeX-AMS_CHTML typesets with (its input, its CommonHTML output, their fonts)
MATHJAX_PARTS = (
    "MathJax.js",
    "config/TeX-AMS_CHTML.js",
    "extensions",
    "jax/element",
    "jax/input/TeX",
    "jax/output/CommonHTML",
    "jax/output/PreviewHTML",
    "fonts/HTML-CSS/TeX/woff",
    "localization/en",
)
mathjax_path = "mathjax/MathJax.js?config=TeX-AMS_CHTML"
# MyST marks its sections tex2jax_ignore and the formulas `math`: MathJax 2 typesets those only (as Sphinx's
# configuration of MathJax 3 does)
# (and a display formula wider than the text breaks into lines instead of being cut off)
mathjax2_config = {
    "messageStyle": "none",
    "CommonHTML": {"linebreaks": {"automatic": True}},
    "tex2jax": {
        "processClass": "tex2jax_process|mathjax_process|math|output_area",
        "ignoreClass": "tex2jax_ignore|mathjax_ignore|document",
    },
}
# figures stay in docs/ (the README shows them too); the pages refer to them as ../NAME.png


def _generate(app) -> None:
    reference_pages.write_all(HERE / "reference")
    work = Path(os.environ.get("STRINGCONTACT_DOCS_DEMO_WORK", Path(app.outdir).parent / "demo-runs"))
    demo_pages.write_pages(
        ROOT / "demos", HERE / "tutorial" / "demos", work, ROOT / "src" / "stringcontact", "../../../demos"
    )


def _copy_mathjax(app, exception) -> None:
    """MathJax's `MATHJAX_PARTS` into the built site's _static/mathjax; without libjs-mathjax, a warning (an error
    under -W): the formulas would show as LaTeX source."""
    if exception is not None or app.builder.format != "html":
        return
    missing = [part for part in MATHJAX_PARTS if not (MATHJAX / part).exists()]
    if missing:
        from sphinx.util import logging

        logging.getLogger(__name__).warning(
            "MathJax not found in %s (missing %s): the formulas show as LaTeX; install Debian's libjs-mathjax "
            "(scripts/setup --docs) or set STRINGCONTACT_MATHJAX",
            MATHJAX,
            ", ".join(missing),
        )
        return
    target = Path(app.outdir) / "_static" / "mathjax"
    for part in MATHJAX_PARTS:
        source = MATHJAX / part
        if source.is_dir():
            shutil.copytree(source, target / part, dirs_exist_ok=True)
        else:
            (target / part).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / part)


def setup(app):
    app.connect("builder-inited", _generate)
    app.connect("build-finished", _copy_mathjax)
    return {"parallel_read_safe": True}
