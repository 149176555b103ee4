"""`solution.xdmf`/`.h5`: the mesh once, and one grid per stored time that carries every field.

Layout (docs/explanation/visualisation.md has the reasons)::

    Domain
      Grid "solution" (Collection, Temporal)
        Grid "t=0" (Uniform): Topology + Geometry -> solution.h5:/topology, /geometry (the same for all)
                              Time, and one node Attribute per field -> solution.h5:/eta_0, /velocity_0, ...

Every grid carries all the fields, so ParaView's readers (Xdmf3ReaderT, Xdmf3ReaderS, XDMFReader) give one
grid per time step and meshio's `TimeSeriesReader` reads it. Rank 0 gathers each frame and writes the heavy
data through the libhdf5 dolfinx itself uses, in the same process (`io.hdf5.Hdf5File`), and the small XML,
appended to per frame (the closing tags are rewritten after each grid), so writing costs O(frames) and the
file is well-formed after every frame. The HDF5 file is flushed to the OS after each frame, before its grid
is written, so the data a grid names are there for any reader. Points are the P1 degrees of freedom in their global
numbering, so the fields need no reordering; the mesh may be 1D (Polyline) or 2D/3D. `io.readback.read_xdmf`
reads the XML back.
"""

from __future__ import annotations

import errno
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OutputError, one_line
from .hdf5 import Hdf5File, stderr_held

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


#: Room kept free beyond a write's own bytes: HDF5's object headers, B-tree nodes and its closing flush.
HDF5_MARGIN = 32 * 1024


def _check_room(folder: Path, nbytes: int) -> None:
    """Raise ENOSPC before a write that the device of `folder` has no room for.

    HDF5 meeting a full disk is survivable (`Hdf5File._reserve`, `Hdf5File.discard`), but libhdf5 1.10.8
    prints its own lines at exit after a failed H5Fcreate (`_silence_exit_later`); refusing the write before
    HDF5 starts it keeps that for the race with another program filling the disk in between.
    """
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


def mesh_arrays(V, comm) -> MeshArrays:
    """The owned points and cells of a scalar P1 space, numbered by its global dofs."""
    from ..fem import compat

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

    Collective: every rank calls each method with its owned values; rank 0 gathers them (in global dof
    order: the ranks own consecutive ranges) and writes both files alone. A file written collectively by
    all ranks hangs the run when the disk fills on one rank only. An error on rank 0 is raised on every
    rank: RuntimeError (petsc4py's Error) or OSError, for the caller to report.
    """

    def __init__(self, folder, mesh: MeshArrays, comm, stem: str = "solution"):
        self.comm, self.mesh, self.frames = comm, mesh, 0
        self.h5name = f"{stem}.h5"
        self.h5path = Path(folder) / self.h5name
        self.h5 = self.xml = None
        points, cells = self._gather(mesh.points), self._gather(mesh.cells)
        try:
            self._on_root(self._open, Path(folder) / f"{stem}.xdmf", points, cells)
        except BaseException:  # the HDF5 file may be open already (the mesh did not fit): close it, quietly
            self.close(discard=True)
            raise

    def _gather(self, values):
        parts = self.comm.gather(np.asarray(values), root=0) if self.comm.size > 1 else [values]
        return np.concatenate(parts) if self.comm.rank == 0 else None

    def _on_root(self, action, *args) -> None:
        """`action(*args)` on rank 0 with stderr held; its error is raised on every rank."""
        failure = None
        if self.comm.rank == 0:
            try:
                with stderr_held():
                    action(*args)
            except (RuntimeError, OSError) as exc:
                failure = exc
        if self.comm.size > 1:
            shared = self.comm.bcast(_portable(failure), root=0)
            failure = failure if self.comm.rank == 0 else shared
        if failure is not None:
            raise failure

    def _open(self, xml_path: Path, points, cells) -> None:
        from petsc4py import PETSc

        _check_room(xml_path.parent, points.nbytes + cells.nbytes)
        # PETSc's integer: the type PETSc's own HDF5 viewer writes the topology in
        topology = cells.astype(PETSc.IntType)
        self.h5 = Hdf5File(self.h5path)
        self.h5.write("geometry", points.astype(np.float64))
        self.h5.write("topology", topology)
        self.h5.flush()
        self.int_bytes = topology.dtype.itemsize
        self.xml = open(xml_path, "w+")  # noqa: SIM115 - kept open, appended per frame
        self.xml.write(f'<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n    <Grid Name="{COLLECTION}" GridType="Collection" CollectionType="Temporal">\n')
        self._end_xml()

    def _end_xml(self) -> None:
        """Write the closing tags after the last grid; the next grid overwrites them."""
        self.body_end = self.xml.tell()
        self.xml.write(_FOOTER)
        self.xml.truncate()
        self.xml.flush()

    def write(self, t: float, fields: dict) -> None:
        """One grid at time `t` with every field of `fields` ({name: owned values}) as a node attribute."""
        gathered = {name: self._gather(values) for name, values in fields.items()}
        self._on_root(self._write_frame, t, gathered)
        self.frames += 1

    def _write_frame(self, t: float, fields: dict) -> None:
        _check_room(self.h5path.parent, sum(np.asarray(v).nbytes for v in fields.values()))
        names = []
        for name, values in fields.items():
            dataset = f"{name}_{self.frames}"
            self.h5.write(dataset, np.asarray(values, dtype=np.float64))
            names.append((name, dataset))
        self.h5.flush()  # the grid below names only data a reader can see
        self.xml.seek(self.body_end)
        self.xml.write(self._grid(t, names))
        self._end_xml()

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

    def close(self, discard: bool = False) -> None:
        """Close both files (collective). Safe to call twice.

        `discard`: the files are about to be removed after a failed write (a full disk): close them
        whatever room is left (`Hdf5File.discard`), and never raise.
        """
        if discard:
            if self.comm.rank == 0:
                self._close_root(discard=True)
            return
        self._on_root(self._close_root)

    def _close_root(self, discard: bool = False) -> None:
        h5, self.h5 = self.h5, None
        xml, self.xml = self.xml, None
        if xml is not None:
            xml.close()
        if h5 is None:
            return
        if discard:
            with stderr_held(replay=False):
                h5.discard()
            return
        try:
            with stderr_held():
                h5.close()
        except (RuntimeError, OSError):
            self.h5 = h5  # still open: close(discard=True) closes it
            raise


def _portable(exc):
    """`exc` as an exception any rank can rebuild (petsc4py's Error does not pickle): OSError or RuntimeError."""
    if exc is None:
        return None
    if isinstance(exc, OSError):
        return OSError(exc.errno, exc.strerror or str(exc))
    return RuntimeError(one_line(exc, 300))
