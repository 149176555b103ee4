"""`Stepper`: one simulation that you step yourself, the thin block `simulate` loops over.

Like dolfinx's `NonlinearProblem` or Irksome's `TimeStepper.advance()`, it holds a run set up as `simulate` sets it
up (the scheme, the model and its constants, the operators, the stored rows, the output folder) and advances it one
time step per call; what happens between steps is plain Python in the caller's loop.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import MutableMapping

import numpy as np
from mpi4py import MPI

from ..errors import InstabilityError, SceneError, SolverError, plugin_code
from ..fem.agree import one_outcome
from ..fem.operators import semi_discrete_operators
from ..fem.outputs import OutputValues
from ..io.result import FIELDS, Result, node_sort_key
from ..model.paper import penetration_bound_of, reads_eps
from ..scene.names import DEFAULT_MODEL
from ..scene.parameters import resolve_parameters
from ..timestepping.base import StepEnergy
from . import setup
from .checks import checks_of, unbalanced_message
from .ledger import _Ledger, energy_roundoff
from .options import grouped
from .rows import _storage, step_times

__all__ = ["MAX_HALVINGS", "Stepper"]

#: A Newton step that fails is retried as 2, 4, … 2^MAX_HALVINGS sub-steps before the run stops.
MAX_HALVINGS = 4


class Stepper:
    """A simulation stepped by the caller::

        st = sc.Stepper(scene, scheme="projection", model="cubic_foundation")
        while st.step < st.nt:
            st.advance()                     # one time step
            print(st.t, st.eta.min(), st.velocity.max())
        result = st.result()                 # the Result simulate() gives, to the bit

    The arguments are `simulate`'s (which is this loop, with a progress bar and signal handling). `eta`,
    `velocity` and `field(name)` (a model's output field, `Model.outputs`) are NumPy arrays of nodal values on this
    rank, in the order of its nodes `x` (sorted as `Result.x`: by x, then y); `gather(values)` collects such arrays
    of every rank into the order of `Result.x` on rank 0 (collective). Arrays handed out are copies: changing them
    changes nothing in the run.

    `parameters` holds the model's constants (`Model.constants`): ``st.parameters["k"] = 2000.0`` between steps
    changes one (checked like the scene's ``[parameters]``; on every rank alike under MPI). The next `advance()`
    takes it up: the model's operators are assembled again with it and the scheme starts afresh from the state
    (η, v), and the energy ledger books the jump of the state's energy as external work (the work done on the
    string by changing the constant), so the balance still closes.

    A restart from a state: ``scene.replace(eta0=st.gather(st.eta), v0=st.gather(st.velocity), T=..., nt=...)``
    (a string's nodal values as arrays) continues the run to round-off under schemes whose state is (η, v): `paper`
    with the explicit penalty and `newmark`. `projection` and `paper`'s semi-implicit penalty carry more state (the
    previous level's η, an active set), which a restart from (η, v) starts afresh.

    A run that becomes unstable raises `InstabilityError` from `advance()` with the partial Result on it
    (``exc.result``), as `simulate` does, and marks its output folder so.
    """

    def __init__(self, scene, scheme: str | type | None = None, penalty: str | None = None, mass: str | None = None, *,
                 model=None, storage=None, output=None, comm=MPI.COMM_WORLD, petsc_options: dict | None = None,
                 restitution: float | None = None, **keywords):
        storage, self.output = grouped(storage, output, keywords)
        if restitution is not None:  # into the scene, as the command line's: summary.json records what ran
            scene = scene.replace(restitution=restitution)
        if petsc_options:
            scene = scene.replace(petsc_options=setup.petsc_options_of(scene, petsc_options))
            petsc_options = None
        spec = model if model is not None else (scene.model or DEFAULT_MODEL)
        self.name, Scheme, self.penalty, self.mass, self.model = setup._choose_scheme(scene, scheme, penalty, mass,
                                                                                      model)
        with plugin_code(f"model '{self.model.name}'"):  # its functions' sys.exit: one line, not exit 0
            self.constants = setup.model_constants(scene, self.model)
            setup._check_before_mesh(scene, Scheme, self.penalty, self.model, petsc_options, comm)
            t0 = time.perf_counter()
            V, params, ops = setup.discretise(scene, self.model, comm, self.constants, not Scheme.LINEAR_PATH)
            setup._check_moving_obstacle(scene, Scheme, self.penalty, self.model, V, params)
            problem = setup._discrete_problem(scene, self.model, V, params, ops, self.penalty, self.mass, comm,
                                              petsc_options)
            self.scene, self.comm, self.problem, self.scheme = scene, comm, problem, Scheme(problem)
            self._Scheme, self._V, self._params, self._petsc_options = Scheme, V, params, petsc_options
            self._newton = ops.nonlinear is not None  # a Newton path, whose step may fail and be sub-stepped
            self._restart = None  # the start terms of a scheme restarted after sub-steps
            self.parameters = _Constants(self)
            self.outputs = OutputValues(self.model, V, params)
        self.rows, self.geometry, self.row_series = _storage(scene, problem, V, storage, self.outputs)
        self.timings = {"setup": time.perf_counter() - t0}
        self.counters, self.solver = {}, {}
        self.origin = setup._model_origin(spec, self.model)
        nonlinear = ops.nonlinear
        derived = nonlinear is not None and nonlinear.energy_derived  # the form's potential is booked
        self.energy_label = self.model.energy_label or (setup.POTENTIAL_LABEL if derived else None)
        self.dt, self.nt, self.step = scene.dt, scene.nt, 0
        self._order = np.argsort(node_sort_key(problem.x), kind="stable")  # this rank's nodes in x order
        self._loop_time, self._done, self._past_timings = 0.0, None, []
        self._start(V)

    def _start(self, V) -> None:
        """The scheme's initial state (η⁰, v⁰) opens the ledger; then the writer, if any, and the row at t = 0."""
        problem, scheme, rows = self.problem, self.scheme, self.rows
        start = one_outcome(problem.comm, setup._initial_state, self.scene, problem)  # one outcome
        self.ledger = _Ledger(scheme.start(*start),
                              conservative=self.model.contact_energy is not None or scheme.energy_may_rise,
                              floor=energy_roundoff(problem.ops.K, scheme.eta, problem.comm), slack=scheme.energy_slack)
        rows.min_eta = float(np.min(scheme.eta[problem.interior])) if problem.interior.any() else math.inf
        # ψ at the owned nodes for the gap η − ψ (`Result.min_gap`): None for the flat ψ = 0 (the gap is η) and for a
        # moving obstacle (ψ at each step's time, `_gap`)
        self._psi = (np.asarray(self.scene.obstacle_values(problem.x), dtype=float)
                     if self.scene.obstacle is not None and problem.obstacle is None else None)
        rows.min_gap = self._gap(scheme.eta, 0)
        self.writer = setup._writer(self.scene, V, self.comm, rows, self.output)
        with self._guarded():
            if rows.next_step == 0:
                self._store(0)

    # --- the state, on this rank, in the order of `x` ------------------------------------------------------------

    @property
    def t(self) -> float:
        """The time of the state: step × Δt (a scene's output time as given at its step, like `Result.t`)."""
        return float(step_times([self.step], self.dt, self.scene.output_times)[0])

    @property
    def x(self) -> np.ndarray:
        """This rank's node coordinates, sorted as `Result.x` (by x, then y): (n,) for a string, (n, 2) for a membrane."""
        return self.problem.x[self._order]

    @property
    def eta(self) -> np.ndarray:
        """η at this rank's nodes, in the order of `x` (a copy)."""
        return self.scheme.eta[self._order]

    @property
    def velocity(self) -> np.ndarray:
        """The scheme's velocity at this rank's nodes, in the order of `x` (a copy)."""
        return np.asarray(self.scheme.velocity)[self._order]

    def field(self, name: str) -> np.ndarray:
        """The model's output field `name` (`Model.outputs`) at this rank's nodes, in the order of `x`."""
        values = self.outputs(self.scheme.eta, getattr(self.scheme, "fields", {}))
        if name not in values:
            raise KeyError(f"field {name!r}: model {self.model.name!r} writes {', '.join(values) or 'none'}")
        return np.asarray(values[name])[self._order]

    def gather(self, values) -> np.ndarray | None:
        """This rank's nodal `values` (in the order of `x`) and every other rank's, in the order of `Result.x`: on
        rank 0 (every rank with ``Storage(gather="all")``), None elsewhere. Collective: every rank calls it."""
        values = np.asarray(values, dtype=float)
        owned = np.empty_like(values)
        owned[self._order] = values
        return self.rows.gather(owned)

    # --- stepping -----------------------------------------------------------------------------------------------

    def advance(self) -> None:
        """One time step from `t` to `t` + Δt: the scheme's step, the energy ledger and its guard, and the row stored
        (and written) if this step is one of the stored ones. Raises `InstabilityError` (with ``exc.result``) if the
        energy rose, ValueError past T."""
        if self.step >= self.nt:
            raise ValueError(f"advance: the run is at T = {self.scene.T:g} (step {self.nt}); take its result()")
        with self._guarded(), np.errstate(all="ignore"):  # NaN, overflow: the energy guard names the step
            if self.parameters.changed:
                self._rebuild()
            self._advance()

    def _rebuild(self) -> None:
        """The model's constants changed: its operators again, a new scheme started from the state (η, v), the
        jump of the state's energy booked as external work (`_Ledger.rebase`)."""
        old = self.scheme
        eta, v = old.eta.copy(), np.asarray(old.velocity, dtype=float).copy()
        ops = semi_discrete_operators(self.model, self._V, self._params, not self._Scheme.LINEAR_PATH,
                                      lambda: (eta, v))  # the state, where a form singular at 0 is linearised
        problem = setup._discrete_problem(self.scene, self.model, self._V, self._params, ops, self.penalty, self.mass,
                                          self.comm, self._petsc_options)
        self._past_timings.append(old.timings)
        self.problem, self.scheme = problem, self._Scheme(problem)
        self.ledger.rebase(self.scheme.start(eta, v))
        self.constants = dict(self.parameters)
        self.parameters.changed = False

    def _advance(self) -> None:
        """`advance` without its guards: the loop of `simulate` holds them once for all its steps."""
        t0 = time.perf_counter()
        scheme, rows = self.scheme, self.rows
        why = self.ledger.add(self._step() if self._newton else scheme.step(), scheme.energy_slack)
        if self._restart is not None:  # a sub-stepped step left a scheme at Δt started afresh from its end
            self.ledger.rebase(self._restart, numerical=True)
            scheme, self._restart = self.scheme, None
        eta = scheme.eta  # once per step: a property of the scheme
        if eta.size:
            low = float(eta.min())
            rows.min_eta = min(rows.min_eta, low)
            rows.min_gap = min(rows.min_gap, low if self.scene.obstacle is None else self._gap(eta, self.step + 1))
        self.step += 1
        if why is not None:
            raise self._unstable(why)
        if self.step == rows.next_step:
            self._store(self.step)
        self._loop_time += time.perf_counter() - t0

    def _gap(self, eta: np.ndarray, n: int) -> float:
        """min (η − ψ) over this rank's nodes at step n (inf without nodes): ψ = 0, the scene's ψ(x) or ψ(x, t_n)."""
        if not eta.size:
            return math.inf
        if self.scene.obstacle is None:
            return float(eta.min())
        psi = self._psi if self._psi is not None else self.problem.obstacle.owned(n * self.dt)
        return float(np.min(eta - psi))

    def _step(self):
        """A Newton path's step, retried as 2, 4, … up to 2^MAX_HALVINGS sub-steps from the same state when Newton fails
        (`_substeps`); a SolverError naming the time, the step and what to change only when the finest fails."""
        scheme = self.scheme
        eta, v = scheme.eta.copy(), np.asarray(scheme.velocity, dtype=float).copy()
        try:
            return scheme.step()
        except SolverError as exc:
            if getattr(exc, "not_finite", False):  # the model's form, not the step size: sub-steps cannot help
                raise SolverError(f"step {self.step + 1}, t = {(self.step + 1) * self.dt:.6g}: {exc}") from None
            if self.scene.obstacle_moves:  # a scheme restarted mid-run would start its obstacle at t = 0
                raise
            for halvings in range(1, MAX_HALVINGS + 1):
                try:
                    begin, step, restart = self._substeps(eta, v, 2**halvings)
                except SolverError:
                    continue
                self.ledger.rebase(begin, numerical=True)  # the state before the step, as the sub-steps count it
                self._restart = restart  # booked after the step (`_advance`): the ledger holds the step's end first
                return step
            raise SolverError(f"step {self.step + 1}, t = {(self.step + 1) * self.dt:.6g}: {exc}, and again in "
                              f"{2**MAX_HALVINGS} sub-steps of dt/{2**MAX_HALVINGS}; use a smaller dt (nt >= "
                              f"{self.nt * 2**MAX_HALVINGS}) or scheme 'paper'") from None

    def _substeps(self, eta, v, m: int):
        """One step as `m` sub-steps of Δt/m by a scheme started afresh from (η, v) (the state before the failed step,
        restored exactly), their energy terms summed; then a scheme at Δt started from the sub-steps' end. Returns
        the fine scheme's start terms, the step's terms and the restarted scheme's start terms (the ledger books the
        two starts' differences from the energies it holds as numerical dissipation: `_Ledger.rebase`)."""
        fine = setup._discrete_problem(self.scene.replace(nt=self.nt * m), self.model, self._V, self._params,
                                       self.problem.ops, self.penalty, self.mass, self.comm, self._petsc_options)
        scheme = self._Scheme(fine)
        begin = scheme.start(eta, v)
        increments = np.zeros(4)  # viscous, contact, numerical, external: summed; the energies of the state: the last
        for _ in range(m):
            terms = scheme.step()
            increments += terms[2:6]
        self.counters["sub-stepped steps"] = self.counters.get("sub-stepped steps", 0) + 1
        self.counters["sub-steps"] = self.counters.get("sub-steps", 0) + m
        end_eta, end_v = scheme.eta.copy(), np.asarray(scheme.velocity, dtype=float).copy()
        self._past_timings.append(self.scheme.timings)
        self._past_timings.append(scheme.timings)
        self.scheme = self._Scheme(self.problem)
        step = StepEnergy(terms.kinetic, terms.elastic, *increments.tolist(), terms.stored)
        return begin, step, self.scheme.start(end_eta, end_v)

    def _unstable(self, why: str) -> InstabilityError:
        n, scheme, scene = self.step, self.scheme, self.scene
        t_n = n * scene.dt
        situation = f"scheme {self.name}" + (f", {scheme.situation}" if scheme.situation else "")
        return InstabilityError(f"unstable at step {n}, t = {t_n:.6g}: {why} ({situation}); {scheme.remedy}", step=n,
                                time=t_n, r=scene.dt / scene.eps if scheme.PENALTIES else None)

    def _store(self, n: int) -> None:
        scheme = self.scheme
        fields = {"eta": scheme.eta, "velocity": scheme.velocity, "contact": scheme.contact(),
                  "contact_force": scheme.contact_force}
        fields.update(self.outputs(scheme.eta, getattr(scheme, "fields", {})))
        t = float(step_times([n], self.dt, self.scene.output_times)[0])
        self.rows.store(fields, self.ledger.cumulative, self.row_series(fields, t))
        if self.writer is not None:
            self.writer.write(t, {k: np.asarray(a, dtype=float) for k, a in fields.items()})

    @contextlib.contextmanager
    def _guarded(self):
        """A stopped run leaves its partial Result on the exception (and its folder marked), an unexpected error no
        folder; a step that fails after the input was accepted is a SolverError, not an input error."""
        try:
            yield
        except (InstabilityError, KeyboardInterrupt) as exc:
            status = "unstable" if isinstance(exc, InstabilityError) else "interrupted"
            exc.result = self._result(status, str(exc) or status)  # the rows so far: partial output, the report
            if self.writer is not None:
                self.writer.abort(status, exc.result.message, result=exc.result, error=exc)
            raise
        except BaseException as exc:
            if self.writer is not None:
                self.writer.discard()  # an unexpected error: no half-written folder, no stale lock
            if isinstance(exc, SceneError):  # a scene's field checked where it is evaluated (an obstacle in t)
                raise
            if isinstance(exc, ValueError):  # the input was checked before the march: no input error
                raise SolverError(f"step failed: {exc}") from exc
            raise

    # --- the result ---------------------------------------------------------------------------------------------

    def result(self) -> Result:
        """The Result of the run, once it is at T: "complete" (or "unbalanced" if its energy balance does not close),
        its output folder written; the same object on a second call."""
        if self._done is not None:
            return self._done
        if self.step < self.nt:
            raise ValueError(f"result: the run is at step {self.step} of {self.nt} (t = {self.t:g}); advance() to T")
        writer = self.writer
        self.timings["solve"] = self._loop_time - (writer.write_time if writer is not None else 0.0)  # I/O apart
        summed = _summed(*self._past_timings, self.scheme.timings)
        self.counters |= {k: v for k, v in summed.items() if isinstance(v, int)}
        self.solver = {k: v for k, v in summed.items() if isinstance(v, str)}
        result = self._result("complete", "")
        unbalanced = unbalanced_message(result)  # a balance that does not close is not a complete run
        if unbalanced is not None:
            result.status, result.message = "unbalanced", unbalanced
        if writer is not None:
            t_io = time.perf_counter()
            writer.finish(result)
            self.timings["output"] = time.perf_counter() - t_io + writer.write_time
        self._done = result
        return result

    def _result(self, status: str, message: str) -> Result:
        rows, comm, scene = self.rows, self.comm, self.scene
        n = rows.n
        together = comm.size > 1 and status == "complete"  # a stopped run's ranks may not all get here
        mins = comm.allreduce(rows.min_eta, op=MPI.MIN) if together else rows.min_eta
        gap = comm.allreduce(rows.min_gap, op=MPI.MIN) if together else rows.min_gap
        if rows.gather.holds:
            stored = {k: v[:n] for k, v in rows.fields.items()}
            per_node = {k: stored.pop(k) for k in FIELDS} | {"fields": stored}  # the rest: the model's output fields
        else:
            per_node = dict.fromkeys(FIELDS) | {"fields": {}}
        result = Result(scene=scene, x=rows.gather.x, t=step_times(rows.steps[:n], scene.dt, scene.output_times),
                        steps=rows.steps[:n], **per_node, energy={k: v[:n] for k, v in rows.energy.items()},
                        min_eta=float(mins), min_gap=float(gap), penalty=self.penalty or "none", mass=self.mass, model=self.model.name,
                        model_origin=self.origin, penetration_bound=penetration_bound_of(self.model),
                        law_reads_eps=reads_eps(self.model, self._V, self._params),
                        energy_label=self.energy_label, status=status, timings=self.timings, message=message,
                        counters=self.counters, solver=self.solver,
                        petsc_options=dict(self.problem.petsc_options or {}), scheme=self.name, **self.geometry,
                        field_info=self.outputs.info, parameters=dict(self.constants),
                        series={k: v[:n] for k, v in rows.series.items()}, has_rows=rows.gather.holds)
        checks_of(result)  # the energy balance and the penetration check, once (summary.json, the CLI)
        return result


def _summed(*timings: dict) -> dict:
    """Schemes' counters one after the other (a constant changed mid-run starts a new scheme): numbers added up,
    a description the last one's."""
    out = {}
    for t in timings:
        for key, value in t.items():
            both = isinstance(value, (int, float)) and isinstance(out.get(key), (int, float))
            out[key] = out[key] + value if both else value
    return out


class _Constants(MutableMapping):
    """`Stepper.parameters`: the model's constants by name, as floats; setting one checks it (`ModelConstant.check`
    and the model's rule) and sets the dolfinx Constant the forms read, for the next step to take up."""

    def __init__(self, stepper: Stepper):
        self._stepper, self.changed = stepper, False

    def _constants(self) -> dict:
        return self._stepper._params.constants

    def __getitem__(self, name: str) -> float:
        return float(self._constants()[name].value)

    def __setitem__(self, name: str, value) -> None:
        st = self._stepper
        if st.scene.obstacle_moves:
            raise ValueError(f"{name}: a constant cannot change during a run with a moving obstacle (its scheme would "
                             "start its obstacle again at t = 0); restart from the state with the new value")
        values = resolve_parameters(st.model.name, st.model.constants, dict(self) | {name: value},
                                    st.model.check_constants)
        self._constants()[name].value = values[name]
        self.changed = True

    def __delitem__(self, name: str) -> None:
        raise TypeError(f"{name}: a model's constant cannot be removed during a run; set its value")

    def __iter__(self):
        return iter(self._constants())

    def __len__(self) -> int:
        return len(self._constants())

    def __repr__(self) -> str:
        return f"parameters({dict(self)})"
