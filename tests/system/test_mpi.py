"""One simulation under `mpirun -n 2` gives the serial answer, and errors stop every rank.

dolfinx distributes the mesh over the ranks; `simulate` gathers the owned arrays, ordered by x, to rank 0
(`gather="root"`, the default: the other ranks hold the per-time series only) or to every rank
(`gather="all"`). Each check starts this file as an MPI program (the worker at the bottom), with a timeout
so that a hang fails instead of blocking the suite, and compares what the ranks saved with a serial run in
this process.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import leftovers, mpirun, xdmf_frames

pytestmark = pytest.mark.mpi

RANKS = 2
TIMEOUT = 300  # seconds for one mpirun; a hang fails the test instead of blocking the suite
# (penalty, mass, pictures): both penalties, both masses; one case draws its pictures on rank 0.
CASES = (("explicit", "lumped", True), ("semi-implicit", "consistent", False))
FIELDS = ("eta", "velocity", "contact_force")
PARITY = 1e-10  # max |mpi − serial| ≤ PARITY · max(1, max |serial|) for every array


def parity_scene():
    """Example 1 coarsened so that r = Δt/ε = 1: the string lands, contact spreads, the ends pull it off."""
    import stringcontact as sc

    return sc.load_scene("example1").replace(nx=300, nt=600)


def run_worker(*args):
    """`mpirun -n 2 python this_file ARGS`; returns the CompletedProcess, or fails the test on a hang."""
    return mpirun([sys.executable, Path(__file__).resolve(), *args], ranks=RANKS, timeout=TIMEOUT)


def rel_error(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


@pytest.fixture(scope="module")
def parity_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("mpi_parity")
    proc = run_worker("parity", out)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def serial_results(tmp_path_factory):
    import stringcontact as sc

    out = tmp_path_factory.mktemp("serial")
    scene = parity_scene()
    return {
        (penalty, mass): (
            sc.simulate(scene, penalty=penalty, mass=mass, output=sc.Output(out / f"{penalty}-{mass}", pictures=False)),
            out / f"{penalty}-{mass}",
        )
        for penalty, mass, _ in CASES
    }


def assert_rows_equal_serial(saved, serial) -> None:
    """Every per-node array and series a rank saved equals the serial run's (PARITY)."""
    assert np.all(np.diff(saved["x"]) > 0), "Result.x must be ordered by x"
    np.testing.assert_array_equal(saved["x"], serial.x)
    for name in FIELDS:
        assert saved[name].shape == getattr(serial, name).shape, name
        err = rel_error(saved[name], getattr(serial, name))
        assert err <= PARITY, f"{name}: mpi differs from serial by {err:.3g} (relative to its maximum)"
    # The contact set η ≤ 0 is the same, except possibly on nodes within round-off of the obstacle.
    differ = saved["contact"] != serial.contact
    assert not np.any(differ & (np.abs(serial.eta) > PARITY)), "contact sets differ"
    # The run did meet the obstacle, so the contact law took part in the comparison.
    assert serial.contact.any() and np.max(serial.contact_force) > 0


def assert_series_equal_serial(saved, serial) -> None:
    """The per-time series every rank holds equal the serial run's: t, energy, min η, contact length."""
    np.testing.assert_array_equal(saved["t"], serial.t)
    np.testing.assert_array_equal(saved["steps"], serial.steps)
    for key, values in serial.energy.items():
        assert rel_error(saved[f"energy_{key}"], values) <= PARITY, key
    assert abs(saved["min_eta"] - serial.min_eta) <= PARITY
    assert str(saved["status"]) == serial.status
    assert np.all(np.abs(saved["contact_length"] - serial.contact_length) <= contact_slack(serial))
    assert serial.contact_length.max() > 10 * (serial.x[1] - serial.x[0])  # a real contact set


def contact_slack(serial) -> np.ndarray:
    """How far another run's contact length may be off at each stored time: the trapezoid weights (Δx) of
    the nodes within round-off of the obstacle (η ≤ 0 may go either way there), plus PARITY."""
    return (serial.x[1] - serial.x[0]) * np.sum(np.abs(serial.eta) <= PARITY, axis=1) + PARITY


@pytest.mark.slow
@pytest.mark.parametrize("penalty,mass", [c[:2] for c in CASES])
def test_mpi_result_on_rank_0_equals_serial(parity_run, serial_results, penalty, mass):
    serial, _ = serial_results[(penalty, mass)]
    saved = np.load(parity_run / f"{penalty}-{mass}.rank0.npz")
    assert saved["comm_size"] == RANKS and saved["has_rows"]
    # The mesh really was distributed: this rank owned only part of the nodes.
    assert 0 < saved["owned_nodes"] < serial.x.size
    assert_rows_equal_serial(saved, serial)
    assert_series_equal_serial(saved, serial)


@pytest.mark.parametrize("penalty,mass", [c[:2] for c in CASES])
@pytest.mark.parametrize("rank", range(1, RANKS))
def test_mpi_other_ranks_hold_the_series_and_no_rows(parity_run, serial_results, penalty, mass, rank):
    serial, _ = serial_results[(penalty, mass)]
    saved = np.load(parity_run / f"{penalty}-{mass}.rank{rank}.npz")
    assert not saved["has_rows"] and "x" not in saved
    assert str(saved["refused"]).startswith("Result.eta: the per-node rows are on rank 0 only")
    assert_series_equal_serial(saved, serial)
    assert 0 < saved["owned_nodes"] < serial.x.size


@pytest.mark.parametrize("rank", range(RANKS))
def test_mpi_gather_all_gives_every_rank_the_serial_rows(parity_run, serial_results, rank):
    penalty, mass, _ = CASES[0]
    serial, _ = serial_results[(penalty, mass)]
    saved = np.load(parity_run / f"all-{penalty}-{mass}.rank{rank}.npz")
    assert saved["has_rows"]
    assert_rows_equal_serial(saved, serial)
    assert_series_equal_serial(saved, serial)


@pytest.mark.parametrize("penalty,mass", [c[:2] for c in CASES])
def test_mpi_xdmf_is_one_collective_file_equal_to_serial(parity_run, serial_results, penalty, mass):
    serial, serial_dir = serial_results[(penalty, mass)]
    folder = parity_run / f"{penalty}-{mass}"
    assert sorted(p.name for p in folder.iterdir() if p.suffix in (".xdmf", ".h5")) == ["solution.h5", "solution.xdmf"]
    mpi, ser = (xdmf_frames(f) for f in (folder, serial_dir))  # the XDMF frames, ordered by x
    np.testing.assert_allclose(mpi.x, serial.x, atol=1e-14)
    np.testing.assert_allclose(ser.x, serial.x, atol=1e-14)
    np.testing.assert_array_equal(mpi.t, ser.t)  # the same XDMF frames (xdmf_frames checks them against the rows)
    assert set(ser.t) <= set(serial.t) and ser.t[0] == serial.t[0] and ser.t[-1] == serial.t[-1]
    for name in (*FIELDS, "contact"):
        a, b = getattr(mpi, name), getattr(ser, name)
        assert a.shape == b.shape == (ser.t.size, serial.x.size), name  # every frame, every node
        err = rel_error(a, b)
        assert err <= PARITY, f"{name}: {err:.3g} (relative to the field's maximum over all times)"
    # and the tables rank 0 wrote from the gathered Result
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["status"] == "complete"
    assert abs(summary["min_eta"] - serial.min_eta) <= PARITY
    lines = (folder / "diagnostics.csv").read_text().splitlines()
    assert len(lines) == serial.t.size + 1
    assert leftovers(parity_run) == []  # no partial folder, no lock


@pytest.mark.slow
def test_mpi_errors_are_raised_on_every_rank_without_a_hang(tmp_path):
    proc = run_worker("errors", tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    reports = [json.loads((tmp_path / f"errors.rank{r}.json").read_text()) for r in range(RANKS)]
    for report in reports:
        assert report["scene"] == "SceneError"
        assert report["before_start"] == ["InstabilityError", 0]
        kind, step = report["during_run"]
        assert kind == "InstabilityError" and step > 0
        assert report["after"] == RANKS  # the communicator still works afterwards
    assert len({tuple(r["during_run"]) for r in reports}) == 1, "ranks stopped at different steps"
    # The aborted run left its folder marked on rank 0, not half-written.
    summary = json.loads((tmp_path / "unstable" / "summary.json").read_text())
    assert summary["status"] == "unstable" and "unstable at step" in summary["message"]


@pytest.mark.slow
def test_mpi_semi_implicit_refactorises_on_all_ranks_when_one_ranks_contact_changes(tmp_path):
    # The damping diagonal changes on one rank only (Example 2 lands on the left first); the collective
    # refactorisation must still run on every rank, or MUMPS fails or the ranks wait for each other.
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    proc = run_worker("asymmetric", tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for mass in ("lumped", "consistent"):
            serial = sc.simulate(asymmetric_scene(), penalty="semi-implicit", mass=mass, comm=MPI.COMM_SELF)
            for rank in range(RANKS):
                saved = np.load(tmp_path / f"asym-{mass}.rank{rank}.npz")
                assert int(saved["refactorisations"]) == serial.counters["refactorisations"] > 1
                np.testing.assert_array_equal(saved["t"], serial.t)
                assert rel_error(saved["total_energy"], serial.total_energy) <= PARITY, (mass, rank)
                assert ("eta" in saved) == (rank == 0)  # the rows on rank 0 only
            assert rel_error(np.load(tmp_path / f"asym-{mass}.rank0.npz")["eta"], serial.eta) <= PARITY, mass


@pytest.mark.slow
def test_mpi_cli_reports_bad_input_once_per_rank_and_exits_2(tmp_path):
    import stringcontact

    example = Path(stringcontact.__file__).parent / "scenes" / "example1.toml"
    bad = tmp_path / "bad.toml"
    bad.write_text(re.sub(r"(?m)^alpha = .*$", "alpha = -1.0", example.read_text()))
    proc = run_worker("cli", "run", bad, "--out", tmp_path / "never", "--no-progress")
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    lines = [line for line in proc.stderr.splitlines() if line.startswith("stringcontact: error:")]
    assert len(lines) == RANKS and "alpha" in lines[0]
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "never").exists()


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["projection", "newmark", "paper"])
def test_mpi_schemes_equal_serial_on_every_rank(tmp_path, scheme):
    # Example 2 lands on the left first, so each rank's projection (or active set) changes at its own steps.
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    proc = run_worker("schemes", tmp_path, scheme)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # example2 starts below the obstacle, as printed
        serial = sc.simulate(scheme_scene(scheme), scheme=scheme, mass="consistent" if scheme == "newmark" else None,
                             comm=MPI.COMM_SELF)
    assert serial.contact.any() and serial.status == "complete"
    for rank in range(RANKS):
        saved = np.load(tmp_path / f"{scheme}.rank{rank}.npz")
        assert ("eta" in saved) == (rank == 0)  # the rows on rank 0 only
        for name in ("eta", "velocity", "contact_force") if rank == 0 else ():
            assert rel_error(saved[name], getattr(serial, name)) <= PARITY, (rank, name)
        if rank == 0:  # a contact force under MPI too: ≥ 0, and 0 off the contact set
            F = saved["contact_force"]
            assert F.max() > 0 and np.all(F >= 0) and np.all(F[~saved["contact"]] == 0), scheme
        for key, values in serial.energy.items():
            assert rel_error(saved[f"energy_{key}"], values) <= PARITY, (rank, key)
        assert np.all(np.abs(saved["contact_length"] - serial.contact_length) <= contact_slack(serial)), rank


# ---------------------------------------------------------------------------------------------------
# The MPI program: `mpirun -n 2 python tests/system/test_mpi.py parity|errors|cli DIR...`


def _save(path: Path, res, **extra) -> None:
    """What this rank's Result holds: the per-node arrays where it has them, else the error reading one gives."""
    arrays = {"t": res.t, "steps": res.steps, "min_eta": res.min_eta, "status": res.status,
              "contact_length": res.contact_length, "has_rows": res.has_rows,
              **{f"energy_{k}": v for k, v in res.energy.items()}}
    if res.has_rows:
        arrays.update({name: getattr(res, name) for name in ("x", "eta", "velocity", "contact", "contact_force")})
    else:
        try:
            _ = res.eta
        except AttributeError as exc:
            arrays["refused"] = str(exc)
    np.savez(path, **arrays, **extra)


def _worker_parity(out: Path) -> None:
    from dolfinx import mesh
    from mpi4py import MPI

    import stringcontact as sc

    comm = MPI.COMM_WORLD
    scene = parity_scene()
    owned = mesh.create_interval(comm, scene.nx, [0.0, scene.length]).topology.index_map(0).size_local
    for penalty, mass, pictures in CASES:
        res = sc.simulate(scene, penalty=penalty, mass=mass,
                          output=sc.Output(out / f"{penalty}-{mass}", pictures=pictures))
        _save(out / f"{penalty}-{mass}.rank{comm.rank}.npz", res, comm_size=comm.size, owned_nodes=owned)
    penalty, mass, _ = CASES[0]
    res = sc.simulate(scene, penalty=penalty, mass=mass, storage=sc.Storage(gather="all"))
    _save(out / f"all-{penalty}-{mass}.rank{comm.rank}.npz", res)


def _worker_errors(out: Path) -> None:
    from mpi4py import MPI

    import stringcontact as sc

    comm = MPI.COMM_WORLD
    report = {}
    bad = out / "bad_scene.toml"
    if comm.rank == 0:
        bad.write_text('name = "bad"\nnx = 0\n')
    comm.barrier()
    try:
        sc.load_scene(bad)
        report["scene"] = "none"
    except sc.SceneError:
        report["scene"] = "SceneError"

    scene = sc.load_scene("example1").replace(nx=200, nt=60)  # Δt/ε = 10: refused before the first step
    try:
        sc.simulate(scene, comm=comm)
        report["before_start"] = ["none", None]
    except sc.InstabilityError as exc:
        report["before_start"] = ["InstabilityError", exc.step]

    # A model whose "contact force" pushes along the velocity: the energy grows, the guard stops the run.
    def pushing(eta, v, p):
        return 50.0 * v

    model = sc.Model(name="pushing", penalty=pushing, penalty_damping=None)
    scene = sc.load_scene("example1").replace(nx=200, nt=600)
    try:
        sc.simulate(scene, model=model, comm=comm, output=sc.Output(out / "unstable", pictures=False))
        report["during_run"] = ["none", None]
    except sc.InstabilityError as exc:
        report["during_run"] = ["InstabilityError", exc.step]
    report["after"] = comm.allreduce(1)
    (out / f"errors.rank{comm.rank}.json").write_text(json.dumps(report))


def asymmetric_scene():
    """Example 2 coarsened: contact starts on the left only, so the ranks' active sets change at different steps."""
    import stringcontact as sc

    return sc.load_scene("example2").replace(nx=200, nt=300)


def scheme_scene(scheme: str):
    """`asymmetric_scene`, with r = Δt/ε = 1 for the paper's explicit penalty (it refuses r >= 2)."""
    scene = asymmetric_scene()
    return scene.replace(eps=scene.dt) if scheme == "paper" else scene


def _worker_asymmetric(out: Path) -> None:
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    comm = MPI.COMM_WORLD
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # example2 starts below the obstacle, as printed
        for mass in ("lumped", "consistent"):
            res = sc.simulate(asymmetric_scene(), penalty="semi-implicit", mass=mass, comm=comm)
            rows = {"eta": res.eta} if res.has_rows else {}
            np.savez(out / f"asym-{mass}.rank{comm.rank}.npz", t=res.t, total_energy=res.total_energy,
                     refactorisations=res.counters["refactorisations"], **rows)


def _worker_schemes(out: Path, scheme: str) -> None:
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sc.simulate(scheme_scene(scheme), scheme=scheme, mass="consistent" if scheme == "newmark" else None,
                          comm=MPI.COMM_WORLD)
    rows = {name: getattr(res, name) for name in ("eta", "velocity", "contact", "contact_force")} if res.has_rows else {}
    np.savez(out / f"{scheme}.rank{MPI.COMM_WORLD.rank}.npz", contact_length=res.contact_length, **rows,
             **{f"energy_{k}": v for k, v in res.energy.items()})


if __name__ == "__main__":
    mode, rest = sys.argv[1], sys.argv[2:]
    if mode == "cli":
        from stringcontact.cli.main import main

        sys.exit(main(rest))
    if mode == "schemes":
        _worker_schemes(Path(rest[0]), rest[1])
        sys.exit(0)
    {"parity": _worker_parity, "errors": _worker_errors, "asymmetric": _worker_asymmetric}[mode](Path(rest[0]))


@pytest.mark.slow
def test_mpi_cli_runs_a_membrane_and_reports_once(tmp_path):
    """`mpirun -n 2 stringcontact run` on a membrane: rank 0 reports and writes, the rowless rank ends cleanly."""
    import stringcontact as sc
    from stringcontact.scene import scene_to_toml

    scene = tmp_path / "drum.toml"
    scene.write_text(scene_to_toml(sc.load_scene("drum").replace(mesh_size=0.2, T=0.2, nt=40, output_times=[0.0, 0.2])))
    out = tmp_path / "out"
    proc = mpirun([sys.executable, "-m", "stringcontact", "run", scene, "--out", out, "--no-progress", "--no-pictures"],
                  ranks=RANKS, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert proc.stdout.count("energy balance:") == 1 and proc.stdout.count(f"wrote {out}") == 1, proc.stdout
    assert "error" not in proc.stderr, proc.stderr
    assert (out / "solution.xdmf").is_file() and (out / "summary.json").is_file()
