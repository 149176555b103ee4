"""The mesh of a scene's domain and its boundary: dolfinx's interval and rectangle, gmsh's disk or an XDMF triangle
mesh (`meshfile.read`), the last two made on rank 0 and distributed by `mesh.create_mesh`."""

from __future__ import annotations

import math
import signal
import threading

import dolfinx.fem.petsc  # noqa: F401 - dolfinx 0.9 no longer imports the PETSc layer with dolfinx.fem
import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SceneError
from . import compat, meshfile
from .agree import one_outcome
from .operators import assemble_vector

__all__ = ["boundary_dofs", "create", "nodal_areas"]


def create(scene, comm):
    """The dolfinx mesh of `scene.domain` on `comm` (checked: 2D meshes have positive cell areas)."""
    if scene.domain == "interval":
        return mesh.create_interval(comm, scene.nx, [0.0, scene.length])
    if scene.domain == "rectangle":
        msh = mesh.create_rectangle(comm, [np.zeros(2), np.array(scene.size)], list(scene.cells), mesh.CellType.triangle)
    else:  # made on rank 0 and distributed; dolfinx's XDMF reader is never given a file (it may read another one)
        disk = scene.domain == "disk"
        args = (_gmsh_disk, scene.radius, scene.mesh_size) if disk else (meshfile.read, scene.mesh)
        cells, x = one_outcome(comm, *args, root=0) or (np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2)))
        msh = compat.create_mesh(comm, cells, x, compat.coordinate_domain("triangle", 2))
    _check_areas(msh, comm, scene.mesh or scene.domain)
    return msh


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
    used, cells = np.unique(triangles, return_inverse=True)  # the nodes renumbered 0 … in tag order
    order = np.argsort(tags)  # getNodes does not promise sorted tags
    points = coords.reshape(-1, 3)[order][np.searchsorted(tags[order], used), :2]
    return cells.reshape(-1, 3).astype(np.int64), np.ascontiguousarray(points)


def _check_areas(msh, comm, label: str) -> None:
    """Refuse a mesh with a cell of zero area (a degenerate triangle; a domain of zero area has only such)."""
    areas = nodal_areas(compat.function_space(msh, "DG", 0))
    n = msh.topology.index_map(msh.topology.dim).size_local
    smallest, total = comm.allreduce(float(np.min(areas[:n], initial=math.inf)), op=MPI.MIN), comm.allreduce(float(areas[:n].sum()))
    if not total > 0.0:
        raise SceneError(f"mesh: the domain of {label!r} has zero area; allowed: a triangle mesh of positive area")
    if not smallest > 1e-12 * total:
        raise SceneError(f"mesh: {label!r} has cells of zero area (smallest {smallest:.3g} of total {total:.3g}); "
                         "allowed: a triangle mesh without degenerate cells")


def nodal_areas(V) -> np.ndarray:
    """The lumped weights ∫ φ_i dx of the owned dofs of V (P1: the area a node stands for, the contact area)."""
    return assemble_vector(ufl.TestFunction(V) * ufl.dx(domain=V.mesh))


def boundary_dofs(V) -> np.ndarray:
    """Owned dofs on the exterior facets of the mesh, a string's ends or a membrane's boundary (marks added to their
    owners: a rank may own a boundary node without a boundary facet)."""
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
