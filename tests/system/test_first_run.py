"""The first run on a fresh machine: scripts/setup compiles the demo's forms, quietly; the demo then compiles none.

A fresh machine is simulated by a private, empty JIT cache (XDG_CACHE_HOME, which dolfinx's cache follows).
"""

import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from stringcontact.jitlog import QuietCompiler

ROOT = Path(__file__).resolve().parents[2]
COMPILER_LINES = ("INFO:root", "running build_ext", "gcc", "building '")


def _compiled(cache: Path) -> set[str]:
    return {p.name for p in (cache / "fenics").glob("*.so")}


@pytest.mark.slow  # six tiny runs that compile, then Example 1 at the paper's resolution
def test_setup_compiles_the_demos_forms_quietly_and_the_demo_compiles_none(tmp_path):
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"), "MPLCONFIGDIR": str(tmp_path / "mpl")}
    setup = subprocess.run([str(ROOT / "scripts" / "setup"), "--only", "warm", sys.prefix], env=env, capture_output=True, text=True,
                           check=False)
    assert setup.returncode == 0, setup.stderr
    assert setup.stdout.startswith("setup: compiling the forms of example1") and setup.stdout.count("\n") == 1
    assert not any(word in setup.stdout + setup.stderr for word in COMPILER_LINES), setup.stderr[:2000]
    forms = _compiled(tmp_path / "cache")
    assert forms  # the fresh cache was filled

    # `make demo`'s command at full resolution (pictures off: they compile no forms).
    demo = subprocess.run([sys.executable, "-m", "stringcontact", "run", "example1", "--no-pictures", "--no-progress"],
                          env=env, capture_output=True, text=True, check=False)
    assert demo.returncode == 0, demo.stderr
    assert _compiled(tmp_path / "cache") == forms
    assert not any(word in demo.stdout + demo.stderr for word in COMPILER_LINES)

    again = subprocess.run([str(ROOT / "scripts" / "setup"), "--only", "warm", sys.prefix], env=env, capture_output=True, text=True,
                           check=False)
    assert again.returncode == 0 and again.stdout == "" and again.stderr == ""  # quiet on a second run


def _record(level, path, name="root"):
    return logging.LogRecord(name, level, path, 1, "msg", None, None)


def test_quiet_compiler_drops_only_the_compilers_chatter():
    quiet = QuietCompiler()
    spawn = "/usr/lib/python3/dist-packages/setuptools/_distutils/spawn.py"
    assert not quiet.filter(_record(logging.INFO, spawn))  # the gcc command line
    assert not quiet.filter(_record(logging.INFO, "/usr/lib/python3.11/distutils/command/build_ext.py"))
    assert quiet.filter(_record(logging.WARNING, spawn))  # a compiler warning still shows
    assert quiet.filter(_record(logging.INFO, "/home/me/analysis.py"))  # the user's own root-logger records pass


def test_importing_the_package_leaves_the_logging_alone_and_the_command_line_quiets_the_compiler():
    code = ("import logging, stringcontact, stringcontact.jitlog as j\nbefore = list(logging.getLogger().filters)\n"
            "from stringcontact.cli.main import main\nmain(['list'])\n"
            "print(before == [], any(isinstance(f, j.QuietCompiler) for f in logging.getLogger().filters))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "True True"
