"""The command line: exit codes, one-line errors, no output left behind on bad input."""

import json
import os
import subprocess
import sys

import pytest

from stringcontact.cli import main

SMALL = ["--nx", "200", "--nt", "750", "--no-progress"]


def test_run_writes_results(tmp_path, capsys):
    out = tmp_path / "ex1"
    assert main(["run", "example1", *SMALL, "--out", str(out)]) == 0
    assert {"solution.xdmf", "solution.h5", "diagnostics.csv", "summary.json"} <= set(os.listdir(out))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "complete"
    assert summary["scene"]["nx"] == 200
    assert summary["min_eta"] < 0
    assert "energy balance" in capsys.readouterr().out


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
    assert main(["run", "example1", *SMALL, "--out", str(out), "--force"]) == 0
    assert not (out / "keep.txt").exists()


def test_list_and_show(capsys):
    assert main(["list"]) == 0
    listing = capsys.readouterr().out
    assert "example1" in listing and "example2" in listing
    assert main(["show", "example2"]) == 0
    assert "h_left" in capsys.readouterr().out


def test_python_dash_m_is_the_same_cli():
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", "nope"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "no built-in scene" in proc.stderr


class _nullcontext:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
