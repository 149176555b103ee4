"""The hand-written pages show what the program prints now: the first run's `list` is `stringcontact list`'s."""

from __future__ import annotations

import re
from pathlib import Path

from stringcontact.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def _listing(page: Path) -> list[str]:
    """The lines of the `text` block that follows the page's `stringcontact list` command."""
    text = page.read_text()
    after = text[text.index("stringcontact list\n") :]
    block = re.search(r"```text\n(.*?)```", after, re.DOTALL)
    assert block, f"{page}: no output block after `stringcontact list`"
    return block.group(1).splitlines()


def test_the_first_runs_list_shows_every_scene_as_list_prints_it(capsys):
    """The same scenes in the same order, each description as printed (a shortened one ends in "...")."""
    assert main(["list"]) == 0
    printed = capsys.readouterr().out.splitlines()
    shown = _listing(ROOT / "docs" / "tutorial" / "first_run.md")
    assert [line.split()[0] for line in shown] == [line.split()[0] for line in printed]
    for page_line, line in zip(shown, printed):
        if page_line.endswith("..."):
            assert line.startswith(page_line[:-3].rstrip()), (page_line, line)
        else:
            assert page_line == line, (page_line, line)
