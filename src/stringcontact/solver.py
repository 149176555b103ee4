"""The time loop: assemble once, factorise once, back-substitute each step.

Only PETSc matrix-vector products, one KSP solve and a few NumPy array operations run per
step. The model (UFL) is turned into operators by `scheme`, and the contact force is taken
from the previous step by evaluating the model's `penalty` at the nodes (`nodal`).
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from . import compat, nodal
from .errors import InstabilityError
from .model import Model, Parameters, inelastic
from .result import ENERGY_KEYS, Result
from .scheme import bc_dofs, node_coordinates, semi_discrete_operators, step_matrices

PENALTIES = ("explicit", "semi-implicit")
MASSES = ("lumped", "consistent")


class InstabilityWarning(UserWarning):
    """The explicit penalty with 1 < Δt/ε < 2: stable, but it rebounds with restitution r − 1."""


def stored_steps(nt: int, dt: float, output_times, max_rows: int) -> np.ndarray:
    """Every k-th step so that about `max_rows` rows are kept, plus 0, nt and the scene's output times."""
    stride = max(1, math.ceil(nt / max(1, max_rows)))
    steps = set(range(0, nt + 1, stride)) | {0, nt}
    steps |= {min(nt, max(0, round(t / dt))) for t in output_times}
    return np.array(sorted(steps), dtype=np.int64)


def check_stability(r: float, penalty: str) -> None:
    """The explicit penalty's restitution is r − 1: refuse r ≥ 2 (energy growth), warn for 1 < r < 2."""
    if penalty != "explicit":
        return
    if r >= 2:
        raise InstabilityError(
            f"explicit penalty with r = dt/eps = {r:.4g} >= 2 grows energy at every impact "
            f"(restitution r-1 = {r - 1:.3g} >= 1) at step 0, t = 0; "
            "use penalty='semi-implicit' (--penalty semi-implicit) or a smaller dt (dt <= eps)",
            step=0,
            time=0.0,
            r=r,
        )
    if r > 1:
        warnings.warn(
            f"explicit penalty with r = dt/eps = {r:.4g} > 1 rebounds with restitution {r - 1:.3g}; "
            "use dt <= eps or penalty='semi-implicit' for inelastic contact",
            InstabilityWarning,
            stacklevel=3,
        )


class _Gather:
    """Gathers owned dof arrays to every rank, ordered by x."""

    def __init__(self, comm, x_owned: np.ndarray):
        self.comm = comm
        xs = comm.allgather(x_owned) if comm.size > 1 else [x_owned]
        self.order = np.argsort(np.concatenate(xs), kind="stable")
        self.x = np.concatenate(xs)[self.order]

    def __call__(self, a: np.ndarray) -> np.ndarray:
        parts = self.comm.allgather(a) if self.comm.size > 1 else [a]
        return np.concatenate(parts)[self.order]


def simulate(
    scene,
    penalty: str = "explicit",
    mass: str = "lumped",
    output_dir=None,
    progress: bool = False,
    model: Model | None = None,
    max_rows: int = 400,
    force: bool = False,
    pictures: bool = True,
    comm=MPI.COMM_WORLD,
) -> Result:
    """Run `scene` and return a `Result`.

    With `output_dir`, also write XDMF, CSV, JSON (and, with `pictures`, PNGs) there. The scene's extra
    expression fields (`scene.fields`, e.g. a load or an obstacle) reach the model as P1 functions in
    `Parameters.extra`.
    """
    if penalty not in PENALTIES:
        raise ValueError(f"penalty must be one of {PENALTIES}, not {penalty!r}")
    if mass not in MASSES:
        raise ValueError(f"mass must be one of {MASSES}, not {mass!r}")
    model = model or inelastic
    if penalty == "semi-implicit" and model.penalty_damping is None:
        raise ValueError(f"model '{model.name}' has no penalty_damping, so it has no semi-implicit penalty")
    dt = scene.dt
    r = dt / scene.eps
    check_stability(r, penalty)

    timings = {}
    t0 = time.perf_counter()
    msh = mesh.create_interval(comm, scene.nx, [0.0, scene.length])
    V = compat.function_space(msh, "Lagrange", 1)
    extra = {}
    for name in getattr(scene, "fields", {}) or {}:
        f = fem.Function(V, name=name)
        f.x.array[:] = scene.field_values(name, V.tabulate_dof_coordinates()[:, 0])
        extra[name] = f
    params = Parameters(
        alpha=fem.Constant(msh, PETSc.ScalarType(scene.alpha)),
        eps=fem.Constant(msh, PETSc.ScalarType(scene.eps)),
        x=ufl.SpatialCoordinate(msh),
        length=scene.length,
        extra=extra,
    )
    ops = semi_discrete_operators(model, V, params)
    A, P, Q, Ms = step_matrices(ops, dt, mass)
    n_owned = V.dofmap.index_map.size_local
    x = node_coordinates(V)
    left, right = bc_dofs(V, scene.length)
    bc = np.concatenate([left[left < n_owned], right[right < n_owned]]).astype(np.int32)
    g = np.concatenate([np.full(np.sum(left < n_owned), scene.h_left), np.full(np.sum(right < n_owned), scene.h_right)])
    rstart = A.getOwnershipRange()[0]
    A.zeroRows((bc + rstart).astype(np.int32), diag=1.0)
    interior = np.ones(n_owned, dtype=bool)
    interior[bc] = False

    # The force law and the contact set as UFL in previous-step placeholders, evaluated at the nodes.
    eta_sym, eta_old_sym = fem.Function(V), fem.Function(V)
    dt_c = fem.Constant(msh, PETSc.ScalarType(dt))
    v_sym = (eta_sym - eta_old_sym) / dt_c
    force_law = nodal.NodalExpression(
        (model.penalty if penalty == "explicit" else model.penalty_damping)(eta_sym, v_sym, params)
    )
    contact_law = nodal.NodalExpression(model.contact_set(eta_sym, params))

    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    if comm.size > 1:
        pc.setFactorSolverType("mumps")
    ksp.setUp()
    timings["setup"] = time.perf_counter() - t0

    # State: η^{n+1}, η^n, η^{n−1} as PETSc vectors sharing memory with NumPy views.
    eta_new, eta, eta_old = A.createVecRight(), A.createVecRight(), A.createVecRight()
    b, tmp = A.createVecLeft(), A.createVecRight()
    eta.array[:] = scene.initial_displacement(x)
    eta.array[bc] = g
    v0 = np.asarray(scene.initial_velocity(x), dtype=float) * interior  # a fixed end does not move
    eta_old.array[:] = eta.array - dt * v0

    m, mF, load = ops.m, ops.m_force, ops.load
    base_diag = A.getDiagonal().array.copy() if penalty == "semi-implicit" else None
    damping_active = np.zeros(n_owned, dtype=bool)
    A_diag = A.createVecLeft()

    def mass_dot(u, w):  # uᵀ M w on owned dofs
        if mass == "lumped":
            return float(np.dot(u, m * w))
        tmp.array[:] = w
        Ms.mult(tmp, b)
        return float(np.dot(u, b.array))

    def k_apply(u):
        tmp.array[:] = u
        ops.K.mult(tmp, b)
        return b.array.copy()

    def c_dot(u):
        tmp.array[:] = u
        ops.C.mult(tmp, b)
        return float(np.dot(u, b.array))

    def allsum(vals):
        vals = np.asarray(vals, dtype=float)
        return comm.allreduce(vals, op=MPI.SUM) if comm.size > 1 else vals

    steps = stored_steps(scene.nt, dt, scene.output_times, max_rows)
    gather = _Gather(comm, x)
    k = len(steps)
    rows = {name: np.empty((k, gather.x.size)) for name in ("eta", "velocity", "contact_force")}
    rows["contact"] = np.empty((k, gather.x.size), dtype=bool)
    energy_rows = {key: np.empty(k) for key in ENERGY_KEYS}

    v = v0.copy()
    K_eta = k_apply(eta.array)
    kin, el = allsum([0.5 * mass_dot(v, v), 0.5 * np.dot(eta.array, K_eta)])
    cumulative = dict.fromkeys(("viscous_dissipation", "contact_dissipation", "numerical_dissipation", "external_work"), 0.0)
    force_density = np.zeros(n_owned)
    min_eta = float(np.min(eta.array[interior])) if interior.any() else math.inf

    writer = None
    if output_dir is not None:
        from .output import OutputWriter

        writer = OutputWriter(output_dir, scene, V, comm, force=force, pictures=pictures)

    extra_nodal = {f: f.x.array[:n_owned] for f in extra.values()}

    def store(row, n):
        coeffs = {eta_sym: eta.array, **extra_nodal}
        contact = contact_law(coeffs, x).astype(bool)
        fields = {"eta": eta.array, "velocity": v, "contact": contact, "contact_force": force_density}
        for name, arr in fields.items():
            rows[name][row] = gather(arr)
        for key in ENERGY_KEYS:
            energy_rows[key][row] = cumulative.get(key, 0.0)
        energy_rows["kinetic"][row] = kin
        energy_rows["elastic"][row] = el
        if writer is not None:
            writer.write(n * dt, {name: np.asarray(a, dtype=float) for name, a in fields.items()})

    from tqdm import tqdm

    bar = tqdm(total=scene.nt, disable=not progress or comm.rank != 0, unit="step", mininterval=0.5, leave=False)
    t_loop = time.perf_counter()
    next_row = 0
    if steps[0] == 0:
        store(0, 0)
        next_row = 1
    E_prev = kin + el
    E_tol = 1e-9 * max(abs(E_prev), 1e-300)
    status, message = "complete", ""
    try:
        for n in range(scene.nt):  # computes η^{n+1}
            coeffs = {eta_sym: eta.array, eta_old_sym: eta_old.array, **extra_nodal}
            law = force_law(coeffs, x)
            if penalty == "explicit":
                f_applied = mF * law
            else:
                active = (law > 0) & interior
                if not np.array_equal(active, damping_active):
                    A_diag.array[:] = base_diag + np.where(active, mF * law / dt, 0.0)
                    A.setDiagonal(A_diag)
                    ksp.setOperators(A)
                    damping_active = active
                f_applied = None
            P.mult(eta, b)
            barr = b.array
            if mass == "lumped":
                barr += Q * eta_old.array
            else:
                Q.multAdd(eta_old, b, b)
                barr = b.array
            if penalty == "explicit":
                barr += f_applied
            else:
                barr += np.where(damping_active, mF * law / dt, 0.0) * eta.array
            barr += load
            barr[bc] = g
            ksp.solve(b, eta_new)

            # Diagnostics of the step n → n+1 (the discrete energy identity, term by term).
            v_new = (eta_new.array - eta.array) / dt
            if penalty != "explicit":
                f_applied = -np.where(damping_active, mF * law, 0.0) * v_new
            K_eta_new = k_apply(eta_new.array)
            d_eta = eta_new.array - eta.array
            dv = v_new - v
            kin, el, visc, con, num, ext = allsum(
                [
                    0.5 * mass_dot(v_new, v_new),
                    0.5 * np.dot(eta_new.array, K_eta_new),
                    dt * c_dot(v_new),
                    -dt * np.dot(v_new, f_applied),
                    0.5 * mass_dot(dv, dv) + 0.5 * np.dot(d_eta, K_eta_new - K_eta),
                    np.dot(d_eta, load),
                ]
            )
            cumulative["viscous_dissipation"] += visc
            cumulative["contact_dissipation"] += con
            cumulative["numerical_dissipation"] += num
            cumulative["external_work"] += ext
            force_density = np.divide(f_applied, mF, out=np.zeros(n_owned), where=mF > 0)
            min_eta = min(min_eta, float(np.min(eta_new.array)) if n_owned else math.inf)

            # rotate: η^{n−1} ← η^n ← η^{n+1}
            eta_old, eta, eta_new = eta, eta_new, eta_old
            v, K_eta = v_new, K_eta_new
            E = kin + el - cumulative["external_work"]
            if not math.isfinite(E) or E > E_prev + E_tol:
                t_n = (n + 1) * dt
                why = "a value is not finite" if not math.isfinite(E) else f"the energy rose from {E_prev:.6g} to {E:.6g}"
                raise InstabilityError(
                    f"unstable at step {n + 1}, t = {t_n:.6g}: {why} (r = dt/eps = {r:.4g}, penalty {penalty}); "
                    "use penalty='semi-implicit' or a smaller dt",
                    step=n + 1,
                    time=t_n,
                    r=r,
                )
            E_prev = E
            if next_row < k and steps[next_row] == n + 1:
                store(next_row, n + 1)
                next_row += 1
            if progress and (n & 63) == 0:
                bar.update(min(64, scene.nt - bar.n))
    except (InstabilityError, KeyboardInterrupt) as exc:
        status = "unstable" if isinstance(exc, InstabilityError) else "interrupted"
        message = str(exc)
        if writer is not None:
            writer.abort(status, message)
        raise
    finally:
        bar.close()
    timings["solve"] = time.perf_counter() - t_loop

    min_eta = comm.allreduce(min_eta, op=MPI.MIN) if comm.size > 1 else min_eta
    result = Result(
        scene=scene,
        x=gather.x,
        t=steps * dt,
        steps=steps,
        eta=rows["eta"],
        velocity=rows["velocity"],
        contact=rows["contact"],
        contact_force=rows["contact_force"],
        energy=energy_rows,
        min_eta=float(min_eta),
        penalty=penalty,
        mass=mass,
        model=model.name,
        status=status,
        timings=timings,
        message=message,
    )
    if writer is not None:
        t_io = time.perf_counter()
        writer.finish(result)
        timings["output"] = time.perf_counter() - t_io + writer.write_time
    return result
