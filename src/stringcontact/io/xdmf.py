"""`solution.xdmf`/`.h5`: the mesh once, and one grid per stored time that carries every field.

Layout (docs/visualisation.md has the reasons)::

    Domain
      Grid "solution" (Collection, Temporal)
        Grid "t=0" (Uniform): Topology + Geometry -> solution.h5:/topology, /geometry (the same for all)
                              Time, and one node Attribute per field -> solution.h5:/eta_0, /velocity_0, ...

Every grid carries all the fields, so ParaView's readers (Xdmf3ReaderT, Xdmf3ReaderS, XDMFReader) give one
grid per time step and meshio's `TimeSeriesReader` reads it. Rank 0 gathers each frame and writes the heavy
data with PETSc's HDF5 viewer (the libhdf5 dolfinx itself uses, in the same process) and the small XML,
appended to per frame (the closing tags are rewritten after each grid), so writing costs O(frames) and the
file is well-formed after every frame. PETSc flushes the HDF5 file after each dataset, so the data a grid
names are on disk before the grid is written. Points are the P1 degrees of freedom in their global
numbering, so the fields need no reordering; the mesh may be 1D (Polyline) or 2D/3D.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import os
import re
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OutputError, one_line

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
#: HDF5 viewers of discarded files that could not be closed (see `XdmfTimeSeries.close`); their files are
#: already removed. Kept referenced, and `_silence_exit` keeps their last words off stderr.
_UNCLOSED = []


def _keep_unclosed(viewer) -> None:
    """Keep `viewer`, whose file HDF5 cannot close, until the process ends, without its noise at exit.

    After one failed flush (a full disk), libhdf5 1.10.8 cannot flush that file again ("slist already
    enabled?" in H5C_set_slist_enabled), so no later close can succeed, with or without free space. What
    is left would print when the process ends: PETSc's error page when PetscFinalize destroys the viewer, and
    libhdf5's ``HDF5: infinite loop closing library`` plus a line of its interfaces from H5close (C atexit,
    printed unconditionally). The command has already reported the one-line error by then.
    """
    if not _UNCLOSED:
        import atexit

        atexit.register(_silence_exit)  # after petsc4py's own atexit handler, so it runs before PetscFinalize
    _UNCLOSED.append(viewer)


def _silence_exit() -> None:
    """Point stderr (fd 2) at /dev/null for the rest of the process's shutdown (see `_keep_unclosed`)."""
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    with contextlib.suppress(OSError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)


@functools.cache
def hdf5_library():
    """The libhdf5 that dolfinx and PETSc loaded (not h5py's bundled copy), through ctypes; None if not found.

    Kept hand-written rather than h5py, measured on bookworm (dolfinx 0.5, libhdf5_openmpi 1.10.8):

    * in the .venv, ``import h5py`` after dolfinx gets the h5py wheel (the tests' meshio needs it; built
      against HDF5 2.0.0) and fails at import: "ValueError: Not a datatype" in h5t, with a warning that it
      runs against HDF5 1.10.8: two libhdf5 versions do not share one process;
    * Debian's h5py (python3-h5py-mpi 3.7.0) picks its serial build unless OMPI_COMM_WORLD_SIZE or
      H5PY_ALWAYS_USE_MPI is set, and the serial build loads libhdf5_serial beside PETSc's libhdf5_openmpi:
      its error switch and object lists would act on the other library. Even the MPI build silences HDF5's
      error printing for the whole process at import (no saved handler to put back, as `Hdf5Quiet` does),
      and its object ids close what they wrap when collected, which PETSc's viewer still owns.
    """
    try:
        with open("/proc/self/maps") as f:
            paths = set(re.findall(r"(/\S*/libhdf5(?:_[a-z]+)?\.so[.\d]*)$", f.read(), re.MULTILINE))
        paths = sorted(p for p in paths if "_hl" not in os.path.basename(p) and ".libs/" not in p)
        if not paths:
            return None
        lib = ctypes.CDLL(paths[0])
        lib.H5Eget_auto2.argtypes = [ctypes.c_int64, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_void_p)]
        lib.H5Eset_auto2.argtypes = [ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p]
        lib.H5Fget_obj_ids.argtypes = [ctypes.c_int64, ctypes.c_uint, ctypes.c_size_t, ctypes.POINTER(ctypes.c_int64)]
        lib.H5Fget_obj_ids.restype = ctypes.c_ssize_t
        lib.H5Oclose.argtypes = [ctypes.c_int64]
        lib.H5Fget_name.argtypes = [ctypes.c_int64, ctypes.c_char_p, ctypes.c_size_t]
        lib.H5Fget_name.restype = ctypes.c_ssize_t
        return lib
    except (OSError, AttributeError):
        return None


class Hdf5Quiet:
    """Turns HDF5's automatic error printing off while the writer runs.

    On a full disk, HDF5 prints a 60-line error stack to stderr before PETSc turns it into an error (a RuntimeError);
    we report one line instead (`describe_os_error`). The switch is HDF5's own H5Eset_auto2 on the libhdf5
    that dolfinx and PETSc loaded (not h5py's bundled copy); where it cannot be found nothing changes.
    """

    @classmethod
    def _library(cls):
        return hdf5_library()

    def __init__(self):
        self.saved = None

    def __enter__(self):
        lib = self._library()
        if lib is not None:
            func, data = ctypes.c_void_p(), ctypes.c_void_p()
            if lib.H5Eget_auto2(0, ctypes.byref(func), ctypes.byref(data)) >= 0:  # 0 is H5E_DEFAULT
                self.saved = (func, data)
                lib.H5Eset_auto2(0, None, None)
        return self

    def __exit__(self, *exc):
        if self.saved is not None:
            self._library().H5Eset_auto2(0, self.saved[0], self.saved[1])
            self.saved = None
        return False




def _close_open_objects(path: Path) -> None:
    """Close the HDF5 datasets and groups of file `path` left open: PETSc's VecView leaves them open when
    its write fails, and then cannot close the file ("there are objects still open")."""
    lib = hdf5_library()
    if lib is None:
        return
    ids, name = (ctypes.c_int64 * 64)(), ctypes.create_string_buffer(4096)
    n = lib.H5Fget_obj_ids(0x1F, 0x2 | 0x4, 64, ids)  # in every file (H5F_OBJ_ALL): datasets and groups
    for k in range(max(n, 0)):
        if lib.H5Fget_name(ids[k], name, len(name)) > 0 and name.value == os.fsencode(path):
            lib.H5Oclose(ids[k])


#: Room kept free beyond a write's own bytes: HDF5's object headers, B-tree nodes and its closing flush.
HDF5_MARGIN = 32 * 1024


def _check_room(folder: Path, nbytes: int) -> None:
    """Raise ENOSPC before a write that the device of `folder` has no room for.

    libhdf5 1.10.8 cannot flush a file again after one flush failed on a full disk, so such a file can never
    be closed (`_keep_unclosed`); refusing the write before HDF5 starts it keeps the file closable. A race
    with other writers can still fill the disk in between: `_keep_unclosed` is the fallback.
    """
    try:
        st = os.statvfs(folder)
    except OSError:
        return
    if st.f_bavail * st.f_frsize < nbytes + HDF5_MARGIN:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(folder))


@contextlib.contextmanager
def stderr_held(replay: bool = True):
    """Hold back what C libraries print to stderr; print it after the block (if `replay`), or drop it if the
    block fails.

    Open MPI's MPI-IO layer, which PETSc's HDF5 viewer writes through, prints its own line for a failed
    write ("mca_fbtl_posix_pwritev: ... No space left on device"); the caller reports one line instead.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with tempfile.TemporaryFile() as held:
            os.dup2(held.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
            held.seek(0)
            text = held.read()
            if text and replay:
                os.write(2, text)
    finally:
        os.close(saved)


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
        self.viewer = self.vec = self.xml = None
        points, cells = self._gather(mesh.points), self._gather(mesh.cells)
        try:
            self._on_root(self._open, Path(folder) / f"{stem}.xdmf", points, cells)
        except BaseException:  # the viewer may be open already (the mesh did not fit): close it, quietly
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
        # bytes: petsc4py encodes a str as strict UTF-8, and a Linux file name need not be UTF-8
        self.viewer = PETSc.Viewer().createHDF5(os.fsencode(self.h5path), "w", comm=PETSc.COMM_SELF)
        self.vec = PETSc.Vec().createSeq(self.mesh.n_points, comm=PETSc.COMM_SELF)
        self._view(PETSc.Vec().createWithArray(points.ravel(), bsize=3, comm=PETSc.COMM_SELF), "geometry")
        topology = PETSc.IS().createGeneral(cells.ravel().astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        topology.setBlockSize(cells.shape[1])
        self._view(topology, "topology")
        self.int_bytes = np.dtype(PETSc.IntType).itemsize
        self.xml = open(xml_path, "w+")  # noqa: SIM115 - kept open, appended per frame
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
        gathered = {name: self._gather(values) for name, values in fields.items()}
        self._on_root(self._write_frame, t, gathered)
        self.frames += 1

    def _write_frame(self, t: float, fields: dict) -> None:
        _check_room(self.h5path.parent, sum(np.asarray(v).nbytes for v in fields.values()))
        names = []
        for name, values in fields.items():
            self.vec.array[:] = values
            dataset = f"{name}_{self.frames}"
            self._view(self.vec, dataset)
            names.append((name, dataset))
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

        `discard`: the files are about to be removed after a failed write (a full disk): empty the HDF5
        file, so that PETSc's closing flush finds room, close what the failed write left open, and never
        raise. A viewer that still cannot be closed is kept until the process ends (`_keep_unclosed`).
        """
        if discard:
            if self.comm.rank == 0:
                self._close_root(discard=True)
            return
        self._on_root(self._close_root)

    def _close_root(self, discard: bool = False) -> None:
        viewer, self.viewer = self.viewer, None
        xml, self.xml = self.xml, None
        if xml is not None:
            xml.close()
        if viewer is None:
            return
        try:
            with stderr_held(replay=not discard):
                if discard:
                    with contextlib.suppress(OSError):
                        os.truncate(self.h5path, 0)
                    _close_open_objects(self.h5path)
                viewer.destroy()
        except RuntimeError:
            if not discard:
                self.viewer = viewer  # still open: close(discard=True) can close it
                raise
            _keep_unclosed(viewer)
            return
        self.vec.destroy()


def _portable(exc):
    """`exc` as an exception any rank can rebuild (petsc4py's Error does not pickle): OSError or RuntimeError."""
    if exc is None:
        return None
    if isinstance(exc, OSError):
        return OSError(exc.errno, exc.strerror or str(exc))
    return RuntimeError(one_line(exc, 300))


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
