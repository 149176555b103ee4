"""Reliability: hostile and broken input through the CLI, interrupted and unstable runs, locks,
disk-full and read-only output folders, and the closing numbers checks (docs/explanation/reliability.md)."""

import errno
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import grid_mesh, leftovers, mpirun
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stringcontact.cli.main import main
from stringcontact.io.publish import TargetLock
from stringcontact.io.readback import read_xdmf
from stringcontact.run.checks import energy_balance, penetration_check

QUICK = ["--no-progress", "--no-pictures"]
SMALL = ["--nx", "50", "--nt", "40", "--eps", "0.01", *QUICK]  # r = 0.75, 41 rows


def toml_string(s: str) -> str:
    # JSON escapes are TOML basic-string escapes; TOML wants DEL escaped too.
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")


def scene_text(eta0: str = "1 + x*(1 - x)", eps: str = "0.01", **lines) -> str:
    base = {"T": "0.01", "alpha": "0.01", "scheme": f"{{ eps = {eps} }}", "nx": "4", "nt": "2", "v0": '"-1"', **lines}
    return "".join(f"{k} = {v}\n" for k, v in base.items()) + f"eta0 = {toml_string(eta0)}\n"


def errors_of(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("stringcontact: error:")]


def assert_one_line_error(err: str, *fragments):
    """Exactly one error line, naming the problem; nothing else but warnings; no traceback, no HDF5 dump."""
    assert "Traceback" not in err and "HDF5-DIAG" not in err, err
    lines = errors_of(err)
    assert len(lines) == 1, err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    others = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("stringcontact: warning:")]
    assert others == lines, err


# --- hostile expressions through the whole command line ------------------------------------------------

HOSTILE = [
    "__import__('os').system('touch PWNED')",
    "().__class__.__bases__[0].__subclasses__()",
    "x.__class__",
    "x.real",
    "getattr(x, 'real')",
    "globals()",
    "__builtins__",
    "open('PWNED', 'w')",
    "exec('1')",
    "eval('1')",
    "lambda: 1",
    "[y for y in (1, 2)]",
    "{y: 1 for y in (1, 2)}",
    "(y for y in (1,))",
    "x if x else 0",
    "x[0]",
    "x @ x",
    "f'{x}'",
    "b'x'",
    "'a'*10**9",
    "9**9**9",
    "10**1000",
    "x**1e6",
    "1" + "0" * 400,
    "1+" * 400 + "1",
    "sin(" * 200 + "x" + ")" * 200,
    "-" * 100 + "x",
    "1/0",
    "1/(x - x)",
    "sqrt(-1)",
    "exp(1000)",
    "1e309",
    "sin()",
    "sin(x, x)",
    "where(x)",
    "x; import os",
    "import os",
    "",
    "   ",
    "\x00",
    "\n",
    "é + x",  # (a look-alike such as "𝔁" is NFKC-normalised to x by the parser, and accepted)
    "x" * 600,
]


def run_hostile(eta0: str, folder: Path, capfd):
    scene = folder / "hostile.toml"
    scene.write_text(scene_text(eta0), encoding="utf-8")
    out = folder / "out"
    capfd.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        code = main(["run", str(scene), *QUICK, "--out", str(out)])
    return code, out, capfd.readouterr()


def check_hostile_outcome(code, out, captured, folder: Path):
    assert code in (0, 2), captured.err
    assert "Traceback" not in captured.err
    assert not (folder / "PWNED").exists() and not Path("PWNED").exists()
    if code == 2:
        assert_one_line_error(captured.err)
        assert sorted(p.name for p in folder.iterdir()) == ["hostile.toml"]  # nothing written
    else:
        assert json.loads((out / "summary.json").read_text())["status"] == "complete"
        assert leftovers(folder) == []


@pytest.mark.parametrize("eta0", HOSTILE, ids=range(len(HOSTILE)))
def test_hostile_expression_via_cli(tmp_path, capfd, eta0):
    code, out, captured = run_hostile(eta0, tmp_path, capfd)
    assert code == 2
    check_hostile_outcome(code, out, captured, tmp_path)
    assert errors_of(captured.err)[0].startswith("stringcontact: error: scene ")
    assert "eta0" in captured.err


_TOKENS = ["x", "l", "pi", "h", "1", "0.5", "1e3", "+", "-", "*", "/", "**", "(", ")", ",", "<", "==", " ",
           "sin", "sqrt", "where", "min", "__class__", ".", "[", "]", "'", "lambda", ":", "import", "os", "\\"]


@pytest.mark.slow
@settings(max_examples=60, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(eta0=st.text(max_size=80) | st.lists(st.sampled_from(_TOKENS), max_size=25).map("".join) | st.sampled_from(HOSTILE))
def test_random_and_hostile_text_via_cli(capfd, eta0):
    """Any text as eta0: exit 0 (it was a valid expression) or 2 with one line; no traceback, no stray file."""
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        code, out, captured = run_hostile(eta0, folder, capfd)
        check_hostile_outcome(code, out, captured, folder)


# --- broken scene files and options through the command line --------------------------------------------

FILE_CASES = [
    ("not-toml", b"this is = not [ toml\n", "invalid TOML"),
    ("empty", b"", "missing required key(s)"),
    ("binary", bytes(range(256)) * 4, "binary file"),
    ("latin1", "T = 0.3 # caf\xe9\n".encode("latin-1"), "not UTF-8"),
    ("huge", b"# padding\n" * 120_000, "larger than 1000000 bytes"),
    ("nx-string", scene_text(nx='"ten"').encode(), "nx: expected an integer, got str"),
    ("T-string", scene_text(T='"0.3"').encode(), "T: expected a number, got str"),
    ("alpha-bool", scene_text(alpha="true").encode(), "alpha: expected a number, got bool"),
    ("eta0-list", scene_text().replace('eta0 = "1 + x*(1 - x)"', "eta0 = [1, 2]").encode(), "eta0: 2 nodal values for nx ="),
    ("nx-1e13", scene_text(nx="1e13").encode(), "nx: 10000000000000 is out of range"),
    ("dt-over-eps-huge", scene_text(eps="1e-12").encode(), "r = dt/eps = 5e+09"),
    ("T-zero", scene_text(T="0").encode(), "T: 0 is out of range"),
    ("T-negative", scene_text(T="-1").encode(), "T: -1 is out of range"),
    ("nt-zero", scene_text(nt="0").encode(), "nt: 0 is out of range"),
    ("unknown-key", scene_text(colour='"red"').encode(), "unknown key(s) 'colour'"),
    ("output-time-bomb", scene_text(T="1", output_times=str([i / 3000 for i in range(3000)])).encode(),
     "output_times: 3000 times; allowed: at most 1000 times"),
    ("stored-rows-too-large", scene_text(T="1", nx="100000", nt="100000000",
                                          output_times=str([i / 1000 for i in range(1000)])).encode(),
     "the stored rows need 3.51 GB (("),
    ("nested-5000-deep", scene_text(nested="[" * 5000 + "]" * 5000).encode(), "malformed TOML: arrays or tables nested too deeply"),
]


@pytest.mark.parametrize("name, content, fragment", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_broken_scene_file_via_cli(tmp_path, capfd, name, content, fragment):
    scene = tmp_path / f"{name}.toml"
    scene.write_bytes(content)
    out = tmp_path / "out"
    assert main(["run", str(scene), *QUICK, "--out", str(out)]) == 2
    assert_one_line_error(capfd.readouterr().err, fragment)
    assert sorted(p.name for p in tmp_path.iterdir()) == [scene.name]


OPTION_CASES = [
    (["run", "{missing}"], "no built-in scene of that name and no such file"),
    (["run", "{folder}"], "is a directory"),
    (["run", "example1", "--nx", "10000000000000"], "nx: 10000000000000 is out of range"),
    (["run", "example1", "--nt", "0"], "nt: 0 is out of range"),
    (["run", "example1", "--eps", "nan"], "eps: nan is not finite"),
    (["run", "example1", "--eps", "1e-300", "--penalty", "semi-implicit"], "eps: 1e-300 is out of range; allowed: a number in [1e-12, "),
    (["run", "example1", "--eps", "5e-324"], "eps: 5e-324 is out of range; allowed: a number in [1e-12, "),
    (["run", "example1", "--nx", "1000000"], "nx: 1000000 is out of range; allowed: an integer in [2, 100000]"),
    (["run", "example1", "--alpha=-inf"], "alpha: -inf is not finite"),
    (["run", "example1", "--nx", "1e13"], "invalid int value"),
    (["run", "example1", "--out", "{file}"], "exists and is not a folder"),
]


@pytest.mark.parametrize("argv, fragment", OPTION_CASES, ids=[" ".join(a[1:]) for a, _ in OPTION_CASES])
def test_bad_options_via_cli(tmp_path, capfd, argv, fragment):
    (tmp_path / "a-file").write_text("x")
    (tmp_path / "a-folder").mkdir()
    names = {"missing": tmp_path / "no-such.toml", "folder": tmp_path / "a-folder", "file": tmp_path / "a-file"}
    argv = [a.format(**names) for a in argv]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "out")]
    try:
        code = main([*argv, *QUICK])
    except SystemExit as exc:  # argparse: its own one-line message
        code = exc.code
    assert code == 2
    err = capfd.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1 and fragment in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "a-folder"]


def test_output_times_are_bounded_by_frames(tmp_path, capfd):
    scene = tmp_path / "times.toml"
    times = [round(0.01 * i, 2) for i in range(1, 30)]  # 29 output times, each a stored row
    scene.write_text(scene_text(T="0.3", nt="300", nx="20", output_times=str(times)))
    out = tmp_path / "out"
    assert main(["run", str(scene), *QUICK, "--frames", "10", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["xdmf_frames"] == 10 == len(read_xdmf(out / "solution.xdmf")[1]["eta"])
    assert summary["stored_rows"] >= 29 + 2
    assert "the scene's 29 output times do not fit in 10 XDMF frames" in capfd.readouterr().err


@pytest.mark.slow
def test_warnings_stay_one_line_after_the_form_compiler_is_loaded(tmp_path):
    # ffcx calls logging.captureWarnings(True) on import: warnings then went to "WARNING:py.warnings:FILE:LINE: ..."
    scene = tmp_path / "times.toml"
    scene.write_text(scene_text(T="0.3", nt="40", nx="20", eps="0.005", output_times="[0.1, 0.2]"))
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", str(scene), *QUICK, "--frames", "2",
                           "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert any("r = dt/eps = 1.5 > 1 rebounds" in line for line in lines)  # before the XDMF writer starts
    assert any("output times do not fit in 2 XDMF frames" in line for line in lines)  # after ffcx is loaded
    assert all(line.startswith("stringcontact: warning: ") for line in lines), proc.stderr


# --- interrupted runs: SIGINT / SIGTERM on a running command line ------------------------------------

READER = r"""
import json, sys
import meshio, numpy as np
with meshio.xdmf.TimeSeriesReader(sys.argv[1] + "/solution.xdmf") as reader:
    points, _ = reader.read_points_cells()
    steps = [reader.read_data(k) for k in range(reader.num_steps)]
order = np.argsort(points[:, 0])
out = {"x": points[order, 0].tolist()}
for name in steps[0][1]:
    rows = [point_data[name] for _, point_data, _ in steps]
    out[name] = {"times": [t for t, _, _ in steps], "finite": bool(all(np.isfinite(r).all() for r in rows)),
                 "shapes": sorted({r.shape for r in rows}), "first": rows[0][order].tolist()}
print(json.dumps(out))
"""


def read_back(folder: Path) -> dict:
    """Read the XDMF and its HDF5 in a fresh Python with meshio (as another program would), not dolfinx."""
    proc = subprocess.run([sys.executable, "-c", READER, str(folder)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def wait_for_rows(proc, parent: Path, name: str, rows: int) -> Path:
    """Wait until the run's partial folder holds `rows` whole time levels (or the process ends)."""
    while proc.poll() is None:
        for partial in parent.glob(f".{name}.partial-*"):
            try:
                if len(read_xdmf(partial / "solution.xdmf")[1].get("contact_force", ())) >= rows:
                    return partial
            except Exception:  # noqa: BLE001 - not there yet, or being rewritten
                pass
        time.sleep(0.1)
    raise AssertionError(f"the run ended before it could be interrupted: {proc.communicate()}")


@pytest.mark.slow
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["SIGINT", "SIGTERM"])
def test_signal_stops_cleanly_and_keeps_a_readable_xdmf(tmp_path, capfd, signum, code):
    out = tmp_path / "out"
    argv = ["run", "example1", "--nx", "500", "--nt", "40000", *QUICK, "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-m", "stringcontact", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        wait_for_rows(proc, tmp_path, "out", 4)

        # Meanwhile a second run into the same folder is refused, at once.
        assert main(argv) == 2
        assert_one_line_error(capfd.readouterr().err, "another stringcontact run", "is writing to this folder")

        proc.send_signal(signum)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code, stderr
    name = signal.Signals(signum).name
    assert_one_line_error(stderr, f"interrupted by {name}")
    assert leftovers(tmp_path) == []  # no partial folder, no lock

    # where the folder went instead, and the run's warnings, if it is not in place
    assert (out / "summary.json").is_file(), (stderr, sorted(p.name for p in tmp_path.iterdir()))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert name in summary["message"]
    n = summary["xdmf_frames"]  # the last stored row always ends the XDMF
    assert n >= 4 and summary["stored_rows"] >= n

    data = read_back(out)
    x = np.array(data["x"])
    times = data["eta"]["times"]
    assert len(times) == n and times[0] == 0.0 and np.all(np.diff(times) > 0) and times[-1] < 0.3
    assert math.isclose(times[-1], summary["last_time"])
    for field in ("eta", "velocity", "contact", "contact_force"):
        assert data[field]["times"] == times
        assert data[field]["finite"] and data[field]["shapes"] == [[501]]
    np.testing.assert_allclose(data["eta"]["first"], 1 + 0.5 * np.sin(10 * np.pi * x) ** 2, atol=1e-12)


# --- an unstable run keeps its partial output -------------------------------------------------------


def test_unstable_run_keeps_partial_output(tmp_path, capfd, monkeypatch):
    # r = dt/eps = 4 is refused before the start; let it through to see the guard stop it mid-run.
    import dataclasses

    from stringcontact.model.interface import inelastic

    monkeypatch.setattr("stringcontact.run.adapter.inelastic", dataclasses.replace(inelastic, stability=None))
    out = tmp_path / "out"
    assert main(["run", "example1", "--nx", "100", "--nt", "150", *QUICK, "--out", str(out)]) == 3
    assert_one_line_error(capfd.readouterr().err, "unstable at step", "r = dt/eps = 4")
    text = (out / "summary.json").read_text()
    summary = json.loads(text, parse_constant=lambda c: pytest.fail(f"summary.json holds {c}, not JSON"))
    assert summary["status"] == "unstable"
    inst = summary["instability"]
    assert inst["step"] > 0 and inst["r"] == pytest.approx(4.0)
    assert inst["time"] == pytest.approx(inst["step"] * 0.3 / 150)
    assert summary["message"] == inst["message"]
    series = read_xdmf(out / "solution.xdmf")[1]
    assert len(series["eta"]) == summary["xdmf_frames"] >= 1 and summary["stored_rows"] >= summary["xdmf_frames"]
    assert max(t for t, _ in series["eta"]) < inst["time"]
    assert leftovers(tmp_path) == []


# --- two runs, one folder -----------------------------------------------------------------------------


def test_lock_refuses_a_second_run_and_is_released(tmp_path, capfd):
    out = tmp_path / "out"
    lock = TargetLock(out)
    try:
        assert main(["run", "example1", *SMALL, "--out", str(out)]) == 2
        assert_one_line_error(capfd.readouterr().err, f"(pid {os.getpid()}) is writing to this folder")
        assert not out.exists()
    finally:
        lock.release()
    assert leftovers(tmp_path) == []  # the lock file goes with the lock
    assert main(["run", "example1", *SMALL, "--out", str(out)]) == 0
    assert leftovers(tmp_path) == []


def test_stale_partial_of_a_killed_run_is_removed(tmp_path, capfd):
    stale = tmp_path / ".out.partial-999999-abc"
    stale.mkdir()
    (stale / "solution.h5").write_bytes(b"half")
    (stale / ".stringcontact-marker").write_text("partial\n")  # the marker every run puts in its partial folder
    (tmp_path / ".out.lock").write_text("999999\n")  # a lock file nobody holds
    assert main(["run", "example1", *SMALL, "--out", str(tmp_path / "out")]) == 0
    assert "removed 1 unfinished folder" in capfd.readouterr().err
    assert leftovers(tmp_path) == []
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["status"] == "complete"


def test_stale_cleanup_matches_exact_names_and_spares_live_runs(tmp_path, capfd):
    """A run into `ex` removes or restores only `.ex.partial-PID-XXX` / `.ex.old-PID-NS` of killed runs."""
    live_target = tmp_path / "ex.old-1"  # another run, alive: it holds its lock
    live = tmp_path / ".ex.old-1.partial-12345-abcd1234"
    killed_other = tmp_path / ".ex.old-1.partial-999999-zz9_zz9z"  # a killed run into ex.old-1, not into ex
    lookalike = tmp_path / ".ex.partial-1-abc.notes"
    hidden_target = tmp_path / ".ex.partial-777-hiddenxx"  # a user's own --out, being written by a live run
    for folder in (live, killed_other, lookalike, hidden_target):
        folder.mkdir()
        (folder / "data").write_text(folder.name)
    locks = [TargetLock(live_target), TargetLock(hidden_target)]
    try:
        assert main(["run", "example1", *SMALL, "--out", str(tmp_path / "ex")]) == 0
    finally:
        for lock in locks:
            lock.release()
    err = capfd.readouterr().err
    assert "restored" not in err and "removed" not in err, err
    for folder in (live, killed_other, lookalike, hidden_target):
        assert (folder / "data").read_text() == folder.name
    assert json.loads((tmp_path / "ex" / "summary.json").read_text())["status"] == "complete"
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == ["ex"]


def test_interrupted_force_swap_is_restored(tmp_path, capfd):
    old = tmp_path / f".out.old-999999-{10**12}"  # killed between the two renames of a --force swap
    old.mkdir()
    (old / "summary.json").write_text('{"status": "complete", "mark": 1}')
    assert main(["run", "example1", *SMALL, "--out", str(tmp_path / "out")]) == 0
    assert "restored the previous result" in capfd.readouterr().err
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["mark"] == 1
    assert json.loads((tmp_path / "out.new" / "summary.json").read_text())["status"] == "complete"
    assert leftovers(tmp_path) == []


# --- the output folder's device: read-only, full -----------------------------------------------------


def read_only_folder(tmp_path, tmpfs) -> Path:
    if os.geteuid() != 0:  # an ordinary user: permissions are enough
        folder = tmp_path / "ro"
        folder.mkdir()
        folder.chmod(0o555)
        return folder
    return tmpfs("ro", "ro,size=64k")  # root ignores permissions: a read-only file system does not


def test_read_only_output_folder(tmp_path, capfd, tmpfs, monkeypatch):
    import stringcontact as sc

    folder = read_only_folder(tmp_path, tmpfs)
    monkeypatch.setattr(sc, "simulate", lambda *a, **k: pytest.fail("found only after the set-up"))
    assert main(["run", "example1", *SMALL, "--out", str(folder / "out")]) == 2
    err = capfd.readouterr().err
    assert_one_line_error(err, "cannot create the output folder")
    assert "read-only" in err or "permission denied" in err
    assert list(folder.iterdir()) == []


def test_disk_full_gives_one_line_and_leaves_nothing(capfd, tmpfs):
    folder = tmpfs("full", "size=256k")  # the run needs about 3 MB
    assert main(["run", "example1", "--nx", "200", "--nt", "750", *QUICK, "--out", str(folder / "out")]) == 2
    assert_one_line_error(capfd.readouterr().err, "the disk is full", "nothing was written there")
    assert list(folder.iterdir()) == []
    assert shutil.disk_usage(folder).used == 0  # the partial folder is gone: the space is free again


@pytest.mark.slow
@pytest.mark.mpi
def test_disk_full_under_mpi_every_rank_exits_2_with_one_line(tmpfs):
    folder = tmpfs("mpi-full", "size=300k")  # the run needs about 3 MB
    proc = mpirun([sys.executable, "-m", "stringcontact", "run", "example1", "--nx", "200", "--nt", "750", *QUICK,
                   "--out", folder / "out"], ranks=2)
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = errors_of(proc.stderr)
    assert len(lines) == 2 and all("the disk is full" in line and "nothing was written there" in line for line in lines)
    for crash in ("Traceback", "HDF5-DIAG", "terminate called", "Signal: Aborted", "MPI_ABORT"):
        assert crash not in proc.stderr, proc.stderr[-3000:]
    assert list(folder.iterdir()) == []  # no partial folder, no lock
    assert shutil.disk_usage(folder).used == 0


@pytest.mark.slow
def test_disk_full_while_drawing_pictures_keeps_nothing_and_exits_2(capfd, tmpfs):
    folder = tmpfs("pictures", "size=640k")  # the data (~550 KB) fit, the pictures (~260 KB more) do not
    assert main(["run", "example1", "--nx", "50", "--nt", "40", "--eps", "0.01", "--no-progress",
                 "--out", str(folder / "out")]) == 2
    assert_one_line_error(capfd.readouterr().err, "cannot write the output files: the disk is full", "nothing was written there")
    assert list(folder.iterdir()) == []
    assert shutil.disk_usage(folder).used == 0


def test_disk_failure_looks_through_the_exception_chain():
    from stringcontact.io.publish import disk_failure

    def raised(inner):
        try:
            try:
                raise inner
            except OSError as exc:
                raise ValueError("vtkPNGWriter failed") from exc
        except ValueError as exc:
            return exc

    full = OSError(errno.ENOSPC, "No space left on device")
    assert disk_failure(raised(full)) is full
    assert disk_failure(OSError(errno.EIO, "I/O error")).errno == errno.EIO
    assert disk_failure(raised(OSError(errno.ENOENT, "No such file"))) is None
    assert disk_failure(ValueError("a bug in a picture")) is None


@pytest.mark.parametrize("cause, code", [(errno.ENOSPC, 2), (errno.EIO, 2), (None, 0)], ids=["ENOSPC", "EIO", "other"])
def test_picture_failure_removes_the_folder_only_when_the_device_fails(tmp_path, capfd, monkeypatch, cause, code):
    def failing_pictures(result, folder, **kwargs):
        try:
            raise OSError(cause, os.strerror(cause)) if cause else KeyError("font")
        except (OSError, KeyError) as exc:
            raise ValueError("the picture layer wrapped it") from exc

    monkeypatch.setattr("stringcontact.plot.run_pictures.write_pictures", failing_pictures)
    out = tmp_path / "out"
    assert main(["run", "example1", "--nx", "50", "--nt", "40", "--eps", "0.01", "--no-progress", "--out", str(out)]) == code
    err = capfd.readouterr().err
    if code == 2:
        assert_one_line_error(err, "cannot write the output files", "nothing was written there")
        assert list(tmp_path.iterdir()) == []
    else:
        assert "stringcontact: warning: pictures not written (ValueError" in err
        assert json.loads((out / "summary.json").read_text())["status"] == "complete"


# --- a run whose energy balance does not close is never "complete" ---------------------------------


def test_unbalanced_run_is_kept_marked_and_exits_3(tmp_path, capfd, monkeypatch):
    out = tmp_path / "out"
    assert main(["run", "example1", *SMALL, "--out", str(out)]) == 0
    before = (out / "summary.json").read_text()
    capfd.readouterr()
    # The verdict decides: with a tolerance below round-off, the same run's balance "does not close".
    monkeypatch.setattr("stringcontact.run.checks.BALANCE_RTOL", 1e-300)
    assert main(["run", "example1", *SMALL, "--out", str(out), "--force"]) == 3
    captured = capfd.readouterr()
    assert_one_line_error(captured.err, "the energy balance does not close", "not trustworthy")
    assert "DOES NOT CLOSE" in captured.out and "(unbalanced at t = 0.3)" in captured.out
    assert (out / "summary.json").read_text() == before  # --force never trades a result for an unbalanced one
    summary = json.loads((tmp_path / "out.unbalanced" / "summary.json").read_text())
    assert summary["status"] == "unbalanced" and not summary["energy_balance"]["closes"]
    assert "does not close" in summary["message"]
    assert leftovers(tmp_path) == []


# --- --force never trades a finished result for an unfinished one ---------------------------------


@pytest.fixture
def space():
    from dolfinx import mesh
    from mpi4py import MPI

    from stringcontact.fem import compat

    return compat.function_space(mesh.create_interval(MPI.COMM_SELF, 8, [0.0, 1.0]), "Lagrange", 1)


def small_result(nx=8, nt=4):
    import stringcontact as sc

    scene = sc.load_scene("example1").replace(nx=nx, nt=nt, eps=0.1)
    return sc.simulate(scene, output=sc.Output(None))


def test_aborted_run_with_force_keeps_the_finished_result(tmp_path, space):
    from stringcontact.io.folder import OutputWriter
    from stringcontact.io.publish import write_manifest

    res = small_result()
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"status": "complete"}')
    write_manifest(out, {"summary.json": (out / "summary.json").stat().st_size})  # a result of ours: --force may replace it
    writer = OutputWriter(out, res.scene, space, space.mesh.comm, force=True, pictures=False)
    n = space.dofmap.index_map.size_local
    writer.write(0.0, {name: np.zeros(n) for name in ("eta", "velocity", "contact", "contact_force")})
    with pytest.warns(UserWarning, match="already holds a result; this run's interrupted output is in"):
        writer.abort("interrupted", "stopped", result=res)
    assert json.loads((out / "summary.json").read_text()) == {"status": "complete"}
    kept = tmp_path / "out.interrupted"
    summary = json.loads((kept / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["message"] == "stopped"
    assert summary["energy_balance"]["closes"]
    assert (kept / "diagnostics.csv").read_text().count("\n") == len(res.t) + 1
    assert writer.path == kept
    assert leftovers(tmp_path) == []


def test_force_replaces_with_a_complete_result(tmp_path):
    out = tmp_path / "out"
    assert main(["run", "example1", *SMALL, "--out", str(out)]) == 0
    assert main(["run", "example1", *SMALL, "--nx", "60", "--out", str(out), "--force"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "complete" and summary["scene"]["nx"] == 60
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("summary", [None, "not json", '{"status": "draft"}', "[1, 2]"])
def test_force_refuses_a_folder_without_a_summary_of_ours(tmp_path, capfd, summary):
    out = tmp_path / "thesis"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work")
    if summary is not None:
        (out / "summary.json").write_text(summary)
    assert main(["run", "example1", *SMALL, "--out", str(out), "--force"]) == 2
    assert_one_line_error(capfd.readouterr().err, "--force replaces only a stringcontact result")
    assert (out / "thesis.tex").read_text() == "years of work"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis"]


def test_unexpected_error_leaves_nothing(tmp_path, space):
    from stringcontact.io.folder import OutputWriter

    res = small_result()
    writer = OutputWriter(tmp_path / "out", res.scene, space, space.mesh.comm, pictures=False)
    assert len(leftovers(tmp_path)) == 2  # the partial folder and the lock
    writer.discard()
    assert leftovers(tmp_path) == [] and not (tmp_path / "out").exists()


# --- the closing numbers checks -------------------------------------------------------------------


def test_energy_balance_verdict():
    res = small_result(nx=50, nt=100)
    good = energy_balance(res)
    assert good["closes"] and good["relative_residual"] < 1e-10
    assert good["initial"] == pytest.approx(
        good["final"] + good["viscous_dissipation"] + good["contact_dissipation"] + good["numerical_dissipation"]
    )
    res.energy["contact_dissipation"] = res.energy["contact_dissipation"] * 1.01  # a term out of step
    bad = energy_balance(res)
    assert not bad["closes"] and bad["relative_residual"] > 1e-4


def test_penetration_check_on_the_paper_example_and_a_tampered_one():
    res = small_result(nx=200, nt=750)
    p = penetration_check(res)
    assert p["within_bound"] and 0 < p["depth"] < p["bound"]
    assert p["depth"] == pytest.approx(-res.min_eta) and p["depth"] == pytest.approx(-res.min_gap)
    res.min_gap = -(p["bound"] + 0.01)  # the depth is the least gap over every step
    assert not penetration_check(res)["within_bound"]


def test_summary_line_and_penetration_warning(tmp_path, capfd):
    # A static load pushes the string through: the velocity penalty only brakes, it cannot hold a load. The
    # impact bound does not apply to a press: the report explains the depth by the creep ε∫F dt, no warning.
    scene = tmp_path / "loaded.toml"
    scene.write_text(
        'T = 0.5\nalpha = 0.01\nscheme = { eps = 0.01 }\nnx = 50\nnt = 500\nh = 0.05\neta0 = "0.05"\nv0 = "0"\n'
        'load = "-100"\nmodel = "loaded_obstacle"\n'
    )
    assert main(["run", str(scene), *QUICK]) == 0
    captured = capfd.readouterr()
    assert "external work" in captured.out and ": closes" in captured.out
    assert "EXCEEDS" not in captured.out and "the string is pressed on the obstacle" in captured.out
    assert "the impact bound 2(eps + dt) max|v| does not apply" in captured.out
    assert "further below the obstacle" not in captured.err

    assert main(["run", "example1", *SMALL]) == 0
    captured = capfd.readouterr()
    assert ": closes" in captured.out and "within the bound" in captured.out
    assert "further below" not in captured.err


# --- staged_folder: the same protocol for commands that write plain files --------------------------


def test_staged_folder_writes_all_or_nothing(tmp_path):
    from stringcontact.errors import OutputError
    from stringcontact.io.publish import staged_folder

    out = tmp_path / "checks"
    with pytest.raises(KeyboardInterrupt):
        with staged_folder(out) as folder:
            (folder / "a.txt").write_text("half")
            raise KeyboardInterrupt
    assert not out.exists() and leftovers(tmp_path) == []

    with staged_folder(out) as folder:
        assert folder.parent == tmp_path and folder.name.startswith(".checks.partial-")
        (folder / "a.txt").write_text("whole")
        (folder / "checks.json").write_text('{"checks": []}')  # what `stringcontact check --out` writes: ours
    assert (out / "a.txt").read_text() == "whole" and leftovers(tmp_path) == []

    with pytest.raises(OutputError, match="folder is not empty"):
        with staged_folder(out):
            pass
    lock = TargetLock(out)
    try:
        with pytest.raises(OutputError, match="another stringcontact run"):
            with staged_folder(out, force=True):
                pass
    finally:
        lock.release()
    with staged_folder(out, force=True) as folder:
        (folder / "b.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["b.txt", "manifest.json"] and leftovers(tmp_path) == []


# --- issue 27: mesh files checked before dolfinx sees them (no hang, no crash) ---------------------------

_MESH_WRITER = """
import json, sys
import h5py, numpy as np
cells, points, path = json.loads(sys.argv[1]), json.loads(sys.argv[2]), sys.argv[3]
with h5py.File(path + ".h5", "w") as f:
    f["topology"] = np.array(cells, dtype=np.int64)
    f["geometry"] = np.array(points, dtype=float)
"""


def write_mesh_file(folder: Path, name: str, cells, points) -> Path:
    """An XDMF + HDF5 triangle mesh of any cells and points, written by h5py in a child process (h5py's
    wheel clashes with the libhdf5 of dolfinx, which this test process may have loaded)."""
    stem = folder / name
    subprocess.run([sys.executable, "-c", _MESH_WRITER, json.dumps(cells), json.dumps(points), str(stem)],
                   check=True, timeout=120)
    stem.with_suffix(".xdmf").write_text(
        '<?xml version="1.0"?>\n<Xdmf Version="3.0"><Domain><Grid Name="mesh" GridType="Uniform">'
        f'<Topology TopologyType="Triangle" NumberOfElements="{len(cells)}" NodesPerElement="3">'
        f'<DataItem Dimensions="{len(cells)} 3" NumberType="Int" Format="HDF">{name}.h5:/topology</DataItem></Topology>'
        f'<Geometry GeometryType="XY"><DataItem Dimensions="{len(points)} 2" Format="HDF">{name}.h5:/geometry</DataItem>'
        '</Geometry></Grid></Domain></Xdmf>\n')
    return stem.with_suffix(".xdmf")


def _bad_meshes():
    cells, points = grid_mesh(9)
    def changed(i, row):
        out = [list(c) for c in cells]
        out[i] = row
        return out
    return {
        "index 10**6": (changed(5, [5, 10**6, 15]), points, "node index 1000000; allowed: indices in [0, 80]"),
        "index -5": (changed(5, [5, -5, 15]), points, "node index -5; allowed: indices in [0, 80]"),
        "too few nodes": (cells, points[:50], "allowed: indices in [0, 49]"),
        "duplicate cell": (cells + [cells[3]], points, "duplicate cell"),
        "duplicates, rotated": (cells + [cells[3][1:] + cells[3][:1]] * 40, points, "duplicate cell"),
        "degenerate cell": (changed(5, [5, 5, 15]), points, "repeats a node"),
        "edge in 3 cells": (cells + [[0, 10, 81]], points + [[0.3, -0.2]], "is in 3 cells"),
        "unused node": (cells, points + [[2.0, 2.0]], "1 of them are in no cell"),
    }


@pytest.mark.slow
@pytest.mark.parametrize("case", list(_bad_meshes()))
def test_a_broken_mesh_file_is_refused_in_one_line_and_never_hangs(tmp_path, case):
    """Issue 27, items 1 and 2: dolfinx hung (index out of range: deaf to SIGTERM) or crashed (duplicate cells)."""
    cells, points, fragment = _bad_meshes()[case]
    mesh = write_mesh_file(tmp_path, "bad", cells, points)
    (tmp_path / "s.toml").write_text(f'mesh = "{mesh.name}"\nT = 0.1\nnt = 10\nalpha = 0\nscheme = {{ eps = 0.01 }}\n'
                                     'eta0 = "1 + 0.1*x*y"\nh = 1\nv0 = -1\n')
    try:  # a hang guard only: the refusal takes seconds; SIGKILL, since the hang ignored SIGTERM
        proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", "s.toml", "--out", "o", *QUICK],
                              cwd=tmp_path, capture_output=True, text=True, timeout=180)
    except subprocess.TimeoutExpired:
        pytest.fail("the run on a broken mesh file did not end (dolfinx was given the mesh)")
    assert proc.returncode == 2, proc.stderr
    assert_one_line_error(proc.stderr, "mesh: ", fragment)
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


def test_a_valid_mesh_file_written_by_hand_still_runs(tmp_path, capfd):
    cells, points = grid_mesh(5)
    mesh = write_mesh_file(tmp_path, "good", cells, points)
    scene = tmp_path / "s.toml"
    scene.write_text(f'mesh = "{mesh}"\nT = 0.01\nnt = 4\nalpha = 0\nscheme = {{ eps = 0.01 }}\n'
                     'eta0 = "1 + 0.1*x*y"\nh = 1\nv0 = -1\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), *QUICK]) == 0, capfd.readouterr().err


# --- issue 27, item 3: a planted lock file (symlink, FIFO) is refused, never followed or blocked on ----------

@pytest.mark.parametrize("dangling", [False, True], ids=["to a file", "dangling"])
def test_a_symlink_planted_as_the_lock_is_refused_and_its_target_kept(tmp_path, capfd, dangling):
    (tmp_path / "o").mkdir()
    victim = tmp_path / "victim.txt"
    if not dangling:
        victim.write_text("precious\n")
    link = tmp_path / "o" / ".x.lock"
    link.symlink_to(victim)
    assert main(["run", "example1", "--out", str(tmp_path / "o" / "x"), *SMALL]) == 2
    assert_one_line_error(capfd.readouterr().err, ".x.lock is a symbolic link")
    assert link.is_symlink() and os.readlink(link) == str(victim)  # the link stays, unfollowed
    assert victim.read_text() == "precious\n" if not dangling else not victim.exists()
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [".x.lock"]


@pytest.mark.slow
def test_a_fifo_planted_as_the_lock_is_refused_without_blocking(tmp_path):
    (tmp_path / "o").mkdir()
    os.mkfifo(tmp_path / "o" / ".x.lock")
    try:  # a hang guard only: a FIFO opened for writing without O_NONBLOCK would block forever
        proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", "example1", "--out", "o/x", *SMALL],
                              cwd=tmp_path, capture_output=True, text=True, timeout=180)
    except subprocess.TimeoutExpired:
        pytest.fail("the run blocked on a FIFO planted as its lock file")
    assert proc.returncode == 2, proc.stderr
    assert_one_line_error(proc.stderr, ".x.lock is a FIFO")
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [".x.lock"]


# --- issue 27, item 6: plot and study follow run's --out rules (not /, not ., no overwriting without --force) ---

@pytest.fixture(scope="module")
def a_result(tmp_path_factory):
    folder = tmp_path_factory.mktemp("result") / "r"
    assert main(["run", "example1", "--out", str(folder), *SMALL]) == 0
    return folder


@pytest.mark.parametrize("argv, fragment", [
    (["plot", "{result}", "--out", "/"], "is the root folder"),
    (["plot", "{result}", "--out", "."], "is the current folder or contains it"),
    (["plot", "{result}", "--out", "full"], "folder is not empty; choose another or pass --force"),
    (["plot", "{result}", "--out", "full", "--force"], "--force replaces only a stringcontact result"),
    (["study", "convergence", "--quick", "--out", "/"], "is the root folder"),
    (["study", "stability", "--quick", "--out", "."], "is the current folder or contains it"),
    (["study", "work-precision", "--quick", "--out", "full"], "folder is not empty"),
], ids=["plot /", "plot .", "plot full", "plot full --force", "study /", "study .", "study full"])
def test_plot_and_study_refuse_the_folders_run_refuses(tmp_path, capfd, monkeypatch, a_result, argv, fragment):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "energy.png").write_text("the user's own picture")
    root_before = sorted(os.listdir("/"))
    assert main([a.format(result=a_result) for a in argv]) == 2
    assert_one_line_error(capfd.readouterr().err, fragment)
    assert sorted(os.listdir("/")) == root_before
    assert sorted(os.listdir(tmp_path)) == ["full"] and (tmp_path / "full" / "energy.png").read_text() == "the user's own picture"


@pytest.mark.slow
def test_plot_out_writes_a_whole_folder_and_replaces_it_only_with_force(tmp_path, capfd, a_result):
    out = tmp_path / "pics"
    assert main(["plot", str(a_result), "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert "pictures.json" in names and "energy.png" in names and leftovers(tmp_path) == []
    assert main(["plot", str(a_result), "--out", str(out)]) == 2  # no silent overwrite
    assert main(["plot", str(a_result), "--out", str(out), "--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == names and leftovers(tmp_path) == []


# --- issue 27, items 7 and 8: tiny length or T, and a huge --delta, are bad input (exit 2), not internal errors ---

@pytest.mark.parametrize("argv, fragment", [
    (["run", "{scene}"], "length: 1e-300 is out of range; allowed: a number in [1e-06, 10000]"),
    (["check", "example1", "--delta", "1e308"], "--delta: 1e+308 is out of range; allowed: a number in (0, length = 1]"),
    (["check", "example1", "--delta", "nan"], "--delta: nan is out of range"),
], ids=["length 1e-300", "delta 1e308", "delta nan"])
def test_tiny_lengths_and_huge_deltas_are_one_line_and_exit_2(tmp_path, capfd, argv, fragment):
    scene = tmp_path / "tiny.toml"
    scene.write_text(scene_text(length="1e-300"))
    argv = [a.format(scene=scene) for a in argv] + ["--out", str(tmp_path / "o")]
    assert main(argv) == 2
    assert_one_line_error(capfd.readouterr().err, fragment)
    assert sorted(os.listdir(tmp_path)) == ["tiny.toml"]
