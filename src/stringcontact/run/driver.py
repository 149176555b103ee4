"""The time loop: discretise, choose the scheme, march, store, write. It knows no scheme.

`simulate` builds the model's operators on the mesh (`fem.operators.semi_discrete_operators`), hands them
to the chosen scheme (`timestepping/`), and then only calls ``step()``, sums the energy terms the scheme
reports into the ledger, guards against energy growth, and stores about `max_rows` rows (`options.Storage`):
on rank 0 (`gather="all"`: every rank), within `ROW_BUDGET` bytes; every rank keeps the per-time series.
What it writes is `options.Output`'s.
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InstabilityError, SceneError, SolverError
from ..fem import compat, domains
from ..fem.agree import agreed
from ..fem.operators import bc_dofs, node_coordinates, semi_discrete_operators
from ..fem.outputs import OutputValues
from ..io.result import ENERGY_KEYS, FIELDS, Result, canonical_cells, node_sort_key
from ..io.signals import StopTogether
from ..model.paper import Model, Parameters, inelastic, penetration_bound_of, unused_fields
from ..scene.parameters import resolve_parameters
from ..scene import BYTES_PER_STORED_NODE, STORED_ROWS, check_petsc_options
from ..timestepping import check_model, check_restitution, scheme_class
from ..timestepping.base import MovingObstacle, NodalLaws, Setting, check_law_stability
from ..timestepping.linear import check_option_values
from .checks import checks_of, unbalanced_message
from .options import ROW_BUDGET, Output, Storage, grouped

#: `ROW_BUDGET`, `STORED_ROWS`: the storage defaults (`options.Storage`), importable from here as before.
__all__ = ["ROW_BUDGET", "STORED_ROWS", "Output", "Storage", "StorageWarning", "simulate"]


def output_steps(nt: int, dt: float, output_times) -> set[int]:
    """The steps nearest to the scene's output times."""
    return {min(nt, max(0, round(t / dt))) for t in output_times}


def step_times(steps, dt: float, output_times=()) -> np.ndarray:
    """The times of `steps`, stored exactly: n·Δt rounded to 12 significant digits (0.04, not the product
    0.039999999999999994), and a scene's output time as given where its step is that time (to round-off)."""
    steps = np.asarray(steps, dtype=np.int64)
    times = np.array([float(f"{n * dt:.12g}") for n in steps.tolist()], dtype=float)
    for t in output_times:
        hit = np.flatnonzero(np.abs(steps * dt - float(t)) <= 1e-9 * max(dt, abs(float(t))))
        times[hit] = float(t)
    return times


def stored_steps(nt: int, dt: float, output_times, max_rows: int) -> np.ndarray:
    """Every k-th step so that about `max_rows` rows are kept, plus 0, nt and the scene's output times."""
    stride = max(1, math.ceil(nt / max(1, max_rows)))
    steps = set(range(0, nt + 1, stride)) | {0, nt} | output_steps(nt, dt, output_times)
    return np.array(sorted(steps), dtype=np.int64)


class StorageWarning(UserWarning):
    """The stored rows were thinned to fit the row budget."""


def budget_steps(nt: int, dt: float, output_times, max_rows: int, nodes: int, budget: int):
    """`stored_steps`, thinned so that the rows (`nodes` × BYTES_PER_STORED_NODE bytes each) fit `budget` bytes.

    Returns (steps, note): note is None, or one line saying what was kept. 0, T and the output times are
    always kept (if they alone do not fit, ValueError), with every k-th step for the smallest k that fits.
    """
    steps = stored_steps(nt, dt, output_times, max_rows)
    row = max(1, nodes) * BYTES_PER_STORED_NODE
    allowed = budget // row
    if len(steps) <= allowed:
        return steps, None
    fixed = {0, nt} | output_steps(nt, dt, output_times)
    if allowed < len(fixed):
        raise ValueError(
            f"output_times: 0, T and the output times are {len(fixed)} stored rows of {nodes} nodes "
            f"({len(fixed) * row / 1e9:.3g} GB); allowed: at most {allowed} rows (row budget {budget / 1e9:.3g} GB); "
            "give fewer output times or a coarser mesh")
    lo, hi = 1, nt + 1  # stride nt + 1 keeps the fixed steps only, which fit
    while lo < hi:  # the smallest stride that fits (a bisection: the count falls with the stride, nearly monotone)
        mid = (lo + hi) // 2
        if nt // mid + 1 + sum(1 for f in fixed if f % mid) <= allowed:
            hi = mid
        else:
            lo = mid + 1
    kept = np.array(sorted(set(range(0, nt + 1, hi)) | fixed), dtype=np.int64)
    note = (f"max_rows = {max_rows}: {len(steps)} stored rows of {nodes} nodes would take {len(steps) * row / 1e9:.3g} GB, "
            f"over the row budget of {budget / 1e9:.3g} GB; keeping {len(kept)} rows (every {hi}-th step, with 0, T "
            "and the output times)")
    return kept, note


class _Gather:
    """Gathers owned dof arrays in x order (2D: by x, then y; the same for any number of ranks) to rank 0,
    or with `to_all` to every rank. Where they are not gathered, `holds` is False and `x` is None.

    The concatenation of the ranks' owned dofs is dolfinx's global dof numbering; `order` maps x order to it.
    """

    def __init__(self, comm, x_owned: np.ndarray, to_all: bool = False):
        self.comm, self.to_all = comm, to_all
        self.counts = comm.allgather(len(x_owned)) if comm.size > 1 else [len(x_owned)]
        self.nodes = int(sum(self.counts))
        self.holds = to_all or comm.rank == 0
        xs = _collect(comm, x_owned, to_all)
        self.order = self.x = None
        self.identity = False
        self._buffers = {}
        if self.holds:
            x = np.concatenate(xs)
            self.order = np.argsort(node_sort_key(x), kind="stable")
            self.x = x[self.order]
            self.identity = bool(np.array_equal(self.order, np.arange(self.order.size)))

    def __call__(self, a: np.ndarray, out: np.ndarray | None = None) -> np.ndarray | None:
        """The gathered array in x order (into `out`) where held; None elsewhere. Collective."""
        a = np.ascontiguousarray(a, dtype=out.dtype if out is not None else None)
        if self.comm.size == 1 and self.identity:  # serial, dofs already in x order: one copy
            if out is None:
                return a.copy()
            out[...] = a
            return out
        send = a.view(np.uint8) if a.dtype == bool else a  # MPI has no NumPy bool: its bytes
        buf = self._buffer(send.dtype) if self.holds else None
        if self.comm.size == 1:
            buf[...] = send
        elif self.to_all:
            self.comm.Allgatherv(send, [buf, self.counts])
        else:
            self.comm.Gatherv(send, [buf, self.counts] if self.holds else None, root=0)
        if not self.holds:
            return None
        return np.take(buf.view(a.dtype), self.order, out=out)

    def _buffer(self, dtype) -> np.ndarray:
        if dtype not in self._buffers:
            self._buffers[dtype] = np.empty(self.nodes, dtype=dtype)
        return self._buffers[dtype]


def _collect(comm, a: np.ndarray, to_all: bool) -> list | None:
    """The ranks' arrays, in rank order: on rank 0 (every rank with `to_all`); None elsewhere."""
    if comm.size == 1:
        return [a]
    return comm.allgather(a) if to_all else comm.gather(a, root=0)


class _Rows:
    """The stored rows where they are gathered (rank 0, or every rank), and on every rank the cumulative
    energy terms and the `series` the ranks sum at each stored time (Result.series)."""

    def __init__(self, steps: np.ndarray, gather: _Gather, extra: tuple = ()):
        self.steps, self.gather, self.n = steps, gather, 0
        k = len(steps)
        self.fields = {}
        if gather.holds:  # `extra`: the model's output fields (`Model.outputs`)
            self.fields = {name: np.empty((k, gather.nodes)) for name in ("eta", "velocity", "contact_force", *extra)}
            self.fields["contact"] = np.empty((k, gather.nodes), dtype=bool)
        self.energy = {key: np.empty(k) for key in ENERGY_KEYS}
        self.series = {key: np.empty(k) for key in SERIES_KEYS}

    @property
    def next_step(self) -> int:
        return self.steps[self.n] if self.n < len(self.steps) else -1

    def store(self, fields: dict, energies, series) -> None:
        for name, arr in fields.items():
            arr = np.asarray(arr, dtype=bool if name == "contact" else float)  # the same bytes from every rank
            self.gather(arr, out=self.fields[name][self.n] if self.fields else None)
        for key, value in zip(ENERGY_KEYS, energies):
            self.energy[key][self.n] = value
        for key, value in zip(SERIES_KEYS, series):
            self.series[key][self.n] = value
        self.n += 1


SERIES_KEYS = ("contact_measure", "max_speed", "depth")


def _row_series(comm, fields: dict, weights: np.ndarray, obstacle: np.ndarray) -> tuple[float, float, float]:
    """One stored time's series over all ranks: Σ weights·contact (the contact length or area), max |v|,
    max (obstacle − η). Collective: two allreduces of a few numbers."""
    measure = float(np.dot(weights, np.asarray(fields["contact"], dtype=float)))
    highs = np.array([np.max(np.abs(fields["velocity"]), initial=-np.inf),
                      np.max(obstacle - fields["eta"], initial=-np.inf)])
    if comm.size > 1:
        measure = comm.allreduce(measure, op=MPI.SUM)
        mine, highs = highs, np.empty(2)
        comm.Allreduce(mine, highs, op=MPI.MAX)
    return measure, float(highs[0]), float(highs[1])


class _Ledger:
    """E(0) + W_ext = E(t) + D_visc + D_con + D_num, summed from the scheme's terms; and the energy guard.

    A dissipative law may not raise the energy at all (1e-9 E(0) per step for round-off). A conservative
    law (a contact spring, `Model.contact_energy`) held explicitly makes it wobble by O(Δt/√ε) during an
    impact, which can be most of E(0) at large Δt/ε; an instability grows exponentially, so there the
    energy may not exceed 2 E(0). So for a scheme that declares `energy_may_rise` (a restitution e > 0, whose
    impact gives back in its later steps what its first steps took; a nonlinear force in a leapfrog step).
    """

    def __init__(self, start, conservative: bool, floor: float = 0.0, slack: float = 0.0):
        kin, el, _, _, _, _, stored = start
        self.kin, self.el = kin, el
        self.visc = self.con = self.num = self.ext = 0.0
        self.conservative = conservative
        self.E_prev = self.E_ref = kin + el + stored + slack
        self.tol = max((1.0 if conservative else 1e-9) * abs(self.E_prev), floor, 1e-300)

    def add(self, terms, slack: float = 0.0) -> str | None:
        """Book one step's terms; the reason if the energy (with the scheme's `energy_slack`) rose or is not finite,
        else None."""
        self.kin, self.el, visc, con, num, ext, stored = terms
        self.num += num
        self.visc += visc
        self.con += con
        self.ext += ext
        E = self.kin + self.el - self.ext + slack
        if self.conservative:
            E += stored
        if not math.isfinite(E):
            return "a value is not finite"
        if E > (self.E_ref if self.conservative else self.E_prev) + self.tol:
            return f"the energy rose from {self.E_prev:.6g} to {E:.6g}"
        self.E_prev = E
        return None

    @property
    def cumulative(self) -> tuple:
        return self.kin, self.el, self.visc, self.con, self.num, self.ext


def energy_roundoff(K, eta: np.ndarray, comm) -> float:
    """The round-off of the energy of a state of height |η|: ½ηᵀKη carries up to u·|η|²·Σ|K_ij| ≤ u·|η|²·N·‖K‖∞
    (8× that here). A small motion on a large height (η = 1e-3 + 1e-8 t) has less energy than this, and its
    energy "rose" by 1e-20 of 5e-17 at step 14 without this floor: noise, not an instability, which grows
    exponentially past any floor. Example 1's floor (4e-7) is below 1e-9 E(0) (1.3e-6). Collective."""
    height = comm.allreduce(float(np.max(np.abs(eta), initial=0.0)), op=MPI.MAX)
    return 8 * np.finfo(float).eps * height**2 * K.getSize()[0] * K.norm(PETSc.NormType.INFINITY)


def model_constants(scene, model: Model) -> dict[str, float]:
    """The model's constants for a run: the scene's ``[parameters]`` checked against `Model.constants` (the model
    actually run, which a ``--model`` or a `Model` object may make another than the scene's), defaults filled in."""
    return resolve_parameters(model.name, model.constants, dict(scene.parameters), model.check_constants)


def discretise(scene, model: Model, comm, constants: dict | None = None):
    """The P1 space on the scene's mesh, the model's parameters (scene fields as P1 functions, its `constants` as
    dolfinx Constants: default, `model_constants`), its operators."""
    msh = domains.create(scene, comm)
    V = compat.function_space(msh, "Lagrange", 1)
    dof_x = node_coordinates(V)  # owned dofs, then ghosts
    values = agreed(comm, lambda: {name: scene.field_values(name, dof_x) for name in scene.fields})  # one outcome
    extra = {}
    for name in scene.fields:
        f = fem.Function(V, name=name)
        f.x.array[:] = values[name]
        extra[name] = f
    params = Parameters(
        alpha=fem.Constant(msh, PETSc.ScalarType(scene.alpha)),
        eps=fem.Constant(msh, PETSc.ScalarType(scene.eps)),
        x=ufl.SpatialCoordinate(msh),
        length=scene.length,
        extra=extra,
        constants={k: fem.Constant(msh, PETSc.ScalarType(v))
                   for k, v in (model_constants(scene, model) if constants is None else constants).items()},
    )
    unused = unused_fields(model, V, params)
    if unused:  # a load the model ignores would give a plausible but wrong answer
        raise ValueError(
            f"scene field(s) {', '.join(unused)}: not used by model '{model.name}'; choose a model that reads them "
            "(e.g. model = 'loaded_obstacle') or remove them from the scene"
        )
    if scene.obstacle_moves:  # ψ_t for the penalty's gap rate v − ψ_t: set each step (`MovingObstacle`)
        rate = extra[RATE] = fem.Function(V, name=RATE)
        rate.x.array[:] = (values["obstacle"] - scene.field_values("obstacle", dof_x, -scene.dt)) / scene.dt
    return V, params, semi_discrete_operators(model, V, params)


#: energy.png's legend of a nonlinear form's stored energy when the model declares none (`fem.operators.potential_energy`)
POTENTIAL_LABEL = r"stored: the potential $\int_0^1 G(s\eta;\eta)\,ds$ of momentum_form"

#: The moving obstacle's rate ψ_t in `Parameters.extra` (the backward quotient of ψ; `MovingObstacle`).
RATE = "obstacle_rate"


def _moving_obstacle(scene, V, params) -> MovingObstacle | None:
    """The scene's obstacle ψ(x, t) as the scheme sets it each step, or None for an obstacle at rest."""
    if not scene.obstacle_moves:
        return None
    dof_x = node_coordinates(V)
    return MovingObstacle(lambda t: scene.field_values("obstacle", dof_x, t), params.extra["obstacle"],
                          params.extra[RATE], scene.dt, V.dofmap.index_map.size_local)


def _check_moving_obstacle(scene, name: str, penalty, model: Model, V, params) -> None:
    """A moving obstacle runs with scheme projection (restitution 0), and with schemes paper (either penalty) and
    newmark when the model's law reads the obstacle's rate (the gap rate v − ψ_t); linear and nonlinear models
    alike. The rest is refused in one line."""
    if not scene.obstacle_moves:
        return
    if name == "projection":
        if scene.restitution:
            raise SceneError("restitution: a moving obstacle (obstacle in t) runs with restitution 0 only")
        return
    law = model.penalty if penalty == "explicit" else model.penalty_damping
    what = "penalty" if penalty == "explicit" else "penalty_damping"
    if law is None:  # no such law: the scheme refuses the model itself
        return
    eta, v = fem.Function(V), fem.Function(V)
    if params.extra[RATE] not in ufl.algorithms.extract_coefficients(law(eta, v, params)):
        raise SceneError(f"obstacle: model '{model.name}''s {what} does not read the obstacle's rate "
                         f"p.extra['{RATE}'] (its gap rate v - psi_t), which a moving obstacle needs; use scheme "
                         "'projection' or a law in the gap rate (model 'loaded_obstacle')")


def _setting(scene, model, V, params, ops, penalty, mass, comm, petsc_options=None) -> Setting:
    """What the scheme is given (`Setting`), from the scene, the model's operators and the run's options."""
    n_owned = V.dofmap.index_map.size_local
    x = node_coordinates(V)[:n_owned]
    bc, g = agreed(comm, _boundary, scene, V, x)  # h at this rank's boundary nodes: one outcome on every rank
    fields = {f: f.x.array[:n_owned] for f in params.extra.values()}
    laws = NodalLaws(model, V, params, scene.dt, fields, x)
    given = petsc_options_of(scene, petsc_options)
    options = _model_options(model, ops, params, scene.dim, comm.size, given) | given
    return Setting(ops=ops, dt=scene.dt, mass=mass, penalty=penalty, bc=bc, g=g, laws=laws, comm=comm, eps=scene.eps, x=x,
                   nt=scene.nt, petsc_options=options, restitution=scene.restitution or 0.0,
                   obstacle=_moving_obstacle(scene, V, params))


def _model_options(model, ops, params, dim: int, ranks: int, given: dict) -> dict:
    """A nonlinear model's own solver defaults (`Model.solver`): below the scene's and the user's options
    (`given`), above the size rule's choice (`solver_options` reads them as given). A user who names ksp_type or
    pc_type chooses the linear solver: the model's linear options go."""
    if ops.nonlinear is None:
        return {}
    hints = model.solver
    if "ksp_type" in given or "pc_type" in given:
        return dict(hints.newton_options)
    return hints.options(dim, ranks, {name: float(c.value) for name, c in params.constants.items()})


def _boundary(scene, V, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The owned boundary dofs and their heights: the two ends at h_left, h_right; a 2D boundary at h(x, y)."""
    if scene.dim == 2:
        bc = domains.boundary_dofs(V)
        return bc, scene.boundary_height(x[bc])
    n_owned = x.size
    left, right = bc_dofs(V, scene.length)
    left, right = left[left < n_owned], right[right < n_owned]
    bc = np.concatenate([left, right]).astype(np.int32)
    return bc, np.concatenate([np.full(left.size, scene.h_left), np.full(right.size, scene.h_right)])


def _mesh_rows(V, gather: _Gather, weights: np.ndarray) -> dict:
    """2D: the nodal areas (`weights`, this rank's owned ones, gathered) and the triangles, both in the gathered
    node order, where the rows are gathered; 1D: none. Each rank sends its triangles in global dof numbers (the
    order the ranks' owned dofs are concatenated in), so that no rank needs the others' coordinates. Collective."""
    if V.mesh.topology.dim == 1:
        return {}
    n_cells = V.mesh.topology.index_map(V.mesh.topology.dim).size_local
    local = compat.cell_dofs(V)[:n_cells]
    cells = V.dofmap.index_map.local_to_global(local.ravel().astype(np.int32)).reshape(local.shape)
    parts = _collect(gather.comm, cells, gather.to_all)
    weights = gather(weights)
    if not gather.holds:
        return {}
    position = np.empty_like(gather.order)
    position[gather.order] = np.arange(gather.order.size)  # global dof -> place in x order
    return {"weights": weights, "cells": canonical_cells(position[np.concatenate(parts)])}


def _initial_state(scene, s: Setting) -> tuple[np.ndarray, np.ndarray]:
    """η⁰ with the ends at their heights, and v⁰ with the ends at rest (a fixed end does not move)."""
    eta0 = np.asarray(scene.initial_displacement(s.x), dtype=float).copy()
    eta0[s.bc] = s.g
    return eta0, np.asarray(scene.initial_velocity(s.x), dtype=float) * s.interior


def _march(scene, name: str, stepper, ledger: _Ledger, rows: _Rows, store, progress: bool, comm=None) -> None:
    """Step from 0 to T, booking each step in the ledger and storing the rows; InstabilityError names the step.
    Under MPI (`comm`), a stop signal on any rank stops every rank at the same step (`StopTogether`): polled at
    every step of a membrane, every 64th of a string (its steps take microseconds)."""
    from tqdm import tqdm

    # disable=None: tqdm's own test, no bar when stderr is not a terminal (a log file, a pipe, CI)
    bar = tqdm(total=scene.nt, disable=None if progress else True, unit="step", mininterval=0.5, leave=False)
    mask = 0 if scene.dim == 2 else 63
    try:
        with np.errstate(all="ignore"), StopTogether(comm) as stop:  # NaN, overflow: the energy guard names the step
            if rows.next_step == 0:
                store(0)
            for n in range(scene.nt):  # computes step n + 1
                why = ledger.add(stepper.step(), stepper.energy_slack)
                eta = stepper.eta  # once per step: a property of the scheme
                if eta.size:
                    rows.min_eta = min(rows.min_eta, float(eta.min()))
                if why is not None:
                    t_n = (n + 1) * scene.dt
                    situation = f"scheme {name}" + (f", {stepper.situation}" if stepper.situation else "")
                    raise InstabilityError(f"unstable at step {n + 1}, t = {t_n:.6g}: {why} ({situation}); "
                                           f"{stepper.remedy}", step=n + 1, time=t_n,
                                           r=scene.dt / scene.eps if stepper.PENALTIES else None)
                if n + 1 == rows.next_step:
                    store(n + 1)
                if (n & mask) == 0:
                    stop.poll()
                if progress and (n & 63) == 0:
                    bar.update(min(64, scene.nt - bar.n))
    finally:
        bar.close()


def _storage(scene, s: Setting, V, storage: Storage, outputs: OutputValues):
    """The stored rows (steps within the budget, gathered to rank 0 or every rank), the mesh rows, and the
    function that sums a stored time's series over the ranks. Collective."""
    gather = _Gather(s.comm, s.x, to_all=storage.gather == "all")
    steps, note = budget_steps(scene.nt, scene.dt, scene.output_times, storage.max_rows, gather.nodes, storage.row_budget)
    if note is not None and s.comm.rank == 0:
        warnings.warn(note, StorageWarning, stacklevel=3)
    n_owned = s.x.shape[0]
    weights = domains.nodal_areas(V)[:n_owned]  # ∫φ_i: the trapezoid's weights in 1D, the lumped areas in 2D
    obstacle = np.asarray(scene.obstacle_values(s.x), dtype=float)
    geometry = _mesh_rows(V, gather, weights)  # the same owned weights, gathered
    extra = tuple(f.name for f in outputs.fields)
    if s.obstacle is not None:  # a moving obstacle: the depth below ψ at the row's time
        return (_Rows(steps, gather, extra), geometry,
                lambda fields, t: _row_series(s.comm, fields, weights, s.obstacle.owned(t)))
    return _Rows(steps, gather, extra), geometry, lambda fields, t: _row_series(s.comm, fields, weights, obstacle)


def _resolve_model(model, scene) -> Model:
    """`model` (a Model, a registered name or "package.module:name"), else the scene's, else the paper's."""
    if model is None and not getattr(scene, "model", None):
        return inelastic
    from ..model.registry import load_model

    return load_model(model if model is not None else scene.model)


def _model_origin(spec, model) -> dict:
    """Where the model came from (summary.json's ``model_origin``): `model.registry.model_origin`."""
    from ..model.registry import model_origin

    return model_origin(spec, model)


def _choose_scheme(scene, scheme, penalty, mass, model):
    """The scheme's name and class, its penalty and mass (its defaults, or refused), the model it must take."""
    name = scheme or getattr(scene, "scheme", None) or "paper"
    Scheme = scheme_class(name)
    penalty, mass = Scheme.check_options(name, penalty, mass)
    check_restitution(name, getattr(scene, "restitution", None) or 0.0)
    model = _resolve_model(model, scene)
    check_model(name, model)
    penetration_bound_of(model)  # a bound the checks do not know is refused before the run, not after it
    return name, Scheme, penalty, mass, model


def petsc_options_of(scene, petsc_options=None) -> dict:
    """The scene's PETSc options with `petsc_options` (checked like the scene's key) on top: the argument's win."""
    return dict(scene.petsc_options) | dict(check_petsc_options(petsc_options or {}))


def _check_before_mesh(scene, Scheme, penalty, model, petsc_options, comm) -> None:
    """What needs no mesh, checked before the mesh is built (seconds to minutes on a large one): the PETSc
    option values and the contact law's bound on r = Δt/ε (its warnings come from the scheme, once). The
    same on every rank, so a refusal ends every rank alike."""
    check_option_values(petsc_options_of(scene, petsc_options), ranks=comm.size)
    if Scheme.PENALTIES and penalty is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            check_law_stability(model, scene.dt, scene.eps, penalty)


def _writer(scene, V, comm, rows: _Rows, output: Output):
    """The output folder's writer (None without `output.dir`): its lock is taken now, its frames chosen."""
    if output.dir is None:
        return None
    from ..io.folder import OutputWriter, xdmf_frames

    pictures = output.pictures
    if pictures is True:
        from ..plot.viz import write_pictures as pictures  # matplotlib and pyvista load when a picture is drawn

    frames = xdmf_frames(rows.steps, output_steps(scene.nt, scene.dt, scene.output_times), output.max_frames)
    return OutputWriter(output.dir, scene, V, comm, force=output.force, pictures=pictures or None, frames=frames)


class _Run:
    """One simulation under way: the scheme, its ledger, the stored rows and the writer; `store` keeps the state
    at a step, `result` makes the Result of the rows so far."""

    def __init__(self, scene, name, model, penalty, mass, comm, stepper, rows, geometry, row_series, timings):
        self.scene, self.name, self.model, self.penalty, self.mass, self.comm = scene, name, model, penalty, mass, comm
        self.stepper, self.rows, self.geometry, self.row_series, self.timings = stepper, rows, geometry, row_series, timings
        self.ledger = self.writer = None
        self.origin = {}  # where the model came from (`_model_origin`)
        self.outputs = None  # the model's output fields at the nodes (`fem.outputs.OutputValues`)
        self.constants = {}  # the model's constants, resolved (`model_constants`)
        nonlinear = stepper.s.ops.nonlinear
        derived = nonlinear is not None and nonlinear.energy_derived  # the form's potential is booked
        self.energy_label = model.energy_label or (POTENTIAL_LABEL if derived else None)  # energy.png's legend
        self.dt = scene.dt  # a property of the scene: read once, not per stored row

    def start(self, s: Setting, V, output: Output) -> None:
        """The scheme's initial state (η⁰, v⁰) opens the ledger; then the writer, if any."""
        stepper, rows = self.stepper, self.rows
        self.ledger = _Ledger(stepper.start(*agreed(s.comm, _initial_state, self.scene, s)),  # eta0, v0: one outcome
                              conservative=self.model.contact_energy is not None or stepper.energy_may_rise,
                              floor=energy_roundoff(s.ops.K, stepper.eta, s.comm), slack=stepper.energy_slack)
        rows.min_eta = float(np.min(stepper.eta[s.interior])) if s.interior.any() else math.inf
        self.writer = _writer(self.scene, V, self.comm, rows, output)

    def store(self, n: int) -> None:
        stepper = self.stepper
        fields = {"eta": stepper.eta, "velocity": stepper.velocity, "contact": stepper.contact(),
                  "contact_force": stepper.contact_force}
        fields.update(self.outputs(stepper.eta, getattr(stepper, "fields", {})))
        t = float(step_times([n], self.dt, self.scene.output_times)[0])
        self.rows.store(fields, self.ledger.cumulative, self.row_series(fields, t))
        if self.writer is not None:
            self.writer.write(t, {k: np.asarray(a, dtype=float) for k, a in fields.items()})

    def result(self, status: str, message: str) -> Result:
        rows, comm, scene = self.rows, self.comm, self.scene
        n, mins = rows.n, comm.allreduce(rows.min_eta, op=MPI.MIN) if comm.size > 1 and status == "complete" else rows.min_eta
        if rows.gather.holds:
            stored = {k: v[:n] for k, v in rows.fields.items()}
            per_node = {k: stored.pop(k) for k in FIELDS} | {"fields": stored}  # the rest: the model's output fields
        else:
            per_node = dict.fromkeys(FIELDS) | {"fields": {}}
        result = Result(scene=scene, x=rows.gather.x, t=step_times(rows.steps[:n], scene.dt, scene.output_times),
                        steps=rows.steps[:n],
                        **per_node, energy={k: v[:n] for k, v in rows.energy.items()},
                        min_eta=float(mins), penalty=self.penalty or "none", mass=self.mass, model=self.model.name,
                        model_origin=self.origin,
                        penetration_bound=penetration_bound_of(self.model), energy_label=self.energy_label,
                        status=status, timings=self.timings, message=message, scheme=self.name, **self.geometry,
                        field_info=self.outputs.info, parameters=dict(self.constants),
                        series={k: v[:n] for k, v in rows.series.items()}, has_rows=rows.gather.holds)
        checks_of(result)  # the energy balance and the penetration check, once (summary.json, the CLI)
        return result


def _march_and_store(run: _Run, progress: bool) -> None:
    """`_march`, storing the rows as it goes; a stopped run leaves its partial Result on the exception (and its
    folder marked), an unexpected error no folder; a step that fails after the input was accepted is a
    SolverError, not an input error."""
    writer = run.writer
    t_loop = time.perf_counter()
    try:
        _march(run.scene, run.name, run.stepper, run.ledger, run.rows, run.store, progress, run.comm)
    except (InstabilityError, KeyboardInterrupt) as exc:
        status = "unstable" if isinstance(exc, InstabilityError) else "interrupted"
        exc.result = run.result(status, str(exc) or status)  # the rows so far: partial output and the CLI's report
        if writer is not None:
            writer.abort(status, exc.result.message, result=exc.result, error=exc)
        raise
    except BaseException as exc:
        if writer is not None:
            writer.discard()  # an unexpected error: no half-written folder, no stale lock
        if isinstance(exc, ValueError):  # the input was checked before the march: a step that fails is no input error
            raise SolverError(f"step failed: {exc}") from exc
        raise
    run.timings["solve"] = time.perf_counter() - t_loop - (writer.write_time if writer is not None else 0.0)  # I/O apart
    run.timings.update(run.stepper.timings)


def _write(run: _Run) -> Result:
    """The complete run's Result ("unbalanced" if its energy balance does not close), written to its folder."""
    result = run.result("complete", "")
    unbalanced = unbalanced_message(result)  # a balance that does not close is not a complete run
    if unbalanced is not None:
        result.status, result.message = "unbalanced", unbalanced
    if run.writer is not None:
        t_io = time.perf_counter()
        run.writer.finish(result)
        run.timings["output"] = time.perf_counter() - t_io + run.writer.write_time
    return result


def simulate(
    scene,
    scheme: str | None = None,
    penalty: str | None = None,
    mass: str | None = None,
    *,
    model: Model | str | None = None,
    storage: Storage | None = None,
    output: Output | None = None,
    comm=MPI.COMM_WORLD,
    petsc_options: dict | None = None,
    restitution: float | None = None,
    **keywords,
) -> Result:
    """Run `scene` with a time scheme (`stringcontact.SCHEMES`; default: the scene's, else "paper").

    `model` is a `Model`, a registered name (`stringcontact models`) or "package.module:name"; default:
    the scene's `model`, else the paper's.

    `penalty` and `mass` default to the scheme's own (for "paper": explicit, lumped); an option the scheme
    does not take is refused.

    `storage` (`Storage`): about `max_rows` time levels are stored (Result, diagnostics.csv, pictures).
    Under MPI the stored rows are gathered to rank 0 (`gather` "root"); the other ranks' Result holds the
    per-time series only (see Result). `gather` "all" gives every rank the rows. The rows a rank holds may
    take at most `row_budget` bytes (ROW_BUDGET): above it fewer are kept, with 0, T and the output times,
    and a StorageWarning in one line says so (an explicit `max_rows` too is capped so).

    `output` (`Output`): with a folder `dir`, XDMF (about `max_frames` of the stored rows, always with 0, T and
    the scene's output times), CSV, JSON and (with `pictures`) PNGs are written there; `progress` shows a bar.

    The old keywords `max_rows`, `gather`, `row_budget`, `output_dir`, `max_frames`, `force`, `pictures` and
    `progress` are still accepted (`options.KEYWORDS`); with their object too they are refused (ValueError).

    The step's linear system is LU-factorised once (in serial for every membrane a scene allows, up to 1001²
    nodes; on several ranks by MUMPS up to 1e3 nodes; a string on any number of ranks) and solved by CG (Jacobi
    or AMG) otherwise (`timestepping.linear.solver_options`); `petsc_options` (checked like the scene's key, which it overrides name
    by name) sets PETSc options for it, e.g. ``{"ksp_type": "cg", "pc_type": "jacobi"}``.

    `restitution` (e in [0, 1], checked like the scene's key, which it replaces; the Result's scene records it):
    scheme "projection"'s restitution coefficient (Paoli-Schatzman); every other scheme refuses e > 0.
    """
    storage, output = grouped(storage, output, keywords)
    if restitution is not None:
        scene = scene.replace(restitution=restitution)
    spec = model if model is not None else (getattr(scene, "model", None) or "inelastic")
    name, Scheme, penalty, mass, model = _choose_scheme(scene, scheme, penalty, mass, model)
    constants = model_constants(scene, model)
    _check_before_mesh(scene, Scheme, penalty, model, petsc_options, comm)
    t0 = time.perf_counter()
    V, params, ops = discretise(scene, model, comm, constants)
    _check_moving_obstacle(scene, name, penalty, model, V, params)
    s = _setting(scene, model, V, params, ops, penalty, mass, comm, petsc_options)
    stepper = Scheme(s)
    outputs = OutputValues(model, V, params)
    rows, geometry, row_series = _storage(scene, s, V, storage, outputs)
    run = _Run(scene, name, model, penalty, mass, comm, stepper, rows, geometry, row_series,
               timings={"setup": time.perf_counter() - t0})
    run.origin, run.outputs, run.constants = _model_origin(spec, model), outputs, constants
    run.start(s, V, output)
    _march_and_store(run, output.progress and comm.rank == 0)
    return _write(run)
