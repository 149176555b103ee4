"""The mesh of a scene's domain and its boundary: the string's interval or a membrane's 2D domain.

``interval`` is today's `mesh.create_interval` (the 1D numbers do not change); ``rectangle`` is
`mesh.create_rectangle` with [0, Lx] x [0, Ly]; ``disk`` is meshed by gmsh on rank 0 and handed to
`mesh.create_mesh`, which distributes it; ``file`` reads an XDMF triangle mesh (`meshfile.read`, handed to `mesh.create_mesh` as arrays). A mesh that is not a
mesh, that is 3D, or that has no area is refused with a one-line `SceneError` naming ``mesh``.
"""

from __future__ import annotations

import math
import signal
import threading

import dolfinx.fem.petsc  # noqa: F401 - dolfinx 0.9 no longer imports the PETSc layer with dolfinx.fem
import numpy as np
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SceneError
from . import compat, meshfile
from .agree import one_outcome

__all__ = ["boundary_dofs", "create", "nodal_areas"]


def create(scene, comm):
    """The dolfinx mesh of `scene.domain` on `comm` (checked: 2D meshes have positive cell areas)."""
    if scene.domain == "interval":
        return mesh.create_interval(comm, scene.nx, [0.0, scene.length])
    if scene.domain == "rectangle":
        msh = mesh.create_rectangle(comm, [np.zeros(2), np.array(scene.size)], list(scene.cells), mesh.CellType.triangle)
    elif scene.domain == "disk":
        msh = _disk(comm, scene.radius, scene.mesh_size)
    else:
        msh = _read(comm, scene.mesh)
    _check_areas(msh, comm, scene.mesh or scene.domain)
    return msh


def _disk(comm, radius: float, size: float):
    """gmsh's triangulation of the disk of `radius` centred at 0, made on rank 0 and distributed."""
    cells, x = one_outcome(comm, _gmsh_disk, radius, size, root=0) or (np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2)))
    return compat.create_mesh(comm, cells, x, compat.coordinate_domain("triangle", 2))


def _gmsh_disk(radius: float, size: float) -> tuple[np.ndarray, np.ndarray]:
    """(cells, points) of gmsh's disk mesh, with only the nodes that the triangles use."""
    held = signal.getsignal(signal.SIGINT) if threading.current_thread() is threading.main_thread() else None
    import gmsh  # its import sets SIGINT to the default action: the CLI's handler is put back below

    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("disk")
        gmsh.model.occ.addDisk(0.0, 0.0, 0.0, radius, radius)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.5 * size)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        types, _, nodes = gmsh.model.mesh.getElements(dim=2)
        triangles = np.asarray(nodes[list(types).index(2)], dtype=np.int64).reshape(-1, 3)
    finally:
        gmsh.finalize()
        if held is not None:
            signal.signal(signal.SIGINT, held)
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    used = np.unique(triangles)
    index[used] = np.arange(used.size)
    order = np.argsort(tags)  # getNodes does not promise sorted tags
    points = coords.reshape(-1, 3)[order][np.searchsorted(tags[order], used), :2]
    return index[triangles], np.ascontiguousarray(points)


def _read(comm, path: str):
    """An XDMF triangle mesh, read and checked on rank 0 (`meshfile.read`) and handed to `mesh.create_mesh` as
    arrays, which distributes it: dolfinx's own XDMF reader is never given the file (it may read another file
    than the one checked, and hangs or crashes on a bad one)."""
    cells, x = one_outcome(comm, meshfile.read, path, root=0) or (np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2)))
    return compat.create_mesh(comm, cells, x, compat.coordinate_domain("triangle", 2))


def _check_areas(msh, comm, label: str) -> None:
    """Refuse a mesh with a cell of zero area (a degenerate triangle; a domain of zero area has only such)."""
    W = compat.function_space(msh, "DG", 0)
    areas = _assemble(W, msh)
    n = msh.topology.index_map(msh.topology.dim).size_local
    smallest, total = comm.allreduce(float(np.min(areas[:n], initial=math.inf)), op=MPI.MIN), comm.allreduce(float(areas[:n].sum()))
    if not total > 0.0:
        raise SceneError(f"mesh: the domain of {label!r} has zero area; allowed: a triangle mesh of positive area")
    if not smallest > 1e-12 * total:
        raise SceneError(f"mesh: {label!r} has cells of zero area (smallest {smallest:.3g} of total {total:.3g}); "
                         "allowed: a triangle mesh without degenerate cells")


def _assemble(V, msh) -> np.ndarray:
    """∫ φ_i dx for the basis functions of V, on the owned dofs (ghost contributions added to their owners)."""
    import ufl

    vec = fem.petsc.assemble_vector(fem.form(ufl.TestFunction(V) * ufl.dx(domain=msh)))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return vec.array.copy()


def nodal_areas(V) -> np.ndarray:
    """The lumped weights ∫ φ_i dx of the owned P1 dofs: the area a node stands for (contact area)."""
    return _assemble(V, V.mesh)


def boundary_dofs(V) -> np.ndarray:
    """Owned dofs on the exterior facets of a 2D mesh.

    A rank may own a boundary node without holding a facet of the boundary next to it; the marks are
    therefore added to their owners (a reverse scatter) before the owned ones are read.
    """
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    facets = mesh.exterior_facet_indices(msh.topology)
    dofs = fem.locate_dofs_topological(V, tdim - 1, facets)
    mark = fem.Function(V)
    mark.x.array[dofs] = 1.0
    compat.petsc_vec(mark).ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    n_owned = V.dofmap.index_map.size_local
    return np.flatnonzero(mark.x.array[:n_owned] > 0).astype(np.int32)
