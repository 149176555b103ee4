"""`TimeStepper`: a `ContactProblem` advanced by a time scheme, one step per call, the state written into the
caller's Functions, every step's energy booked in its `EnergyLedger`, its observers told."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import MutableMapping

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from ..errors import PLUGIN_FAULTS, InstabilityError, SceneError, SolverError, plugin_code, plugin_failure
from ..fem.agree import one_outcome, same_on_every_rank
from ..fem.dissipation import InternalDissipation, internal_variables
from ..model.forms import FormError
from ..scene.parameters import resolve_parameters
from ..timestepping import check_scheme_run
from ..timestepping.base import DiscreteProblem, MovingObstacle, NodalLaws, StepEnergy
from .ledger import EnergyLedger, energy_roundoff
from .problem import RATE, ContactProblem

__all__ = ["MAX_HALVINGS", "TimeStepper"]

#: A Newton step that fails is retried as 2, 4, … 2^MAX_HALVINGS sub-steps before the stepper gives up.
MAX_HALVINGS = 4


class TimeStepper:
    """`problem` advanced by the time scheme `scheme` (a registered name or a `Scheme` subclass) with the time step
    `dt`; `options` are the scheme's (`Scheme.OPTIONS`: ``penalty``, ``mass``, ``eps``, ``restitution``,
    ``petsc_options``, ...). `nt`: the number of steps the caller means to take, if known.

    ``advance()`` takes one step: the state goes into the problem's Functions (``eta``, ``v``, the model's
    ``unknowns``), the energy terms into the `ledger` (whose guard raises `InstabilityError`), and every observer's
    ``stepped(stepper)`` is called. A new `dt` takes effect at the next step (mesh, forms and operators kept);
    `parameters` changes a model constant between steps. A failed Newton step is retried in 2, 4, … 16 sub-steps.
    After an error inside a step (an instability, Ctrl-C) the stepper refuses to go on, in one line.

    `initial` sets the start of an unknown by name (``"eta"``, ``"v"``, a model field): this rank's owned values or
    a function of their coordinates `problem.x`. Every restart (a new Δt, a constant, sub-steps) carries the whole
    state.
    """

    def __init__(self, problem: ContactProblem, dt: float, scheme="paper", *, nt: int | None = None,
                 initial: dict | None = None, **options):
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise SceneError(f"dt: {dt!r} is not a time step; allowed: a finite number > 0")
        _set_initial(problem, initial or {})
        self.problem, self.model, self.comm = problem, problem.model, problem.comm
        model = problem.model
        self.name, self.Scheme, self.options = check_scheme_run(scheme, model, dt, options, self.comm.size)
        self.penalty, self.mass = self.options["penalty"], self.options["mass"]
        problem.params.eps.value = self.options["eps"] if self.options["eps"] is not None else np.nan
        self.nt, self._dt, self.step, self._t0, self._step0 = nt, float(dt), 0, 0.0, 0
        self.observers, self._stepped = [], []  # _stepped: the observers' `stepped` methods, called after every step
        self.counters, self.past_timings, self.energies = {}, [], None
        # why the stepper may not go on (an error inside a step); the start terms of a scheme restarted after sub-steps
        self._broken = self._restart = None
        self.parameters = _Constants(self)
        self._plugins = f"model '{model.name}' with scheme '{self.name}'"  # whose code runs in a step
        same_on_every_rank(self.comm, "the time step, scheme, options and constants",
                           [self._dt, self.name, nt, self.options, dict(self.parameters)])
        with plugin_code(f"model '{model.name}'"):
            ops = problem.operators(not self.Scheme.LINEAR_PATH)
            self._check_moving_obstacle()
            self.newton = ops.nonlinear is not None  # a Newton path, whose step may fail and be sub-stepped
            self.discrete = self._discrete(ops, self._dt)
        with plugin_code(self._plugins):
            self.scheme = self.Scheme(self.discrete)
        self._start()

    def _discrete(self, ops, dt: float, fields0: dict | None = None, t0: float = 0.0) -> DiscreteProblem:
        """The `DiscreteProblem` at the time step `dt`, its further unknowns starting at `fields0` (default: given), a
        moving obstacle at the time t0 when its scheme starts."""
        p = self.problem
        fields = {f: f.x.array[: p.n_owned] for f in p.params.extra.values()}
        laws = NodalLaws(self.model, p.V, p.params, dt, fields, p.x)
        given = self.options["petsc_options"]
        options = _model_options(self.model, ops, p.params, p.dim, self.comm.size, given) | given
        obstacle = None if p.obstacle is None else MovingObstacle(
            p.obstacle_values, p.params.extra["obstacle"], p.params.extra[RATE], dt, p.n_owned, t0)
        return DiscreteProblem(ops=ops, dt=dt, mass=self.mass, penalty=self.penalty, bc=p.bc, g=p.g, laws=laws,
                               comm=self.comm, eps=self.options["eps"], x=p.x, nt=self.nt or 0, petsc_options=options,
                               restitution=self.options["restitution"] or 0.0, obstacle=obstacle,
                               options=self.options, fields0=p.initial_fields() if fields0 is None else fields0)

    def _check_moving_obstacle(self) -> None:
        """A moving obstacle needs restitution 0 without a penalty, else a law in the gap rate v − ψ_t."""
        p = self.problem
        if p.obstacle is None:
            return
        if not self.Scheme.PENALTIES:
            if self.options["restitution"]:
                raise SceneError("restitution: a moving obstacle (obstacle in t) runs with restitution 0 only")
            return
        law = self.model.penalty if self.penalty == "explicit" else self.model.penalty_damping
        what = "penalty" if self.penalty == "explicit" else "penalty_damping"
        if law is None:  # no such law: the scheme refuses the model itself
            return
        eta, v = fem.Function(p.V), fem.Function(p.V)
        if p.params.extra[RATE] not in ufl.algorithms.extract_coefficients(law(eta, v, p.params)):
            raise SceneError(f"obstacle: model '{self.model.name}''s {what} does not read the obstacle's rate "
                             f"p.extra['{RATE}'] (its gap rate v - psi_t), which a moving obstacle needs; use scheme "
                             "'projection' or a law in the gap rate (model 'loaded_obstacle')")

    def _start(self) -> None:
        """The initial state opens the ledger and goes into the Functions."""
        p = self.problem
        if p.obstacle is not None:  # ψ_t for the penalty's gap rate at t = 0
            rate = p.params.extra[RATE]
            rate.x.array[:] = (p.obstacle_values(0.0) - p.obstacle_values(-self._dt)) / self._dt
        eta0, v0 = one_outcome(self.comm, p.initial_state)
        with plugin_code(self._plugins):
            start = _energy_terms(self.scheme.start(eta0, v0), f"{self._plugins}: start()")
        # a declared energy not finite at t = 0: no step can fix it (a form's own potential: the step names the form)
        declared = self.model.stored_energy is not None or self.model.contact_energy is not None
        if declared and not all(math.isfinite(term) for term in start):
            raise SceneError(f"{self._plugins}: the initial state's energy is not finite ({start}); allowed: finite "
                             "energies at t = 0 (the model's stored_energy, contact_energy at eta0)")
        self.ledger = EnergyLedger(start, conservative=self.model.contact_energy is not None
                                   or self.scheme.energy_may_rise,
                                   floor=energy_roundoff(self.discrete.ops.K, self.scheme.eta, self.comm),
                                   slack=self.scheme.energy_slack)
        self.energies = start
        names = internal_variables(self.model, p.V, p.params)
        if set(names) & set(self.model.dissipative_fields):  # booked twice, and the spring's work as viscous
            raise FormError(f"model '{self.model.name}': dissipative_fields names {', '.join(names)}, whose own rate "
                            "enters the residual: its dissipation is booked from its rate terms; allowed: fields "
                            "without a rate (an algebraic field's work on eta)")
        state = [self.scheme.eta, *self.scheme.fields.values()]
        self._internal = InternalDissipation(self.model, p.V, p.params, names, state) if names else None
        for name in names:  # the energy picture names them
            p.outputs.info[name]["internal"] = True
        self._owned = (p.eta.x.array[: p.n_owned], p.v.x.array[: p.n_owned])  # views the state is copied into
        self._write_state()

    @property
    def dt(self) -> float:
        """The time step; a new value takes effect at the next step (its energy jump booked as numerical)."""
        return self._dt

    @dt.setter
    def dt(self, value: float) -> None:
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"dt: {value!r} is not a time step; allowed: a finite number > 0")
        if value == self._dt:
            return
        if self.problem.obstacle is not None:
            raise ValueError("dt: the time step of a run with a moving obstacle cannot change during the run; "
                             "restart from its state with the new dt")
        self._t0, self._step0, self._dt = self.t, self.step, float(value)
        self.scheme = self._restarted(self._dt)
        self.ledger.rebase(self._restart_terms, numerical=True)

    @property
    def t(self) -> float:
        """The time of the state."""
        return self._t0 + (self.step - self._step0) * self._dt

    @property
    def contact_force(self):
        """The contact force density of the last step, as the problem's Function ``contact_force`` (filled now)."""
        f = self.problem.contact_force
        f.x.array[: self.problem.n_owned] = self.scheme.contact_force
        f.x.scatter_forward()
        return f

    def attach(self, observer):
        """Attach `observer` (`core.observers.Observer`): it is told of the initial state now and of every step after."""
        self.observers.append(observer)
        if getattr(observer, "stepped", None) is not None:
            self._stepped.append(observer.stepped)
        if getattr(observer, "started", None) is not None:
            observer.started(self)
        return observer

    def finish(self) -> None:
        """Tell the observers the caller has finished (``finished(stepper)``)."""
        for observer in self.observers:
            if getattr(observer, "finished", None) is not None:
                observer.finished(self)

    def _write_state(self) -> None:
        """The scheme's state into the problem's Functions (owned values, then the ghosts)."""
        p = self.problem
        np.copyto(self._owned[0], self.scheme.eta)
        np.copyto(self._owned[1], self.scheme.velocity)
        fields = self.scheme.fields if p.unknowns else {}
        for name, values in fields.items():
            p.unknowns[name].x.array[: p.n_owned] = values
        if self.comm.size > 1:
            for f in (p.eta, p.v, *(p.unknowns[name] for name in fields)):
                f.x.scatter_forward()

    def advance(self) -> StepEnergy:
        """One time step from `t` to `t` + `dt`; returns its energy terms. `InstabilityError` if the energy rose."""
        if self._broken is not None:
            why = self._broken or f"step {self.step + 1} did not finish (interrupted, or an error inside it)"
            raise ValueError(f"advance: the stepper cannot go on: {why}; make a new one from its last state")
        changed = self.parameters.changed
        if self.comm.size > 1:  # a constant set on one rank only: every rank refuses, none waits in the rebuild
            changed = self.comm.allreduce(changed, op=MPI.LOR)
            if changed:
                same_on_every_rank(self.comm, "parameters", dict(self.parameters))
        self._broken = ""  # cleared below: an error within the step or an observer (Ctrl-C) leaves it set
        if changed:
            self._rebuild()
        try:
            terms = self._step()
        except (SystemExit, *PLUGIN_FAULTS) as exc:  # a plugin's sys.exit or broken contract: one line naming it
            raise plugin_failure(f"{self._plugins} at step {self.step + 1}", exc) from None
        if type(terms) is not StepEnergy:
            terms = _energy_terms(terms, f"{self._plugins}: step()")
        internal = self._internal and self._internal.step([self.scheme.eta, *self.scheme.fields.values()], self._dt)
        why = self.ledger.add(terms, self.scheme.energy_slack, internal)
        if self._restart is not None:  # a sub-stepped step left a scheme at Δt started afresh from its end
            self.ledger.rebase(self._restart, numerical=True)
            self._restart = None
        self.step += 1
        self.energies = terms
        if why is not None:
            self._broken = f"it became unstable at step {self.step}"
            raise self._unstable(why)
        self._write_state()
        for stepped in self._stepped:
            stepped(self)
        self._broken = None
        return terms

    def _step(self) -> StepEnergy:
        """The scheme's step; a failed Newton step is retried as 2, 4, … 2^MAX_HALVINGS sub-steps from its state."""
        scheme = self.scheme
        if self.newton:
            eta, v, fields = _state(scheme)
        try:
            return scheme.step()
        except SolverError as exc:
            where = f"step {self.step + 1}, t = {self.t + self._dt:.6g}"
            if not self.newton or getattr(exc, "not_finite", False):  # sub-steps cannot help: the form, a linear solve
                raise SolverError(f"{where}: {exc}") from None
            for halvings in range(1, MAX_HALVINGS + 1):
                try:
                    begin, step, restart = self._substeps(eta, v, fields, 2**halvings)
                except SolverError:
                    continue
                self.ledger.rebase(begin, numerical=True)  # the state before the step, as the sub-steps count it
                self._restart = restart  # booked after the step: the ledger holds the step's end first
                return step
            raise SolverError(f"{where}: {exc}, and again in {2**MAX_HALVINGS} sub-steps of dt/{2**MAX_HALVINGS}; "
                              f"use a smaller dt (nt >= {(self.nt or 1) * 2**MAX_HALVINGS})"
                              + ("" if self.name == "paper" else " or scheme 'paper'")) from None

    def _restarted(self, dt: float, state=None, ops=None, t0: float | None = None):
        """A new scheme at `dt` on `ops` (default: the same operators), started from `state` at the time `t0`
        (default: the current state and time)."""
        scheme = self.scheme
        eta, v, fields = state or _state(scheme)
        self.past_timings.append(scheme.timings)
        self.discrete = self._discrete(ops or self.discrete.ops, dt, fields, self.t if t0 is None else t0)
        fresh = self.Scheme(self.discrete)
        self._restart_terms = fresh.start(eta, v)
        return fresh

    def _substeps(self, eta, v, fields, m: int):
        """One step as `m` sub-steps of Δt/m from (η, v), then a scheme at Δt from their end: the terms of the fine
        start, of the step and of the restart."""
        coarse = self.discrete
        fine = self.Scheme(dataclasses.replace(self._discrete(coarse.ops, self._dt / m, fields, self.t),
                                               nt=(self.nt or 0) * m))
        begin = fine.start(eta, v)
        increments = np.zeros(4)  # viscous, contact, numerical, external: summed; the state's energies: the last
        for _ in range(m):
            terms = fine.step()
            increments += terms[2:6]
        self.counters["sub-stepped steps"] = self.counters.get("sub-stepped steps", 0) + 1
        self.counters["sub-steps"] = self.counters.get("sub-steps", 0) + m
        self.past_timings.append(fine.timings)
        end = _state(fine)
        self.discrete = coarse
        self.scheme = self._restarted(self._dt, end, t0=self.t + self._dt)
        step = StepEnergy(terms.kinetic, terms.elastic, *increments.tolist(), terms.stored)
        return begin, step, self._restart_terms

    def _rebuild(self) -> None:
        """A constant changed: operators and scheme again from the state, the energy jump booked as external work."""
        eta, v, _ = state = _state(self.scheme)
        ops = self.problem.reassemble(not self.Scheme.LINEAR_PATH, lambda: (eta, v))
        self.scheme = self._restarted(self._dt, state, ops)
        self.ledger.rebase(self._restart_terms)
        self.parameters.changed = False

    def _unstable(self, why: str) -> InstabilityError:
        n, scheme, eps = self.step, self.scheme, self.options["eps"]
        situation = f"scheme {self.name}" + (f", {scheme.situation}" if scheme.situation else "")
        return InstabilityError(f"unstable at step {n}, t = {self.t:.6g}: {why} ({situation}); {scheme.remedy}",
                                step=n, time=self.t, r=self._dt / eps if self.Scheme.PENALTIES and eps else None)

    def timings(self) -> dict:
        """Every scheme's counters (a restart makes a new one): numbers summed, descriptions the last one's."""
        out = {}
        for t in [*self.past_timings, self.scheme.timings]:
            for key, value in t.items():
                both = isinstance(value, (int, float)) and isinstance(out.get(key), (int, float))
                out[key] = out[key] + value if both else value
        return out


def _state(scheme) -> tuple:
    """A scheme's whole state, copied: η, v and the model's further unknowns by name."""
    fields = {name: np.array(values) for name, values in scheme.fields.items()}
    return scheme.eta.copy(), np.asarray(scheme.velocity, dtype=float).copy(), fields


def _set_initial(problem: ContactProblem, initial: dict) -> None:
    """`TimeStepper`'s `initial` into the problem's Functions."""
    targets = {"eta": problem.eta, "v": problem.v, **problem.unknowns}
    for name, value in initial.items():
        if name not in targets:
            raise ValueError(f"initial: {name!r} is not an unknown of model '{problem.model.name}'; allowed: "
                             f"{', '.join(targets)}")
        values = np.asarray(value(problem.x) if callable(value) else value, dtype=float)
        if values.shape != (problem.n_owned,) or not np.all(np.isfinite(values)):
            raise ValueError(f"initial: {name!r} needs {problem.n_owned} finite values (this rank's owned dofs)")
        targets[name].x.array[: problem.n_owned] = values
        targets[name].x.scatter_forward()
        if name in problem.unknowns:
            problem.given.add(name)


def _energy_terms(terms, what: str) -> StepEnergy:
    """`terms` as a `StepEnergy` (seven numbers), else a one-line SceneError naming `what` (the plugin's method)."""
    try:
        return StepEnergy(*(float(v) for v in terms))
    except (TypeError, ValueError):
        raise SceneError(f"{what} returned {type(terms).__name__} {terms!r:.80}; allowed: a StepEnergy (seven "
                         "numbers: kinetic, elastic, viscous, contact, numerical, external, stored)") from None


def _model_options(model, ops, params, dim: int, ranks: int, given: dict) -> dict:
    """A nonlinear model's solver defaults, below the user's `given` (a ksp_type or pc_type drops its linear ones)."""
    if ops.nonlinear is None:
        return {}
    hints = model.solver
    if "ksp_type" in given or "pc_type" in given:
        return dict(hints.newton_options)
    return hints.options(dim, ranks, {name: float(c.value) for name, c in params.constants.items()})


class _Constants(MutableMapping):
    """`TimeStepper.parameters`: the model's constants as floats; setting one checks it and sets its Constant."""

    def __init__(self, stepper: TimeStepper):
        self._stepper, self.changed = stepper, False

    def __getitem__(self, name: str) -> float:
        return float(self._stepper.problem.constants[name].value)

    def __setitem__(self, name: str, value) -> None:
        st = self._stepper
        if st.problem.obstacle is not None:
            raise ValueError(f"{name}: a constant cannot change during a run with a moving obstacle; restart from the "
                             "state with the new value")
        values = resolve_parameters(st.model.name, st.model.constants, dict(self) | {name: value},
                                    st.model.check_constants)
        if name not in self._stepper.problem.constants:  # the forms were compiled without it
            raise SceneError(f"{name}: model {st.model.name!r}'s optional constant was not given when the run started, "
                             "and its forms do not read it; allowed: the constants the run started with "
                             f"({', '.join(self) or 'none'}); start a run with {name} in [parameters]")
        self._stepper.problem.constants[name].value = values[name]
        self.changed = True

    def __delitem__(self, name: str) -> None:
        raise TypeError(f"{name}: a model's constant cannot be removed during a run; set its value")

    def __iter__(self):
        return iter(self._stepper.problem.constants)

    def __len__(self) -> int:
        return len(self._stepper.problem.constants)

    def __repr__(self) -> str:
        return f"parameters({dict(self)})"

