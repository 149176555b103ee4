"""A model's output fields at the nodes: its further unknowns as the scheme solved them, its derived fields (UFL
expressions of the unknowns, `OutputField.expression`) interpolated into P1 at each stored time."""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from ..errors import one_line
from ..model.forms import FormError
from ..model.interface import output_fields
from . import compat

__all__ = ["OutputValues"]


class OutputValues:
    """The model's output fields at this rank's owned nodes, from η and the further unknowns; a derived field is a
    `fem.Expression` interpolated at the stored times only (too slow for every step)."""

    def __init__(self, model, V, params):
        self.fields = output_fields(model)
        self.info = {f.name: f.metadata() for f in self.fields}
        self.n = V.dofmap.index_map.size_local
        derived = [f for f in self.fields if f.expression is not None]
        self._unknowns = self._expressions = None
        if derived:
            names = ("eta", *getattr(model, "fields", ()))
            self._unknowns = {name: fem.Function(V, name=name) for name in names}
            U = tuple(self._unknowns.values())
            points = compat.interpolation_points(V)
            self._expressions = {f.name: _expression(model.name, f, U, params, points) for f in derived}
            self._target = fem.Function(V)
        self._model, self._comm = model.name, V.mesh.comm

    def __call__(self, eta: np.ndarray, fields: dict) -> dict[str, np.ndarray]:
        """Every output field at the owned nodes: the unknowns from `fields`, the derived ones evaluated at (η, fields)."""
        out = {f.name: fields[f.name] for f in self.fields if f.expression is None}
        if self._expressions:
            for name, f in self._unknowns.items():
                f.x.array[: self.n] = eta if name == "eta" else fields[name]
                f.x.scatter_forward()
            for name, expression in self._expressions.items():
                self._target.interpolate(expression)
                out[name] = self._target.x.array[: self.n].copy()
            finite = all(np.isfinite(out[name]).all() for name in self._expressions)
            if not self._comm.allreduce(finite, op=MPI.LAND):  # every rank: the rows are gathered next
                raise FormError(f"model '{self._model}': an output field ({', '.join(self._expressions)}) is not "
                                "finite at a stored time; allowed: finite values, which the pictures and plot read back")
        return out


def _expression(model: str, field, U, params, points):
    """The output field's `fem.Expression`, or a FormError naming it: a scalar UFL expression of the unknowns."""
    try:
        value = field.expression(U, params)
        if ufl.as_ufl(value).ufl_shape != ():
            raise ValueError(f"of shape {ufl.as_ufl(value).ufl_shape}")
        return fem.Expression(value, points)
    except Exception as exc:  # noqa: BLE001 - UFL's and dolfinx's errors about the user's expression
        raise FormError(f"model '{model}': output field {field.name!r}: its expression is not a scalar UFL expression "
                        f"of the unknowns U ({type(exc).__name__}: {one_line(exc, 200)}); allowed: e.g. "
                        "lambda U, p: U[0] ** 2") from None
