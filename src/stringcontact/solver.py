"""The time loop: assemble once, factorise once, back-substitute each step.

Per step only one PETSc mat-vec (two more with a consistent mass), one LU back-substitution (the KSP's
factor, set up once) and a few NumPy array operations run. The model (UFL) is turned into operators by
`scheme`, and the contact force is taken from the previous step by evaluating the model's `penalty` at
the nodes (`nodal`).
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
from .model import Model, Parameters, inelastic, unused_fields
from .result import ENERGY_KEYS, Result
from .scheme import bc_dofs, node_coordinates, semi_discrete_operators, stacked, step_matrices

PENALTIES = ("explicit", "semi-implicit")
MASSES = ("lumped", "consistent")


class InstabilityWarning(UserWarning):
    """The explicit penalty with 1 < Δt/ε < 2: stable, but it rebounds with restitution r − 1."""


def output_steps(nt: int, dt: float, output_times) -> set[int]:
    """The steps nearest to the scene's output times."""
    return {min(nt, max(0, round(t / dt))) for t in output_times}


def stored_steps(nt: int, dt: float, output_times, max_rows: int) -> np.ndarray:
    """Every k-th step so that about `max_rows` rows are kept, plus 0, nt and the scene's output times."""
    stride = max(1, math.ceil(nt / max(1, max_rows)))
    steps = set(range(0, nt + 1, stride)) | {0, nt} | output_steps(nt, dt, output_times)
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

        self.identity = bool(np.array_equal(self.order, np.arange(self.order.size)))

    def __call__(self, a: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        if self.comm.size == 1 and self.identity:  # serial, dofs already in x order: one copy
            if out is None:
                return a.copy()
            out[...] = a
            return out
        parts = self.comm.allgather(a) if self.comm.size > 1 else [a]
        return np.take(np.concatenate(parts), self.order, out=out)


def simulate(
    scene,
    penalty: str = "explicit",
    mass: str = "lumped",
    output_dir=None,
    progress: bool = False,
    model: Model | None = None,
    max_rows: int = 400,
    max_frames: int = 100,
    force: bool = False,
    pictures=True,
    comm=MPI.COMM_WORLD,
) -> Result:
    """Run `scene` and return a `Result`.

    About `max_rows` time levels are stored (in the Result, diagnostics.csv and the pictures); about
    `max_frames` of them go to solution.xdmf, always with 0, T and the scene's output times.

    With `output_dir`, also write XDMF, CSV, JSON (and, with `pictures`, PNGs) there; `pictures` may be
    `viz.Painters` started earlier, so that VTK's start-up overlaps more of the run. The scene's extra
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
    n_owned = V.dofmap.index_map.size_local
    dof_x = node_coordinates(V)  # owned dofs, then ghosts
    x = dof_x[:n_owned]
    extra = {}
    for name in scene.fields:
        f = fem.Function(V, name=name)
        f.x.array[:] = scene.field_values(name, dof_x)
        extra[name] = f
    params = Parameters(
        alpha=fem.Constant(msh, PETSc.ScalarType(scene.alpha)),
        eps=fem.Constant(msh, PETSc.ScalarType(scene.eps)),
        x=ufl.SpatialCoordinate(msh),
        length=scene.length,
        extra=extra,
    )
    unused = unused_fields(model, V, params)
    if unused:  # a load the model ignores would give a plausible but wrong answer
        raise ValueError(
            f"scene field(s) {', '.join(unused)}: not used by model '{model.name}'; choose a model that reads them "
            "(e.g. model = 'stringcontact.variants:loaded_obstacle') or remove them from the scene"
        )
    ops = semi_discrete_operators(model, V, params)
    A, Ms, C_over_dt = step_matrices(ops, dt, mass)
    KC = stacked(ops.K, C_over_dt)  # K η and (C/Δt) η of one η in one mat-vec
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
    energy_law = None if model.contact_energy is None else nodal.NodalExpression(model.contact_energy(eta_sym, params))

    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    if comm.size > 1:
        pc.setFactorSolverType("mumps")
    ksp.setUp()
    lu_solve = pc.getFactorMatrix().solve  # the back-substitution itself, without KSPSolve's bookkeeping
    timings["setup"] = time.perf_counter() - t0

    # Every vector of the loop is allocated here, once: rows of a few 2-D NumPy arrays, wrapped without
    # copying as PETSc vectors where PETSc needs them. The loop then only calls ufuncs with out=, one
    # PETSc mat-vec ([K; C/Δt] η^{n+1}), one back-substitution and two einsum calls for all the energy
    # dot products (rows dotted with the same vector are stacked, so one einsum does several dots).
    # Pairs of rows hold a quantity at the new and the previous step; the loop swaps which row is which,
    # so the previous step's K η, C η and M v are reused, never recomputed, and nothing is copied.
    def wrap(a):
        """(PETSc vector over `a`'s memory, `a`): this rank's part of a vector is all of `a`."""
        return PETSc.Vec().createWithArray(a.reshape(-1), size=(a.size, PETSc.DECIDE), comm=comm), a

    etas = np.zeros((3, n_owned))  # η^{n+1}, η^n, η^{n−1} in rotating rows
    vels = np.zeros((2, n_owned))  # v^{n+1}, v^n in rotating rows
    # Dotted with v^{n+1}: C(η^{n+1} − η^n)/Δt = C v^{n+1}, the applied force m_F∘F, and M v^{n+1}, M v^n.
    by_v = np.zeros((4, n_owned))
    # [K η, (C/Δt) η] of η^{n+1} and of η^n, each pair from one mat-vec with [K; C/Δt]
    KC_etas = np.zeros((2, 2, n_owned))
    K_etas = KC_etas[:, 0]  # K η^{n+1}, K η^n (rows alternate): dotted with η^{n+1}
    eta_new, eta, eta_old = (wrap(row) for row in etas)
    v_new, v = (wrap(row) for row in vels)
    C_v, f_applied = by_v[0], by_v[1]
    M_v_new, M_v = wrap(by_v[2]), wrap(by_v[3])
    KC_new, KC_old = (wrap(pair) for pair in KC_etas)
    b, b_a = wrap(np.zeros(n_owned))  # the right-hand side
    two_steps, two_steps_a = wrap(np.zeros(n_owned))  # consistent mass: 2η^n − η^{n−1}, multiplied by M/Δt²
    dots_v, dots_K = np.zeros(4), np.zeros(2)
    diag_w = np.zeros(n_owned)  # semi-implicit: the damping weights m_F d / Δt on the active set

    eta[1][:] = scene.initial_displacement(x)
    eta[1][bc] = g
    v[1][:] = np.asarray(scene.initial_velocity(x), dtype=float) * interior  # a fixed end does not move
    eta_old[1][:] = eta[1] - dt * v[1]

    m, mF, load = ops.m, ops.m_force, ops.load
    has_load = bool(np.any(load != 0))
    lumped = mass == "lumped"
    explicit = penalty == "explicit"
    base_diag = A.getDiagonal().array.copy() if not explicit else None
    damping_diag = np.zeros(n_owned)  # the damping weights now in the factorised diagonal
    A_diag = A.createVecLeft()
    refactorisations = 0
    m_dt2 = m / dt**2

    def apply_mass(u, out) -> None:
        if lumped:
            np.multiply(m, u[1], out=out[1])
        else:
            Ms.mult(u[0], out[0])

    if comm.size > 1:

        def allsum(*vals):
            return comm.allreduce(np.array(vals), op=MPI.SUM).tolist()

    else:

        def allsum(*vals):
            return vals

    steps = stored_steps(scene.nt, dt, scene.output_times, max_rows)
    gather = _Gather(comm, x)
    k = len(steps)
    rows = {name: np.empty((k, gather.x.size)) for name in ("eta", "velocity", "contact_force")}
    rows["contact"] = np.empty((k, gather.x.size), dtype=bool)
    energy_rows = {key: np.empty(k) for key in ENERGY_KEYS}

    KC.mult(eta[0], KC_old[0])
    apply_mass(v, M_v)
    kin, el = allsum(0.5 * float(np.dot(v[1], M_v[1])), 0.5 * float(np.dot(eta[1], KC_old[1][0])))
    visc_sum = con_sum = num_sum = ext_sum = 0.0  # the cumulative dissipations and external work
    min_eta = float(np.min(eta[1][interior])) if interior.any() else math.inf

    writer = None
    if output_dir is not None:
        from .output import OutputWriter, xdmf_frames

        frames = xdmf_frames(steps, output_steps(scene.nt, dt, scene.output_times), max_frames)
        writer = OutputWriter(output_dir, scene, V, comm, force=force, pictures=pictures, frames=frames)

    # One environment for the nodal laws; the loop only swaps the arrays of η^n and η^{n−1} in it.
    env = nodal.environment({f: f.x.array[:n_owned] for f in extra.values()}, x)
    k_eta, k_eta_old = id(eta_sym), id(eta_old_sym)
    inv_mF = np.divide(1.0, mF, out=np.zeros(n_owned), where=mF > 0)  # 0 where no force acts (Dirichlet ends)
    force_density = np.zeros(n_owned)

    def store(row, n):
        env[k_eta], env[k_eta_old] = eta[1], eta_old[1]
        contact = contact_law.evaluate_env(env)  # cast to bool by the copy into its row
        np.multiply(f_applied, inv_mF, out=force_density)
        fields = {"eta": eta[1], "velocity": v[1], "contact": contact, "contact_force": force_density}
        for name, arr in fields.items():
            gather(arr, out=rows[name][row])
        cumulative = (kin, el, visc_sum, con_sum, num_sum, ext_sum)
        for key, value in zip(ENERGY_KEYS, cumulative):
            energy_rows[key][row] = value
        if writer is not None:
            writer.write(n * dt, {name: np.asarray(a, dtype=float) for name, a in fields.items()})

    def result_of(n_rows: int, min_eta: float, status: str, message: str) -> Result:
        """The first `n_rows` stored rows as a Result (all of them after a complete run)."""
        return Result(
            scene=scene,
            x=gather.x,
            t=steps[:n_rows] * dt,
            steps=steps[:n_rows],
            **{name: rows[name][:n_rows] for name in ("eta", "velocity", "contact", "contact_force")},
            energy={key: values[:n_rows] for key, values in energy_rows.items()},
            min_eta=float(min_eta),
            penalty=penalty,
            mass=mass,
            model=model.name,
            status=status,
            timings=timings,
            message=message,
        )

    from tqdm import tqdm

    bar = tqdm(total=scene.nt, disable=not progress or comm.rank != 0, unit="step", mininterval=0.5, leave=False)
    t_loop = time.perf_counter()
    next_row = 0
    if steps[0] == 0:
        store(0, 0)
        next_row = 1
    next_store = steps[next_row] if next_row < k else -1

    def stored_energy(eta_now) -> float:  # Σ m_F Φ(η) on owned dofs: the energy held by a conservative (spring) law
        env[k_eta] = eta_now
        return float(np.dot(mF, energy_law.evaluate_env(env)))

    E_prev = kin + el + (float(allsum(stored_energy(eta[1]))[0]) if energy_law is not None else 0.0)
    # A dissipative law may not raise the energy at all. An explicit contact spring (a conservative law)
    # makes it wobble by O(dt/√ε) during an impact, so there the energy may not exceed E(0) by 1e-3 E(0).
    E_tol = (1e-9 if energy_law is None else 1e-3) * max(abs(E_prev), 1e-300)
    E_ref = E_prev
    inv_dt = 1.0 / dt
    status, message = "complete", ""
    dot, subtract, multiply, einsum = np.dot, np.subtract, np.multiply, np.einsum
    KC_mult = KC.mult
    inv_dt2 = 1.0 / dt**2
    ends = [(int(i), float(g_i)) for i, g_i in zip(bc, g)]
    errstate = np.errstate(all="ignore")  # a NaN or overflow is caught by the energy guard, which names the step
    errstate.__enter__()
    try:
        for n in range(scene.nt):  # computes η^{n+1}
            e0, em = eta[1], eta_old[1]
            env[k_eta], env[k_eta_old] = e0, em
            law = force_law.evaluate_env(env)

            # Right-hand side b = (M/Δt²)(2η^n − η^{n−1}) + (C/Δt)η^n + m_F∘F^n + load.
            if explicit:
                multiply(mF, law, out=f_applied)
            else:
                active = law > 0
                active &= interior
                multiply(mF, law, out=diag_w)
                diag_w *= inv_dt
                multiply(diag_w, active, out=diag_w)
                # Refactorise when the damping on the diagonal changes (the active set, or a state-dependent
                # coefficient of a model variant); only the diagonal changes, so PETSc keeps the symbolic
                # factorisation. Every rank must take part, so under MPI the ranks agree first.
                changed = not np.array_equal(diag_w, damping_diag)
                if comm.size > 1:
                    changed = comm.allreduce(changed, op=MPI.LOR)
                if changed:
                    np.add(base_diag, diag_w, out=A_diag.array)
                    A.setDiagonal(A_diag)
                    ksp.setOperators(A)
                    ksp.setUp()
                    lu_solve = pc.getFactorMatrix().solve
                    damping_diag[:] = diag_w
                    refactorisations += 1
                multiply(diag_w, e0, out=f_applied)  # the damping's known part, (d/Δt) η^n, moves to b
            if lumped:
                subtract(e0, em, out=b_a)
                b_a += e0
                b_a *= m_dt2
            else:
                subtract(e0, em, out=two_steps_a)
                two_steps_a += e0
                Ms.mult(two_steps, b)
                b_a *= inv_dt2
            b_a += KC_old[1][1]  # (C/Δt) η^n
            b_a += f_applied
            if has_load:
                b_a += load
            for i, g_i in ends:  # item assignment: a fancy-indexed b_a[bc] = g costs 3 µs per step
                b_a[i] = g_i
            lu_solve(b, eta_new[0])

            # Diagnostics of the step n → n+1: the discrete energy identity, term by term.
            e1, v1 = eta_new[1], v_new[1]
            subtract(e1, e0, out=v1)
            v1 *= inv_dt
            if not explicit:  # the force actually applied: −m_F d v^{n+1}
                multiply(diag_w, v1, out=f_applied)
                f_applied *= -dt
            KC_mult(eta_new[0], KC_new[0])  # K η^{n+1} and (C/Δt) η^{n+1}
            subtract(KC_new[1][1], KC_old[1][1], out=C_v)  # = C v^{n+1}
            apply_mass(v_new, M_v_new)
            einsum("ij,j->i", by_v, v1, out=dots_v)  # v¹·Cv¹, v¹·f, v¹·Mv¹ and v¹·Mv⁰ (rows 2, 3 alternate)
            einsum("ij,j->i", K_etas, e1, out=dots_K)  # η¹·Kη¹ and η¹·Kη⁰ (rows alternate)
            iM = 2 + (n & 1)  # the row of M v^{n+1}: rows 2 and 3 swap roles every step, as do the K rows
            iK = n & 1
            # With M, K symmetric: ½|v¹−v⁰|²_M = ½v¹·Mv¹ + ½v⁰·Mv⁰ − v¹·Mv⁰, and likewise for K and η, so
            # the numerical dissipation needs no difference vectors.
            kin_new, el_new, visc, con, cross, ext, stored = allsum(
                0.5 * dots_v[iM],
                0.5 * dots_K[iK],
                dt * dots_v[0],
                -dt * dots_v[1],
                dots_v[5 - iM] + dots_K[1 - iK],
                dt * float(dot(v1, load)) if has_load else 0.0,
                stored_energy(e1) if energy_law is not None else 0.0,
            )
            num_sum += kin_new + kin + el_new + el - cross
            visc_sum += visc
            con_sum += con
            ext_sum += ext
            kin, el = kin_new, el_new
            if n_owned:
                low = e1.min()
                if low < min_eta:
                    min_eta = float(low)

            # rotate: η^{n−1} ← η^n ← η^{n+1}, and the new step's v, Kη, (C/Δt)η and Mv become the old ones
            eta_old, eta, eta_new = eta, eta_new, eta_old
            v, v_new = v_new, v
            KC_old, KC_new = KC_new, KC_old
            M_v, M_v_new = M_v_new, M_v
            E = kin + el - ext_sum
            if energy_law is not None:
                E += stored
            if not math.isfinite(E) or E > (E_prev if energy_law is None else E_ref) + E_tol:
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
            if n + 1 == next_store:
                store(next_row, n + 1)
                next_row += 1
                next_store = steps[next_row] if next_row < k else -1
            if progress and (n & 63) == 0:
                bar.update(min(64, scene.nt - bar.n))
    except (InstabilityError, KeyboardInterrupt) as exc:
        status = "unstable" if isinstance(exc, InstabilityError) else "interrupted"
        message = str(exc) or status
        # The rows stored so far: the partial output's diagnostics.csv and energy balance, and the CLI's report.
        partial = result_of(next_row, min_eta, status, message)
        exc.result = partial
        if writer is not None:
            writer.abort(status, message, result=partial, error=exc)
        raise
    except BaseException:
        if writer is not None:
            writer.discard()  # an unexpected error: no half-written folder, no stale lock
        raise
    finally:
        errstate.__exit__(None, None, None)
        bar.close()
    timings["solve"] = time.perf_counter() - t_loop - (writer.write_time if writer is not None else 0.0)  # I/O apart
    if not explicit:
        timings["refactorisations"] = refactorisations

    min_eta = comm.allreduce(min_eta, op=MPI.MIN) if comm.size > 1 else min_eta
    result = result_of(k, min_eta, status, message)
    if writer is not None:
        t_io = time.perf_counter()
        writer.finish(result)
        timings["output"] = time.perf_counter() - t_io + writer.write_time
    return result
