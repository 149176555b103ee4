"""A model's output fields at the nodes: its further unknowns as the scheme solved them, its derived fields (UFL
expressions of the unknowns, `OutputField.expression`) interpolated into P1 at each stored time."""

from __future__ import annotations

import numpy as np
from dolfinx import fem

from ..model.interface import output_fields
from . import compat

__all__ = ["OutputValues"]


class OutputValues:
    """The model's output fields (`model.interface.output_fields`) at this rank's owned nodes, from η and the scheme's
    further unknowns; a derived field is a `fem.Expression` compiled once and interpolated into P1 at the stored times
    only (a kernel call per cell: too slow for every step, cheap for a few hundred rows)."""

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
            self._expressions = {f.name: fem.Expression(f.expression(U, params), points) for f in derived}
            self._target = fem.Function(V)

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
        return out
