"""`ContactProblem`: a model on the caller's P1 space, Functions, boundary conditions, fields and obstacle."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..fem.compat import set_bc
from ..fem.operators import Operators, node_coordinates, semi_discrete_operators
from ..fem.outputs import OutputValues
from ..model.forms import check_declarations
from ..model.interface import Model, Parameters, unused_fields
from ..scene.parameters import resolve_parameters

__all__ = ["RATE", "ContactProblem"]

#: The moving obstacle's rate ψ_t in `Parameters.extra` (the backward quotient of ψ; `MovingObstacle`).
RATE = "obstacle_rate"


class ContactProblem:
    """The model `model` on the P1 space of the caller's Function `eta`: the state a `TimeStepper` advances.

    * `eta`, `v`: the caller's Functions of the height and the velocity (`v` made, zero, when not given); the
      stepper writes the state into them after every step. Their values when the stepper is made are the initial
      state (the fixed dofs taken at their boundary values, the velocity 0 there).
    * `bcs`: dolfinx ``DirichletBC`` objects on the space: the dofs held at their values (a string's ends, a membrane's
      boundary); their values are read once, here.
    * `alpha`: the viscosity α of the paper's form (``Parameters.alpha``, a dolfinx Constant).
    * `constants`: the model's own constants (`Model.constants`) by name, checked like a scene's ``[parameters]``
      (defaults filled in); ``problem.constants[name]`` is the dolfinx Constant the forms read.
    * `fields`: P1 Functions the model reads as data, by name (``Parameters.extra``: ``load``, ``obstacle``).
    * `obstacle`: ``psi(x, t) -> values`` for an obstacle that moves: at the dof coordinates `x` (as
      `node_coordinates`: a string's x, shape (n,); a membrane's (x, y), shape (n, 2)) and the time t; it fills
      ``fields["obstacle"]`` and its rate ``fields["obstacle_rate"]`` every step. None: the obstacle is at rest.
    * `unknowns`: Functions for the model's further unknowns (`Model.fields`), made on the space when not given; a
      given one's values when the stepper is made are that field's initial value (`initial_fields`).

    `contact_force` is a Function the stepper fills with the contact force density (`TimeStepper.contact_force`).
    """

    def __init__(self, model: Model, eta, v=None, *, bcs=(), alpha: float = 0.0, constants: dict | None = None,
                 fields: dict | None = None, obstacle: Callable | None = None, unknowns: dict | None = None):
        check_declarations(model)  # what it declares is of its kind, before any of it is read
        V = eta.function_space
        if V.num_sub_spaces or V.dofmap.index_map_bs != 1:
            raise ValueError("eta: expected a Function on a scalar P1 space (dolfinx functionspace(mesh, ('Lagrange', 1)))")
        self.model, self.V, self.comm = model, V, V.mesh.comm
        self.eta = eta
        self.v = v if v is not None else fem.Function(V, name="velocity")
        for name, f in (("v", self.v), *((f"fields[{k!r}]", g) for k, g in (fields or {}).items())):
            if f.x.array.shape != eta.x.array.shape:
                raise ValueError(f"{name}: expected a Function on eta's space")
        self.n_owned = V.dofmap.index_map.size_local
        self.dof_x = node_coordinates(V)  # owned dofs, then ghosts
        self.x = self.dof_x[: self.n_owned]
        self.bc, self.g = _held_dofs(V, list(bcs), self.n_owned)
        self.obstacle = obstacle
        extra = dict(fields or {})
        if obstacle is not None:
            for name in ("obstacle", RATE):
                extra.setdefault(name, fem.Function(V, name=name))
        values = resolve_parameters(model.name, model.constants, dict(constants or {}), model.check_constants)
        msh = V.mesh
        self.params = Parameters(
            alpha=fem.Constant(msh, PETSc.ScalarType(alpha)),
            eps=fem.Constant(msh, PETSc.ScalarType(np.nan)),  # the scheme's eps, set by the stepper
            x=ufl.SpatialCoordinate(msh),
            length=_length(self.x, self.comm) if msh.topology.dim == 1 else None,
            extra=extra,
            constants={k: fem.Constant(msh, PETSc.ScalarType(c)) for k, c in values.items()},
        )
        self.constants = self.params.constants
        unused = [name for name in unused_fields(model, V, self.params) if name != RATE]
        if unused:  # a load the model ignores would give a plausible but wrong answer
            raise ValueError(f"field(s) {', '.join(unused)}: not used by model '{model.name}'; choose a model that "
                             "reads them (e.g. model 'loaded_obstacle') or leave them out")
        self.unknowns = {name: (unknowns or {}).get(name) or fem.Function(V, name=name) for name in model.fields}
        self.given = set(unknowns or {}) & set(model.fields)  # the fields whose start the caller gave
        self.contact_force = fem.Function(V, name="contact_force")
        self.outputs = OutputValues(model, V, self.params)
        self._operators: dict[bool, Operators] = {}

    @property
    def dim(self) -> int:
        """The mesh's dimension: 1 for a string, 2 for a membrane."""
        return self.V.mesh.topology.dim

    @property
    def interior(self) -> np.ndarray:
        """True at the owned dofs that are not held (bool per node)."""
        mask = np.ones(self.n_owned, dtype=bool)
        mask[self.bc] = False
        return mask

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """η and v at the owned dofs from the caller's Functions, the held dofs at their values and at rest."""
        eta0 = np.array(self.eta.x.array[: self.n_owned], dtype=float)
        eta0[self.bc] = self.g
        return eta0, np.array(self.v.x.array[: self.n_owned], dtype=float) * self.interior

    def initial_fields(self) -> dict[str, np.ndarray]:
        """The given unknowns' values at the owned dofs (their start); a field not given starts as the scheme starts it:
        on an affine residual solved from its rows at (η⁰, v⁰) with its own rate 0, else at 0."""
        return {name: np.array(self.unknowns[name].x.array[: self.n_owned]) for name in sorted(self.given)}

    def operators(self, residual: bool = False, state=None) -> Operators:
        """The model's semi-discrete operators (`fem.operators.semi_discrete_operators`), assembled once per `residual`
        (with the residual: the Newton path); a form singular at 0 is linearised at `state`'s (η, v) (default: η⁰)."""
        if residual not in self._operators:
            self._operators[residual] = semi_discrete_operators(self.model, self.V, self.params, residual,
                                                                state or self.initial_state)
        return self._operators[residual]

    def reassemble(self, residual: bool, state) -> Operators:
        """The operators again (a model constant changed), linearised at `state` where they must be."""
        self._operators.pop(residual, None)
        return self.operators(residual, state)

    def obstacle_values(self, t: float) -> np.ndarray:
        """ψ at every dof (owned, then ghosts) at the time t: the moving obstacle's, the ``obstacle`` field's, or 0."""
        if self.obstacle is not None:
            return np.asarray(self.obstacle(self.dof_x, t), dtype=float)
        if "obstacle" in self.params.extra:
            return np.asarray(self.params.extra["obstacle"].x.array, dtype=float)
        return np.zeros(self.dof_x.shape[0])


def _held_dofs(V, bcs: list, n_owned: int) -> tuple[np.ndarray, np.ndarray]:
    """The owned dofs the boundary conditions hold and their values (a NaN array that `set_bc` fills)."""
    values = np.full(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts, np.nan)
    if bcs:
        set_bc(values, bcs)
    held = np.flatnonzero(~np.isnan(values[:n_owned])).astype(np.int32)
    return held, values[held].copy()


def _length(x: np.ndarray, comm) -> float:
    """A string's length: the extent of its nodes over all ranks."""
    from mpi4py import MPI

    low = comm.allreduce(float(np.min(x, initial=math.inf)), op=MPI.MIN)
    high = comm.allreduce(float(np.max(x, initial=-math.inf)), op=MPI.MAX)
    return high - low
