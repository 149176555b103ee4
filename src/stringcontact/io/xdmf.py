"""`solution.xdmf`/`.h5`: a temporal collection of grids, one per stored time, each naming the mesh (written once)
and every field as a node Attribute, as ParaView and meshio read them (docs/explanation/visualisation.md). Each grid
is appended after its data are flushed and the closing tags rewritten: a reader sees a well-formed series after every
frame, and writing costs O(frames). Points are the P1 dofs in their global numbering."""

from __future__ import annotations

import errno
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..fem.agree import one_outcome
from .hdf5 import Hdf5File

#: dolfinx cell type -> (XDMF topology type, nodes per cell) for P1 meshes.
TOPOLOGY_TYPES = {"interval": ("Polyline", 2), "triangle": ("Triangle", 3), "quadrilateral": ("Quadrilateral", 4),
                  "tetrahedron": ("Tetrahedron", 4), "hexahedron": ("Hexahedron", 8)}
_FOOTER = "    </Grid>\n  </Domain>\n</Xdmf>\n"
#: Room kept free beyond a write's own bytes: HDF5's object headers, B-tree nodes and its closing flush.
HDF5_MARGIN = 32 * 1024


def _check_room(folder: Path, nbytes: int) -> None:
    """ENOSPC before a write `folder`'s device has no room for: HDF5 meets a full disk only in a race (the dolfinx
    wheel's libhdf5 1.14 aborts the process there)."""
    try:
        st = os.statvfs(folder)
    except OSError:
        return
    if st.f_bavail * st.f_frsize < nbytes + HDF5_MARGIN:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(folder))


@dataclass
class MeshArrays:
    """This rank's share of a P1 mesh: owned points (global dof order) and owned cells (global dof indices)."""

    points: np.ndarray  # (n_owned, 3) float64
    cells: np.ndarray  # (n_owned_cells, nodes per cell), global indices
    topology_type: str
    n_points: int  # over all ranks
    n_cells: int


def global_cells(V) -> np.ndarray:
    """This rank's owned cells as the global dof numbers of their nodes (a scalar space `V`)."""
    from ..fem import compat

    local = compat.cell_dofs(V)[:V.mesh.topology.index_map(V.mesh.topology.dim).size_local]
    return np.asarray(V.dofmap.index_map.local_to_global(local.ravel().astype(np.int32))).reshape(local.shape)


def mesh_arrays(V, comm) -> MeshArrays:
    """The owned points and cells of a scalar P1 space, numbered by its global dofs."""
    name = V.mesh.topology.cell_type.name
    if name not in TOPOLOGY_TYPES or V.dofmap.index_map_bs != 1:
        raise OutputError(f"solution.xdmf: cannot write a {name} mesh with block size {V.dofmap.index_map_bs}")
    topology_type, per_cell = TOPOLOGY_TYPES[name]
    cells, index_map = global_cells(V), V.dofmap.index_map
    if cells.shape[1] != per_cell:
        raise OutputError(f"solution.xdmf: expected a P1 space ({per_cell} dofs per {name}), got {cells.shape[1]}")
    points = np.ascontiguousarray(V.tabulate_dof_coordinates()[:index_map.size_local], dtype=np.float64)
    return MeshArrays(points, cells, topology_type, index_map.size_global, comm.allreduce(len(cells)))


class XdmfTimeSeries:
    """``XdmfTimeSeries(folder, mesh, comm)``, ``.write(t, fields)``, ``.close()``, all collective: rank 0 gathers
    and writes alone (files written by all ranks hang the run when the disk fills on one rank only); its error is
    raised on every rank."""

    def __init__(self, folder, mesh: MeshArrays, comm, stem: str = "solution"):
        self.comm, self.mesh, self.frames = comm, mesh, 0
        self.h5name = f"{stem}.h5"
        self.h5path = Path(folder) / self.h5name
        self.h5 = self.xml = None
        points, cells = self._gather(mesh.points), self._gather(mesh.cells)
        try:
            one_outcome(comm, self._open, Path(folder) / f"{stem}.xdmf", points, cells, root=0)
        except BaseException:  # the HDF5 file may be open already (the mesh did not fit)
            self.close(discard=True)
            raise

    def _gather(self, values):
        parts = self.comm.gather(np.asarray(values), root=0) if self.comm.size > 1 else [values]
        return np.concatenate(parts) if self.comm.rank == 0 else None

    def _open(self, xml_path: Path, points, cells) -> None:
        from petsc4py import PETSc

        _check_room(xml_path.parent, points.nbytes + cells.nbytes)
        topology = cells.astype(PETSc.IntType)  # the type PETSc's own HDF5 viewer writes the topology in
        self.h5 = Hdf5File(self.h5path)
        self.h5.write("geometry", points.astype(np.float64))
        self.h5.write("topology", topology)
        self.h5.flush()
        self.int_bytes = topology.dtype.itemsize
        self.xml = open(xml_path, "w+")  # noqa: SIM115 - kept open, appended per frame
        self.xml.write('<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n    <Grid Name="solution" '
                       'GridType="Collection" CollectionType="Temporal">\n')
        self._end_xml()

    def _end_xml(self) -> None:
        """The closing tags after the last grid; the next grid overwrites them."""
        self.body_end = self.xml.tell()
        self.xml.write(_FOOTER)
        self.xml.truncate()
        self.xml.flush()

    def write(self, t: float, fields: dict) -> None:
        """One grid at time `t` with every field of `fields` ({name: owned values}) as a node attribute."""
        gathered = {name: self._gather(values) for name, values in fields.items()}
        one_outcome(self.comm, self._write_frame, t, gathered, root=0)
        self.frames += 1

    def _write_frame(self, t: float, fields: dict) -> None:
        _check_room(self.h5path.parent, sum(np.asarray(v).nbytes for v in fields.values()))
        for name, values in fields.items():
            self.h5.write(f"{name}_{self.frames}", np.asarray(values, dtype=np.float64))
        self.h5.flush()  # the grid below names only data a reader can see
        self.xml.seek(self.body_end)
        self.xml.write(self._grid(t, fields))
        self._end_xml()

    def _grid(self, t: float, fields) -> str:
        m, h5, per_cell = self.mesh, self.h5name, self.mesh.cells.shape[1]
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
        for name in fields:
            lines += [f'        <Attribute Name="{name}" AttributeType="Scalar" Center="Node">',
                      f'          <DataItem DataType="Float" Precision="8" Dimensions="{m.n_points}" Format="HDF">{h5}:/{name}_{self.frames}</DataItem>',
                      "        </Attribute>"]
        return "\n".join([*lines, "      </Grid>\n"])

    def close(self, discard: bool = False) -> None:
        """Close both files (collective; safe twice). `discard`: they are about to be removed after a failed write:
        closed by rank 0 whatever room is left, never raising."""
        if not discard:
            one_outcome(self.comm, self._close_root, root=0)
        elif self.comm.rank == 0:
            self._close_root(discard=True)

    def _close_root(self, discard: bool = False) -> None:
        if self.xml is not None:
            self.xml.close()
            self.xml = None
        if self.h5 is not None:  # a failed close keeps it open: close(discard=True) closes it
            (self.h5.discard if discard else self.h5.close)()
            self.h5 = None
