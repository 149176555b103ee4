"""The demos (demos/*.py, jupytext "light") as pages of the site, executed when the site is built.

Each demo runs in its own process (`python demo_pages.py DEMO OUT RECORD`), cell by cell, at reduced resolution
(STRINGCONTACT_DEMO_FAST=1) with its output folder STRINGCONTACT_DEMO_OUT inside the build; the process records
what each code cell printed and which pictures it wrote. The page is the demo's prose and code, each code cell
followed by its printed lines and its pictures, as dolfinx renders its demos (jupytext to MyST).

Why executed and not cached: the pictures and numbers on a page are then those of the code beside them, and a
demo that no longer runs fails the build. A page is made again only when its demo or the package's source changed
(a hash of both, kept beside the records in the build folder). The tests run the demos through `execute` too
(tests/conftest.py's `demo_run`), into the folder their site build then reads: each demo runs once per test run.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

PICTURE_SUFFIXES = (".png", ".gif")
#: The file that marks a demo's output folder as made by this module: only a folder holding it is ever removed
#: (STRINGCONTACT_DOCS_DEMO_WORK may name a folder of the user's, whose demo_* subfolders are theirs).
MARKER = ".stringcontact-docs-demo"
#: Printed lines kept per cell on the page (the rest is cut, with a note).
MAX_LINES = 40


def _cells(demo: Path) -> list[tuple[str, str]]:
    """The demo's cells as (kind, source): kind "markdown" or "code" (a raw cell, jupytext's header, is left out)."""
    import jupytext

    notebook = jupytext.read(demo, fmt="py:light")
    return [(cell.cell_type, cell.source) for cell in notebook.cells
            if cell.source.strip() and cell.cell_type in ("markdown", "code")]


def _pictures(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in sorted(folder.rglob("*"))
            if p.suffix in PICTURE_SUFFIXES}


def run(demo: Path, out: Path, record: Path) -> None:
    """Run `demo` cell by cell in one namespace (our own file, as `python demo.py` would); write `record`: per code
    cell, what it printed and the pictures it wrote or rewrote under `out`."""
    os.environ.update(STRINGCONTACT_DEMO_FAST="1", STRINGCONTACT_DEMO_OUT=str(out), MPLBACKEND="Agg")
    out.mkdir(parents=True, exist_ok=True)
    namespace = {"__name__": "__main__", "__file__": str(demo)}
    cells = []
    for kind, source in _cells(demo):
        if kind != "code":
            continue
        before = _pictures(out)
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            exec(compile(source, str(demo), "exec"), namespace)  # noqa: S102 - the demo's own code, as `python demo.py`
        after = _pictures(out)
        cells.append({"printed": printed.getvalue(), "pictures": [p for p in after if before.get(p) != after[p]]})
    record.write_text(json.dumps(cells, indent=1))


def _stamp(demo: Path, package: Path) -> str:
    digest = hashlib.sha256(demo.read_bytes())
    for path in sorted(package.rglob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()


#: seconds a demo may run (at reduced resolution each takes well under a minute): a hung demo fails the build
TIMEOUT = 900


def execute(demo: Path, work: Path, package: Path) -> tuple[list[dict], Path]:
    """The records of `demo` and its output folder: run it unless a run of the same sources is kept in `work`.

    The demo runs in an empty folder of its own (work/DEMO.cwd) and must leave it empty: a demo writes only under
    STRINGCONTACT_DEMO_OUT. What it printed to stderr is kept in work/DEMO.stderr."""
    out, record, stamp = work / demo.stem, work / f"{demo.stem}.json", work / f"{demo.stem}.stamp"
    want = _stamp(demo, package)
    if not (record.exists() and stamp.exists() and stamp.read_text() == want):
        _fresh_folder(out)
        stamp.unlink(missing_ok=True)
        cwd = work / f"{demo.stem}.cwd"
        shutil.rmtree(cwd, ignore_errors=True)
        cwd.mkdir()
        proc = subprocess.run([sys.executable, __file__, str(demo), str(out), str(record)], cwd=cwd,
                              capture_output=True, text=True, check=False, timeout=TIMEOUT)
        (work / f"{demo.stem}.stderr").write_text(proc.stderr)
        if proc.returncode != 0:
            raise RuntimeError(f"demo {demo.name} failed (exit {proc.returncode}):\n{proc.stdout[-2000:]}\n"
                               f"{proc.stderr[-4000:]}")
        if left := sorted(p.name for p in cwd.iterdir()):
            raise RuntimeError(f"demo {demo.name} wrote outside STRINGCONTACT_DEMO_OUT, in its working folder: {left}")
        stamp.write_text(want)
    return json.loads(record.read_text()), out


def _fresh_folder(out: Path) -> None:
    """`out` made empty and marked as this module's (`MARKER`): removed first only if it holds the marker; any
    other folder (or file) there is the user's and stops the build, untouched."""
    if out.is_symlink() or (out.exists() and not (out.is_dir() and (out / MARKER).is_file())):
        raise RuntimeError(f"{out} exists and was not made by the docs build (no {MARKER} in it); move it away or "
                           "set STRINGCONTACT_DOCS_DEMO_WORK to another folder")
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    (out / MARKER).write_text("made by docs/_ext/demo_pages.py; removed and made again by the docs build\n")


def _printed(text: str) -> str:
    lines = text.rstrip("\n").splitlines()
    if not lines:
        return ""
    if len(lines) > MAX_LINES:
        lines = lines[:MAX_LINES] + [f"... ({len(lines) - MAX_LINES} more lines)"]
    return "```text\n" + "\n".join(lines) + "\n```\n"


def page(demo: Path, records: list[dict], out: Path, pictures: Path, link: str) -> str:
    """The MyST page of `demo`: its prose, its code, each code cell's output; the pictures copied to `pictures`."""
    parts, code = [], iter(records)
    for kind, source in _cells(demo):
        if kind == "markdown":
            parts.append(source.rstrip() + "\n")
            if len(parts) == 1:  # after the title: where the script is and how to run it
                parts.append(f"*This page is the script {{download}}`demos/{demo.name} <{link}>` run with "
                             "`STRINGCONTACT_DEMO_FAST=1` (reduced resolution); run it yourself with "
                             f"`.venv/bin/python demos/{demo.name}`.*\n")
            continue
        parts.append("```python\n" + source.rstrip() + "\n```\n")
        cell = next(code)
        parts.append(_printed(cell["printed"].replace(str(out), f"out/{demo.stem}")))  # its folder without the env
        for name in cell["pictures"]:
            target = pictures / f"{demo.stem}__{name.replace('/', '__')}"
            shutil.copyfile(out / name, target)
            parts.append(f"![{Path(name).name}]({pictures.name}/{target.name})\n")
    return "\n".join(p for p in parts if p)


def write_pages(demos: Path, target: Path, work: Path, package: Path, link_base: str) -> list[Path]:
    """A page per demo in `target` (its pictures in target/_pictures), running each in `work` when its sources
    changed."""
    work.mkdir(parents=True, exist_ok=True)
    pictures = target / "_pictures"
    shutil.rmtree(pictures, ignore_errors=True)
    pictures.mkdir(parents=True)
    pages = []
    for demo in sorted(demos.glob("demo_*.py")):
        records, out = execute(demo, work, package)
        path = target / f"{demo.stem}.md"
        text = page(demo, records, out, pictures, f"{link_base}/{demo.name}")
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
        pages.append(path)
    return pages


if __name__ == "__main__":
    run(Path(sys.argv[1]).resolve(), Path(sys.argv[2]).resolve(), Path(sys.argv[3]).resolve())
