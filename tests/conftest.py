"""Helpers shared by several test files: `mpirun` for the MPI checks, `leftovers` for the output folders,
`plot_refusal` for damaged folders, `meshio_read` and `xdmf_frames` for the XDMF files, `run_problem` for a scheme
driven directly, `register_distribution` for a plugin installed by hand, `sine_mode` the exact mode without contact;
the hypothesis profile of every property test."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from stringcontact import stack

# The dolfinx wheel's MPI before any test module imports dolfinx, petsc4py or mpi4py (`stack.load`'s rule; nothing
# happens on Debian's or conda's dolfinx).
stack.load_mpi_first()

# No clock in a test: hypothesis's per-example deadline (200 ms by default) and its too-slow health check
# fail a correct test on a busy machine. Loaded here, before any test module is imported, for all of them.
settings.register_profile("stringcontact", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("stringcontact")

#: tests/: this file's folder; the test files sit in folders below it that mirror the package (tests/system: the
#: command line, MPI, ParaView, the container, the demos and the repository as a whole) and import it as `conftest`
#: (`pythonpath` in pyproject's [tool.pytest.ini_options]).
TESTS = Path(__file__).resolve().parent


def pytest_configure(config):
    """A crash of the test process shows where it happened (`_crashes_show_their_stack`), and in a pytest-xdist
    worker (`make test` runs one per core) a longer wait for a form another worker compiles.

    ffcx's JIT cache is shared by the processes of a machine: the first to need a form creates its C file
    (exclusively) and compiles it; another that needs the same form polls for the finished module once a second,
    `timeout` times, and then raises TimeoutError (dolfinx's default: 10). On a cold cache two workers often need
    the same form at once, and on a busy machine a compile can take longer than 10 s."""
    if os.environ.get("PYTEST_XDIST_WORKER") or not getattr(config.option, "numprocesses", None):  # not a controller
        _crashes_show_their_stack()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        try:
            import dolfinx.jit
        except ImportError:
            return
        for name in ("DOLFINX_DEFAULT_JIT_PARAMETERS", "DOLFINX_DEFAULT_JIT_OPTIONS"):  # 0.5; 0.7 and later
            defaults = getattr(dolfinx.jit, name, None)
            if defaults is not None and "timeout" in defaults:
                defaults["timeout"] = (JIT_WAIT, defaults["timeout"][1])


#: seconds a pytest-xdist worker waits for a form that another process is compiling
JIT_WAIT = 300


def _crashes_show_their_stack() -> None:
    """PETSc's handlers of fatal signals (SIGSEGV, SIGBUS, ...) taken down in the test process, faulthandler's put
    back, on the stream pytest keeps for it (the terminal, not a test's captured stderr).

    PETSc, once initialised, takes the fatal signals: it prints its message to stderr, which pytest captures for
    the running test, and aborts the MPI job; a pytest-xdist worker that crashes so dies without a word ("node
    down: Not properly terminated"). With faulthandler's the crash prints every thread's Python stack, then the
    signal goes on to its default action. The command's own processes (subprocesses of the tests) keep PETSc's."""
    import faulthandler

    from petsc4py import PETSc

    PETSc.Sys.popSignalHandler()  # its stack empty, PETSc puts the signals' default actions back
    stream = sys.__stderr__ if sys.__stderr__ is not None else sys.stderr
    faulthandler.disable()
    faulthandler.enable(file=os.dup(stream.fileno()), all_threads=True)  # a descriptor of its own, open to the end


def pytest_collection_modifyitems(config, items):
    """A test that calls `mpirun` is an `mpi` test, marked or not; an `mpi` test starts two Python processes that
    each import dolfinx and run, and a test that calls `pvpython` (tests/system/test_paraview.py) starts ParaView
    under xvfb-run: both are `slow` too, and `make test-fast` (``-m "not slow"``) leaves them out."""
    for item in items:
        code = getattr(getattr(item, "function", None), "__code__", None)
        calls = set(code.co_names) if code is not None else set()
        if "mpirun" in calls and item.get_closest_marker("mpi") is None:
            item.add_marker(pytest.mark.mpi)
        if "pvpython" in calls and item.get_closest_marker("slow") is None:
            item.add_marker(pytest.mark.slow)
        if item.get_closest_marker("mpi") is not None and item.get_closest_marker("slow") is None:
            item.add_marker(pytest.mark.slow)
    # The files with slow tests first, each file's tests in their order: pytest-xdist (`--dist loadfile`) hands the
    # files out in this order, so the long ones start first and no worker is left alone with one at the end.
    slow_files = {item.path for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: item.path not in slow_files)


# If pytest itself runs inside an MPI job, that job's wiring must not reach the new one.
_MPI_JOB_VARIABLES = ("PMIX_", "OMPI_COMM_WORLD_", "OMPI_MCA_ess", "OMPI_MCA_orte", "OMPI_MCA_pmix", "PRTE_")


def mpirun(argv, ranks: int = 2, timeout: float = 300) -> subprocess.CompletedProcess:
    """`mpirun -n RANKS --oversubscribe --bind-to none ARGV...` (idle ranks yield), output captured as text.

    Skips the test when there is no mpirun; fails it (killing the whole job) when it runs longer than
    `timeout` seconds, so that a hang fails instead of blocking the suite.
    """
    exe = shutil.which("mpirun") or shutil.which("mpiexec")
    if exe is None:
        pytest.skip("mpirun not found (scripts/setup installs openmpi-bin; the wheel's stack has MPICH's)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(_MPI_JOB_VARIABLES)}
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", PYTHONDONTWRITEBYTECODE="1")
    # a test file run as the MPI program (`python tests/system/test_mpi.py ...`) imports this module by name
    env["PYTHONPATH"] = os.pathsep.join(filter(None, (str(TESTS), env.get("PYTHONPATH"))))
    env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    # The job shares two cores with the other pytest worker: a rank waiting for the other (a barrier while rank 0
    # compiles a form, a solve's reductions) yields its core instead of spinning on it, and neither rank is pinned
    # to a core the other worker is using (Open MPI binds to cores by default for two ranks).
    env.setdefault("OMPI_MCA_mpi_yield_when_idle", "1")
    env.setdefault("MPIR_CVAR_ENABLE_HEAVY_YIELD", "1")  # MPICH's (the dolfinx wheel's): a waiting rank sleeps, not spins
    argv = [str(a) for a in argv]
    if len(argv) > 1 and argv[0] == sys.executable and argv[1].endswith(".py"):  # a test file as the MPI program:
        argv = [argv[0], "-c", RUN_FILE, *argv[1:]]  # the stack's import order first, as the package's own modules do
    cmd = [exe, "-n", str(ranks), *MPIRUN_FLAGS[mpi_flavour(exe)], *argv]
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True
    )
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"mpirun -n {ranks} {' '.join(argv)} hung for {timeout} s\n{out[-2000:]}\n{err[-2000:]}")
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


#: `python -c RUN_FILE FILE ARGS...`: FILE run as __main__ with ARGS, after `stack.load_mpi_first` (a test file that
#: imports dolfinx or petsc4py at its top runs so on the dolfinx wheel, which needs its MPI loaded first).
RUN_FILE = ("import runpy, sys; from stringcontact import stack; stack.load_mpi_first(); sys.argv = sys.argv[1:]; "
            "runpy.run_path(sys.argv[0], run_name='__main__')")

#: The launcher's flags for two ranks sharing the cores with the other pytest worker: Open MPI's (Debian) refuses
#: more ranks than cores unless told, and pins each rank to a core; MPICH's hydra (the dolfinx wheel's) does neither
#: unless told.
MPIRUN_FLAGS = {"openmpi": ("--oversubscribe", "--bind-to", "none"), "mpich": ("-bind-to", "none")}


def mpi_flavour(exe: str) -> str:
    """"openmpi" or "mpich": the MPI whose launcher `exe` is (its ``--version`` names it)."""
    out = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout
    return "mpich" if "HYDRA" in out or "MPICH" in out else "openmpi"


def one_error_line(stderr: str, *fragments) -> str:
    """The command's one error line (warnings aside), asserted to be one line, not an internal error, and to hold
    every fragment."""
    lines = [line for line in stderr.splitlines() if not line.startswith("stringcontact: warning:")]
    assert len(lines) == 1 and lines[0].startswith("stringcontact: error: "), stderr[-3000:]
    assert "internal error" not in lines[0], lines[0]
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


def register_distribution(folder: Path, dist: str, group: str, entries: str) -> None:
    """An installed distribution `dist` as importlib.metadata sees it (a ``.dist-info`` folder in `folder`, which the
    test puts on sys.path): `entries`, lines ``name = module:attribute``, under the entry-point `group`."""
    info = folder / f"{dist.replace('-', '_')}-0.1.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{group}]\n{entries}\n")


def leftovers(folder: Path) -> list[str]:
    """Anything a run may leave beside its target: partial folders, locks, .old swaps (all start with ".")."""
    return sorted(p.name for p in Path(folder).iterdir() if p.name.startswith("."))


def plot_refusal(folder: Path, damage, tmp_path: Path, capsys) -> tuple[Path, str]:
    """`stringcontact plot` on a damaged copy of `folder`: (the copy, its error line). Asserts exit 2, one line,
    no traceback and no picture folder; `damage(copy)` damages the copy."""
    from stringcontact.cli.main import main

    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    damage(copy)
    assert main(["plot", str(copy), "--out", str(tmp_path / "pics")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err and "internal error" not in err, err
    assert not (tmp_path / "pics").exists()
    return copy, err


# meshio (with the h5py wheel) runs in a separate Python: h5py's bundled libhdf5 must not meet dolfinx's.
MESHIO = r"""
import json, sys
import meshio
with meshio.xdmf.TimeSeriesReader(sys.argv[1]) as reader:
    points, cells = reader.read_points_cells()
    steps = [reader.read_data(k) for k in range(reader.num_steps)]
print(json.dumps({
    "points": points.tolist(),
    "cells": {c.type: c.data.tolist() for c in cells},
    "times": [t for t, _, _ in steps],
    "data": [{name: values.tolist() for name, values in point_data.items()} for _, point_data, _ in steps],
}))
"""


def meshio_read(path) -> dict:
    proc = subprocess.run([sys.executable, "-c", MESHIO, str(path)], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout)


def xdmf_frames(folder):
    """The XDMF frames of a run's folder as a `Result`: the fields read from solution.xdmf/.h5 themselves (with pyfive,
    in this process: h5py's libhdf5 must not meet dolfinx's), the nodes in the run's order, in 2D the triangles and
    lumped nodal areas from the file's topology; the scene, options and the energies at those times from the
    folder's own Result (`read_output`)."""
    import dataclasses
    import xml.etree.ElementTree as ET

    import numpy as np
    import pyfive

    from stringcontact.io.readback import read_output, read_xdmf
    from stringcontact.io.result import FIELDS, canonical_cells, node_sort_key

    folder = Path(folder)
    run = read_output(folder)
    geometry, series = read_xdmf(folder / "solution.xdmf")
    times = np.array([t for t, _ in series["eta"]])
    rows = np.searchsorted(run.t, times)
    assert np.array_equal(run.t[rows], times), "the XDMF's times are not stored rows"
    with pyfive.File(str(folder / "solution.h5")) as h5:
        def data(ref):
            return np.asarray(h5[ref.split(":", 1)[1]][:])

        points = data(geometry)
        x = points[:, 0] if run.dim == 1 else points[:, :2]
        width = float(np.max(np.ptp(x, axis=0))) or 1.0  # the file's points may differ from the mesh's by an ulp
        order = np.argsort(x if run.dim == 1 else node_sort_key(np.round(x / width, 12)), kind="stable")
        fields = {name: np.stack([data(ref).reshape(-1)[order] for _, ref in frames]) for name, frames in series.items()}
        mesh = {}
        if run.dim == 2:
            topology = ET.parse(folder / "solution.xdmf").getroot().find("Domain/Grid/Grid/Topology/DataItem").text
            rank = np.empty_like(order)
            rank[order] = np.arange(order.size)
            cells = canonical_cells(rank[data(topology.strip()).reshape(-1, 3)])
            a, b, c = (x[order][cells[:, k]] for k in range(3))
            area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
            mesh = {"cells": cells, "weights": np.bincount(cells.ravel(), np.repeat(area / 3, 3), minlength=len(x))}
    return dataclasses.replace(
        run, x=x[order], t=times, steps=run.steps[rows], eta=fields["eta"], velocity=fields["velocity"],
        contact=fields["contact"] > 0.5, contact_force=fields["contact_force"],
        energy={key: values[rows] for key, values in run.energy.items()},
        fields={name: fields[name] for name in run.fields if name in fields and name not in FIELDS}, **mesh)


@pytest.fixture
def tmpfs(tmp_path):
    """Mount a small tmpfs: needs root and CAP_SYS_ADMIN (a podman container may refuse: the test is skipped)."""
    mounted = []

    def mount(name: str, options: str) -> Path:
        folder = tmp_path / name
        folder.mkdir()
        if shutil.which("mount") is None or os.geteuid() != 0:
            pytest.skip("mounting a tmpfs needs root and the mount command")
        mount_argv = ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)]
        proc = subprocess.run(mount_argv, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here ({proc.stderr.strip()}); needs CAP_SYS_ADMIN")
        mounted.append(folder)
        return folder

    yield mount
    for folder in mounted:
        subprocess.run(["umount", "-l", str(folder)], check=False)


@pytest.fixture(scope="session")
def piston_folder(tmp_path_factory):
    """A short `piston` run (the obstacle moves) written to a folder, XDMF frames and all, no pictures: the folder
    and its Result, read by the XDMF and the ParaView tests alike (neither writes into it)."""
    import stringcontact as sc

    out = tmp_path_factory.mktemp("piston") / "piston"
    scene = sc.load_scene("piston").replace(nx=40, T=0.3, nt=75, output_times=[0.0, 0.1, 0.15, 0.3])
    res = sc.simulate(scene, output=sc.Output(out, max_frames=8, pictures=False))
    return out, res


#: the demos (demos/demo_*.py), in the order tests/system/test_demos.py runs them; the site build takes them backwards
DEMOS = sorted((TESTS.parent / "demos").glob("demo_*.py"))


@pytest.fixture(scope="session")
def demo_work(tmp_path_factory, worker_id) -> Path:
    """The folder the demos run into once per test run, shared by all pytest-xdist workers (their common base
    folder, as pytest-xdist's documentation shares a session's data): the demo tests read the runs, and the site
    build (tests/docs/test_site.py) renders them as its pages instead of running them again."""
    base = tmp_path_factory.getbasetemp()
    return (base if worker_id == "master" else base.parent) / "demo-runs"


def demo_run(demo: Path, work: Path) -> tuple[list[dict], Path, str]:
    """`demo` run by the docs build's own runner (docs/_ext/demo_pages.py's `execute`: cell by cell at reduced
    resolution, in an empty working folder it must leave empty) into `work`, once: (its records, per code cell
    what it printed and which pictures it wrote; its output folder; what it printed to stderr). Each demo has
    its own lock, so two workers run two demos at once and a worker that needs a demo being run waits for it."""
    from filelock import FileLock

    sys.path.insert(0, str(TESTS.parent / "docs" / "_ext"))
    import demo_pages

    work.mkdir(parents=True, exist_ok=True)
    with FileLock(str(work / f"{demo.stem}.lock")):
        records, out = demo_pages.execute(demo, work, TESTS.parent / "src" / "stringcontact")
    return records, out, (work / f"{demo.stem}.stderr").read_text()


def run_problem(scene, scheme=None, penalty=None, mass=None, model=None):
    """(the `DiscreteProblem` a serial run of `scene` hands its scheme, η⁰, v⁰): a `Stepper`'s problem, for a test
    that drives a scheme object itself; η⁰ with the ends at their heights, v⁰ at rest at the ends, in its dof
    order."""
    import numpy as np
    from mpi4py import MPI

    from stringcontact.run.stepper import Stepper

    problem = Stepper(scene, scheme, penalty, mass, model=model, comm=MPI.COMM_SELF).discrete
    eta0 = np.asarray(scene.initial_displacement(problem.x), dtype=float).copy()
    eta0[problem.bc] = problem.g
    return problem, eta0, np.asarray(scene.initial_velocity(problem.x), dtype=float) * problem.interior


def grid_mesh(n: int):
    """The cells and points of an n x n node grid of the unit square (2 (n-1)^2 triangles), for mesh files."""
    import numpy as np

    xs = np.linspace(0.0, 1.0, n)
    points = [[x, y] for y in xs for x in xs]
    cells = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            cells += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    return cells, points


def damped_oscillator(t, *, a0, a1, damping, stiffness):
    r"""``(a, a')`` of :math:`a'' + 2\beta a' + \kappa^2 a = 0`, :math:`a(0) = a_0`, :math:`a'(0) = a_1`
    (``damping`` :math:`2\beta`, ``stiffness`` :math:`\kappa^2`): :math:`a = a_0 C + (a_1 + \beta a_0) S`,
    :math:`a' = a_1 C - (\kappa^2 a_0 + \beta a_1) S`, :math:`C = e^{-\beta t}\cos\omega t`,
    :math:`S = e^{-\beta t}\sin(\omega t)/\omega`, :math:`\omega^2 = \kappa^2 - \beta^2` (cosh, sinh below 0)."""
    import numpy as np

    t = np.asarray(t, dtype=float)
    beta = 0.5 * damping
    omega2 = stiffness - beta**2
    if omega2 > 0.0:
        omega = np.sqrt(omega2)
        C = np.exp(-beta * t) * np.cos(omega * t)
        S = np.exp(-beta * t) * t * np.sinc(omega * t / np.pi)  # sin(ωt)/ω via sinc: accurate as ω → 0
    elif omega2 == 0.0:
        C = np.exp(-beta * t)
        S = t * C
    else:
        gamma = np.sqrt(-omega2)
        # with the slow rate γ − β = −κ²/(β + γ) and e^{−2γt} ≤ 1 nothing overflows or cancels for small γ
        slow = np.exp(-stiffness / (beta + gamma) * t)
        fast = np.exp(-2.0 * gamma * t)
        C = 0.5 * slow * (1.0 + fast)
        z = 2.0 * gamma * t  # S = slow t (1 − e^{−z})/z, that quotient 1 at z = 0
        S = slow * t * np.where(z == 0.0, 1.0, -np.expm1(-z) / np.where(z == 0.0, 1.0, z))
    a = a0 * C + (a1 + beta * a0) * S
    da = a1 * C - (stiffness * a0 + beta * a1) * S
    return a, da


def sine_mode(t, x, *, k, a0, a1, alpha, length, h):
    r"""No-contact mode :math:`\eta = h + a(t)\sin(\kappa x)`, :math:`\kappa = k\pi/l`, of :math:`\eta_{tt} -
    \alpha\eta_{txx} - \eta_{xx} = 0`: :math:`a'' + \alpha\kappa^2 a' + \kappa^2 a = 0`, :math:`a(0) = a_0`,
    :math:`a'(0) = a_1`."""
    import numpy as np

    if alpha < 0:
        raise ValueError(f"alpha must be >= 0, got {alpha}")
    kappa = k * np.pi / length
    tt = np.atleast_1d(np.asarray(t, dtype=float))[:, None]  # rows: times
    a, da = damped_oscillator(tt, a0=a0, a1=a1, damping=alpha * kappa**2, stiffness=kappa**2)
    shape = np.sin(kappa * np.asarray(x, dtype=float))[None, :]
    eta, velocity = h + a * shape, da * shape
    return (eta[0], velocity[0]) if np.ndim(t) == 0 else (eta, velocity)


# A Ctrl-C at a chosen point of the start-up: a finder on sys.meta_path sends SIGINT to its own process when
# the module argv[1] is first imported (no clock: the signal arrives exactly there); argv[2:] is the command line.
CTRL_C_AT_IMPORT = r"""
import os, signal, sys

class CtrlC:
    def find_spec(self, name, path=None, target=None):
        if name == sys.argv[1]:
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, CtrlC())
from stringcontact.cli.main import main
sys.exit(main(sys.argv[2:]))
"""
