"""Membranes (issue 15): the same model and schemes on 2D domains.

The square membrane's exact damped mode (convergence order), the drum's radially symmetric landing (its
contact patch is a disk), the energy ledger of every scheme in 2D, projection's dt_max against SciPy's
eigsh, MPI parity, and bad meshes and domain keys refused in one line.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.errors import SceneError
from stringcontact.scene import Scene, scene_to_toml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: conftest.py

K2 = 2 * math.pi**2  # -Δ of sin(πx) sin(πy)


def square(cells: int, nt: int, alpha: float, T: float = 0.5, **keys) -> Scene:
    """No contact: η = 0.5 + 0.1 a(t) sin(πx) sin(πy) stays above 0.4, the boundary held at 0.5."""
    data = dict(domain="rectangle", size=[1, 1], cells=[cells, cells], T=T, nt=nt, alpha=alpha, scheme={"eps": 1e-3},
                eta0="0.5 + 0.1*sin(pi*x)*sin(pi*y)", v0=0, h=0.5)
    data.update(keys)
    return Scene.from_dict(data)


def mode_amplitude(t, alpha: float):
    """a'' + α k² a' + k² a = 0, a(0) = 1, a'(0) = 0 (underdamped for the α used here)."""
    g = 0.5 * alpha * K2
    w = math.sqrt(K2 - g * g)
    return np.exp(-g * t) * (np.cos(w * t) + g / w * np.sin(w * t))


def mode_error(res, alpha: float) -> float:
    x, y = res.x[:, 0], res.x[:, 1]
    exact = 0.5 + 0.1 * mode_amplitude(res.t[-1], alpha) * np.sin(np.pi * x) * np.sin(np.pi * y)
    return float(np.max(np.abs(res.eta[-1] - exact)))


@pytest.mark.parametrize("scheme, alpha, order", [("newmark", 0.0, 2), ("newmark", 0.05, 2), ("paper", 0.05, 1)])
def test_square_membrane_converges_to_the_exact_mode(scheme, alpha, order):
    errors = []
    for cells in (8, 16, 32):
        res = sc.simulate(square(cells, nt=4 * cells, alpha=alpha), scheme=scheme, penalty="semi-implicit")
        assert not res.contact.any()
        errors.append(mode_error(res, alpha))
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(rates > order - 0.2), (errors, rates)


def test_projection_in_2d_converges_to_the_exact_mode():
    """Order 1, as in 1D (docs/explanation/study.md): its start η^-1 = η^0 - Δt v0 takes v0 half a step early."""
    errors = [mode_error(sc.simulate(square(c, nt=4 * c, alpha=0.0), scheme="projection"), 0.0) for c in (16, 32, 64)]
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(rates > 0.75) and rates[-1] > 0.85, (errors, rates)


def small_drum(**keys) -> Scene:
    return sc.load_scene("drum").replace(**{"mesh_size": 0.08, "T": 0.4, "nt": 80, "output_times": [0.2], **keys})


def test_the_drums_contact_patch_is_a_disk_centred_at_the_middle():
    scene = small_drum()
    res = sc.simulate(scene)
    r = np.hypot(res.x[:, 0], res.x[:, 1])
    landed = np.flatnonzero(res.contact_measure > 0)
    assert landed.size >= 3  # it lands within T
    patches = res.contact_patches()
    for i in landed:
        inside, outside = r[res.contact[i]], r[~res.contact[i]]
        # every node closer to the centre than the nearest free node is in contact, and the contact nodes
        # reach at most one cell further out: a disk, up to the mesh
        assert inside.max() - outside.min() <= scene.mesh_size, (res.t[i], inside.max(), outside.min())
        assert res.contact[i][np.argmin(r)]
        assert patches[i] == 1
    assert res.contact_measure[landed[-1]] > res.contact_measure[landed[0]]  # it grows while landing


def test_the_bump_lands_on_both_humps_and_the_patches_join():
    res = sc.simulate(sc.load_scene("bump"))
    patches = res.contact_patches()
    first = int(np.argmax(patches > 0))
    assert patches[first] == 2 and patches[-1] == 1  # one patch per hump, joined by the end
    assert res.contact_measure[-1] > 10 * res.contact_measure[first]


def test_without_viscosity_the_bumps_patch_splits_again():
    res = sc.simulate(sc.load_scene("bump").replace(alpha=0))
    patches = res.contact_patches()
    joined = int(np.argmax(patches == 1))
    assert patches[joined] == 1 and patches[joined:].max() >= 3  # it rings: one patch breaks into several


def contact_scene(**keys) -> Scene:
    data = dict(domain="rectangle", cells=[12, 12], T=0.4, nt=80, alpha=0.02, scheme={"eps": 0.005},
                eta0="0.05 + 0.1*sin(pi*x)*sin(pi*y)", v0="-2*sin(pi*x)*sin(pi*y)", h=0.05)
    data.update(keys)
    return Scene.from_dict(data)


@pytest.mark.parametrize("scheme", sc.SCHEMES)
def test_energy_ledger_closes_in_2d(scheme):
    res = sc.simulate(contact_scene(), scheme=scheme)
    assert res.status == "complete"
    assert res.contact_measure.max() > 0.1  # a real landing
    assert res.energy["contact_dissipation"][-1] > 0.01 * res.total_energy[0]
    assert np.max(np.abs(res.balance_residual)) <= 1e-10 * res.total_energy[0]


def test_contact_area_is_the_lumped_area_of_the_contact_nodes():
    res = sc.simulate(contact_scene(T=0.2, nt=40), scheme="newmark")
    assert res.weights.sum() == pytest.approx(1.0, rel=1e-12)  # the unit square
    i = int(np.argmax(res.contact_measure))
    assert res.contact_measure[i] == pytest.approx(float(res.weights[res.contact[i]].sum()), rel=1e-14)
    assert 0 < res.contact_measure[i] < 1


def test_projection_dt_max_is_the_top_eigenvalue_of_the_operators():
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla
    from conftest import run_problem

    from stringcontact.timestepping import projection, spectrum

    problem, _, _ = run_problem(small_drum(mesh_size=0.15), "projection", mass="lumped")
    ops = problem.ops
    ia, ja, a = ops.K.getValuesCSR()
    inner = np.flatnonzero(problem.interior)
    K = sp.csr_matrix((a, ja, ia))[inner][:, inner]
    D = sp.diags(1 / np.sqrt(ops.m[inner]))
    lam = sla.eigsh(D @ K @ D, k=1, which="LA")[0][0]
    assert spectrum.top_mode_krylov(ops.K, ops.m, problem.interior)[0] == pytest.approx(lam, rel=1e-8)
    bound = spectrum.gershgorin_bound(ops.K, ops.m, problem.interior)
    assert lam <= bound < 2 * lam
    dt_max = spectrum.largest_stable_dt(ops, problem.interior, krylov=True)
    assert dt_max >= 2 / math.sqrt(lam) * (1 - 1e-8)  # α > 0: viscosity relieves the bound
    # the scene's small dt: no eigenvalue
    assert projection.ProjectionScheme(problem).dt_max == pytest.approx(2 / math.sqrt(bound))
    T = 0.2
    for factor, stable in ((0.98, True), (1.05, False)):  # both above Gershgorin's dt: decided by the eigenvalue
        nt = math.ceil(T / (factor * dt_max)) if stable else math.floor(T / (factor * dt_max))
        assert T / nt > 2 / math.sqrt(bound)
        if stable:
            assert sc.simulate(small_drum(mesh_size=0.15, T=T, nt=nt), scheme="projection").status == "complete"
        else:
            with pytest.raises(sc.InstabilityError, match="dt_max"):
                sc.simulate(small_drum(mesh_size=0.15, T=T, nt=nt), scheme="projection")


# --- bad input -------------------------------------------------------------------------------------

def xdmf(tmp_path, name, cells, points, cell="triangle"):
    """A mesh file written by dolfinx itself (XDMF + HDF5), of any cells and points, degenerate or not."""
    from dolfinx.io import XDMFFile
    from mpi4py import MPI

    from stringcontact.fem import compat

    points = np.asarray(points, dtype=float)
    msh = compat.create_mesh(MPI.COMM_SELF, np.asarray(cells, dtype=np.int64), points,
                             compat.coordinate_domain(cell, points.shape[1]))
    path = tmp_path / name
    with XDMFFile(MPI.COMM_SELF, str(path), "w") as f:
        f.write_mesh(msh)
    return path


def text_file(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def file_scene(path) -> Scene:
    return Scene.from_dict(dict(mesh=str(path), T=0.1, nt=10, alpha=0, scheme={"eps": 1e-3}, eta0="1", v0=0))


def test_a_mesh_file_runs_like_the_same_rectangle(tmp_path):
    points = [[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]
    path = xdmf(tmp_path, "square.xdmf", [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]], points)
    res = sc.simulate(file_scene(path).replace(eta0="1 + 0.1*x*y", h=1, v0=-1), scheme="newmark")
    assert res.x.shape == (5, 2) and res.weights.sum() == pytest.approx(1.0)
    assert res.eta[-1][np.argmin(np.hypot(res.x[:, 0] - 0.5, res.x[:, 1] - 0.5))] < 1.0  # the free node moved


@pytest.mark.parametrize("make, message", [
    (lambda p: text_file(p / "text.xdmf", "this is not xml"), "is not an XDMF mesh file"),
    (lambda p: xdmf(p, "flat.xdmf", [[0, 1, 2], [1, 2, 3]], [[0, 0], [1, 0], [2, 0], [3, 0]]), "zero area"),
    (lambda p: xdmf(p, "tet.xdmf", [[0, 1, 2, 3]], [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], "tetrahedron"),
     "is a 3D mesh"),
    (lambda p: xdmf(p, "tilted.xdmf", [[0, 1, 2]], [[0, 0, 0], [1, 0, 0], [0, 1, 1]]), "surface in 3D"),
])
def test_bad_mesh_files_are_refused_in_one_line(tmp_path, make, message):
    scene = file_scene(make(tmp_path))
    with pytest.raises(SceneError, match=message) as info:
        sc.simulate(scene, scheme="newmark")  # the paper's explicit penalty refuses r = 10 before the mesh is read
    assert str(info.value).startswith("mesh: ") and "\n" not in str(info.value)


@pytest.mark.parametrize("keys, message", [
    (dict(domain="rectangle", cells=[4, 4], size=[1, 0]), r"size: list \[1, 0\] is out of range; allowed: two numbers"),
    (dict(domain="rectangle", cells=[4, 0]), r"cells: .* allowed: two integers \[nx, ny\] in \[1, 2000\]"),
    (dict(domain="disk", radius=0, mesh_size=0.1), r"radius: 0 is out of range"),
    (dict(domain="disk", mesh_size=0.0001), r"mesh_size: .* allowed: a number in \[radius/1000, radius\]"),
    (dict(domain="disk", mesh_size=0.1, cells=[2, 2]), r"cells: only for domain 'rectangle', not 'disk'"),
    (dict(domain="rectangle", cells=[4, 4], nx=4), r"nx: only for domain 'interval', not 'rectangle'"),
    (dict(domain="sphere"), r"domain: invalid value str 'sphere'; allowed: interval, rectangle, disk, file"),
    (dict(domain="rectangle", cells=[4, 4], eta0="z"), r"eta0: unknown name 'z'; allowed names are x, y, h, pi"),
    (dict(nx=4, eta0="1 + y"), r"eta0: unknown name 'y'; allowed names are x, l, h, pi"),
    (dict(mesh="missing.xdmf"), r"mesh: no such file 'missing.xdmf'"),
])
def test_bad_domain_keys_are_refused_in_one_line(keys, message):
    data = dict(T=0.1, nt=10, alpha=0, scheme={"eps": 1e-3}, eta0="1", v0=0)
    data.update(keys)
    with pytest.raises(SceneError, match=message) as info:
        Scene.from_dict(data)
    assert "\n" not in str(info.value)


def test_2d_scenes_round_trip_through_toml(tmp_path):
    for scene in (sc.load_scene("drum"), sc.load_scene("bump"), contact_scene(h="0.05 + 0.01*x*y")):
        path = tmp_path / f"{scene.name}.toml"
        path.write_text(scene_to_toml(scene))
        assert sc.load_scene(path) == scene


def test_boundary_height_may_vary_along_the_boundary():
    res = sc.simulate(contact_scene(h="0.05 + 0.1*x", eta0="0.05 + 0.1*x", v0=0, T=0.05, nt=10), scheme="newmark")
    x, y = res.x[:, 0], res.x[:, 1]
    rim = (x == 0) | (x == 1) | (y == 0) | (y == 1)
    assert np.allclose(res.eta[-1][rim], 0.05 + 0.1 * x[rim], rtol=0, atol=1e-14)
    assert np.allclose(res.eta[-1], 0.05 + 0.1 * x, atol=1e-10)  # an affine membrane at rest stays


# --- MPI parity ---------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.mpi
@pytest.mark.parametrize("scheme", ["projection", "newmark"])
def test_mpi_2d_run_equals_serial(tmp_path, scheme):
    # rank 0 holds the rows (gather="root"); rank 1 only the series; with gather="all" both hold the rows
    from conftest import mpirun

    proc = mpirun([sys.executable, Path(__file__).resolve(), scheme, tmp_path])
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    serial = sc.simulate(small_drum(), scheme=scheme)
    assert serial.contact_measure.max() > 0.1  # a real landing
    for label, rank in (("root", 0), ("all", 0), ("all", 1)):
        got = np.load(tmp_path / f"{label}.rank{rank}.npz")
        assert int(got["size"]) == 2 and got["has_rows"], (label, rank)
        np.testing.assert_array_equal(got["x"], serial.x)
        np.testing.assert_array_equal(got["cells"], serial.cells)
        np.testing.assert_array_equal(got["contact"], serial.contact)
        for name in ("eta", "velocity", "weights", "contact_measure"):
            assert_close(got[name], getattr(serial, name), (label, rank, name))
    got = np.load(tmp_path / "root.rank1.npz")
    assert not got["has_rows"] and "x" not in got
    assert str(got["refused"]).startswith("Result.cells: the per-node rows are on rank 0 only")
    assert_close(got["contact_measure"], serial.contact_measure, "contact_measure")  # summed over the ranks
    for key, values in serial.energy.items():
        assert_close(got[f"energy_{key}"], values, key)
    np.testing.assert_array_equal(got["t"], serial.t)


def assert_close(a, b, what) -> None:
    assert np.max(np.abs(a - b)) <= 1e-10 * max(1.0, np.max(np.abs(b))), what


def _worker(scheme: str, out: Path) -> None:
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    for gather in ("root", "all"):
        res = sc.simulate(small_drum(), scheme=scheme, storage=sc.Storage(gather=gather))
        keep = dict(size=comm.size, has_rows=res.has_rows, t=res.t, contact_measure=res.contact_measure,
                    **{f"energy_{k}": v for k, v in res.energy.items()})
        if res.has_rows:
            keep.update(x=res.x, cells=res.cells, contact=res.contact, eta=res.eta, velocity=res.velocity,
                        weights=res.weights)
        else:
            try:
                res.contact_patches()
            except AttributeError as exc:
                keep["refused"] = str(exc)
        np.savez(out / f"{gather}.rank{comm.rank}.npz", **keep)


if __name__ == "__main__":
    _worker(sys.argv[1], Path(sys.argv[2]))


@pytest.mark.slow
def test_a_membrane_run_writes_an_xdmf_meshio_reads_and_no_string_pictures(tmp_path):
    from conftest import meshio_read  # meshio in its own process: h5py's libhdf5 must not meet dolfinx's

    from stringcontact.plot import run_pictures as viz

    scene = sc.load_scene("drum").replace(mesh_size=0.2, T=0.2, nt=40, output_times=[0.1])
    res = sc.simulate(scene, output=sc.Output(tmp_path / "drum", pictures=True))
    drawn = sorted(p.name for p in (tmp_path / "drum").iterdir() if p.suffix in (".png", ".gif"))
    assert drawn == sorted(viz.MEMBRANE_PICTURES)  # the membrane's; the (x, t) pictures are of a string
    data = meshio_read(tmp_path / "drum" / "solution.xdmf")
    assert len(data["points"]) == res.x.shape[0] and list(data["cells"]) == ["triangle"]
    assert data["times"][-1] == pytest.approx(res.t[-1])
    last = data["data"][-1]
    assert set(last) == {"eta", "velocity", "contact", "contact_force"}
    # the same values as the Result, whatever the node order of the file
    np.testing.assert_allclose(np.sort(np.ravel(last["eta"])), np.sort(res.eta[-1]), atol=1e-12)
