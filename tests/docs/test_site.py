"""The site builds with warnings as errors and every internal link checked (`make docs`), the demos' pages show
their pictures, and a broken internal link fails the build."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

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
    return subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-n", "-q", "-b", "html",
                           str(repo / "docs"), str(repo / "docs" / "_build" / "html")],
                          env=env, capture_output=True, text=True, timeout=1800, check=False)


@pytest.mark.slow
def test_the_site_builds_without_a_warning_and_a_broken_link_fails_it(tmp_path):
    repo, work = _checkout(tmp_path), tmp_path / "demo-runs"
    proc = _build(repo, work)
    assert proc.returncode == 0, proc.stderr[-5000:]
    html = repo / "docs" / "_build" / "html"
    keys = (html / "reference" / "scene_keys.html").read_text()
    assert all(f"<code class=\"docutils literal notranslate\"><span class=\"pre\">{k}</span></code>" in keys
               for k in limits.FILE_KEYS)
    assert 'id="stringcontact.simulate"' in (html / "reference" / "api.html").read_text()
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
            "drum_variants.png"}, written
    # a link to a page that does not exist is an error (the demos are not run again: their sources are unchanged)
    install = repo / "docs" / "tutorial" / "install.md"
    install.write_text(install.read_text() + "\nSee [a page that does not exist](../howto/no_such_page.md).\n")
    proc = _build(repo, work)
    assert proc.returncode != 0 and "no_such_page" in proc.stderr
