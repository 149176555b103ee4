"""Mesh files that dolfinx would hang or crash on, and mesh paths that are not files: each one line and exit 2,
or a run on exactly the file the XDMF names; never a hang (docs/explanation/reliability_promises.md).

Every run is a fresh process with a hang guard: before these checks, dolfinx spun at 100 % CPU, deaf to
SIGTERM, on several of these files, so a hang must fail the test rather than block the suite."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import grid_mesh, leftovers

QUICK = ["--no-progress", "--no-pictures"]

_WRITER = """
import json, sys
import h5py, numpy as np
path, arrays = sys.argv[1], json.loads(sys.argv[2])
with h5py.File(path, "w") as f:
    for name, (values, dtype) in arrays.items():
        f[name] = np.array(values, dtype=dtype)
"""


def write_h5(path: Path, cells, points, point_dtype: str = "float64") -> None:
    """An HDF5 file with /topology and /geometry, written by h5py in a child process (its libhdf5 clashes with
    dolfinx's)."""
    arrays = {"topology": (cells, "int64"), "geometry": (points, point_dtype)}
    subprocess.run([sys.executable, "-c", _WRITER, str(path), json.dumps(arrays)], check=True, timeout=120)


def write_xdmf(path: Path, h5_name: str, n_cells: int, n_points: int, grid_name: str = "mesh") -> Path:
    name = grid_name.replace("&", "&amp;").replace('"', "&quot;").replace("'", "&apos;")
    path.write_text(
        '<?xml version="1.0"?>\n<Xdmf Version="3.0"><Domain>'
        f'<Grid Name="{name}" GridType="Uniform">'
        f'<Topology TopologyType="Triangle" NumberOfElements="{n_cells}" NodesPerElement="3">'
        f'<DataItem Dimensions="{n_cells} 3" NumberType="Int" Format="HDF">{h5_name}:/topology</DataItem></Topology>'
        f'<Geometry GeometryType="XY"><DataItem Dimensions="{n_points} 2" Format="HDF">{h5_name}:/geometry</DataItem>'
        '</Geometry></Grid></Domain></Xdmf>\n')
    return path


def scene(folder: Path, mesh: str) -> Path:
    path = folder / "s.toml"
    path.write_text(f'mesh = "{mesh}"\nT = 0.01\nnt = 4\nalpha = 0\nscheme = {{ eps = 0.01 }}\n'
                    'eta0 = "1 + 0.1*x*y"\nh = 1\nv0 = -1\n')
    return path


def run(folder: Path, *argv, timeout: float = 300) -> subprocess.CompletedProcess:
    """`stringcontact run s.toml --out o` in `folder`, bounded: a hang fails the test (SIGKILL: the hang was deaf
    to SIGTERM)."""
    try:
        return subprocess.run([sys.executable, "-m", "stringcontact", "run", "s.toml", "--out", "o", *QUICK, *argv],
                              cwd=folder, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail("the run did not end: dolfinx was handed a mesh it hangs on")


def one_error_line(stderr: str, *fragments) -> str:
    lines = [line for line in stderr.splitlines() if not line.startswith("stringcontact: warning:")]
    assert len(lines) == 1 and lines[0].startswith("stringcontact: error: "), stderr[-3000:]
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


@pytest.mark.slow
def test_the_mesh_is_read_from_the_file_the_xdmf_names(tmp_path):
    """dolfinx 0.5 read `<xdmf stem>.h5` whatever the DataItem named: a good x_data.h5 named beside a bad x.h5
    (an index out of range) was checked, then dolfinx read x.h5 and spun forever. The file named is the file
    meshed now."""
    cells, points = grid_mesh(5)
    write_h5(tmp_path / "x_data.h5", cells, points)
    bad = [list(c) for c in cells]
    bad[3] = [0, 10**6, 2]
    write_h5(tmp_path / "x.h5", bad, points)
    write_xdmf(tmp_path / "x.xdmf", "x_data.h5", len(cells), len(points))
    scene(tmp_path, "x.xdmf")
    proc = run(tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "complete"


@pytest.mark.slow
@pytest.mark.parametrize("grid_name", ["x' or @Name='evil", 'a"b', "m]/../Grid[1"])
def test_a_grid_name_is_never_code(tmp_path, grid_name):
    """dolfinx built an XPath from the grid's name: `x' or @Name='evil` hung it. The name is not used now."""
    cells, points = grid_mesh(5)
    write_h5(tmp_path / "m.h5", cells, points)
    write_xdmf(tmp_path / "m.xdmf", "m.h5", len(cells), len(points), grid_name=grid_name)
    scene(tmp_path, "m.xdmf")
    proc = run(tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]


def _special(kind: str, path: Path) -> None:
    if kind == "FIFO":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    else:
        os.symlink(path.name + ".b", path.with_name(path.name + ".a"))
        os.symlink(path.name + ".a", path.with_name(path.name + ".b"))
        os.symlink(path.name + ".a", path)


@pytest.mark.slow
@pytest.mark.parametrize(("kind", "fragment"), [("FIFO", "is a FIFO"), ("directory", "is a directory"),
                                                ("loop", "loop of symbolic links")])
def test_a_mesh_h5_that_is_not_a_file_is_one_line_and_never_blocks(tmp_path, kind, fragment):
    """A FIFO as the mesh's .h5 hung the run until it was signalled (6 minutes under MPI)."""
    cells, points = grid_mesh(5)
    _special(kind, tmp_path / "m.h5")
    write_xdmf(tmp_path / "m.xdmf", "m.h5", len(cells), len(points))
    scene(tmp_path, "m.xdmf")
    proc = run(tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "mesh: ", fragment)
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


@pytest.mark.parametrize(("kind", "fragment"), [("FIFO", "is a FIFO"), ("directory", "is a directory"),
                                                ("loop", "loop of symbolic links")])
def test_a_mesh_path_that_is_not_a_file_says_what_it_is(tmp_path, kind, fragment):
    """It was called "no such file"."""
    _special(kind, tmp_path / "m.xdmf")
    scene(tmp_path, "m.xdmf")
    proc = run(tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    line = one_error_line(proc.stderr, "mesh: ", fragment)
    assert "no such file" not in line


@pytest.mark.slow
def test_string_coordinates_are_refused_before_they_are_read(tmp_path):
    """A 2.8 KB .h5 with string coordinates took 2 GB and then gave a wrong message."""
    cells, points = grid_mesh(5)
    write_h5(tmp_path / "m.h5", cells, [[str(x), str(y)] for x, y in points], point_dtype="S40")
    write_xdmf(tmp_path / "m.xdmf", "m.h5", len(cells), len(points))
    scene(tmp_path, "m.xdmf")
    proc = run(tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "mesh: ", "its geometry holds", "allowed: floating-point or integer numbers")


@pytest.mark.slow
def test_huge_coordinates_are_named_as_such(tmp_path):
    """Coordinates of 1e200 were reported as "cells of zero area (smallest inf)"."""
    cells, points = grid_mesh(5)
    write_h5(tmp_path / "m.h5", cells, [[x * 1e200, y * 1e200] for x, y in points])
    write_xdmf(tmp_path / "m.xdmf", "m.h5", len(cells), len(points))
    scene(tmp_path, "m.xdmf")
    proc = run(tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "mesh: ", "node coordinate of 1e+200", "allowed: coordinates in [-1e+06, 1e+06]")
