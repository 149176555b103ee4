"""`solution.xdmf`/`.h5`: the mesh once, and one grid per stored time that carries every field.

Layout (docs/visualisation.md has the reasons)::

    Domain
      Grid "solution" (Collection, Temporal)
        Grid "t=0" (Uniform): Topology + Geometry -> solution.h5:/topology, /geometry (the same for all)
                              Time, and one node Attribute per field -> solution.h5:/eta_0, /velocity_0, ...

Every grid carries all the fields, so ParaView's readers (Xdmf3ReaderT, Xdmf3ReaderS, XDMFReader) give one
grid per time step and meshio's `TimeSeriesReader` reads it. The heavy data are written collectively by
PETSc's HDF5 viewer (the libhdf5 dolfinx itself uses, in the same process, under MPI too); the small XML is
written by rank 0 and appended to per frame (the closing tags are rewritten after each grid), so writing
costs O(frames) and the file is well-formed after every frame. PETSc flushes the HDF5 file after each
dataset (an fsync under MPI-IO), so the data a grid names are on disk before the grid is written. Points are the P1 degrees of freedom in
their global numbering, so the fields need no reordering; the mesh may be 1D (Polyline) or 2D/3D.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import OutputError, one_line

#: dolfinx cell type -> (XDMF topology type, nodes per cell) for P1 meshes.
TOPOLOGY_TYPES = {
    "interval": ("Polyline", 2),
    "triangle": ("Triangle", 3),
    "quadrilateral": ("Quadrilateral", 4),
    "tetrahedron": ("Tetrahedron", 4),
    "hexahedron": ("Hexahedron", 8),
}
COLLECTION = "solution"
_FOOTER = "    </Grid>\n  </Domain>\n</Xdmf>\n"


@dataclass
class MeshArrays:
    """This rank's share of a P1 mesh: owned points (global dof order) and owned cells (global dof indices)."""

    points: np.ndarray  # (n_owned, 3) float64
    cells: np.ndarray  # (n_owned_cells, nodes per cell), global indices
    topology_type: str
    n_points: int  # over all ranks
    n_cells: int


def mesh_arrays(V, comm) -> MeshArrays:
    """The owned points and cells of a scalar P1 space, numbered by its global dofs."""
    from . import compat

    msh = V.mesh
    name = msh.topology.cell_type.name
    if name not in TOPOLOGY_TYPES or V.dofmap.index_map_bs != 1:
        raise OutputError(f"solution.xdmf: cannot write a {name} mesh with block size {V.dofmap.index_map_bs}")
    topology_type, per_cell = TOPOLOGY_TYPES[name]
    index_map = V.dofmap.index_map
    n_owned = index_map.size_local
    owned_cells = msh.topology.index_map(msh.topology.dim).size_local
    local = compat.cell_dofs(V)[:owned_cells]
    if local.shape[1] != per_cell:
        raise OutputError(f"solution.xdmf: expected a P1 space ({per_cell} dofs per {name}), got {local.shape[1]}")
    cells = np.asarray(index_map.local_to_global(local.ravel().astype(np.int32))).reshape(local.shape)
    points = np.ascontiguousarray(V.tabulate_dof_coordinates()[:n_owned], dtype=np.float64)
    return MeshArrays(points, cells, topology_type, index_map.size_global, comm.allreduce(owned_cells))


class XdmfTimeSeries:
    """Writes the layout above: ``XdmfTimeSeries(folder, mesh, comm)``, ``.write(t, fields)``, ``.close()``.

    Collective: every rank calls each method with its owned values. Errors come as RuntimeError (petsc4py's
    Error) or OSError, for the caller to report.
    """

    def __init__(self, folder, mesh: MeshArrays, comm, stem: str = "solution"):
        from petsc4py import PETSc

        self.comm, self.mesh, self.frames = comm, mesh, 0
        self.h5name = f"{stem}.h5"
        self.viewer = PETSc.Viewer().createHDF5(str(Path(folder) / self.h5name), "w", comm=comm)
        self.vec = PETSc.Vec().createMPI((len(mesh.points), mesh.n_points), comm=comm)
        self._view(PETSc.Vec().createWithArray(mesh.points.ravel(), bsize=3, comm=comm), "geometry")
        topology = PETSc.IS().createGeneral(mesh.cells.ravel().astype(PETSc.IntType), comm=comm)
        topology.setBlockSize(mesh.cells.shape[1])
        self._view(topology, "topology")
        self.int_bytes = np.dtype(PETSc.IntType).itemsize
        self.xml = None
        if comm.rank == 0:
            self.xml = open(Path(folder) / f"{stem}.xdmf", "w+")  # noqa: SIM115 - kept open, appended per frame
            self.xml.write(f'<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n    <Grid Name="{COLLECTION}" GridType="Collection" CollectionType="Temporal">\n')
            self._end_xml()

    def _view(self, obj, name: str) -> None:
        obj.setName(name)
        obj.view(self.viewer)

    def _end_xml(self) -> None:
        """Write the closing tags after the last grid; the next grid overwrites them."""
        self.body_end = self.xml.tell()
        self.xml.write(_FOOTER)
        self.xml.truncate()
        self.xml.flush()

    def write(self, t: float, fields: dict) -> None:
        """One grid at time `t` with every field of `fields` ({name: owned values}) as a node attribute."""
        names = []
        for name, values in fields.items():
            self.vec.array[:] = values
            dataset = f"{name}_{self.frames}"
            self._view(self.vec, dataset)
            names.append((name, dataset))
        if self.xml is not None:
            self.xml.seek(self.body_end)
            self.xml.write(self._grid(t, names))
            self._end_xml()
        self.frames += 1

    def _grid(self, t: float, names) -> str:
        m, h5 = self.mesh, self.h5name
        per_cell = m.cells.shape[1]
        lines = [
            f'      <Grid Name="t={float(t)!r}" GridType="Uniform">',
            f'        <Topology TopologyType="{m.topology_type}" NumberOfElements="{m.n_cells}" NodesPerElement="{per_cell}">',
            f'          <DataItem DataType="Int" Precision="{self.int_bytes}" Dimensions="{m.n_cells} {per_cell}" Format="HDF">{h5}:/topology</DataItem>',
            "        </Topology>",
            '        <Geometry GeometryType="XYZ">',
            f'          <DataItem DataType="Float" Precision="8" Dimensions="{m.n_points} 3" Format="HDF">{h5}:/geometry</DataItem>',
            "        </Geometry>",
            f'        <Time Value="{float(t)!r}"/>',
        ]
        for name, dataset in names:
            lines += [
                f'        <Attribute Name="{name}" AttributeType="Scalar" Center="Node">',
                f'          <DataItem DataType="Float" Precision="8" Dimensions="{m.n_points}" Format="HDF">{h5}:/{dataset}</DataItem>',
                "        </Attribute>",
            ]
        lines.append("      </Grid>\n")
        return "\n".join(lines)

    def close(self) -> None:
        """Close both files (collective). Safe to call twice."""
        viewer, self.viewer = self.viewer, None
        if viewer is not None:
            viewer.destroy()
            self.vec.destroy()
        xml, self.xml = self.xml, None
        if xml is not None:
            xml.close()


# --- reading the XML back -------------------------------------------------------------------------------


def read_xdmf(path) -> tuple[str | None, dict[str, list[tuple[float, str]]]]:
    """The mesh and the time series of `solution.xdmf`: ``(geometry, series)``.

    `geometry` is the HDF5 reference of the first grid's point coordinates (``"solution.h5:/geometry"``;
    None if there is no grid); `series` is {field: [(t, "solution.h5:/eta_0"), ...]} in file order. Raises
    OutputError naming the file, with the parser's error as its ``__cause__``, if the file is not
    well-formed XML (a truncated write), has no temporal collection, or holds a time that is not a number.
    """
    try:
        root = ET.parse(path).getroot()
        collection = root.find("Domain/Grid[@CollectionType='Temporal']")
        if collection is None:
            raise ValueError("no temporal collection of grids")
        geometry, series = None, {}
        for grid in collection.findall("Grid"):
            t = float(grid.find("Time").get("Value"))
            if geometry is None:
                geometry = (grid.find("Geometry/DataItem").text or "").strip() or None
            for attribute in grid.findall("Attribute"):
                ref = (attribute.find("DataItem").text or "").strip()
                series.setdefault(attribute.get("Name"), []).append((t, ref))
    except (ET.ParseError, OSError, TypeError, ValueError, AttributeError) as exc:
        raise OutputError(f"{path} is not a readable XDMF file ({one_line(exc, 300)})") from exc
    return geometry, series


def xdmf_series(path) -> dict[str, list[tuple[float, str]]]:
    """The time series of `solution.xdmf`, {field: [(t, "solution.h5:/eta_0"), ...]} (see `read_xdmf`)."""
    return read_xdmf(path)[1]
