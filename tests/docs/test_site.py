"""The site builds with warnings as errors and every internal link checked (`make docs`), the demos' pages show
their pictures, the formulas are typeset offline by the site's own MathJax, wide content stays in the page, and a
broken internal link fails the build. One build serves all tests here (the `site` fixture)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import DEMOS, demo_run

from stringcontact.scene import limits

ROOT = Path(__file__).resolve().parents[2]
GENERATED = ("_build", "_generated", "demo_*.md", "_pictures")


def _checkout(tmp_path: Path) -> Path:
    """A copy of docs/ (nothing generated) beside links to the demos and the package: the build writes there."""
    repo = tmp_path / "repo"
    shutil.copytree(ROOT / "docs", repo / "docs", ignore=shutil.ignore_patterns(*GENERATED))
    for name in ("demos", "src"):
        (repo / name).symlink_to(ROOT / name)
    return repo


def _build(repo: Path, work: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, STRINGCONTACT_DOCS_DEMO_WORK=str(work))
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "sphinx",
            "-W",
            "--keep-going",
            "-n",
            "-q",
            "-b",
            "html",
            str(repo / "docs"),
            str(repo / "docs" / "_build" / "html"),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
        check=False,
    )


@pytest.fixture(scope="module")
def site(tmp_path_factory, demo_work):
    """One build of the site for this file's tests (it takes minutes): (checkout, demo work folder, html). The
    demos' pages come from the test run's one run of each demo (`conftest.demo_run`; taken last to first, while
    tests/system/test_demos.py takes them first to last in another worker)."""
    tmp_path = tmp_path_factory.mktemp("site")
    repo = _checkout(tmp_path)
    for demo in reversed(DEMOS):
        demo_run(demo, demo_work)
    proc = _build(repo, demo_work)
    assert proc.returncode == 0, proc.stderr[-5000:]
    return repo, demo_work, repo / "docs" / "_build" / "html"


#: pages with formulas: the index, the model, a demo
MATH_PAGES = ("index.html", "explanation/model.html", "tutorial/demos/demo_example1.html")


@pytest.mark.slow
def test_the_site_builds_without_a_warning(site):
    _, work, html = site
    keys = (html / "reference" / "scene_keys.html").read_text()
    assert all(
        f'<code class="docutils literal notranslate"><span class="pre">{k}</span></code>' in keys
        for k in limits.FILE_KEYS
    )
    api = (html / "reference" / "api.html").read_text()
    assert 'id="simulate"' in api and "comm=MPI.COMM_WORLD" in re.sub(r"<[^>]+>", "", api)  # its signature, highlighted
    assert "stringcontact show" in (html / "reference" / "cli.html").read_text()
    demos = sorted((ROOT / "demos").glob("demo_*.py"))
    for demo in demos:  # every demo is a page, and the paper's examples show their pictures
        page = (html / "tutorial" / "demos" / f"{demo.stem}.html").read_text()
        assert "<pre>" in page or "highlight-python" in page
    for name in ("demo_example1", "demo_example2", "demo_membrane"):
        page = (html / "tutorial" / "demos" / f"{name}.html").read_text()
        images = [line for line in page.splitlines() if "<img" in line and "_images/" in line]
        assert len(images) >= 3, name
        for line in images:
            src = line.split('src="', 1)[1].split('"', 1)[0]
            assert (html / "tutorial" / "demos" / src).resolve().is_file(), src
    # the output reference names every file a run writes (the demos' runs, from the build)
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    import reference_pages

    for folder in (work / "demo_example1" / "example1", work / "demo_membrane"):
        written = {p.name for p in folder.rglob("*") if p.is_file() and p.parent.name != "pictures"} - {
            ".stringcontact-docs-demo"}  # demo_pages.MARKER: the build's own mark on the folder
        assert written and not written - set(reference_pages.FILES) - set(reference_pages.PICTURES) - {
            "drum_variants.png"
        }, written


def _scripts(page: Path) -> list[dict]:
    """The attributes of each <script> of an HTML page."""
    from html.parser import HTMLParser

    found = []

    class Scripts(HTMLParser):
        def handle_starttag(self, tag, attrs):
            if tag == "script":
                found.append(dict(attrs))

    Scripts().feed(page.read_text())
    return found


@pytest.mark.slow
def test_the_formulas_are_typeset_by_the_sites_own_mathjax(site):
    """No page with formulas loads a script from the network (a cluster without internet shows the formulas
    too): MathJax is the site's copy in _static/mathjax, with what its configuration loads."""
    _, _, html = site
    for name in MATH_PAGES:
        page = html / name
        assert "\\[" in page.read_text() or "\\(" in page.read_text(), f"{name}: no formula to typeset"
        scripts = _scripts(page)
        remote = [s["src"] for s in scripts if re.match(r"(https?:)?//", s.get("src") or "")]
        assert remote == [], f"{name} loads {remote}"
        (mathjax,) = [s["src"] for s in scripts if "MathJax.js" in (s.get("src") or "")]
        assert (page.parent / mathjax.split("?", 1)[0]).resolve().is_file(), mathjax
        assert mathjax.endswith("?config=TeX-AMS_CHTML"), mathjax
        # MyST marks the sections tex2jax_ignore: MathJax 2 must be told to typeset the formulas' class `math`
        text = page.read_text()
        config = json.loads(text.split("MathJax.Hub.Config(", 1)[1].split(")</script>", 1)[0])
        assert "tex2jax_ignore" in text and "math" in config["tex2jax"]["processClass"].split("|"), config
        assert config["CommonHTML"]["linebreaks"]["automatic"] is True, config  # a long formula breaks
    mathjax = html / "_static" / "mathjax"
    for part in (
        "config/TeX-AMS_CHTML.js",
        "jax/input/TeX/config.js",
        "jax/output/CommonHTML/jax.js",
        "extensions/MathMenu.js",
        "fonts/HTML-CSS/TeX/woff/MathJax_Main-Regular.woff",
    ):
        assert (mathjax / part).is_file(), part


@pytest.mark.slow
def test_wide_tables_long_signatures_and_code_stay_in_the_page(site):
    """The site's CSS is on every page (wrapping cells, code and the contents' names); a class's signature is
    apart from its heading, one parameter a line."""
    _, _, html = site
    css = (html / "_static" / "custom.css").read_text()
    assert ".bd-article table td" in css and "div.highlight pre" in css and "bd-sidebar-secondary" in css
    for name in ("reference/scene_keys.html", "reference/api.html", *MATH_PAGES):
        assert any('href="' in line and "custom.css" in line for line in (html / name).read_text().splitlines()), name
    api = (html / "reference" / "api.html").read_text()
    model = api.split('id="model"', 1)[1].split("</pre>", 1)[0]  # Model's signature: its code block
    assert "sig-param" not in model and model.count("\n") > 5, "Model's parameters not one a line"


@pytest.mark.slow
def test_a_broken_link_fails_the_build(site):
    """A link to a page that does not exist is an error (the demos are not run again: their sources are
    unchanged)."""
    repo, work, _ = site
    install = repo / "docs" / "tutorial" / "install.md"
    text = install.read_text()
    install.write_text(text + "\nSee [a page that does not exist](../howto/no_such_page.md).\n")
    try:
        proc = _build(repo, work)
    finally:
        install.write_text(text)
    assert proc.returncode != 0 and "no_such_page" in proc.stderr
