"""solution.xdmf/.h5: the mesh once, one grid per stored time carrying every field; read by meshio.

meshio (with the h5py wheel) runs in a separate Python: h5py's bundled libhdf5 must not meet dolfinx's.
ParaView's readers are checked in tests/system/test_paraview.py.
"""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from conftest import meshio_read, mpirun

import stringcontact as sc
from stringcontact.io import readback
from stringcontact.io.result import FIELDS


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("xdmf") / "run"
    res = sc.simulate(sc.load_scene("example1").replace(nx=60, nt=600), output_dir=out, max_rows=40, max_frames=12, pictures=False)
    return out, res


def test_each_time_is_one_grid_with_every_field_in_double_precision(run):
    out, _ = run
    root = ET.parse(out / "solution.xdmf").getroot()
    assert [g.get("CollectionType") for g in root.find("Domain")] == ["Temporal"]  # nothing beside the series
    grids = root.findall("Domain/Grid/Grid")
    assert len(grids) >= 12
    for grid in grids:
        assert grid.find("Topology").get("TopologyType") == "Polyline"
        assert grid.find("Geometry/DataItem").text.strip() == "solution.h5:/geometry"  # the mesh is stored once
        assert [a.get("Name") for a in grid.findall("Attribute")] == list(FIELDS)
        for item in [grid.find("Geometry/DataItem"), *grid.findall("Attribute/DataItem")]:
            assert (item.get("DataType"), item.get("Precision")) == ("Float", "8")


def test_meshio_reads_the_series_as_written(run):
    out, res = run
    data = meshio_read(out / "solution.xdmf")
    back = readback.read_output(out, from_xdmf=True)  # the frames meshio reads
    x = np.array(data["points"])[:, 0]
    order = np.argsort(x)
    np.testing.assert_array_equal(x[order], res.x)
    assert len(data["cells"]["line"]) == 60
    np.testing.assert_array_equal(data["times"], back.t)
    for k, point_data in enumerate(data["data"]):
        assert sorted(point_data) == sorted(FIELDS)
        row = int(np.flatnonzero(res.t == back.t[k])[0])
        for name in ("eta", "velocity", "contact_force"):
            np.testing.assert_array_equal(np.array(point_data[name])[order], getattr(res, name)[row], err_msg=name)
        np.testing.assert_array_equal(np.array(point_data["contact"])[order] > 0.5, res.contact[row])


def test_the_xdmf_is_well_formed_after_every_frame(tmp_path):
    from dolfinx import mesh
    from mpi4py import MPI

    from stringcontact.fem import compat
    from stringcontact.io.xdmf import XdmfTimeSeries, mesh_arrays, xdmf_series

    V = compat.function_space(mesh.create_interval(MPI.COMM_SELF, 10, [0.0, 1.0]))
    series = XdmfTimeSeries(tmp_path, mesh_arrays(V, MPI.COMM_SELF), MPI.COMM_SELF)
    try:
        for k in range(3):  # read back while the writer still holds the file open
            series.write(0.5 * k, {"eta": np.full(11, float(k))})
            assert [t for t, _ in xdmf_series(tmp_path / "solution.xdmf")["eta"]] == [0.5 * j for j in range(k + 1)]
    finally:
        series.close()


def test_a_triangle_mesh_is_written_with_the_same_layout(tmp_path):
    """The writer does not assume 1D: a P1 field on a 2D triangle mesh, read back by meshio."""
    from dolfinx import fem, mesh
    from mpi4py import MPI

    from stringcontact.fem import compat
    from stringcontact.io.xdmf import XdmfTimeSeries, mesh_arrays

    V = compat.function_space(mesh.create_unit_square(MPI.COMM_SELF, 3, 2))
    u = fem.Function(V)
    arrays = mesh_arrays(V, MPI.COMM_SELF)
    series = XdmfTimeSeries(tmp_path, arrays, MPI.COMM_SELF)
    for t in (0.0, 1.0):
        u.interpolate(lambda x, t=t: x[0] + 10 * x[1] + 100 * t)
        series.write(t, {"membrane": u.x.array[: arrays.n_points]})
    series.close()
    data = meshio_read(tmp_path / "solution.xdmf")
    points = np.array(data["points"])
    assert points.shape == (12, 3) and len(data["cells"]["triangle"]) == 12
    for t, point_data in zip(data["times"], data["data"]):
        np.testing.assert_allclose(point_data["membrane"], points[:, 0] + 10 * points[:, 1] + 100 * t, atol=1e-12)


def test_a_run_stopped_early_keeps_the_same_readable_layout(tmp_path):
    from dolfinx import mesh
    from mpi4py import MPI

    from stringcontact.fem import compat
    from stringcontact.io.folder import OutputWriter

    scene = sc.load_scene("example1").replace(nx=10, nt=20)
    V = compat.function_space(mesh.create_interval(MPI.COMM_SELF, 10, [0.0, 1.0]))
    writer = OutputWriter(tmp_path / "out", scene, V, MPI.COMM_SELF, pictures=False)
    for k in range(3):
        writer.write(0.1 * k, {name: np.full(11, float(k)) for name in FIELDS})
    writer.abort("interrupted", "stopped")
    assert json.loads((writer.path / "summary.json").read_text())["status"] == "interrupted"
    data = meshio_read(writer.path / "solution.xdmf")
    assert data["times"] == pytest.approx([0.0, 0.1, 0.2]) and len(data["cells"]["line"]) == 10
    for k, point_data in enumerate(data["data"]):
        assert sorted(point_data) == sorted(FIELDS)
        np.testing.assert_array_equal(point_data["eta"], float(k))


TRIANGLES_UNDER_MPI = r"""
import sys
from dolfinx import fem, mesh
from mpi4py import MPI
from stringcontact.fem import compat
from stringcontact.io.xdmf import XdmfTimeSeries, mesh_arrays
V = compat.function_space(mesh.create_unit_square(MPI.COMM_WORLD, 6, 5))
u, arrays = fem.Function(V), mesh_arrays(V, MPI.COMM_WORLD)
series = XdmfTimeSeries(sys.argv[1], arrays, MPI.COMM_WORLD)
u.interpolate(lambda x: x[0] + 10 * x[1])
series.write(0.0, {"membrane": u.x.array[: len(arrays.points)]})
series.close()
"""


@pytest.mark.mpi
def test_a_triangle_mesh_distributed_over_two_ranks_is_one_whole_mesh(tmp_path):
    proc = mpirun([sys.executable, "-c", TRIANGLES_UNDER_MPI, tmp_path], ranks=2)
    assert proc.returncode == 0, proc.stderr[-3000:]
    data = meshio_read(tmp_path / "solution.xdmf")
    points, triangles = np.array(data["points"]), np.array(data["cells"]["triangle"])
    assert points.shape == (42, 3) and triangles.shape == (60, 3)
    corners = points[triangles][:, :, :2]
    areas = 0.5 * np.abs(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    assert areas.min() > 0 and areas.sum() == pytest.approx(1.0)  # the two ranks' halves tile the square
    np.testing.assert_allclose(data["data"][0]["membrane"], points[:, 0] + 10 * points[:, 1], atol=1e-12)
