"""docs/_ext/demo_pages.py removes and makes again only the demo output folders it marked as its own."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import demo_pages  # from the docs' extension folder, put on sys.path above


@pytest.fixture
def demo(tmp_path, monkeypatch):
    """A demo file, and a stand-in for its run (the subprocess) that writes its record."""
    path = tmp_path / "demos" / "demo_film.py"
    path.parent.mkdir()
    path.write_text("# # A demo\nprint(1)\n")
    package = tmp_path / "package"
    package.mkdir()

    def ran(argv, **kwargs):
        record = argv[-1]
        Path(record).write_text(json.dumps([{"printed": "1\n", "pictures": []}]))
        return subprocess.CompletedProcess(argv, 0, "", "")

    monkeypatch.setattr(demo_pages.subprocess, "run", ran)
    return path, package


def test_a_folder_of_the_users_under_the_work_folder_is_never_removed(tmp_path, demo):
    """STRINGCONTACT_DOCS_DEMO_WORK pointing at a user's folder deleted its demo_film subfolder."""
    path, package = demo
    work = tmp_path / "mine"
    (work / "demo_film").mkdir(parents=True)
    (work / "demo_film" / "thesis.tex").write_text("years of work")
    with pytest.raises(RuntimeError, match="was not made by the docs build"):
        demo_pages.execute(path, work, package)
    assert (work / "demo_film" / "thesis.tex").read_text() == "years of work"


def test_a_folder_it_marked_is_made_again(tmp_path, demo):
    path, package = demo
    work = tmp_path / "work"
    work.mkdir()
    records, out = demo_pages.execute(path, work, package)
    assert out == work / "demo_film" and (out / demo_pages.MARKER).is_file() and records[0]["printed"] == "1\n"
    (out / "old.png").write_text("from the last build")
    (work / "demo_film.stamp").write_text("sources changed")
    demo_pages.execute(path, work, package)
    assert sorted(p.name for p in out.iterdir()) == [demo_pages.MARKER]


def test_a_demo_that_writes_outside_its_output_folder_fails_the_build(tmp_path, demo, monkeypatch):
    path, package = demo

    def litters(argv, **kwargs):
        Path(argv[-1]).write_text("[]")
        (Path(kwargs["cwd"]) / "stray.png").write_text("a picture in the working folder")
        return subprocess.CompletedProcess(argv, 0, "", "")

    monkeypatch.setattr(demo_pages.subprocess, "run", litters)
    with pytest.raises(RuntimeError, match=r"wrote outside STRINGCONTACT_DEMO_OUT.*stray\.png"):
        demo_pages.execute(path, tmp_path / "work", package)
    assert not (tmp_path / "work" / "demo_film.stamp").exists()  # not kept: the next build runs it again
