"""A run's set-up, checked before its mesh where it can be: the scheme and its options, the model and its
constants, the mesh and the model's operators on it, the discrete problem the scheme steps (`DiscreteProblem`), the
initial state, the output folder's writer. `Stepper` calls these in order; a test or a benchmark may call one alone."""

from __future__ import annotations

import warnings

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..errors import SceneError
from ..fem import compat, domains
from ..fem.agree import one_outcome
from ..fem.operators import bc_dofs, node_coordinates, semi_discrete_operators
from ..model.forms import check_declarations
from ..model.interface import Model, Parameters, inelastic, penetration_bound_of, unused_fields
from ..scene import check_petsc_options
from ..scene.limits import MAX_MAGNITUDE, MAX_MEMBRANE_NODES, SETUP_BYTES_PER_NODE
from ..scene.names import DEFAULT_SCHEME
from ..scene.parameters import resolve_parameters
from ..timestepping import check_model, check_restitution, resolve_scheme
from ..timestepping.base import DiscreteProblem, MovingObstacle, NodalLaws, check_law_stability
from ..timestepping.linear import check_option_values
from ..timestepping.newton_options import check_snes_options
from .options import Output, picture_function
from .rows import StoredRows, output_steps

__all__ = ["POTENTIAL_LABEL", "RATE", "discretise", "model_constants", "petsc_options_of"]


def model_constants(scene, model: Model) -> dict[str, float]:
    """The model's constants for a run: the scene's ``[parameters]`` checked against `Model.constants` (the model
    actually run, which a ``--model`` or a `Model` object may make another than the scene's), defaults filled in."""
    return resolve_parameters(model.name, model.constants, dict(scene.parameters), model.check_constants)


def discretise(scene, model: Model, comm, constants: dict | None = None, residual: bool = False):
    """The P1 space on the scene's mesh, the model's parameters (scene fields as P1 functions, its `constants` as
    dolfinx Constants: default, `model_constants`), its operators (with the residual for any model if `residual`:
    a scheme without a linear path of its own, ``Scheme.LINEAR_PATH``)."""
    msh = domains.create(scene, comm)
    V = compat.function_space(msh, "Lagrange", 1)
    dof_x = node_coordinates(V)  # owned dofs, then ghosts
    values = one_outcome(comm, lambda: {name: _checked_values(scene, name, dof_x) for name in scene.fields})  # one outcome
    extra = {}
    for name in scene.fields:
        f = fem.Function(V, name=name)
        f.x.array[:] = values[name]
        extra[name] = f
    params = Parameters(
        alpha=fem.Constant(msh, PETSc.ScalarType(scene.alpha)),
        eps=fem.Constant(msh, PETSc.ScalarType(scene.eps if scene.eps is not None else np.nan)),  # nan: no eps (projection)
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
        rate.x.array[:] = (values["obstacle"] - _checked_values(scene, "obstacle", dof_x, -scene.dt)) / scene.dt
    owned = dof_x[: V.dofmap.index_map.size_local]

    def initial_state():  # where a form singular at η = 0 is linearised (`semi_discrete_operators`)
        return scene.initial_displacement(owned), scene.initial_velocity(owned)

    return V, params, semi_discrete_operators(model, V, params, residual, initial_state)


#: energy.png's legend of a nonlinear form's stored energy when the model declares none (`fem.operators.potential_energy`)
POTENTIAL_LABEL = r"stored: the potential $\int_0^1 G(s\eta;\eta)\,ds$ of momentum_form"


#: The moving obstacle's rate ψ_t in `Parameters.extra` (the backward quotient of ψ; `MovingObstacle`).
RATE = "obstacle_rate"


def _checked_values(scene, name: str, x: np.ndarray, t: float = 0.0) -> np.ndarray:
    """The scene's field `name` at the nodes `x` and the time `t`, finite and within ±MAX_MAGNITUDE at every node,
    else SceneError naming the field, the time, the value and where (the scene's own check samples a few points
    and times: 5e6·sin²(πt/0.2) is 0 at t = 0, T/2 and T)."""
    try:
        values = np.asarray(scene.field_values(name, x, t), dtype=float)
    except SceneError as exc:
        raise SceneError(f"{name} at t = {t:.6g}: {str(exc).removeprefix(f'{name}: ')}") from None
    bad = np.flatnonzero(~(np.abs(values) <= MAX_MAGNITUDE))
    if bad.size:
        i = bad[np.argmax(np.nan_to_num(np.abs(values[bad]), nan=np.inf))]
        where = ", ".join(f"{c:.4g}" for c in np.atleast_1d(x[i]))
        raise SceneError(f"{name}: at t = {t:.6g} it is {values[i]:.4g} at x = ({where}); allowed: finite values in "
                         f"[-{MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}] at every node and time step")
    return values


def _moving_obstacle(scene, V, params) -> MovingObstacle | None:
    """The scene's obstacle ψ(x, t) as the scheme sets it each step, or None for an obstacle at rest: checked at
    every time it is evaluated (`_checked_values`)."""
    if not scene.obstacle_moves:
        return None
    dof_x = node_coordinates(V)
    # not collective: a rank may evaluate it alone; a rank that fails alone ends the whole job (the CLI aborts it)
    return MovingObstacle(lambda t: _checked_values(scene, "obstacle", dof_x, t), params.extra["obstacle"],
                          params.extra[RATE], scene.dt, V.dofmap.index_map.size_local)


def _check_moving_obstacle(scene, Scheme, penalty, model: Model, V, params) -> None:
    """A moving obstacle runs with a scheme without penalty (`projection`: the obstacle through the model's gap;
    restitution 0), and with the penalty schemes (`paper`, `newmark`) when the model's law reads the obstacle's
    rate (the gap rate v − ψ_t); linear and nonlinear models alike. The rest is refused in one line."""
    if not scene.obstacle_moves:
        return
    if not Scheme.PENALTIES:
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


def _discrete_problem(scene, model, V, params, ops, penalty, mass, comm, petsc_options=None) -> DiscreteProblem:
    """The discrete problem the scheme steps (`DiscreteProblem`), from the scene, the model's operators and the run's
    options."""
    n_owned = V.dofmap.index_map.size_local
    x = node_coordinates(V)[:n_owned]
    bc, g = one_outcome(comm, _boundary, scene, V, x)  # h at this rank's boundary nodes: one outcome on every rank
    fields = {f: f.x.array[:n_owned] for f in params.extra.values()}
    laws = NodalLaws(model, V, params, scene.dt, fields, x)
    given = petsc_options_of(scene, petsc_options)
    options = _model_options(model, ops, params, scene.dim, comm.size, given) | given
    return DiscreteProblem(ops=ops, dt=scene.dt, mass=mass, penalty=penalty, bc=bc, g=g, laws=laws, comm=comm,
                           eps=scene.eps, x=x, nt=scene.nt, petsc_options=options,
                           restitution=scene.restitution or 0.0, obstacle=_moving_obstacle(scene, V, params))


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


def _initial_state(scene, problem: DiscreteProblem) -> tuple[np.ndarray, np.ndarray]:
    """η⁰ with the ends at their heights, and v⁰ with the ends at rest (a fixed end does not move)."""
    eta0 = np.asarray(scene.initial_displacement(problem.x), dtype=float).copy()
    eta0[problem.bc] = problem.g
    return eta0, np.asarray(scene.initial_velocity(problem.x), dtype=float) * problem.interior


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
    name, Scheme = resolve_scheme(scheme or getattr(scene, "scheme", None) or DEFAULT_SCHEME)
    penalty, mass = Scheme.check_options(name, penalty, mass)
    if Scheme.PENALTIES and scene.eps is None:  # a scene for an ε-free scheme, run with a penalty
        raise SceneError(f"eps: scheme {name!r} needs the penalty's eps, and the scene gives none (a scheme without "
                         f"a penalty, such as projection, does not read it); add eps to the scene")
    check_restitution(name, getattr(scene, "restitution", None) or 0.0, Scheme)
    model = _resolve_model(model, scene)
    check_model(name, model, Scheme)
    penetration_bound_of(model)  # a bound the checks do not know is refused before the run, not after it
    check_declarations(model)  # the fields it holds or books as dissipative are its own
    return name, Scheme, penalty, mass, model


def petsc_options_of(scene, petsc_options=None) -> dict:
    """The scene's PETSc options with `petsc_options` (checked like the scene's key) on top: the argument's win."""
    return dict(scene.petsc_options) | dict(check_petsc_options(petsc_options or {}))


def _check_before_mesh(scene, Scheme, penalty, model, petsc_options, comm) -> None:
    """What needs no mesh, checked before the mesh is built (seconds to minutes on a large one): the PETSc
    option values and the contact law's bound on r = Δt/ε (its warnings come from the scheme, once). The
    same on every rank, so a refusal ends every rank alike."""
    given = petsc_options_of(scene, petsc_options)
    check_option_values(given, ranks=comm.size)
    check_snes_options(given)  # tolerances that would make Newton's stopping test pass without solving
    _check_size(scene, model)
    if Scheme.PENALTIES and penalty is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            check_law_stability(model, scene.dt, scene.eps, penalty)


#: The least wall time one node's time step takes (a string on the linear path, measured on the 2-core VM: Example 1
#: at nx = 2e4 took 2.5e-7 s; 2.3e-8 s in the fastest runs): the estimate below which a long run is told it is long.
SECONDS_PER_NODE_STEP = 2.5e-8
#: A run predicted to take longer than this is told so at its start, with its estimate.
LONG_RUN_SECONDS = 3600.0


def _check_size(scene, model: Model) -> None:
    """A membrane's set-up memory with the model's own cost per node (`SolverHints.setup_bytes_per_node`; the core's
    `SETUP_BYTES_PER_NODE` without) within the scene's budget (`MAX_MEMBRANE_NODES` such nodes), else SceneError;
    a run predicted to take over an hour (`SECONDS_PER_NODE_STEP`) says so in a warning, with its estimate."""
    nodes = scene.node_estimate
    per_node = getattr(model.solver, "setup_bytes_per_node", None) or SETUP_BYTES_PER_NODE
    budget = MAX_MEMBRANE_NODES * SETUP_BYTES_PER_NODE
    if scene.dim == 2 and nodes * per_node > budget:
        key = {"rectangle": "cells", "disk": "mesh_size"}.get(scene.domain, "mesh")
        value = getattr(scene, key, None)
        raise SceneError(f"{key}: {list(value) if isinstance(value, tuple) else value} gives {'about ' if key == 'mesh_size' else ''}{nodes} "
                         f"nodes, about {nodes * per_node / 1e9:.3g} GB to set up with model '{model.name}' "
                         f"({per_node / 1e3:g} KB per node, measured); allowed: at most {int(budget // per_node)} "
                         f"nodes with this model ({budget / 1e9:.2g} GB)")
    seconds = nodes * scene.nt * SECONDS_PER_NODE_STEP
    if seconds > LONG_RUN_SECONDS:
        warnings.warn(f"nt = {scene.nt} steps of {nodes} nodes: this run will take about {seconds / 3600:.3g} hours or "
                      f"more (at least {SECONDS_PER_NODE_STEP:g} s per node and step); reduce nt or the mesh for a "
                      "shorter one", UserWarning, stacklevel=2)


def _writer(scene, V, comm, rows: StoredRows, output: Output):
    """The output folder's writer (None without `output.dir`): its lock is taken now, its frames chosen."""
    if output.dir is None:
        return None
    from ..io.folder import OutputWriter, xdmf_frames

    pictures = picture_function(output)  # the default pictures and/or the caller's function
    frames = xdmf_frames(rows.steps, output_steps(scene.nt, scene.dt, scene.output_times), output.max_frames)
    return OutputWriter(output.dir, scene, V, comm, force=output.force, pictures=pictures or None, frames=frames)
