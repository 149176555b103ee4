"""`Stepper`: a scene's run stepped by the caller: the scene adapted to a `ContactProblem` (`run.adapter`), its
`TimeStepper`, and the standard observers (the stored rows, the output folder), with the `Result` at the end."""

from __future__ import annotations

import contextlib
import functools
import time

import numpy as np
from mpi4py import MPI

from ..core.stepper import TimeStepper
from ..errors import InstabilityError, ModelError, SceneError, SolverError, one_line, plugin_code
from ..io.result import FIELDS, Result, node_sort_key
from ..model.interface import penetration_bound_of, reads_eps
from ..scene.names import DEFAULT_MODEL
from . import adapter
from .checks import checks_of, restless, still_message, unbalanced_message
from .options import Output, Storage, picture_function
from .rows import RowObserver, output_steps, step_times

__all__ = ["POTENTIAL_LABEL", "THREADED_LENGTH", "Stepper", "one_thread"]

#: energy.png's legend of a nonlinear form's stored energy when the model declares none (`fem.operators.potential_energy`)
POTENTIAL_LABEL = r"stored: the potential $\int_0^1 G(s\eta;\eta)\,ds$ of momentum_form"
#: BLAS is held to one thread (threadpoolctl) while a run steps nodal vectors longer than this: OpenBLAS threads a dot
#: product of over 10,000 entries, and the stiff string's Example 1 stepped 5 to 14 times slower for it on a loaded
#: 2-core machine (`benchmarks/bench_blas_threads.py`); shorter ones set no limit (it costs about 11 µs, a tenth of a
#: small string's step).
THREADED_LENGTH = 8192


@functools.cache
def _blas():
    """threadpoolctl's view of the BLAS libraries loaded now (made once: it scans the process's libraries)."""
    from threadpoolctl import ThreadpoolController

    controller = ThreadpoolController().select(user_api="blas")
    return controller if any(lib.num_threads > 1 for lib in controller.lib_controllers) else None


def one_thread(length: int):
    """A context in which BLAS runs on one thread, for a run whose nodal vectors have `length` entries (nothing to
    do up to `THREADED_LENGTH`, or where BLAS has one thread already); the caller's setting comes back after."""
    controller = _blas() if length > THREADED_LENGTH else None
    return controller.limit(limits=1) if controller is not None else contextlib.nullcontext()


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
    of every rank into the order of `Result.x` on rank 0 (collective). Arrays handed out are copies.

    It is the scene's `ContactProblem` (`problem`: the mesh, the Functions) and its `TimeStepper` (`core`), with the
    stored rows and the output folder attached as observers. `parameters` holds the model's constants:
    ``st.parameters["k"] = 2000.0`` between steps changes one, the jump of the state's energy booked as external work.

    `fields0` starts the model's further unknowns (the scene key ``fields0``); ``sc.continued(scene, st)``
    (`run.restart`) makes the scene of the whole state now (docs/tutorial/own_time_loop.md).

    A run that becomes unstable raises `InstabilityError` from `advance()` with the partial Result on it
    (``exc.result``), as `simulate` does, and marks its output folder so; the stepper then refuses to go on.
    """

    def __init__(self, scene, scheme: str | type | None = None, penalty: str | None = None, mass: str | None = None, *,
                 model=None, storage=None, output=None, comm=MPI.COMM_WORLD, petsc_options: dict | None = None,
                 restitution: float | None = None, fields0: dict | None = None):
        storage = storage if storage is not None else Storage()
        self.output = output if output is not None else Output()
        changes = {"fields0": dict(scene.fields0) | dict(fields0)} if fields0 else {}  # into the scene, as its keys:
        changes |= {"restitution": restitution} if restitution is not None else {}  # summary.json records what ran
        changes |= {"petsc_options": dict(scene.petsc_options) | dict(petsc_options)} if petsc_options else {}
        scene = scene.replace(**changes) if changes else scene
        spec = model if model is not None else (scene.model or DEFAULT_MODEL)
        plan = adapter.check_scene_run(scene, scheme, model, comm, penalty=penalty, mass=mass)
        self.name, self.model = plan.name, plan.model
        self.penalty, self.mass = plan.options["penalty"], plan.options["mass"]
        self.scene, self.comm, self.constants = scene, comm, plan.constants
        t0 = time.perf_counter()
        with plugin_code(f"model '{self.model.name}'"):  # its functions' sys.exit: one line, not exit 0
            self.problem = adapter.scene_problem(scene, self.model, comm, plan.constants)
            eta0, v0 = self.problem.initial_state()  # the state the checks read, not the scheme's copy of it
            self.core = TimeStepper(self.problem, scene.dt, plan.Scheme, nt=scene.nt, **plan.options)
            self._start = eta0, restless(self.core, eta0, v0)
        self.parameters = self.core.parameters
        self.timings = {"setup": time.perf_counter() - t0}
        self.counters, self.solver = self.core.counters, {}
        from ..model.registry import model_origin

        self.origin = model_origin(spec, self.model)
        nonlinear = self.core.discrete.ops.nonlinear
        derived = nonlinear is not None and nonlinear.energy_derived  # the form's potential is booked
        self.energy_label = self.model.energy_label or (POTENTIAL_LABEL if derived else None)
        self.law_reads_eps = reads_eps(self.model, self.problem.V, self.problem.params)
        self.dt, self.nt = scene.dt, scene.nt
        self._order = np.argsort(node_sort_key(self.problem.x), kind="stable")  # this rank's nodes in x order
        self._loop_time, self._done, self._stopped = 0.0, None, None  # _stopped: the error that stopped the run
        self.rows = RowObserver(self.core, scene.nt, scene.dt, scene.output_times, storage)
        self.writer = self._writer()
        self.rows.sink = self.writer.write if self.writer is not None else None
        self.vector_length = self.problem.n_owned * (1 + len(self.model.fields))  # this rank's unknowns
        with self._guarded():
            self.core.attach(self.rows)

    def _writer(self):
        """The output folder's writer (None without `output.dir`): its lock is taken now, its frames chosen."""
        output = self.output
        if output.dir is None:
            return None
        from ..io.folder import OutputWriter, xdmf_frames

        pictures = picture_function(output)  # the default pictures and/or the caller's function
        frames = xdmf_frames(self.rows.steps, output_steps(self.nt, self.dt, self.scene.output_times),
                             output.max_frames)
        return OutputWriter(output.dir, self.scene, self.problem.V, self.comm, force=output.force,
                            pictures=pictures or None, frames=frames)

    # --- the state, on this rank, in the order of `x` ------------------------------------------------------------

    @property
    def step(self) -> int:
        """The steps taken."""
        return self.core.step

    @property
    def scheme(self):
        """The scheme stepping the run now (a `timestepping.base.Scheme`)."""
        return self.core.scheme

    @property
    def discrete(self):
        """The discrete problem the scheme steps (`timestepping.base.DiscreteProblem`)."""
        return self.core.discrete

    @property
    def ledger(self):
        """The run's energy ledger (`core.ledger.EnergyLedger`)."""
        return self.core.ledger

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
        values = self.problem.outputs(self.scheme.eta, self.scheme.fields)
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
        self._refuse_if_stopped("advance")
        if self.step >= self.nt:
            raise ValueError(f"advance: the run is at T = {self.scene.T:g} (step {self.nt}); take its result()")
        # NaN, overflow: the energy guard names the step; BLAS on one thread for long vectors (`one_thread`)
        with self._guarded(), np.errstate(all="ignore"), one_thread(self.vector_length):
            self._advance()

    def _advance(self) -> None:
        """`advance` without its guards: the loop of `simulate` holds them once for all its steps."""
        t0 = time.perf_counter()
        self.core.advance()
        self._loop_time += time.perf_counter() - t0

    @contextlib.contextmanager
    def _guarded(self):
        """A stopped run leaves its partial Result on the exception (and its folder marked), an unexpected error no
        folder; a step that fails after the input was accepted is a SolverError, not an input error."""
        try:
            yield
        except (InstabilityError, KeyboardInterrupt) as exc:
            self._stopped = exc  # its folder is marked: the run cannot go on
            status = "unstable" if isinstance(exc, InstabilityError) else "interrupted"
            exc.result = self._result(status, str(exc) or status)  # the rows so far: partial output, the report
            if self.writer is not None:
                self.writer.abort(status, exc.result.message, result=exc.result, error=exc)
            raise
        except BaseException as exc:
            self._stopped = exc
            if self.writer is not None:
                self.writer.discard()  # an unexpected error: no half-written folder, no stale lock
            if isinstance(exc, (SceneError, ModelError)):  # a scene's field checked where it is evaluated (an obstacle
                raise  # in t), a model's output field that is not finite
            if isinstance(exc, ValueError):  # the input was checked before the march: no input error
                raise SolverError(f"step failed: {exc}") from exc
            raise

    def _refuse_if_stopped(self, what: str) -> None:
        """A run stopped by an error (an instability, Ctrl-C, a plugin's failure) cannot go on: one line."""
        if self._stopped is not None:
            result = getattr(self._stopped, "result", None)
            why = f"{result.status}: {result.message}" if result is not None else f"failed: {self._stopped}"
            raise ValueError(f"{what}: the run stopped at step {self.step} ({one_line(why, 300)}); "
                             "it cannot go on; result() gives what it stored (if it stopped unstable or interrupted), or start a new "
                             "Stepper from its state")

    # --- the result ---------------------------------------------------------------------------------------------

    def result(self) -> Result:
        """The Result of the run, once it is at T: "complete" (or "unbalanced" if its energy balance does not close),
        its output folder written; the same object on a second call."""
        if self._done is not None:
            return self._done
        if getattr(self._stopped, "result", None) is not None:  # unstable or interrupted: that partial Result
            return self._stopped.result
        self._refuse_if_stopped("result")
        if self.step < self.nt:
            raise ValueError(f"result: the run is at step {self.step} of {self.nt} (t = {self.t:g}); advance() to T")
        writer = self.writer
        self.timings["solve"] = self._loop_time - (writer.write_time if writer is not None else 0.0)  # I/O apart
        summed = self.core.timings()
        self.counters |= {k: v for k, v in summed.items() if isinstance(v, int)}
        self.solver = {k: v for k, v in summed.items() if isinstance(v, str)}
        result = self._result("complete", "")
        # a balance that does not close, or a string that never moved though not at rest, is not a complete run
        unbalanced = unbalanced_message(result) or still_message(self, *self._start)
        if unbalanced is not None:
            result.status, result.message = "unbalanced", unbalanced
        self.core.finish()
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
                        min_eta=float(mins), min_gap=float(gap), penalty=self.penalty or "none", mass=self.mass,
                        model=self.model.name, model_origin=self.origin,
                        penetration_bound=penetration_bound_of(self.model), law_reads_eps=self.law_reads_eps,
                        energy_label=self.energy_label,
                        status=status, timings=self.timings, message=message, counters=self.counters,
                        solver=self.solver, petsc_options=dict(self.discrete.petsc_options or {}), scheme=self.name,
                        **rows.geometry, field_info=self.problem.outputs.info, parameters=dict(self.parameters),
                        series={k: v[:n] for k, v in rows.series.items()}, has_rows=rows.gather.holds)
        checks_of(result)  # the energy balance and the penetration check, once (summary.json, the CLI)
        return result

