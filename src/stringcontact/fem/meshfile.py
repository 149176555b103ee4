"""A mesh file read here, checked, and handed to dolfinx as arrays: what was checked is what dolfinx meshes.

Hand-written because dolfinx trusts its input: a cell index out of range left `create_mesh` spinning in C++, deaf to
Ctrl-C, duplicate cells corrupted its heap, and dolfinx 0.5's XDMF reader reads ``<xdmf stem>.h5`` whatever file the
DataItem names (tests/system/test_reliability_meshfiles.py). The data are read with pyfive (h5py's wheel clashes with
dolfinx's libhdf5) and refused in one line naming ``mesh`` unless a plain triangle mesh of at most `MAX_NODES` nodes.
"""

from __future__ import annotations

import io
import os
import stat
import xml.etree.ElementTree as ET

import numpy as np

from ..errors import SceneError
from ..scene.checks import file_kind, os_reason
from ..scene.limits import MAX_MEMBRANE_NODES, SETUP_BYTES_PER_NODE

__all__ = ["MAX_CELLS", "MAX_COORDINATE", "MAX_NODES", "MAX_XDMF_BYTES", "read", "regular_file"]

#: The largest mesh file: as many nodes as the largest membrane (scene.limits), twice as many cells.
MAX_NODES = MAX_MEMBRANE_NODES
MAX_CELLS = 2 * MAX_MEMBRANE_NODES
#: The largest |coordinate|: a scene's `length` bound (1e4) with room for other units (area overflows near 1e154).
MAX_COORDINATE = 1e6
#: The largest XDMF file read: a mesh's XML is a few hundred bytes (its data are in the HDF5 file).
MAX_XDMF_BYTES = 10_000_000


def regular_file(path: str, what: str = "mesh") -> int:
    """An open descriptor of `path`, a regular file (O_NONBLOCK: a FIFO is never waited on); else SceneError."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise SceneError(f"{what}: {path!r} {os_reason(exc)}; allowed: a readable regular file") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise SceneError(f"{what}: {path!r} is {file_kind(mode)}, not a regular file; allowed: a regular file")
    return fd


def read(path: str) -> tuple[np.ndarray, np.ndarray]:
    """(cells, points) of the XDMF triangle mesh at `path`, int64 (cells, 3) and float64 (nodes, 2), checked."""
    grid = _grid(path)
    cells = _data(path, grid.find("Topology"), "topology", MAX_CELLS)
    points = _data(path, grid.find("Geometry"), "geometry", MAX_NODES)
    _check_shapes(path, cells, points)
    _check_cells(path, cells, len(points))
    if points.shape[1] == 3 and np.any(points[:, 2] != 0.0):
        raise SceneError(f"mesh: {path!r} is a surface in 3D (z is not 0); allowed: a flat 2D triangle mesh")
    return cells.astype(np.int64), np.ascontiguousarray(points[:, :2], dtype=np.float64)


def _grid(path: str):
    fd = regular_file(path)
    with os.fdopen(fd, "rb") as f:
        text = f.read(MAX_XDMF_BYTES + 1)
    if len(text) > MAX_XDMF_BYTES:
        raise SceneError(f"mesh: {path!r} is larger than {MAX_XDMF_BYTES} bytes; allowed: an XDMF file (its data "
                         "in an HDF5 file beside it)")
    try:
        root = ET.fromstring(text)
    except (ET.ParseError, ValueError, RecursionError) as exc:
        raise SceneError(f"mesh: {path!r} is not an XDMF mesh file ({type(exc).__name__}: "
                         f"{str(exc)[:120]}); allowed: an XDMF triangle mesh") from None
    grid = next((grid for grid in root.iter("Grid") if grid.find("Topology") is not None), None)
    if grid is None:
        raise SceneError(f"mesh: {path!r} holds no grid with a topology; allowed: an XDMF triangle mesh")
    cell = grid.find("Topology").get("TopologyType") or grid.find("Topology").get("Type") or "?"
    if cell.lower() in ("tetrahedron", "hexahedron", "wedge", "pyramid"):
        raise SceneError(f"mesh: {path!r} is a 3D mesh ({cell} cells); allowed: a 2D triangle mesh")
    if cell.lower() != "triangle":
        raise SceneError(f"mesh: {path!r} has {cell} cells; allowed: a 2D triangle mesh (Triangle cells)")
    return grid


def _data(path: str, element, what: str, limit: int) -> np.ndarray:
    """The array of the DataItem of `element` (Topology or Geometry), checked against its stated Dimensions."""
    item = element.find("DataItem") if element is not None else None
    if item is None:
        raise SceneError(f"mesh: {path!r} has no {what} data; allowed: an XDMF triangle mesh with its HDF5 file")
    fmt = item.get("Format", "XML")
    if fmt != "HDF":
        raise SceneError(f"mesh: {path!r} gives its {what} as Format={fmt!r}; allowed: Format='HDF' "
                         "(an XDMF file with its HDF5 file, as dolfinx writes it)")
    try:
        dims = tuple(int(d) for d in (item.get("Dimensions") or "").split())
    except ValueError:
        dims = ()
    if len(dims) != 2 or min(dims) < 1:
        raise SceneError(f"mesh: {path!r}: the {what} Dimensions {item.get('Dimensions')!r} are not two positive "
                         "integers; allowed: 'rows columns'")
    if dims[0] > limit:
        nodes = dims[0] if what == "geometry" else dims[0] // 2
        raise SceneError(f"mesh: {path!r} has {dims[0]} {'cells' if what == 'topology' else 'nodes'}, about "
                         f"{nodes * SETUP_BYTES_PER_NODE / 1e9:.3g} GB to set up; allowed: at most {limit}")
    ref = (item.text or "").strip()
    file, _, inside = ref.partition(":")
    if not file or not inside.startswith("/"):
        raise SceneError(f"mesh: {path!r}: the {what} reference {ref[:80]!r} is not FILE.h5:/DATASET")
    h5 = os.path.join(os.path.dirname(os.path.abspath(path)), file)
    fd = regular_file(h5)  # a FIFO, a directory or a link loop: one line, never a wait
    try:
        import pyfive

        with _Reader(io.FileIO(fd, "rb")) as fh, pyfive.File(fh) as f:
            dataset = f[inside]
            shape = tuple(dataset.shape)
            if shape != dims:
                raise SceneError(f"mesh: {path!r}: the {what} in {file} has shape {shape}, the XDMF file says {dims}; "
                                 "allowed: the same shape")
            _check_dtype(path, what, dataset.dtype)  # before reading: strings would take gigabytes
            values = np.asarray(dataset[:])
    except SceneError:
        raise
    except Exception as exc:  # noqa: BLE001 - pyfive on a damaged or missing file fails in many ways: one line
        raise SceneError(f"mesh: {path!r}: cannot read its {what} from {file!r} ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0][:120] if str(exc) else ''}); allowed: a readable HDF5 file") from None
    return values


class _Reader(io.BufferedReader):
    """The open .h5 without a `fileno`, so that pyfive reads through it (not the name, since maybe a FIFO)."""

    def fileno(self):
        raise io.UnsupportedOperation("fileno")


def _check_dtype(path: str, what: str, declared) -> None:
    try:
        dtype = np.dtype(declared)  # pyfive gives a tuple for variable-length strings and references
    except TypeError:
        dtype = np.dtype(object)
    numeric = np.issubdtype(dtype, np.integer) or (what == "geometry" and np.issubdtype(dtype, np.floating))
    if not numeric or dtype.itemsize > 8 or dtype.fields is not None:
        dtype = declared if dtype == np.dtype(object) else dtype
        allowed = "integers" if what == "topology" else "floating-point or integer numbers"
        raise SceneError(f"mesh: {path!r}: its {what} holds {dtype} values; allowed: {allowed}")


def _check_shapes(path: str, cells: np.ndarray, points: np.ndarray) -> None:
    if cells.shape[1] != 3:
        raise SceneError(f"mesh: {path!r} has {cells.shape[1]} nodes per cell; allowed: 3 (triangles)")
    if points.shape[1] not in (2, 3):  # the dtypes were checked before reading (`_check_dtype`)
        raise SceneError(f"mesh: {path!r}: its geometry has {points.shape[1]} columns; allowed: 2 or 3 (x, y[, z])")
    if not np.all(np.isfinite(points)):
        raise SceneError(f"mesh: {path!r} has a node with a coordinate that is not finite; allowed: finite numbers")
    largest = float(np.max(np.abs(points), initial=0.0))
    if largest > MAX_COORDINATE:
        raise SceneError(f"mesh: {path!r} has a node coordinate of {largest:.3g}; allowed: coordinates in "
                         f"[-{MAX_COORDINATE:g}, {MAX_COORDINATE:g}]")
    if len(points) < 3:
        raise SceneError(f"mesh: {path!r} has {len(points)} nodes; allowed: at least 3")


def _check_cells(path: str, cells: np.ndarray, n_nodes: int) -> None:
    low, high = int(cells.min()), int(cells.max())
    if low < 0 or high >= n_nodes:
        bad = low if low < 0 else high
        raise SceneError(f"mesh: {path!r} has a cell with node index {bad}; allowed: indices in [0, {n_nodes - 1}] "
                         f"({n_nodes} nodes)")
    cells = np.sort(cells.astype(np.int64), axis=1)
    degenerate = np.flatnonzero((cells[:, 0] == cells[:, 1]) | (cells[:, 1] == cells[:, 2]))
    if degenerate.size:
        raise SceneError(f"mesh: {path!r}: cell {degenerate[0]} repeats a node ({degenerate.size} such cells); "
                         "allowed: three distinct nodes per cell")
    unique, counts = np.unique(cells, axis=0, return_counts=True)
    if unique.shape[0] != cells.shape[0]:
        raise SceneError(f"mesh: {path!r} has {cells.shape[0] - unique.shape[0]} duplicate cell(s) (nodes "
                         f"{unique[np.argmax(counts)].tolist()}); allowed: each cell once")
    edges = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [0, 2]]])
    edge, shared = np.unique(edges, axis=0, return_counts=True)
    if shared.max() > 2:
        raise SceneError(f"mesh: {path!r}: the edge {edge[np.argmax(shared)].tolist()} is in {shared.max()} cells; "
                         "allowed: at most 2 (a surface, not a fan)")
    unused = n_nodes - np.unique(cells).size
    if unused:
        raise SceneError(f"mesh: {path!r} has {n_nodes} nodes and {unused} of them are in no cell; "
                         "allowed: every node in a cell")
