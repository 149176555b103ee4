"""A mesh file's topology and geometry, checked before dolfinx sees them.

dolfinx's `create_mesh` trusts its input: a cell index out of range (10**6 on 81 nodes, or -5) leaves it
spinning in C++, deaf to Ctrl-C and SIGTERM, and duplicate cells corrupt its heap (a segfault or
``malloc(): unsorted double linked list corrupted``). So the XDMF file's first grid is read here with pyfive
(pure Python: h5py's wheel clashes with the libhdf5 dolfinx loads) and refused, in one line naming
``mesh``, unless it is a plain triangle mesh: data in an HDF5 file, the shapes the XML states, integer cell
indices in [0, nodes), three distinct nodes per cell, no cell twice, no edge in more than two cells,
every node in a cell, finite coordinates, and at most `MAX_NODES` nodes and `MAX_CELLS` cells.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import numpy as np

from ..errors import SceneError
from ..scene.limits import MAX_MEMBRANE_NODES, SETUP_BYTES_PER_NODE

__all__ = ["check", "MAX_NODES", "MAX_CELLS"]

#: The largest mesh file: as many nodes as the largest membrane (the set-up's memory, scene.limits), and twice
#: as many cells (a triangulation has about two cells per node).
MAX_NODES = MAX_MEMBRANE_NODES
MAX_CELLS = 2 * MAX_MEMBRANE_NODES


def check(path: str, name: str) -> None:
    """Refuse (SceneError, one line) a mesh file whose grid `name` is not a valid 2D triangle mesh."""
    grid = _grid(path, name)
    cells = _data(path, grid.find("Topology"), "topology", MAX_CELLS)
    points = _data(path, grid.find("Geometry"), "geometry", MAX_NODES)
    _check_shapes(path, cells, points)
    _check_cells(path, cells, len(points))


def _grid(path: str, name: str):
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"mesh: {path!r} is not an XDMF mesh file ({exc}); allowed: an XDMF triangle mesh") from None
    for grid in root.iter("Grid"):
        if grid.get("Name", "mesh") == name and grid.find("Topology") is not None:
            return grid
    raise SceneError(f"mesh: {path!r} holds no grid {name!r} with a topology; allowed: an XDMF triangle mesh")


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
    try:
        import pyfive

        with pyfive.File(h5) as f:
            dataset = f[inside]
            shape = tuple(dataset.shape)
            if shape != dims:
                raise SceneError(f"mesh: {path!r}: the {what} in {file} has shape {shape}, the XDMF file says {dims}; "
                                 "allowed: the same shape")
            values = np.asarray(dataset[:])
    except SceneError:
        raise
    except Exception as exc:  # noqa: BLE001 - pyfive on a damaged or missing file fails in many ways: one line
        raise SceneError(f"mesh: {path!r}: cannot read its {what} from {file!r} ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0][:120] if str(exc) else ''}); allowed: a readable HDF5 file") from None
    return values


def _check_shapes(path: str, cells: np.ndarray, points: np.ndarray) -> None:
    if cells.shape[1] != 3:
        raise SceneError(f"mesh: {path!r} has {cells.shape[1]} nodes per cell; allowed: 3 (triangles)")
    if not np.issubdtype(cells.dtype, np.integer):
        raise SceneError(f"mesh: {path!r}: its cell indices are {cells.dtype}; allowed: integers")
    if points.shape[1] not in (2, 3) or not np.issubdtype(points.dtype, np.number):
        raise SceneError(f"mesh: {path!r}: its geometry has {points.shape[1]} columns; allowed: 2 or 3 (x, y[, z])")
    if not np.all(np.isfinite(points)):
        raise SceneError(f"mesh: {path!r} has a node with a coordinate that is not finite; allowed: finite numbers")
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
