"""What a newcomer meets on the command line: `--version`, `run` without `--out`, `--model module:name` from the
current folder with the installed command, where the model came from (summary.json, the pictures' titles),
`list`'s columns, `show` of a scheme without ε, a membrane's diagnostics, `check` of scheme projection, and
progress bars only on a terminal."""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import importlib.metadata
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import stringcontact as sc
from stringcontact.cli.main import main

REPO = Path(__file__).resolve().parents[2]
SMALL = ["--nx", "200", "--nt", "40", "--eps", "0.01", "--no-progress", "--no-pictures"]  # r = 0.75
SOFT = ["--nx", "200", "--nt", "600", "--no-progress", "--no-pictures"]  # r = 1: stable for soft_ground too
COMMAND = Path(sys.executable).with_name("stringcontact")  # the installed console script, not `python -m`


def _environment():
    """The test's environment without PYTHONPATH: the current folder must be found by the command itself."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return env | {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}


def test_version_prints_the_installed_version(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out == f"stringcontact {importlib.metadata.version('stringcontact')}\n"


def test_run_without_out_says_in_one_line_that_nothing_is_written(capsys):
    assert main(["run", "example1", *SMALL]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "nothing written" in line]
    assert lines == ["nothing written (no --out): add --out DIR to write XDMF, CSV, JSON and pictures"]


@pytest.mark.slow
def test_the_installed_command_finds_a_model_module_in_the_current_folder(tmp_path):
    """`stringcontact run ... --model my_ground:soft_ground` from the folder holding my_ground.py (the demo's
    variant, copied as a plain module): found as under `python -m stringcontact`; summary.json names the file
    and its hash."""
    if not COMMAND.exists():
        pytest.skip(f"{COMMAND} is not installed (scripts/setup)")
    module = tmp_path / "my_ground.py"
    shutil.copy(REPO / "examples" / "soft_ground" / "soft_ground.py", module)
    out = tmp_path / "out"
    proc = subprocess.run(
        [str(COMMAND), "run", "example1", *SOFT, "--model", "my_ground:soft_ground", "--out", "out"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=_environment(),
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["model"] == "soft_ground"
    origin = summary["model_origin"]
    assert origin["source"] == "module" and origin["spec"] == "my_ground:soft_ground", origin
    assert Path(origin["file"]).resolve() == module.resolve()
    assert origin["sha256"] == hashlib.sha256(module.read_bytes()).hexdigest()
    # and from elsewhere it is not found: the current folder, not the module's, is searched
    away = tmp_path / "elsewhere"
    away.mkdir()
    proc = subprocess.run(
        [str(COMMAND), "run", "example1", *SOFT, "--model", "my_ground:soft_ground"],
        cwd=away,
        capture_output=True,
        text=True,
        env=_environment(),
        timeout=600,
        check=False,
    )
    assert proc.returncode == 2 and "cannot import module 'my_ground'" in proc.stderr, proc.stderr


@pytest.mark.parametrize(
    ("model", "source", "package"),
    [(None, "built-in", "stringcontact"), ("soft_ground", "entry point", "stringcontact-soft-ground")],
)
def test_summary_says_where_a_registered_model_came_from(tmp_path, capsys, model, source, package):
    from stringcontact.model.registry import registered

    if model is not None and model not in registered():
        pytest.skip(f"{model} is not installed (scripts/setup installs examples/soft_ground)")
    out = tmp_path / "out"
    assert main(["run", "example1", *SOFT, *(["--model", model] if model else []), "--out", str(out)]) == 0
    origin = json.loads((out / "summary.json").read_text())["model_origin"]
    assert origin["source"] == source and origin["package"] == package, origin
    assert origin["name"] == (model or "inelastic")
    assert origin["version"] == importlib.metadata.version(package)


def test_a_model_object_from_python_is_named_in_captions_and_summary(tmp_path):
    from stringcontact.io.readback import read_output
    from stringcontact.model.interface import inelastic
    from stringcontact.plot import charts, mesh_pictures

    winkler = dataclasses.replace(inelastic, name="winkler")
    scene = sc.load_scene("example1").replace(nx=100, nt=40, eps=0.01)
    res = sc.simulate(scene, model=winkler, output=sc.Output(tmp_path / "w", pictures=False, progress=False))
    assert "model winkler, scheme paper" in charts.parameter_line(res)
    summary = json.loads((tmp_path / "w" / "summary.json").read_text())
    assert summary["model"] == "winkler" and summary["model_origin"] == {"name": "winkler", "source": "object"}
    back = read_output(tmp_path / "w")
    assert back.model_origin == summary["model_origin"]
    assert "model winkler" in charts.parameter_line(back)  # `stringcontact plot` redraws the same captions
    assert mesh_pictures.titled is charts.titled  # the pyvista pictures caption the same line


def test_list_aligns_its_columns_for_every_built_in_scene(capsys):
    from stringcontact.scene.toml import list_scenes

    assert main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    scenes = list_scenes()
    assert len(lines) == len(scenes)
    starts = {line.index(description) for line, (_, description) in zip(lines, scenes)}
    assert len(starts) == 1, lines  # every description starts in the same column
    (start,) = starts
    assert [line[:start].rstrip() for line in lines] == [name for name, _ in scenes]


def test_show_names_r_only_for_a_scheme_with_eps(capsys):
    assert main(["show", "drum"]) == 0  # scheme projection: no eps
    first = capsys.readouterr().out.splitlines()[0]
    assert "r = dt/eps" not in first and first.startswith("# scene 'drum': dt = 0.005"), first
    assert main(["show", "example1"]) == 0
    assert "r = dt/eps = 0.4" in capsys.readouterr().out.splitlines()[0]


def test_a_membranes_diagnostics_name_the_contact_area(tmp_path):
    from stringcontact.io.readback import read_output

    drum = sc.load_scene("drum").replace(mesh_size=0.2, T=0.4, nt=80, output_times=[0.0, 0.4])
    res = sc.simulate(drum, output=sc.Output(tmp_path / "drum", pictures=False, progress=False))
    with open(tmp_path / "drum" / "diagnostics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert "contact_area" in rows[0] and "contact_length" not in rows[0], list(rows[0])
    assert [float(r["contact_area"]) for r in rows] == pytest.approx(res.contact_measure, rel=1e-15)
    assert max(float(r["contact_area"]) for r in rows) > 0.5  # an area of the unit disk's π, not a length
    back = read_output(tmp_path / "drum")  # the reader keeps working
    assert back.contact_measure == pytest.approx(res.contact_measure)
    string = sc.simulate(
        sc.load_scene("example1").replace(nx=100, nt=40, eps=0.01),
        output=sc.Output(tmp_path / "s", pictures=False, progress=False),
    )
    with open(tmp_path / "s" / "diagnostics.csv", newline="") as f:
        header = next(csv.reader(f))
    assert "contact_length" in header and "contact_area" not in header
    assert string.contact_length is not None


@pytest.mark.slow
def test_check_of_scheme_projection_names_no_penalty_and_no_minus_zero(capsys):
    assert main(["check", "example1", "--scheme", "projection", "--nx", "100", "--nt", "600", "--levels", "2"]) == 0
    out = capsys.readouterr().out
    assert "scheme projection" in out
    assert "explicit penalty" not in out, out
    assert " -0 " not in out and " -0\n" not in out and "=-0" not in out, out


@pytest.mark.slow
def test_progress_bars_only_on_a_terminal(tmp_path):
    """stderr a pipe (a log file, CI): no bar; stderr a terminal: the bar."""
    import fcntl
    import pty
    import struct
    import termios

    if not COMMAND.exists():
        pytest.skip(f"{COMMAND} is not installed (scripts/setup)")
    argv = [str(COMMAND), "run", "example1", "--nx", "200", "--nt", "40", "--eps", "0.01", "--no-pictures"]
    piped = subprocess.run(argv, capture_output=True, text=True, env=_environment(), timeout=600, check=False)
    assert piped.returncode == 0, piped.stderr
    assert "step" not in piped.stderr and "%|" not in piped.stderr, piped.stderr
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a new pty is 0 columns wide
    try:
        proc = subprocess.run(
            argv, stdout=subprocess.DEVNULL, stderr=follower, env=_environment(), timeout=600, check=False
        )
        os.close(follower)
        follower = None
        written = b""
        while True:
            try:
                chunk = os.read(leader, 65536)
            except OSError:  # the terminal's other end is closed: all read
                break
            if not chunk:
                break
            written += chunk
    finally:
        os.close(leader)
        if follower is not None:
            os.close(follower)
    assert proc.returncode == 0
    assert b"0/40" in written and b"step/s" in written, written[-500:]


def _shell_block(text: str, after: str) -> list[str]:
    """The command lines of the first ```sh block after `after` in `text` (comments dropped)."""
    block = text[text.index(after) :].split("```sh\n", 1)[1].split("```", 1)[0]
    lines = [line.split("  #", 1)[0].strip() for line in block.splitlines()]
    return [line for line in lines if line and not line.startswith("#")]


@pytest.mark.slow
def test_the_readmes_quick_start_runs_as_written_after_make_demo(tmp_path):
    """`make demo` (its recipe in the Makefile), then the README's quick start in order, in one folder: every
    stringcontact command exits 0 (a `run` into the folder make demo wrote needs --force, else exit 2). The runs
    are shortened with --nx/--nt/--no-pictures, which the folder check does not look at; ParaView's line is
    tests/system/test_paraview.py's."""
    import shlex

    if not COMMAND.exists():
        pytest.skip(f"{COMMAND} is not installed (scripts/setup)")
    recipe = (REPO / "Makefile").read_text().split("\ndemo:", 1)[1].split("\n\n", 1)[0]
    (demo,) = [line.strip() for line in recipe.splitlines()[1:] if "stringcontact" in line]
    readme = (REPO / "README.md").read_text()
    assert "make demo" in _shell_block(readme, "## Two commands")[0]
    quick = _shell_block(readme, "## Quick start")
    assert any(line.startswith("paraview") for line in quick)
    commands = [demo.replace("$(VENV)/bin/", ".venv/bin/")] + [line for line in quick if "stringcontact" in line]
    assert len(commands) == 6, commands
    short = ["--nx", "200", "--nt", "600", "--no-progress", "--no-pictures"]
    for line in commands:
        words = shlex.split(line)
        assert words[0] == ".venv/bin/stringcontact", line
        stdout = None
        if ">" in words:
            words, stdout = words[: words.index(">")], tmp_path / words[words.index(">") + 1]
        argv = [str(COMMAND), *words[1:]]
        if words[1] == "run":
            argv = (
                [*argv, *short]
                if "--nx" not in words
                else [*argv[: argv.index("--nx")], *argv[argv.index("--nx") + 2 :], *short]
            )
        proc = subprocess.run(
            argv,
            cwd=tmp_path,
            capture_output=True,
            text=True,
            env=dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1"),
            timeout=600,
            check=False,
        )
        assert proc.returncode == 0, f"{line}: exit {proc.returncode}: {proc.stderr[-1000:]}"
        if stdout is not None:
            stdout.write_text(proc.stdout)
    assert (tmp_path / "out" / "example1" / "view.py").is_file() and (tmp_path / "out" / "mine").is_dir()
    assert (tmp_path / "out" / "paper" / "contact_set.pdf").read_bytes().startswith(b"%PDF")  # the vector figures
