"""The command line: exit codes, one-line errors, no output left behind on bad input."""

import json
import os
import signal
import subprocess
import sys
import tomllib

import pytest
from conftest import CTRL_C_AT_IMPORT

from stringcontact.cli.main import main
from stringcontact.scene import Scene, load_scene

SMALL = ["--nx", "200", "--nt", "40", "--eps", "0.01", "--no-progress", "--no-pictures"]  # r = 0.75


def test_run_writes_results(tmp_path, capsys):
    out = tmp_path / "ex1"
    assert main(["run", "example1", *SMALL, "--out", str(out)]) == 0
    assert {"solution.xdmf", "solution.h5", "diagnostics.csv", "summary.json"} <= set(os.listdir(out))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "complete"
    assert summary["scene"]["nx"] == 200
    assert summary["min_eta"] < 0
    assert summary["stored_rows"] == 41 and summary["last_time"] == pytest.approx(0.3)
    assert summary["energy_balance"]["closes"] and summary["penetration"]["within_bound"]
    stdout = capsys.readouterr().out
    assert "energy balance: E(0) = " in stdout and ": closes" in stdout
    assert "penetration: max depth" in stdout and "within the bound" in stdout
    assert oct(out.stat().st_mode & 0o777) == oct(0o777 & ~_umask())  # an ordinary folder, not mkdtemp's 0700


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["run", "no-such-scene"], "no built-in scene"),
        (["run", "example1", "--nx", "0"], "nx"),
        (["run", "example1", "--eps", "-1"], "eps"),
        (["run", "example1", "--eps", "5e-5"], "r = dt/eps = 4"),
        (["run", "example1", "--penalty", "magic"], "invalid choice"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_no_output(tmp_path, capsys, argv, needle):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) if "magic" in argv else _nullcontext():
        code = main([*argv, "--out", str(out)])
        assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert any(needle in line for line in err)
    assert all("Traceback" not in line for line in err)
    assert not out.exists()
    assert not any(p.name.startswith(".out") for p in tmp_path.iterdir())


def test_non_empty_output_folder_is_refused_without_force(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["run", "example1", *SMALL, "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert (out / "keep.txt").read_text() == "mine"
    capsys.readouterr()
    # --force replaces a result of ours only: never a folder of other files (a thesis.tex was lost so)
    assert main(["run", "example1", *SMALL, "--out", str(out), "--force"]) == 2
    assert "--force replaces only a stringcontact result" in capsys.readouterr().err
    assert (out / "keep.txt").read_text() == "mine"


@pytest.mark.parametrize("out, message", [(".", "is the current folder or contains it"),
                                          ("..", "is the current folder or contains it"),
                                          ("/", "is the root folder")])
def test_out_that_would_replace_the_current_or_root_folder_is_refused_before_the_run(tmp_path, capsys, monkeypatch,
                                                                                     out, message):
    import stringcontact as sc

    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    monkeypatch.setattr(sc, "simulate", lambda *a, **k: pytest.fail("the run started"))
    assert main(["run", "example1", *SMALL, "--out", out, "--force"]) == 2
    err = capsys.readouterr().err
    assert err == f"stringcontact: error: --out {out}: {message}; choose a new folder\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["work"] and list((tmp_path / "work").iterdir()) == []


def test_a_law_bound_warning_is_one_line_once(capsys):
    """r = dt/eps = 4/3 under the explicit penalty: the contact law's warning comes once (the scheme's, when it is
    made), not again from the check before the run."""
    assert main(["run", "example1", "--nx", "100", "--nt", "1500", "--eps", "1.5e-4", "--no-progress",
                 "--no-pictures"]) == 0
    err = capsys.readouterr().err
    assert err.count("rebounds with restitution") == 1, err

def test_list_and_show(capsys):
    assert main(["list"]) == 0
    listing = capsys.readouterr().out
    assert "example1" in listing and "example2" in listing
    assert main(["show", "example2"]) == 0
    assert "h_left" in capsys.readouterr().out


def test_show_prints_every_key_the_run_uses(capsys, tmp_path):
    # the defaults a scene leaves to the solver are written out; the optional fields it does not give are comments
    assert main(["show", "example1"]) == 0
    text = capsys.readouterr().out
    data = tomllib.loads(text)
    assert (data["scheme"]["name"], data["scheme"]["eps"], data["model"]) == ("paper", 0.0005, "inelastic")
    assert "load" not in data and "obstacle" not in data
    assert "# load: not given" in text and "# obstacle: not given" in text
    assert load_scene("example1").replace(scheme="paper", model="inelastic") == Scene.from_dict(data)
    # a scene that gives its fields and solver options shows them as keys, the table last
    path = tmp_path / "given.toml"
    path.write_text('T = 0.1\nalpha = 0.01\nnx = 10\nnt = 10\neta0 = "1"\nv0 = "0"\nload = "-1"\n'
                    'obstacle = "0.5*x"\nmodel = "loaded_obstacle"\nscheme = { name = "projection", eps = 0.01 }\n'
                    'petsc_options = { ksp_type = "cg" }\n')
    assert main(["show", str(path)]) == 0
    text = capsys.readouterr().out
    data = tomllib.loads(text)
    assert (data["load"], data["obstacle"], data["model"], data["scheme"]) == (
        "-1", "0.5*x", "loaded_obstacle", {"name": "projection", "eps": 0.01})
    assert data["petsc_options"] == {"ksp_type": "cg"}
    assert not [key for key in ("load", "obstacle", "petsc_options") if f"# {key}: not given" in text]
    assert Scene.from_dict(data) == load_scene(path)


def test_python_dash_m_is_the_same_cli():
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", "nope"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "no built-in scene" in proc.stderr


def test_exit_codes_are_documented():
    import stringcontact.cli.main as cli
    from stringcontact.errors import Interrupted

    assert (cli.EXIT_OK, cli.EXIT_INTERNAL, cli.EXIT_INPUT, cli.EXIT_UNSTABLE) == (0, 1, 2, 3)
    assert (cli.EXIT_INTERRUPTED, Interrupted(signal.SIGTERM).exit_code) == (130, 143)
    for code in ("0 success", "2 bad input", "3 a run that became unstable", "130 interrupted by SIGINT", "143 by SIGTERM"):
        assert code in cli.__doc__


def test_signal_handlers_are_restored_after_main():
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    assert main(["list"]) == 0
    assert {s: signal.getsignal(s) for s in before} == before


def test_internal_error_is_one_line_exit_1(monkeypatch, capsys):
    import stringcontact as sc

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(sc, "simulate", broken)
    assert main(["run", "example1", *SMALL]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error ZeroDivisionError: a bug" in err and "STRINGCONTACT_TRACEBACK" in err
    monkeypatch.setenv("STRINGCONTACT_TRACEBACK", "1")
    with pytest.raises(ZeroDivisionError):
        main(["run", "example1", *SMALL])


def test_a_broken_subcommand_does_not_break_run(monkeypatch, tmp_path, capsys):
    import stringcontact.cli.main as cli

    monkeypatch.setitem(cli.SUBCOMMANDS, "broken", ("stringcontact.no_such_module", "a subcommand that fails to import"))
    assert main(["broken", "x"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the 'broken' command is unavailable (ModuleNotFoundError" in err
    assert main(["run", "example1", *SMALL, "--out", str(tmp_path / "out")]) == 0


@pytest.mark.slow
def test_broken_pipe_ends_quietly():
    # `stringcontact run ... | head -c 0`: the reader is gone before the closing lines are written. The run
    # ends by the default SIGPIPE, as Unix tools do (the shell's 141 = 128 + 13; Popen reports -13), with
    # no PETSc "Caught signal number 13 Broken Pipe" page, no traceback and no error line.
    proc = subprocess.Popen([sys.executable, "-m", "stringcontact", "run", "example1", *SMALL],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()
    with proc.stderr:
        stderr = proc.stderr.read()
    proc.wait(timeout=300)
    assert proc.returncode == -signal.SIGPIPE, stderr
    assert "PETSC ERROR" not in stderr and "Traceback" not in stderr and "MPI_ABORT" not in stderr
    assert not any("error" in line.lower() for line in stderr.splitlines()), stderr


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


class _nullcontext:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_frames_sets_the_xdmf_frames_and_refuses_zero(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", "example1", *SMALL, "--frames", "5", "--no-pictures", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stored_rows"] == 41 and summary["xdmf_frames"] == 5  # --frames bounds every frame
    capsys.readouterr()
    assert main(["run", "example1", *SMALL, "--frames", "0", "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--frames: 0 is out of range; allowed: a whole number in [1, " in err
    assert not (tmp_path / "refused").exists()


@pytest.mark.parametrize("module", ["stringcontact.scene.toml", "petsc4py", "dolfinx"])
def test_ctrl_c_during_start_up_is_one_line_and_exit_130(tmp_path, module):
    out = tmp_path / "out"
    argv = ["run", "example1", *SMALL, "--out", str(out)]
    proc = subprocess.run([sys.executable, "-c", CTRL_C_AT_IMPORT, module, *argv], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr == "stringcontact: error: interrupted by SIGINT (Ctrl-C)\n"
    assert list(tmp_path.iterdir()) == []
