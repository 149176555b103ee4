"""The scene as an adapter: a `Scene` turned into the core's objects in one place.

`check_scene_run` checks what needs no mesh (the scheme and its options, the model and its constants, the PETSc
options, the size), before the mesh is built (seconds to minutes on a large one); `scene_problem` builds the mesh,
the P1 space, the initial Functions, the boundary conditions, the fields and the moving obstacle, and returns the
`ContactProblem`, which `run.stepper` steps.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from dolfinx import fem

from ..core.problem import ContactProblem
from ..errors import SceneError
from ..fem import compat, domains
from ..fem.agree import one_outcome, same_on_every_rank
from ..fem.operators import node_coordinates
from ..model.forms import check_declarations
from ..model.interface import Model, inelastic
from ..scene.limits import MAX_MAGNITUDE, MAX_MEMBRANE_NODES, SETUP_BYTES_PER_NODE
from ..scene.names import DEFAULT_SCHEME
from ..scene.parameters import resolve_parameters
from ..timestepping import check_scheme_run

__all__ = ["RunPlan", "check_scene_run", "model_constants", "resolve_model", "scene_problem"]

#: The least wall time one node's time step takes (a string on the linear path, measured on the 2-core VM: Example 1
#: at nx = 2e4 took 2.5e-7 s; 2.3e-8 s in the fastest runs): the estimate below which a long run is told it is long.
SECONDS_PER_NODE_STEP = 2.5e-8
#: A run predicted to take longer than this is told so at its start, with its estimate.
LONG_RUN_SECONDS = 3600.0


@dataclass(frozen=True)
class RunPlan:
    """What a scene's run is, resolved before the mesh: the scheme's name and class, its options (`Scheme.OPTIONS`,
    defaults filled in), the model and its constants."""

    name: str
    Scheme: type
    options: dict
    model: Model
    constants: dict


def resolve_model(model, scene) -> Model:
    """`model` (a Model, a registered name or "package.module:name"), else the scene's, else the paper's."""
    if model is None and not getattr(scene, "model", None):
        return inelastic
    from ..model.registry import load_model

    return load_model(model if model is not None else scene.model)


def model_constants(scene, model: Model) -> dict[str, float]:
    """The model's constants for a run: the scene's ``[parameters]`` checked against `Model.constants` (the model
    actually run), defaults filled in."""
    return resolve_parameters(model.name, model.constants, dict(scene.parameters), model.check_constants)


def check_scene_run(scene, scheme=None, model=None, comm=None, **options) -> RunPlan:
    """The scheme (`scheme`, else the scene's, else "paper") and its options (the scene's ``[scheme]`` table with
    `options` on top), the model and its constants, the PETSc options, the size and the contact law's bound, checked
    before the mesh; the same on every rank, so that a refusal ends every rank alike."""
    model = resolve_model(model, scene)
    check_declarations(model)  # what it declares is of its kind
    from ..errors import plugin_code

    with plugin_code(f"model '{model.name}'"):  # its functions' sys.exit: one line, not exit 0
        constants = model_constants(scene, model)
    scheme = scheme or scene.scheme or DEFAULT_SCHEME
    given = dict(scene.scheme_options) | {k: v for k, v in options.items() if v is not None}
    given["petsc_options"] = dict(scene.petsc_options)
    if comm is not None:  # ranks given different input would run a mixture, or wait forever for each other
        same_on_every_rank(comm, "the scene, scheme, options and model", [scene.as_dict(), scheme, given, model.name,
                                                                          constants])
    _check_size(scene, model)
    name, Scheme, resolved = check_scheme_run(scheme, model, scene.dt, given, comm.size if comm else 1)
    return RunPlan(name, Scheme, resolved, model, constants)


def scene_problem(scene, model: Model, comm, constants: dict | None = None) -> ContactProblem:
    """The scene's `ContactProblem`: its mesh (`fem.domains`), the P1 space, η, v and the fields in ``fields0`` from
    its initial state, its ends or boundary held at their heights, its fields (a load, an obstacle) and a moving
    obstacle ψ(x, t), each checked where it is evaluated (finite, within ±MAX_MAGNITUDE)."""
    msh = domains.create(scene, comm)
    V = compat.function_space(msh, "Lagrange", 1)
    dof_x = node_coordinates(V)  # owned dofs, then ghosts
    values = one_outcome(comm, lambda: {name: _checked_values(scene, name, dof_x) for name in scene.fields})
    fields = {}
    for name in scene.fields:
        f = fem.Function(V, name=name)
        f.x.array[:] = values[name]
        fields[name] = f
    eta, v = fem.Function(V, name="eta"), fem.Function(V, name="velocity")
    n_owned = V.dofmap.index_map.size_local
    eta.x.array[:n_owned], v.x.array[:n_owned] = one_outcome(
        comm, lambda: (scene.initial_displacement(dof_x[:n_owned]), scene.initial_velocity(dof_x[:n_owned])))
    eta.x.scatter_forward()
    v.x.scatter_forward()
    unknowns = {}
    for name, _ in scene.fields0:  # the further unknowns the scene starts
        if name not in model.fields:
            raise SceneError(f"fields0.{name}: not a field of model '{model.name}'; allowed: "
                             f"{', '.join(model.fields) or 'none (the model has no fields)'}")
        unknowns[name] = fem.Function(V, name=name)
        unknowns[name].x.array[:n_owned] = one_outcome(comm, scene.initial_field, name, dof_x[:n_owned])
        unknowns[name].x.scatter_forward()
    held = one_outcome(comm, _held, scene, V, dof_x)  # one outcome on every rank
    obstacle = None
    if scene.obstacle_moves:  # not collective: a rank may evaluate it alone; one that fails ends the whole job
        def obstacle(x, t):
            return _checked_values(scene, "obstacle", x, t)
    return ContactProblem(model, eta, v, bcs=[held], alpha=scene.alpha,
                          constants=model_constants(scene, model) if constants is None else constants,
                          fields=fields, obstacle=obstacle, unknowns=unknowns)


def _held(scene, V, dof_x: np.ndarray):
    """The DirichletBC of the scene: a string's ends at h_left, h_right; a membrane's boundary at h(x, y)."""
    g = fem.Function(V)
    dofs = domains.boundary_dofs(V)
    if scene.dim == 2:
        g.x.array[dofs] = scene.boundary_height(dof_x[dofs])
    else:
        g.x.array[dofs] = np.where(dof_x[dofs] < 0.5 * scene.length, scene.h_left, scene.h_right)
    return fem.dirichletbc(g, dofs)


def _checked_values(scene, name: str, x: np.ndarray, t: float = 0.0) -> np.ndarray:
    """The scene's field `name` at the nodes `x` and the time `t`, finite and within ±MAX_MAGNITUDE at every node,
    else SceneError naming the field, the time, the value and where."""
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


def _check_size(scene, model: Model) -> None:
    """A membrane's set-up memory with the model's own cost per node within the scene's budget, else SceneError; a
    run predicted to take over an hour (`SECONDS_PER_NODE_STEP`) says so in a warning, with its estimate."""
    nodes = scene.node_estimate
    per_node = getattr(model.solver, "setup_bytes_per_node", None) or SETUP_BYTES_PER_NODE
    budget = MAX_MEMBRANE_NODES * SETUP_BYTES_PER_NODE
    if scene.dim == 2 and nodes * per_node > budget:
        key = {"rectangle": "cells", "disk": "mesh_size"}.get(scene.domain, "mesh")
        value = getattr(scene, key, None)
        raise SceneError(f"{key}: {list(value) if isinstance(value, tuple) else value} gives "
                         f"{'about ' if key == 'mesh_size' else ''}{nodes} nodes, about {nodes * per_node / 1e9:.3g} GB "
                         f"to set up with model '{model.name}' ({per_node / 1e3:g} KB per node, measured); allowed: at "
                         f"most {int(budget // per_node)} nodes with this model ({budget / 1e9:.2g} GB)")
    seconds = nodes * scene.nt * SECONDS_PER_NODE_STEP
    if seconds > LONG_RUN_SECONDS:
        warnings.warn(f"nt = {scene.nt} steps of {nodes} nodes: this run will take about {seconds / 3600:.3g} hours or "
                      f"more (at least {SECONDS_PER_NODE_STEP:g} s per node and step); reduce nt or the mesh for a "
                      "shorter one", UserWarning, stacklevel=3)
