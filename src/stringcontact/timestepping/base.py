"""What every scheme steps (`DiscreteProblem`), what it must provide (`Scheme`), and the parts they share (the
linear solves are `linear.py`'s).

A scheme advances the nodal state (η, v) one step and reports the terms of its own discrete energy
identity, so that the driver's ledger E(0) + W_ext = E(t) + D_visc + D_con + D_num closes to round-off
whatever the scheme. Energy that the contact law (or a projection) removes is always D_con, booked the
same way by every scheme: the work of the nodal contact force f with the step's mean velocity,
−(Δt/2) f·(v^n + v^{n+1}). It is ½ m V² for a node that lands at speed V and stops, whatever ε, and
about 0 for a node held at rest on the obstacle; what a scheme's identity puts elsewhere is D_num.
"""

from __future__ import annotations

import warnings
import weakref
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms.analysis import extract_constants

from ..errors import InstabilityError, InstabilityWarning, SceneError
from ..fem import nodal
from ..fem.operators import Operators


class StepEnergy(NamedTuple):
    """A scheme's energy terms at the start or after one step: the state's kinetic and elastic (stored) energy, the
    step's increments of the viscous, contact and numerical dissipation and of the external work, and the energy
    held by a conservative contact law (a spring)."""

    kinetic: float
    elastic: float
    viscous: float
    contact: float
    numerical: float
    external: float
    stored: float


class NodalLaws:
    """The model's pointwise laws compiled to NumPy at the nodes, in placeholders η, η_old and v: ``quotient`` is
    v^n = (η^n − η^{n−1})/Δt as UFL (a scheme with a nodal velocity passes ``v``), ``set`` points the placeholders at
    arrays (no copy), ``compile`` makes a `nodal.NodalExpression` whose ``evaluate_env(self.env)`` reads them."""

    def __init__(self, model, V, params, dt: float, fields: dict, x: np.ndarray):
        self.model, self.params = model, params
        self.eta, self.eta_old, self.v = fem.Function(V), fem.Function(V), fem.Function(V)
        self.quotient = (self.eta - self.eta_old) / fem.Constant(V.mesh, PETSc.ScalarType(dt))
        self.env = nodal.environment(fields, x)
        self._keys = {"eta": id(self.eta), "eta_old": id(self.eta_old), "v": id(self.v)}

    def compile(self, expr):
        """`expr` (UFL in the placeholders and the model's fields) as a nodal NumPy expression: a
        `fem.nodal.NodalExpression`, whose ``evaluate_env(self.env)`` gives its value at every node. A law reading ε
        in a run without one (a scheme that takes no penalty) is a TypeError, which names the scheme."""
        if np.isnan(self.params.eps.value) and self.params.eps in extract_constants(expr):
            raise TypeError(f"it applies model '{self.model.name}''s penalty, whose eps it has not got: it declares "
                            "no penalty option (no eps); allowed: a penalty option (Scheme.OPTIONS) or no law reading eps")
        return nodal.NodalExpression(expr)

    def set(self, **arrays) -> None:
        """Point the placeholders named by the keywords (``eta``, ``eta_old``, ``v``) at these arrays (no copy)."""
        for name, a in arrays.items():
            self.env[self._keys[name]] = a

    def key(self, name: str) -> int:
        """The key of placeholder `name` in `env`: a hot loop sets ``env[key] = array`` itself, as `set` does."""
        return self._keys[name]


class MovingObstacle:
    """A moving obstacle ψ(x, t): the model's P1 ``obstacle`` field and its rate ``obstacle_rate`` (the backward
    quotient (ψ(t) − ψ(t − Δt))/Δt, the exact rate of the discrete gap η^n − ψ^n), set in place to a time by `set`.
    `values(t)` gives ψ at every dof of the field (owned and ghosts); the last few times are kept. A scheme's time t is
    the run's t0 + t: `t0` is the run's time when the scheme started (a scheme started afresh from a state mid-run)."""

    def __init__(self, values, psi_field, rate_field, dt: float, n_owned: int, t0: float = 0.0):
        self.values, self.psi_field, self.rate_field, self.dt, self.n = values, psi_field, rate_field, dt, n_owned
        self.t0 = t0
        self._kept: dict[float, np.ndarray] = {}

    def at(self, t: float) -> np.ndarray:
        """ψ(·, t) at every dof (kept for the last four times asked)."""
        key = round(t / self.dt, 6)
        if key not in self._kept:
            if len(self._kept) >= 4:
                self._kept.pop(next(iter(self._kept)))
            self._kept[key] = np.asarray(self.values(self.t0 + t), dtype=float)
        return self._kept[key]

    def set(self, t: float) -> np.ndarray:
        """The fields at the time t; returns ψ on the owned dofs (a view: copy it to keep it)."""
        psi = self.at(t)
        self.psi_field.x.array[:] = psi
        if self.rate_field is not None:
            np.subtract(psi, self.at(t - self.dt), out=self.rate_field.x.array)
            self.rate_field.x.array[:] *= 1.0 / self.dt
        return psi[: self.n]

    def owned(self, t: float) -> np.ndarray:
        """ψ(·, t) on the owned dofs, the fields untouched."""
        return self.at(t)[: self.n]

    def owned_at_run_time(self, t: float) -> np.ndarray:
        """ψ on the owned dofs at the run's time t (the scheme's t − t0), the fields untouched."""
        return self.owned(t - self.t0)

    def centred_rate(self, t: float) -> np.ndarray:
        """ψ_t(·, t) at every dof as the centred quotient (ψ(t + Δt) − ψ(t − Δt))/(2Δt): exact on a uniformly
        accelerating obstacle (`newmark`'s trapezoidal velocity follows it)."""
        return (self.at(t + self.dt) - self.at(t - self.dt)) / (2.0 * self.dt)

    def set_centred(self, t: float) -> None:
        """The fields at the time t with the centred rate (`centred_rate`) in place of `set`'s backward one."""
        self.set(t)
        self.rate_field.x.array[:] = self.centred_rate(t)


@dataclass
class DiscreteProblem:
    """The discrete problem a scheme steps, what the driver hands ``Scheme.__init__`` (kept as ``self.problem``):

    * ``ops``: the model's assembled operators (`Operators`); ``dt``, ``nt``: the time step and the number of steps;
    * ``mass``, ``penalty``, ``eps``: the mass matrix, the penalty (None for an ε-free scheme) and its ε;
    * ``bc``, ``g``: the owned dof indices of the fixed ends (a membrane's boundary) and their heights;
    * ``laws``: the model's pointwise laws at the nodes (`NodalLaws`); ``comm``: the run's MPI communicator;
    * ``x``: the coordinates of the owned dofs (a string's x, a membrane's (x, y) rows);
    * ``petsc_options``: PETSc options on top of the size rule's (or None); ``restitution``: the coefficient e;
    * ``obstacle``: a moving obstacle ψ(x, t) (`MovingObstacle`), or None for an obstacle at rest;
    * ``options``: every option the scheme was given (`Scheme.OPTIONS`, defaults filled in);
    * ``fields0``: the initial values of the model's further unknowns given by name (owned arrays); a field not in it
      starts as `newton.NewtonStep.start_fields` starts it.
    """

    ops: Operators
    dt: float
    mass: str
    penalty: str | None
    bc: np.ndarray
    g: np.ndarray
    laws: NodalLaws
    comm: MPI.Comm
    eps: float
    x: np.ndarray
    nt: int
    petsc_options: dict | None = None
    restitution: float = 0.0
    obstacle: MovingObstacle | None = None
    options: dict = field(default_factory=dict)
    fields0: dict = field(default_factory=dict)

    @property
    def n_owned(self) -> int:
        """The number of dofs this rank owns (the length of the schemes' nodal arrays)."""
        return self.ops.m.size

    @cached_property
    def ends(self) -> list[tuple[int, float]] | None:
        """A string's fixed ends as (index, height) items; None for a membrane's boundary (many nodes)."""
        return [(int(i), float(g)) for i, g in zip(self.bc, self.g)] if self.x.ndim == 1 else None

    def hold_ends(self, a: np.ndarray) -> None:
        """The fixed ends' heights into `a`: a string's two by item (a fancy-indexed a[bc] = g costs 3 µs per
        step), a membrane's boundary by fancy index."""
        if self.ends is None:
            a[self.bc] = self.g
        else:
            for i, g_i in self.ends:
                a[i] = g_i

    @cached_property
    def interior(self) -> np.ndarray:  # read every step: computed once
        """True at the owned dofs that are not fixed ends (bool per node)."""
        mask = np.ones(self.n_owned, dtype=bool)
        mask[self.bc] = False
        return mask


@dataclass(frozen=True)
class SchemeOption:
    """One option a scheme declares, as a model declares a constant: a scene sets it in its ``[scheme]`` table, Python
    as a keyword of `TimeStepper`, `Stepper` or `simulate`.

    A word option lists its `choices` (its default first); a number option its closed range [`low`, `high`]; a
    `required` one has no default (a penalty's ε). `unit` and `description` (one line) are shown by the scene-key
    reference and ``stringcontact show``."""

    name: str
    default: object = None
    choices: tuple = ()
    low: float | None = None
    high: float | None = None
    unit: str = ""
    description: str = ""
    required: bool = False

    @property
    def allowed(self) -> str:
        """The allowed values in words, as the messages give them."""
        if self.choices:
            return " or ".join(repr(c) for c in self.choices)
        if self.low is not None:
            return f"a number in [{self.low:g}, {self.high:g}]"
        return "a table of PETSc options" if isinstance(self.default, dict) else "any value"

    def check(self, scheme: str, value):
        """`value` if this option takes it, else a one-line SceneError naming ``scheme.NAME`` and what is allowed."""
        where = f"scheme.{self.name}"
        if self.choices:
            if value not in self.choices:
                raise SceneError(f"{where}: scheme {scheme!r} takes {self.allowed}, not {value!r}")
            return value
        if self.low is not None:
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
            if not ok or not self.low <= float(value) <= self.high:
                raise SceneError(f"{where}: {value!r} is out of range; allowed: {self.allowed}")
            return float(value)
        return value


#: The options several schemes share.
PETSC_OPTIONS = SchemeOption("petsc_options", {}, description="PETSc options for the step's linear and Newton solvers")
EPS = SchemeOption("eps", None, low=1e-12, high=1e6, unit="t", required=True,
                   description="the penalty's ε: the contact law's time scale")
RESTITUTION = SchemeOption("restitution", 0.0, low=0.0, high=1.0,
                           description="restitution coefficient e (Paoli-Schatzman): 0 inelastic, 1 elastic")


def penalty_option(*choices: str) -> SchemeOption:
    """The `penalty` option over `choices` (the first is the default)."""
    return SchemeOption("penalty", choices[0], choices,
                        description="the contact law from the previous step (explicit) or as a damping of the new "
                                    "velocity (semi-implicit)")


def mass_option(*choices: str) -> SchemeOption:
    """The `mass` option over `choices` (the first is the default)."""
    return SchemeOption("mass", choices[0], choices, description="the mass matrix: lumped (row sums) or consistent")


class Scheme:
    """The contract. A scheme module defines one class named after its scheme (``class MyScheme(base.Scheme)``) with:

    * ``OPTIONS``: the `SchemeOption`s it takes (``penalty``, ``mass``, ``eps``, ``restitution``, ``petsc_options``,
      or its own), checked by `resolve_options`; a scheme without a ``penalty`` option uses no penalty and no ε;
    * ``DESCRIPTION``: one line for `stringcontact.SCHEMES`;
    * ``LINEAR_PATH``: True if it steps a linear model with the constant operators M, C, K alone; False if every
      model reaches it with its residual (`Operators.nonlinear`: `implicit.ImplicitScheme`);
    * ``requires(model)``: why it cannot run a model (one clause), or None;
    * ``__init__(problem)``: assemble and factorise (set-up time); ``problem`` is the `DiscreteProblem`, its
      options resolved (``problem.mass``, ``problem.penalty``, ``problem.eps``, ``problem.options``);
    * ``start(eta0, v0) -> StepEnergy``: the initial state (this rank's nodal float64 arrays: ends already at their
      heights, v0 = 0 there), called before the first step and again whenever the stepper starts a scheme afresh (a
      new Δt, a constant changed, sub-steps); the scheme sets every level it steps from, so its order is its own
      (``implicit.ImplicitScheme``: η^{−1} = η0 − Δt v0, `level_before`; second order adds ½Δt² a0 from
      ``problem.ops``, ``implicit.acceleration``); the model's further unknowns start at ``problem.fields0``;
    * ``step() -> StepEnergy``: one step;
    * ``eta``, ``velocity``, ``contact_force``: this rank's nodal arrays of the current state (the force density
      applied in the last step); ``fields``: the model's further unknowns by name (empty for one field);
    * ``timings``: extra counters for the summary (e.g. refactorisations).

    ``PENALTIES``, ``MASSES`` and ``RESTITUTION`` are read off ``OPTIONS`` (the choices of ``penalty`` and ``mass``,
    whether it takes ``restitution``).
    """

    OPTIONS: tuple = (mass_option("lumped", "consistent"), PETSC_OPTIONS)
    DESCRIPTION = ""
    LINEAR_PATH = True
    #: A non-negative part of the scheme's energy that the ledger does not show, at the state last reported; the
    #: energy guard watches E + energy_slack, the quantity the scheme does not increase (projection's (Δt/4)|v|²_C).
    energy_slack = 0.0
    #: Whether the scheme's energy may rise for a while without an instability (a rebound giving energy back, a
    #: nonlinear force in a non-dissipative step): the guard then allows what it allows a contact spring.
    energy_may_rise = False
    situation = ""  # for the instability message: e.g. "r = dt/eps = 4, penalty explicit"
    remedy = "use a smaller dt"
    PENALTIES: tuple = ()
    MASSES: tuple = ("lumped", "consistent")
    RESTITUTION = False

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        by_name = {o.name: o for o in cls.OPTIONS}
        cls.PENALTIES = by_name["penalty"].choices if "penalty" in by_name else ()
        cls.MASSES = by_name["mass"].choices if "mass" in by_name else ("lumped",)
        cls.RESTITUTION = "restitution" in by_name

    def __init__(self, problem: DiscreteProblem):
        self.problem = problem

    @property
    def timings(self) -> dict:
        """Extra counters for the summary (e.g. refactorisations)."""
        return {}

    @staticmethod
    def requires(model) -> str | None:
        """Why this scheme cannot run `model` (one clause), or None."""
        return None

    def start(self, eta0: np.ndarray, v0: np.ndarray) -> StepEnergy:
        """The initial state; returns its energy terms."""
        raise NotImplementedError(f"{type(self).__qualname__} must define start(eta0, v0)")

    def step(self) -> StepEnergy:
        """One step; returns its energy terms."""
        raise NotImplementedError(f"{type(self).__qualname__} must define step()")

    @property
    def eta(self) -> np.ndarray:
        """η at this rank's nodes."""
        raise NotImplementedError(f"{type(self).__qualname__} must define eta")

    @property
    def velocity(self) -> np.ndarray:
        """The velocity at this rank's nodes."""
        raise NotImplementedError(f"{type(self).__qualname__} must define velocity")

    @property
    def contact_force(self) -> np.ndarray:
        """The contact force density of the last step at this rank's nodes."""
        raise NotImplementedError(f"{type(self).__qualname__} must define contact_force")

    @property
    def fields(self) -> dict:
        """The model's further unknowns at this rank's nodes, by name (none for a model of one field)."""
        return {}

    @classmethod
    def check_options(cls, name: str, penalty, mass) -> tuple:
        """(penalty, mass) with the scheme's defaults; ValueError naming the scheme and what it accepts."""
        if penalty is None:
            penalty = cls.PENALTIES[0] if cls.PENALTIES else None
        elif penalty not in cls.PENALTIES:
            accepts = f"penalty {' or '.join(cls.PENALTIES)}" if cls.PENALTIES else "no penalty (and no eps)"
            raise ValueError(f"scheme {name!r} accepts {accepts}, not penalty {penalty!r}")
        if mass is None:
            mass = cls.MASSES[0]
        elif mass not in cls.MASSES:
            raise ValueError(f"scheme {name!r} accepts mass {' or '.join(cls.MASSES)}, not {mass!r}")
        return penalty, mass

    def contact(self) -> np.ndarray:
        """The model's contact set at the current η (bool per node)."""
        laws = self.problem.laws
        if not hasattr(self, "_contact_law"):
            self._contact_law = laws.compile(laws.model.contact_set(laws.eta, laws.params))
        laws.set(eta=self.eta)
        return self._contact_law.evaluate_env(laws.env)


# --- shared parts -------------------------------------------------------------------------------------


def check_law_stability(model, dt: float, eps: float, penalty: str) -> None:
    """Apply the contact law's own bound on Δt and ε (`Model.stability`): refuse or warn before the run."""
    r = dt / eps
    verdict = model.stability(dt, eps, penalty) if model.stability is not None else None
    if verdict is None:
        return
    kind, why = verdict
    if kind == "refuse":
        raise InstabilityError(f"{why} (model '{model.name}', at step 0, t = 0)", step=0, time=0.0, r=r)
    warnings.warn(why, InstabilityWarning, stacklevel=4)


def petsc_callback(method):
    """The bound `method` as a PETSc callback (a SNES's function or Jacobian) that does not keep its object alive.

    petsc4py 3.25 keeps a callback where Python's garbage collector cannot see it, so a bound method makes a cycle
    (object → SNES → method → object) that is never freed, with its mesh, forms and matrices and the mesh's MPI
    communicators: 8 a nonlinear run, of MPICH's 2,048 (the dolfinx wheel's; test_nonlinear.py counts the objects)."""
    ref = weakref.WeakMethod(method)

    def call(*args):
        return ref()(*args)

    return call


def petsc_vector(a: np.ndarray, comm) -> PETSc.Vec:
    """A PETSc vector over `a`'s memory (this rank's part of the vector is all of `a`)."""
    return PETSc.Vec().createWithArray(a.reshape(-1), size=(a.size, PETSc.DECIDE), comm=comm)


class Ranks:
    """Reductions over the ranks of `comm` in one allreduce each, free in serial: `sum` and `any`."""

    def __init__(self, comm):
        self.comm, self.serial = comm, comm.size == 1

    def sum(self, *values) -> list | tuple:
        """The sums of `values` over the ranks (the values themselves in serial)."""
        if self.serial:
            return values
        return self.comm.allreduce(np.array(values), op=MPI.SUM).tolist()

    def any(self, flag: bool) -> bool:
        """Whether `flag` is set on any rank (the flag itself in serial)."""
        if self.serial:
            return flag
        return self.comm.allreduce(flag, op=MPI.LOR)
