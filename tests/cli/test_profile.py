"""`stringcontact run --profile`: where the run's time went, section by section, adding up to the total."""

import re
import subprocess
import sys

import pytest

from stringcontact.cli.main import main

SMALL = ["--nx", "200", "--nt", "40", "--eps", "0.01", "--no-progress"]  # r = 0.75
SECTIONS = ("imports", "set-up", "solve", "output", "pictures", "other", "total")  # called from Python: no start-up


def _sections(stdout: str) -> dict:
    block = stdout.split("where the time went:\n", 1)[1]
    found = {}
    for line in block.splitlines():
        m = re.match(r"\s+(\S+).*?\s(-?[0-9.]+) s\s+(-?[0-9.]+) %$", line)
        if m:
            found[m.group(1)] = float(m.group(2))
    return found


@pytest.mark.slow
def test_profile_prints_each_section_and_they_add_up(tmp_path, capsys):
    assert main(["run", "example1", *SMALL, "--out", str(tmp_path / "run"), "--profile"]) == 0
    found = _sections(capsys.readouterr().out)
    assert tuple(found) == SECTIONS
    parts = sum(v for k, v in found.items() if k != "total")
    assert abs(parts - found["total"]) <= 0.0005 * len(found)  # rounding of the printed milliseconds
    assert found["solve"] > 0 and found["set-up"] > 0 and found["output"] > 0 and found["pictures"] > 0


def test_without_profile_no_sections(tmp_path, capsys):
    assert main(["run", "example1", *SMALL, "--no-pictures", "--out", str(tmp_path / "run")]) == 0
    assert "where the time went" not in capsys.readouterr().out


@pytest.mark.slow
def test_as_a_command_the_start_up_is_a_section_too(tmp_path):
    """Started as `stringcontact run`, the process's own start-up (Python, the command line, PETSc) comes first."""
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", "example1", *SMALL, "--no-pictures", "--out",
                           str(tmp_path / "run"), "--profile"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    found = _sections(proc.stdout)
    assert tuple(found) == ("start-up", *SECTIONS)
    assert 0 < found["start-up"] < found["total"] and found["pictures"] == 0.0
