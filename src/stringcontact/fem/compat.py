"""Every dolfinx API difference between 0.5 (Debian bookworm), 0.9 (Debian trixie) and 0.11 (the PyPI wheel) lives
here: the rest of the package never branches on the dolfinx version (DEVELOPERS.md lists each difference)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dolfinx import fem

# NumPy 2 deprecates `np.trapz` for `np.trapezoid`; dolfinx is imported inside the helpers (`Result` loads none).
trapezoid = getattr(np, "trapezoid", None) or np.trapz


def dolfinx_version() -> tuple[int, int]:
    """dolfinx's (major, minor) version."""
    import dolfinx

    return tuple(int(p) for p in dolfinx.__version__.split(".")[:2])


def function_space(msh, family: str = "Lagrange", degree: int = 1):
    """`fem.functionspace` (0.7+) replaces `fem.FunctionSpace` (0.5)."""
    from dolfinx import fem

    return (fem.functionspace if hasattr(fem, "functionspace") else fem.FunctionSpace)(msh, (family, degree))


def petsc_vec(u: fem.Function):
    """`u.x.petsc_vec` (0.9) replaces `u.vector` (0.5)."""
    x = u.x
    return x.petsc_vec if hasattr(x, "petsc_vec") else u.vector


def interpolation_points(V) -> np.ndarray:
    """A property in 0.5, a method from 0.7 on."""
    pts = V.element.interpolation_points
    return pts() if callable(pts) else pts


def create_vector(form):
    """In 0.10 `create_vector` takes function spaces; before, it took the compiled form."""
    import dolfinx.fem.petsc  # 0.9 no longer imports the PETSc layer with dolfinx.fem

    return dolfinx.fem.petsc.create_vector(form.function_spaces[0] if dolfinx_version() >= (0, 10) else form)


def pack_coefficients(form) -> dict:
    """dolfinx's packed coefficients of a compiled form, {(integral type, id): array}: the form itself in 0.5, its
    `_cpp_object` from 0.7 on."""
    from dolfinx.cpp.fem import pack_coefficients as pack

    return pack(getattr(form, "_cpp_object", form))


def _p1_vector_element(cell: str, n: int):
    """A P1 element of `n` components on `cell` (a name): `basix.ufl.element` (0.7+) or `ufl.VectorElement` (0.5)."""
    try:
        import basix.ufl

        return basix.ufl.element("Lagrange", cell, 1, shape=(n,))
    except (ImportError, AttributeError):
        import ufl

        return ufl.VectorElement("Lagrange", cell, 1, dim=n)


def coordinate_domain(cell: str, gdim: int):
    """The `ufl.Mesh` of a P1 coordinate element."""
    import ufl

    return ufl.Mesh(_p1_vector_element(cell, gdim))


def create_mesh(comm, cells: np.ndarray, x: np.ndarray, domain):
    """`mesh.create_mesh` of `cells` on the points `x`: (comm, cells, x, domain) to 0.9, (…, domain, x) from 0.10."""
    from dolfinx import mesh

    return mesh.create_mesh(comm, cells, *((domain, x) if dolfinx_version() >= (0, 10) else (x, domain)))


def snes_diverged_nan():
    """PETSc's SNES reason for a NaN residual: ``DIVERGED_FNORM_NAN``, ``DIVERGED_FUNCTION_NANORINF`` from 3.25."""
    from petsc4py import PETSc

    reasons = PETSc.SNES.ConvergedReason
    return getattr(reasons, "DIVERGED_FUNCTION_NANORINF", None) or reasons.DIVERGED_FNORM_NAN


def geometry_nodes(msh) -> np.ndarray:
    """The geometry nodes of every local cell, (cells, nodes per cell): `geometry.dofmap` (an AdjacencyList in 0.5),
    `dofmaps(0)` in 0.9, `dofmaps[0]` in 0.11."""
    dofmaps = getattr(msh.geometry, "dofmaps", None)
    nodes = msh.geometry.dofmap if dofmaps is None else dofmaps(0) if callable(dofmaps) else dofmaps[0]
    flat = nodes.array if hasattr(nodes, "array") else nodes
    return np.asarray(flat).reshape(-1, msh.topology.dim + 1)  # P1 simplices: one node per vertex


def cell_dofs(V) -> np.ndarray:
    """The local dofs of every cell, (cells, dofs per cell): `V.dofmap.list`, an AdjacencyList in 0.5, is it from 0.8."""
    dofs = V.dofmap.list
    flat = dofs.array if hasattr(dofs, "array") else dofs
    return np.asarray(flat).reshape(-1, V.dofmap.dof_layout.num_dofs)


def mixed_space(msh, fields: int):
    """P1^fields on `msh` as one blocked space (its matrices carry the block size, which PCFIELDSPLIT splits by)."""
    from dolfinx import fem

    try:
        import basix.ufl

        element = basix.ufl.element("Lagrange", msh.basix_cell(), 1, shape=(fields,))
        return fem.functionspace(msh, element)
    except (ImportError, AttributeError):
        import ufl

        element = ufl.VectorElement("Lagrange", msh.ufl_cell(), 1, dim=fields)
        return fem.FunctionSpace(msh, element)


def sub_dofs(V, Z, i: int) -> np.ndarray:
    """For each local dof of the P1 space V, the local dof of component `i` of the mixed space Z at its node."""
    index = np.empty(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts, dtype=np.int64)
    index[cell_dofs(V).ravel()] = cell_dofs(Z.sub(i)).ravel()
    return index


def set_bc(values: np.ndarray, bcs: list) -> None:
    """Write the boundary conditions' values into an array: `DirichletBC.set` (0.9+) replaces `fem.set_bc` (0.5)."""
    from dolfinx import fem

    if hasattr(bcs[0], "set"):
        for bc in bcs:
            bc.set(values)
    else:
        fem.set_bc(values, bcs)
