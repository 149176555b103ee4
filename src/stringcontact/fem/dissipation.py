"""The dissipation of a model's internal variables, derived from its residual: a further unknown whose own rate
enters the residual (a dashpot, c q_t s) dissipates [R(U, U_t) − R(U, 0)]_q · Δq over a step (c|Δq|²/Δt there)."""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

__all__ = ["InternalDissipation", "internal_variables"]


def internal_variables(model, V, params) -> tuple[str, ...]:
    """The model's further unknowns (`Model.fields`) whose own rate U_t[i] its residual reads."""
    if not getattr(model, "fields", ()) or model.residual is None:
        return ()
    k = 1 + len(model.fields)
    U, U_t, U_tt = (tuple(fem.Function(V) for _ in range(k)) for _ in range(3))
    w = ufl.TestFunction(V)
    used = set(ufl.algorithms.extract_coefficients(model.residual(U, U_t, U_tt, fem.Function(V), (w,) * k, params)))
    return tuple(name for name, rate in zip(model.fields, U_t[1:]) if rate in used)


class InternalDissipation:
    """Each internal variable's dissipation over one step, from the owned unknowns (η, *fields) at the start
    (`values`) and after each step (`step`), with the rates ΔU/Δt (the rest of a scheme's quotient stays in D_num)."""

    def __init__(self, model, V, params, names: tuple[str, ...], values: list[np.ndarray]):
        k = 1 + len(model.fields)
        self.comm, self.n = V.mesh.comm, V.dofmap.index_map.size_local
        self.old, self.new = ([fem.Function(V) for _ in range(k)] for _ in range(2))
        self.dt = fem.Constant(V.mesh, PETSc.ScalarType(1.0))
        zero = fem.Function(V)  # a Function, not a Constant: a term in it keeps its integration domain
        rates = tuple((a - b) / self.dt for a, b in zip(self.new, self.old))
        self.forms = {}
        for name in names:
            i = 1 + model.fields.index(name)
            W = tuple(self.new[i] - self.old[i] if j == i else zero for j in range(k))  # the row tested by Δq
            R = [model.residual(tuple(self.new), U_t, (zero,) * k, zero, W, params) for U_t in (rates, (zero,) * k)]
            self.forms[name] = fem.form(R[0] - R[1])
        self._set(values)

    def _set(self, values: list[np.ndarray]) -> None:
        for f, a in zip(self.new, values):  # (η, *fields) now, this rank's owned values
            f.x.array[: self.n] = a
            f.x.scatter_forward()

    def step(self, values: list[np.ndarray], dt: float) -> dict[str, float]:
        """The unknowns after a step of `dt`: each internal variable's dissipation over it, summed over the ranks."""
        for a, b in zip(self.old, self.new):
            a.x.array[:] = b.x.array
        self._set(values)
        self.dt.value = dt
        local = np.array([fem.assemble_scalar(form) for form in self.forms.values()])
        return dict(zip(self.forms, self.comm.allreduce(local, op=MPI.SUM).tolist()))
