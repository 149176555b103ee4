"""A run compiles none of its modules from source: scripts/setup byte-compiles this package and the Debian packages
whose bytecode Debian leaves out (dolfinx, petsc4py, slepc4py under /usr/lib/petsc and /usr/lib/slepc).

Without that bytecode Python compiles those modules at every start wherever it cannot write their `__pycache__`:
in the image, for a user who does not own /usr/lib, and with PYTHONDONTWRITEBYTECODE set (the Makefile's, the
image's). benchmarks/bench_bytecode.py measures what it costs a run.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# Every module compiled from a .py file is reported by Python's "compile" audit event (importlib compiles a
# module's source through the built-in compile when it finds no valid bytecode).
RUN = textwrap.dedent(
    """
    import sys
    compiled = []
    sys.addaudithook(lambda event, args: compiled.append(str(args[1]))
                     if event == "compile" and str(args[1]).endswith(".py") else None)
    from stringcontact.cli.main import main
    try:
        main(["run", "example1", "--nx", "20", "--nt", "20", "--no-pictures", "--no-progress", "--out", sys.argv[1]])
    except SystemExit as stop:
        assert not stop.code, stop.code
    import slepc4py  # the membranes' dt_max on 2-D meshes
    from stringcontact.plot import animation, charts, mesh_pictures, run_pictures  # what a run's pictures import
    print("MODULES", *(m.__file__ for m in list(sys.modules.values()) if getattr(m, "__file__", None)), sep="\\n")
    print("COMPILED", *compiled, sep="\\n")
    """
)


def _lines(out: str, section: str, until: str | None = None) -> list[str]:
    lines = out.splitlines()
    start = lines.index(section) + 1
    end = lines.index(until) if until else len(lines)
    return lines[start:end]


@pytest.mark.slow
def test_a_run_compiles_no_module_from_source(tmp_path):
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}  # the test writes no bytecode itself
    proc = subprocess.run([sys.executable, "-c", RUN, str(tmp_path / "out")], env=env, capture_output=True, text=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    modules = _lines(proc.stdout, "MODULES", "COMPILED")
    compiled = _lines(proc.stdout, "COMPILED")
    ours = ROOT.resolve()
    # This checkout's modules may be newer than their bytecode while someone edits them (scripts/setup, which
    # `make test` runs first, compiles them again); everything else must load from bytecode.
    theirs = [f for f in compiled if not Path(f).resolve().is_relative_to(ours)]
    assert not theirs, f"compiled from source at every run (run scripts/setup): {theirs}"
    for name in ("dolfinx", "petsc4py", "slepc4py", "stringcontact"):
        assert any(f"/{name}/" in f for f in modules), name  # the run did import them
    missing = [f for f in modules if f.endswith(".py") and Path(f).resolve().is_relative_to(ours)
               and not Path(importlib.util.cache_from_source(f)).exists()]
    assert not missing, f"no bytecode (run scripts/setup): {missing}"
