"""GetFEM's impacting rod, solved by GetFEM's own demo schemes and by stringcontact, side by side.

The problem is that of GetFEM's ``interface/tests/python/demo_dynamic_contact_1D.py`` (Y. Renard,
F. Chouly, LGPL 2.1; Debian ``python3-getfem`` 5.4): see `rod.py` beside this script and docs/explanation/getfem.md.
`getfem_rod` below runs the demo's time loop with GetFEM's own assembly and solves, following the demo line by
line, for each combination of `GETFEM_METHODS`: its contact treatments (``version`` 0 Signorini, 2 penalty,
3 Nitsche, 4 Taylor-Flanagan), mass matrices (consistent, redistributed, singular dynamic mass) and Newmark's
β (0 explicit, ¼ implicit), at the Δt/h of each. The demo's ``linsolve_superlu`` segfaults in Debian's build,
so ``gf.linsolve_mumps`` is used, as in the demo once per solve (it factorises the matrix at every call).
stringcontact runs the same problem mirrored into a string on (0, 2) over a point obstacle at x = 1, for every
method of `METHODS`; the headline one (`SIGNORINI`) is `projection` with the contact point released as
Signorini's (`Model.release`), at Δt = h.

Measured for each run: the relative max-in-time L² error of u (every time step, the demo's ``LinfL2u``) and
the relative L²(0,T;L²) error of v (the demo's ``L2L2v``) against the exact solution, the energy at T over
the energy at 0, the lowest u at the contact point, and the CPU time of the time loop (``time.process_time``).
The process table runs each GetFEM method with Δt ≥ h/4 and the headline method at NX = 80 and 160 in a process
of its own and takes its wall time from outside: the whole process (interpreter, imports, set-up, run,
errors), what a user waits for. The GetFEM side always runs in processes that never import dolfinx (both
bring a MUMPS).

    .venv/bin/python benchmarks/bench_getfem.py --out docs            # NX = 20 to 160 (15 to 25 minutes here)
    .venv/bin/python benchmarks/bench_getfem.py --quick --out /tmp/g  # NX = 20 only
    .venv/bin/python benchmarks/bench_getfem.py --out docs --getfem-rows docs/getfem_comparison.csv  # no GetFEM here

Writes getfem_comparison.csv (with err_v and, for the timed methods, process_s), getfem_sinking.csv,
getfem_restitution.csv and getfem_comparison.png to --out and prints the tables, the first of them the
summary: GetFEM's best err_u and err_v per NX against the headline method's, and the two processes' times.
Exits 0 with one line if GetFEM is not installed (``apt-get install python3-getfem``), unless ``--getfem-rows``
gives GetFEM's rows of an earlier run (its CSV: the rows whose side is "getfem", their process times too;
GetFEM's numbers are deterministic but for the times). getfem_restitution.csv: `projection` with
restitution e = 0 and e = 1 over three periods at four resolutions (`RESTITUTION_NXS`), the energy at each
period and its largest deviation over the run.

``--sweep`` (the Courant sweep, `COURANT` at `COURANT_NXS`): every combination of the demo's options that it runs at
each Δt/h (`sweep_methods`: contact treatment, mass matrix, lumping, β, P1 or P2; each matrix factorised once) against
`projection` and `fitted` with either release (`sweep_ours`); writes getfem_courant.csv and prints, per NX and Δt/h
and over any Δt/h, GetFEM's best err_u and err_v against stringcontact's best that gains no energy
(`courant_summary`). With ``--getfem-rows`` GetFEM's rows come from the getfem_courant.csv beside that CSV.

    .venv/bin/python benchmarks/bench_getfem.py --sweep --out docs     # both sides (10 to 40 minutes here)
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import importlib.util
import itertools
import json
import math
import resource
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rod

NXS = (20, 40, 80)  # rod cells; the string has twice as many, of the same size h = 1/NX
DT_OVER_H = 0.04  # the issue's Δt = 0.04 h, well inside the explicit schemes' CFL limit h/2
SINKING_NXS = (20, 40, 80, 160)
SINKING_DT_OVER_H = (0.04, 1.0)
LANDING = 1.0  # the rod first touches the obstacle at t = 1: energy lost before it is the bulk scheme's own


@dataclass(frozen=True)
class Method:
    """One way of running stringcontact: `scheme` is passed to `simulate` only when it is not "paper"."""

    label: str
    scheme: str
    penalty: str | None  # None: not passed (a scheme without a penalty choice)
    model: str  # "inelastic" (the paper's law) or "elastic" (the spring), both only at x = 1
    eps: Callable[[float, float], float]  # ε(h, Δt)
    mass: str = "lumped"
    dt_over_h: float = DT_OVER_H  # the schemes without a CFL limit below h may take their natural step
    restitution: float = 0.0  # scheme projection's restitution coefficient e (passed to `simulate` when > 0)
    nxs: tuple | None = None  # its own resolutions (default: the run's)
    release: str = "inelastic"  # the point contact's `Model.release`: "signorini" for the rod's elastic contact


#: The headline method: `projection` with the rod's contact point released as Signorini's (`Model.release`), Δt = h.
SIGNORINI = "projection, release=signorini, dt=h"
METHODS = (
    Method("paper, semi-implicit, eps=1e-9", "paper", "semi-implicit", "inelastic", lambda h, dt: 1e-9),
    Method(
        "paper, semi-implicit, eps=1e-9, consistent",
        "paper",
        "semi-implicit",
        "inelastic",
        lambda h, dt: 1e-9,
        mass="consistent",
    ),
    Method("paper, explicit, r=1", "paper", "explicit", "inelastic", lambda h, dt: dt),
    Method("elastic, explicit, r=1.9", "paper", "explicit", "elastic", lambda h, dt: dt / 1.9),
    Method("elastic, explicit, eps=h^2", "paper", "explicit", "elastic", lambda h, dt: h * h),
    Method("elastic, explicit, r=10", "paper", "explicit", "elastic", lambda h, dt: dt / 10),
    Method("elastic, explicit, r=100", "paper", "explicit", "elastic", lambda h, dt: dt / 100),
    Method("projection", "projection", None, "inelastic", lambda h, dt: 1e-9),
    Method("newmark, semi-implicit, eps=1e-9", "newmark", "semi-implicit", "inelastic", lambda h, dt: 1e-9),
    Method("projection, dt=h", "projection", None, "inelastic", lambda h, dt: 1e-9, dt_over_h=1.0),
    Method(
        "newmark, semi-implicit, eps=1e-9, dt=h",
        "newmark",
        "semi-implicit",
        "inelastic",
        lambda h, dt: 1e-9,
        dt_over_h=1.0,
    ),
    Method(
        "projection, e=1", "projection", None, "inelastic", lambda h, dt: 1e-9, restitution=1.0, nxs=(20, 40, 80, 160)
    ),
    Method(
        "projection, e=1, dt=h",
        "projection",
        None,
        "inelastic",
        lambda h, dt: 1e-9,
        dt_over_h=1.0,
        restitution=1.0,
        nxs=(20, 40, 80, 160),
    ),
    Method(
        SIGNORINI,
        "projection",
        None,
        "inelastic",
        lambda h, dt: 1e-9,
        dt_over_h=1.0,
        nxs=(20, 40, 80, 160),
        release="signorini",
    ),
    Method(
        "projection, release=signorini, dt=h/2",
        "projection",
        None,
        "inelastic",
        lambda h, dt: 1e-9,
        dt_over_h=0.5,
        nxs=(20, 40, 80, 160),
        release="signorini",
    ),
)
#: `restitution_rows`: scheme projection with e = 0 and 1 at these Δt/h, over RESTITUTION_PERIODS periods, at these NX.
RESTITUTION_NXS = (20, 40, 80, 160)
RESTITUTION_DT_OVER_H = (0.04, 0.5, 1.0)
RESTITUTION_PERIODS = 3
SINKING_METHODS = METHODS[0], METHODS[2]


@dataclass(frozen=True)
class GetfemMethod:
    """One of the demo's combinations: ``version`` (0 Signorini, 1 Paoli-Schatzman, 2 penalty, 3 Nitsche,
    4 Taylor-Flanagan), ``mass`` (0 consistent, 1 redistributed, 2 singular dynamic mass) and Newmark's β (0 explicit,
    ¼ implicit), at Δt = dt_over_h · h. The demo's other parameters keep its defaults: γ = ½, Nitsche γ0 = 5 and
    θ = 0, penalty γ0 = 1, e_PS = 0, P1."""

    label: str
    version: int
    mass: int
    beta: float
    dt_over_h: float
    nxs: tuple | None = (20, 40, 80, 160)  # its own resolutions with the default NXS (None: the run's)
    degree: int = 1  # the demo's u_degree: P1 or P2
    lump: bool = False  # the demo's lump_mass_matrix (P1)


GETFEM_METHODS = (
    GetfemMethod("taylor-flanagan", 4, 0, 0.0, DT_OVER_H, nxs=(20, 40, 80)),
    GetfemMethod("redistributed-mass", 0, 1, 0.0, DT_OVER_H, nxs=(20, 40, 80)),
    GetfemMethod("Signorini, singular mass, explicit, dt=h/4", 0, 2, 0.0, 0.25),
    GetfemMethod("penalty, redistributed mass, explicit, dt=h/4", 2, 1, 0.0, 0.25),
    GetfemMethod("Signorini, singular mass, implicit, dt=h", 0, 2, 0.25, 1.0),
    GetfemMethod("Signorini, singular mass, implicit, dt=h/2", 0, 2, 0.25, 0.5),
    GetfemMethod("Nitsche, singular mass, implicit, dt=h/2", 3, 2, 0.25, 0.5),
    GetfemMethod("penalty, singular mass, implicit, dt=h/2", 2, 2, 0.25, 0.5),
    GetfemMethod("Signorini, redistributed mass, implicit, dt=h/2", 0, 1, 0.25, 0.5),
    GetfemMethod("penalty, redistributed mass, implicit, dt=h/2", 2, 1, 0.25, 0.5),
)


FIELDS = (
    "side",
    "method",
    "nx",
    "dt",
    "eps",
    "r",
    "status",
    "cpu_s",
    "err_u",
    "err_v",
    "energy_ratio",
    "energy_landing",
    "min_u_contact",
    "contact_loss",
)


# --- GetFEM's side (child process) ---------------------------------------------------------------


def getfem_rod(method: GetfemMethod, nx: int, T: float = rod.PERIOD, demo_norms: bool = False,
               factorised: bool = False) -> dict:
    """One run of the demo's scheme `method` on the rod, with GetFEM's assembly and solves, as the demo writes it
    (``interface/tests/python/demo_dynamic_contact_1D.py``, GetFEM 5.4): every step's u and v, the energy and the
    loop's CPU time. The demo's ``linsolve_superlu`` is ``gf.linsolve_mumps`` here (Debian's SuperLU segfaults).
    With `demo_norms` every step also does what the demo does there: the exact u and v at the nodes (vectorised here;
    the demo loops over the nodes in Python) and its six norms by ``gf.compute_L2_norm``/``compute_H1_norm`` (the
    errors returned are still computed from U and V). With `factorised` each of the demo's matrices is factorised once
    (SciPy's SuperLU) instead of by MUMPS at every solve: the same numbers to round-off, for the Courant sweep."""
    import getfem as gf

    h, dt, beta, gamma, version, mass = 1.0 / nx, method.dt_over_h / nx, method.beta, 0.5, method.version, method.mass
    deg = method.degree
    gamma_n, theta_n, gamma_p = 5.0, 0.0, 1.0  # the demo's Nitsche and penalty parameters
    m = gf.Mesh("cartesian", np.linspace(0.0, 1.0, nx + 1))
    border = m.outer_faces()
    normals = m.normal_of_faces(border)
    m.set_region(1, border[:, np.nonzero(normals[0] < -0.01)[0]])  # GAMMAC: x = 0
    mfu = gf.MeshFem(m)
    mfu.set_classical_fem(deg)
    mim = gf.MeshIm(m, 4)
    md = gf.Model("real")
    md.add_fem_variable("u", mfu)
    md.add_initialized_data("t_N", theta_n)
    md.add_initialized_data("g_N", gamma_n / h)
    x = mfu.basic_dof_nodes()[0]
    if not (x[0] == 0.0 and x[-1] == 1.0 and np.all(np.diff(x) > 0)):  # the demo's rows 0 and n−1 need this order
        raise RuntimeError("GetFEM numbered the rod's dofs out of x order; the demo's scheme assumes x order")
    n = x.size
    M = gf.asm_generic(mim, 2, "u*Test_u", -1, md)
    norm_matrix = gf.Spmat("copy", M)  # the L² norm of a function of this space, before any change of M
    if method.lump:  # the demo's "basic lumped mass matrix" (P1 only)
        for j in range(n):
            for i in range(1, deg + 1):
                if j + i < n:
                    M[j, j] += M[j, j + i]
                    M[j, j + i] = 0.0
                if j - i >= 0:
                    M[j, j] += M[j, j - i]
                    M[j, j - i] = 0.0
    K = gf.asm_generic(mim, 2, "Grad_u*Grad_Test_u", -1, md)
    for A in (M, K):  # Dirichlet row at x = 1
        for i in range(deg + 1):
            A[n - 1, n - 1 - i] = 0.0
        A[n - 1, n - 1] = 1.0
    M2 = gf.Spmat("copy", M)
    if mass == 1:  # redistributed: the contact node's mass goes to its neighbours
        M[1, 1] += M[0, 0]
        M[0, 0] = 0.0
        for i in range(1, deg + 1):
            M[i, i] += M[i, 0]
            M[0, i] = M[i, 0] = 0.0
    elif mass == 2:  # singular dynamic mass (Renard): the contact node massless, its neighbour's 7h/12
        if deg != 1:
            raise ValueError("the demo's singular mass is P1 only")
        M[1, 1] = 7.0 * h / 12.0
        M[0, 0] = M[0, 1] = M[1, 0] = 0.0
    if mass:
        M2 = gf.Spmat("copy", M)
        M2[0, 0] = 1.0

    factors = {}

    def solve(A, b):
        if not factorised:
            return gf.linsolve_mumps(A, b)[:, 0]
        if id(A) not in factors:  # the demo's matrices do not change after the set-up: factorised once
            import scipy.sparse
            import scipy.sparse.linalg

            columns, rows = A.csc_ind()
            factors[id(A)] = (A, scipy.sparse.linalg.splu(scipy.sparse.csc_matrix((A.csc_val(), rows, columns),
                                                                                  shape=A.size())))
        return factors[id(A)][1].solve(np.asarray(b, dtype=float))

    U0, V0 = 0.5 - 0.5 * x, np.zeros(n)
    MV0, MA0 = M.mult(V0), -K.mult(U0)
    if mass:
        MA0[0] = 0.0
    K_m = gf.Spmat("copy", K)
    K_m.scale(dt * dt * beta)
    K_N = gf.Spmat("add", M, K_m)  # Newmark's matrix without contact
    K_N_C = gf.Spmat("copy", K_N)  # with the contact
    if version in (0, 1, 4):
        for i in range(deg + 1):
            K_N_C[0, i] = 0.0
        K_N_C[0, 0] = 1.0
    elif version == 2:
        K_N_C[0, 0] += dt * dt * beta * gamma_p / h
    else:  # Nitsche
        K_N1 = gf.asm_generic(mim, 2, "-(t_N/g_N)*Grad_u*Grad_Test_u", 1, md)
        K_nitsche1 = gf.Spmat("add", K, K_N1)
        K_N1.scale(dt * dt * beta)
        K_N = gf.Spmat("add", K_N, K_N1)
        K_N2 = gf.asm_generic(mim, 2, "(1/g_N)*(g_N*u+Grad_u)*(g_N*Test_u+t_N*Grad_Test_u)", 1, md)
        K_nitsche2 = gf.Spmat("add", K_nitsche1, K_N2)
        K_N2.scale(dt * dt * beta)
        K_N_C = gf.Spmat("add", K_N, K_N2)
        nitsche = "(t_N/g_N)*Grad_u*Grad_Test_u+(1/g_N)*neg_part(g_N*u+Grad_u)*(g_N*Test_u+t_N*Grad_Test_u)"
    Fc = np.zeros(n)
    nt = round(T / dt)
    U, V = np.empty((nt + 1, n)), np.empty((nt + 1, n))
    U[0], V[0] = U0, V0
    k_landing, energy_landing = round(LANDING / dt), float("nan")
    energies = np.full(nt + 1, 0.5 * (V0 @ M.mult(V0) + U0 @ K.mult(U0)))  # the demo's energy at every step
    cpu = time.process_time()
    for k in range(1, nt + 1):
        if beta == 0:  # explicit Newmark
            F = Fc - K.mult(U0)
            FF = solve(M2, F)
            U1 = U0 + dt * V0 + (dt * dt / 2) * FF
            V1 = V0 + (dt * (1 - gamma)) * FF
            a = sum(K[0, i] * U1[i] for i in range(1, deg + 1))
            if version == 0:
                if not mass:
                    raise ValueError("the demo has no explicit pure Signorini scheme with the consistent mass")
                U1[0] = max(0.0, -a) / K[0, 0]
                Fc[0] = max(0.0, a)
            elif version == 1:
                if mass:
                    U1[0] = max(0.0, -a) / K[0, 0]
                elif U1[0] < 0:  # e_PS = 0
                    U1_0 = U1.copy()
                    B = M.mult(U0) + dt * M.mult(V0) - (dt * dt / 2) * K.mult(U0)
                    B0 = B.copy()
                    B0[0] = 0.0
                    U1 = solve(K_N_C, B0)
                    V1 += (U1 - U1_0) / dt
                Fc[0] = 0.0
            elif version == 4:
                if mass:
                    U1[0] = max(0.0, -a) / K[0, 0]
                elif U1[0] < 0:  # Taylor-Flanagan: the force that brings u(0) back to 0
                    e0 = np.zeros(n)
                    e0[0] = 1.0
                    s1 = V1[0] / (solve(M, e0)[0] * dt)
                    e0[0] = -s1
                    F2 = solve(M, e0)
                    U1 += dt * dt * F2
                    V1 += dt * F2
            elif version == 2:
                if mass:
                    U1[0] = -a / K[0, 0]
                    if U1[0] < 0:
                        U1[0] = -a / (K[0, 0] + gamma_p / h)
                Fc[0] = -(gamma_p / h) * min(0.0, U1[0])
            else:
                if mass:
                    U1[0] = -sum(K_nitsche1[0, i] * U1[i] for i in range(1, deg + 1)) / K_nitsche1[0, 0]
                    if U1[0] < 0:
                        U1[0] = -sum(K_nitsche2[0, i] * U1[i] for i in range(1, deg + 1)) / K_nitsche2[0, 0]
                md.set_variable("u", U1)
                Fc = gf.asm_generic(mim, 1, nitsche, 1, md)
            FF = solve(M2, Fc - K.mult(U1))
            V1 += dt * gamma * FF
        else:  # implicit Newmark
            B = M.mult(U0) + dt * MV0 + (dt * dt * (1 - 2 * beta) / 2) * MA0
            U1 = solve(K_N, B)
            MV1 = MV0.copy()
            Fc1 = np.zeros(n)
            if version == 0:
                if U1[0] < 0:
                    B2 = B.copy()
                    B2[0] = 0.0
                    U1 = solve(K_N_C, B2)
                    Fc1 = (K_N.mult(U1) - B) / (beta * dt * dt)
            elif version == 1:
                if U1[0] < 0:  # e_PS = 0
                    B2 = B.copy()
                    B2[0] = 0.0
                    U1 = solve(K_N_C, B2)
                    MV1 += dt * (K_N.mult(U1) - B) / (dt * dt)
            elif version == 2:
                if U1[0] < 0:
                    U1 = solve(K_N_C, B)
                    Fc1 = (K_N.mult(U1) - B) / (beta * dt * dt)
            else:
                md.set_variable("u", U1)
                ux = md.interpolation("Grad_u", [0.0], m)[0]
                if (gamma_n / h) * U1[0] + ux < 0:
                    U1 = solve(K_N_C, B)
                Fc1 = (K_N.mult(U1) - B) / (beta * dt * dt)
            MA1 = Fc1 - K.mult(U1)
            MV1 += dt * ((1 - gamma) * MA0 + gamma * MA1)
            V1 = solve(M2, MV1)
            V1[n - 1] = 0.0
            MA0, MV0 = MA1, MV1
        if mass:
            V1[0] = (U1[0] - U0[0]) / dt
        U0, V0 = U1, V1
        U[k], V[k] = U0, V0
        if demo_norms:  # the demo's per-step work: the exact solution at the nodes, six norms by GetFEM
            u_ex, v_ex = rod.rod_exact(x, k * dt), rod.rod_exact(x, k * dt, "t")  # (the demo: node by node)
            for field in (v_ex, u_ex, V0 - v_ex, U0 - u_ex):
                gf.compute_L2_norm(mfu, field, mim)
            for field in (u_ex, U0 - u_ex):
                gf.compute_H1_norm(mfu, field, mim)
        energies[k] = 0.5 * (V0 @ M.mult(V0) + U0 @ K.mult(U0))
        if k == k_landing:
            energy_landing = energies[k]
    cpu = time.process_time() - cpu
    energy = 0.5 * (V0 @ M.mult(V0) + U0 @ K.mult(U0))
    return {
        "x": x,
        "u": U,
        "v": V,
        "cpu_s": cpu,
        "energy": energy,
        "energy_max": float(energies.max()),
        "energy_landing": energy_landing,
        "nt": nt,
        "dt": dt,
        "norm": norm_matrix,
    }


def getfem_row(method: GetfemMethod, nx: int, T: float, demo_norms: bool = False, factorised: bool = False) -> dict:
    """`getfem_rod`'s run as a row of the comparison: the errors of u and v, the energy, the contact point."""
    run = getfem_rod(method, nx, T, demo_norms, factorised)
    t = run["dt"] * np.arange(run["nt"] + 1)
    return {
        "side": "getfem",
        "method": method.label,
        "nx": nx,
        "dt": run["dt"],
        "eps": "",
        "r": "",
        "status": "complete",
        "cpu_s": run["cpu_s"],
        "err_u": _getfem_error(run, t, "u", method.degree),
        "err_v": _getfem_error(run, t, "t", method.degree),
        "energy_ratio": run["energy"] / rod.ROD_ENERGY,
        "energy_max": run["energy_max"] / rod.ROD_ENERGY,
        "energy_landing": run["energy_landing"] / rod.ROD_ENERGY,
        "min_u_contact": float(run["u"][:, 0].min()),
        "contact_loss": "",
    }


def _getfem_error(run: dict, t: np.ndarray, field: str, degree: int) -> float:
    """The demo's LinfL2u (`field` "u") or L2L2v ("t"): P1 by `rod`'s exact nodal norms, P2 by GetFEM's mass matrix
    (the L² norm of a P2 function, exact)."""
    if degree == 1:
        error = rod.relative_error if field == "u" else rod.relative_velocity_error
        return error(run["x"], t, run["u" if field == "u" else "v"], exact=rod.rod_exact)
    exact = np.array([rod.rod_exact(run["x"], tk, field) for tk in t])
    diff = (run["u"] if field == "u" else run["v"]) - exact
    norms = [np.sqrt(np.einsum("ij,ij->i", a, np.array([run["norm"].mult(r) for r in a]))) for a in (diff, exact)]
    if field == "u":
        return float(norms[0].max() / norms[1].max())
    return float(np.sqrt(np.sum(norms[0] ** 2) / np.sum(norms[1] ** 2)))


def getfem_rows(nxs, T: float, methods=None) -> list[dict]:
    return [getfem_row(m, nx, T) for m in (methods or GETFEM_METHODS) for nx in _resolutions(m, nxs)]


# --- stringcontact's side --------------------------------------------------------------------------


def ours(method: Method, nx: int, dt_over_h: float, T: float) -> dict:
    """One stringcontact run of the mirrored rod; `status` says why a run gave no numbers."""
    import stringcontact as sc
    from stringcontact import InstabilityError
    from stringcontact.model.interface import inelastic
    from stringcontact.model.variants import elastic

    h = 1.0 / nx
    dt = dt_over_h * h
    eps = method.eps(h, dt)
    row = {"side": "stringcontact", "method": method.label, "nx": nx, "dt": dt, "eps": eps, "r": dt / eps}
    law = {"inelastic": inelastic, "elastic": elastic}[method.model]
    kwargs = {"mass": method.mass, "model": dataclasses.replace(rod.point_contact(law, h), release=method.release)}
    if method.penalty is not None:
        kwargs["penalty"] = method.penalty
    if method.restitution:
        kwargs["restitution"] = method.restitution
    if method.scheme != "paper":
        if method.scheme not in getattr(sc, "SCHEMES", ()):
            return {**row, "status": "no such scheme yet"}
        kwargs["scheme"] = method.scheme
    scene = rod.rod_scene(nx, dt, eps, T)
    cpu = time.process_time()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the 1 < r < 2 rebound warning is about the velocity penalty
            res = sc.simulate(scene, storage=sc.Storage(max_rows=scene.nt + 1), **kwargs)
    except InstabilityError as exc:
        return {**row, "status": "refused" if exc.step == 0 else "unstable"}
    except (
        ValueError,
        TypeError,
    ) as exc:  # a combination (or, in an older checkout, an option) the solver does not offer
        return {**row, "status": f"n/a: {exc}"[:60]}
    cpu = time.process_time() - cpu
    E = res.total_energy
    at_contact = np.argmin(np.abs(res.x - rod.CONTACT_POINT))
    periods = np.arange(1, round(T / rod.PERIOD) + 1) * rod.PERIOD
    return {
        **row,
        "status": res.status,
        "cpu_s": cpu,
        "err_u": rod.relative_error(res.x, res.t, res.eta),
        "err_v": rod.relative_velocity_error(res.x, res.t, res.velocity),
        "energy_ratio": E[-1] / E[0],
        "energy_landing": E[np.argmin(np.abs(res.t - LANDING))] / E[0],
        "min_u_contact": float(res.eta[:, at_contact].min()),
        "contact_loss": res.energy["contact_dissipation"][-1] / E[0],
        "energy_periods": " ".join(f"{E[np.argmin(np.abs(res.t - p))] / E[0]:.6f}" for p in periods),
        "energy_max_deviation": float(np.max(np.abs(E / E[0] - 1))),
        "energy_max": float(E.max() / E[0]),
        "contact_min": float(res.energy["contact_dissipation"].min() / E[0]),
    }


def our_rows(nxs, T: float) -> list[dict]:
    ours(METHODS[0], nxs[0], DT_OVER_H, T)  # fills the form cache, so no run below pays the JIT compiler
    return [ours(m, nx, m.dt_over_h, T) for m in METHODS for nx in _resolutions(m, nxs)]


def _resolutions(method: Method, nxs) -> tuple:
    """The method's own resolutions with the default NXS, else (--quick, --nx) the run's."""
    return method.nxs if method.nxs and tuple(nxs) == NXS else tuple(nxs)


def restitution_rows(nxs, periods: int) -> list[dict]:
    """`projection` with e = 0 and e = 1 on the rod over `periods` periods: its error and energy drift."""
    rows = []
    for q in RESTITUTION_DT_OVER_H:
        for e in (0.0, 1.0):
            method = Method(f"projection, e={e:g}", "projection", None, "inelastic", lambda h, dt: 1e-9, restitution=e)
            rows += [ours(method, nx, q, periods * rod.PERIOD) | {"dt_over_h": q, "restitution": e} for nx in nxs]
    return rows


def sinking_rows(nxs, T: float) -> list[dict]:
    return [ours(m, nx, q, T) | {"dt_over_h": q} for q in SINKING_DT_OVER_H for m in SINKING_METHODS for nx in nxs]


# --- the Courant sweep -----------------------------------------------------------------------------

#: The sweep's Δt/h, ¼ to 1 by 0.05, and its resolutions (docs/explanation/getfem.md, "At every Courant number").
COURANT = tuple(round(0.25 + 0.05 * k, 2) for k in range(16))
COURANT_NXS = (80, 160)
VERSIONS = {0: "Signorini", 1: "Paoli-Schatzman", 2: "penalty", 3: "Nitsche", 4: "Taylor-Flanagan"}
MASS_TYPES = {0: "standard mass", 1: "redistributed mass", 2: "singular mass"}
#: Round-off allowed in "no energy gained": E(t) <= (1 + this) E(0) and D_con >= -this E(0) at every step.
ENERGY_ROUNDOFF = 1e-9


def _explicit_limit(version: int, degree: int) -> float:
    """The demo's largest explicit Δt/h: h/(2 degree), and 2h/γ0 for the penalty (γ0 = 1) and Nitsche (γ0 = 5)."""
    return min(0.5 / degree, {2: 2.0, 3: 0.4}.get(version, math.inf))


def sweep_methods(q: float) -> list[GetfemMethod]:
    """Every combination of the demo's options that it runs at Δt/h = `q`: its contact treatment, mass matrix, lumping,
    Newmark β (0 or ¼) and degree (P1, P2). The demo stops with an assertion for Taylor-Flanagan with β > 0, explicit
    Signorini with the standard mass, the singular mass or the lumping with P2, and an explicit Δt above its bound."""
    methods = []
    for version, mass, lump, beta, degree in itertools.product(VERSIONS, MASS_TYPES, (False, True), (0.0, 0.25), (1, 2)):
        if (version == 4 and beta) or (version == 0 and not beta and not mass) or (degree == 2 and (mass == 2 or lump)):
            continue
        if not beta and q > _explicit_limit(version, degree) + 1e-12:
            continue
        label = (f"{VERSIONS[version]}, {'lumped ' if lump else ''}{MASS_TYPES[mass]}, "
                 f"{'implicit' if beta else 'explicit'}, P{degree}")
        methods.append(GetfemMethod(label, version, mass, beta, q, nxs=None, degree=degree, lump=lump))
    return methods


def sweep_ours(q: float) -> list[Method]:
    """stringcontact's ε-free schemes at Δt/h = `q`, each with the paper's release and with Signorini's."""
    return [Method(f"{scheme}, release={release}", scheme, None, "inelastic", lambda h, dt: 1e-9, mass=mass, dt_over_h=q,
                   release=release)
            for scheme, mass in (("projection", "lumped"), ("fitted", "blended")) for release in ("inelastic", "signorini")]


def getfem_sweep_rows(nxs, T: float) -> list[dict]:
    return [getfem_row(m, nx, T, factorised=True) | {"dt_over_h": q} for q in COURANT for m in sweep_methods(q)
            for nx in nxs]


def our_sweep_rows(nxs, T: float) -> list[dict]:
    return [ours(m, nx, q, T) | {"dt_over_h": q} for q in COURANT for m in sweep_ours(q) for nx in nxs]


def _keeps_energy(row: dict) -> bool:
    return row["energy_max"] <= 1 + ENERGY_ROUNDOFF and row.get("contact_min", 0.0) >= -ENERGY_ROUNDOFF


def courant_summary(rows: list[dict], nxs=COURANT_NXS) -> list[dict]:
    """Per NX and Δt/h (and over every Δt/h, "any"): GetFEM's best err_u and err_v over all its combinations, and
    stringcontact's best over its runs that gain no energy, with the ratios (GetFEM's over ours: above 1, ours is
    smaller)."""
    out = []
    for nx, q in itertools.product(nxs, [*COURANT, "any"]):
        here = [r for r in rows if r["nx"] == nx and r["status"] == "complete" and q in ("any", r["dt_over_h"])]
        theirs = [r for r in here if r["side"] == "getfem"]
        mine = [r for r in here if r["side"] == "stringcontact" and _keeps_energy(r)]
        if not theirs or not mine:
            continue
        row = {"nx": nx, "dt_over_h": q}
        for key, short in (("err_u", "u"), ("err_v", "v")):
            a, b = min(theirs, key=lambda r: r[key]), min(mine, key=lambda r: r[key])
            at = (lambda r: f", dt={r['dt_over_h']:g}h") if q == "any" else (lambda r: "")
            row |= {f"getfem_{short}": a[key], f"getfem_{short}_method": a["method"] + at(a),
                    f"getfem_{short}_energy_max": a["energy_max"], f"ours_{short}": b[key],
                    f"ours_{short}_method": b["method"] + at(b), f"ratio_{short}": a[key] / max(b[key], 1e-300)}
        out.append(row)
    return out


def stored_sweep_rows(path: Path, nxs) -> list[dict]:
    """GetFEM's rows of the sweep (side "getfem") at the resolutions `nxs` from a getfem_courant.csv this script wrote."""
    with path.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["side"] == "getfem" and int(r["nx"]) in nxs]
    numbers = ("dt", "dt_over_h", "cpu_s", "err_u", "err_v", "energy_ratio", "energy_max")
    return [{**r, "nx": int(r["nx"]), **{k: float(r[k]) for k in numbers}} for r in rows]


def sweep(args) -> int:
    """--sweep: both sides over `COURANT` at `COURANT_NXS` (or --nx), getfem_courant.csv and the summary table."""
    nxs = args.nx or COURANT_NXS
    if args.getfem_rows is not None:
        rows = stored_sweep_rows(args.getfem_rows.with_name("getfem_courant.csv"), nxs)
    elif importlib.util.find_spec("getfem") is None:
        print("bench_getfem: GetFEM is not installed (apt-get install python3-getfem); skipped")
        return 0
    else:
        child = [sys.executable, __file__, "--getfem-side", "--sweep", "--T", str(args.T), "--nx", *map(str, nxs)]
        rows = json.loads(subprocess.run(child, check=True, capture_output=True, text=True).stdout)
    rows += our_sweep_rows(nxs, args.T)
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(args.out / "getfem_courant.csv", rows)
    print_table(courant_summary(rows, nxs), ("nx", "dt_over_h", "getfem_u", "getfem_u_method", "ours_u", "ours_u_method",
                                             "ratio_u", "getfem_v", "getfem_v_method", "ours_v", "ours_v_method",
                                             "ratio_v"))
    print(f"wrote {args.out}/getfem_courant.csv")
    return 0


# --- tables and chart -------------------------------------------------------------------------------


def write_csv(path: Path, rows: list[dict]) -> None:
    keys = list(dict.fromkeys([*FIELDS, *(k for row in rows for k in row)]))
    tmp = path.with_name("." + path.name)
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys, restval="")
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)


def fmt(value, spec: str) -> str:
    return format(value, spec) if isinstance(value, float) else str(value)


def print_table(rows: list[dict], columns: tuple[str, ...]) -> None:
    specs = {
        "dt": ".2e",
        "eps": ".2e",
        "r": ".3g",
        "cpu_s": ".2f",
        "err_u": ".3g",
        "err_v": ".3g",
        "process_s": ".2f",
        "getfem_u": ".3g",
        "getfem_v": ".3g",
        "ours_u": ".3g",
        "ours_v": ".3g",
        "ratio_u": ".3g",
        "ratio_v": ".3g",
        "getfem_process_s": ".2f",
        "getfem_demo_process_s": ".2f",
        "ours_process_s": ".2f",
        "getfem_process_cpu_s": ".2f",
        "getfem_demo_process_cpu_s": ".2f",
        "ours_process_cpu_s": ".2f",
        "energy_ratio": ".4f",
        "energy_landing": ".4f",
        "min_u_contact": ".4f",
        "contact_loss": ".3f",
        "dt_over_h": "g",
        "energy_max_deviation": ".2e",
    }
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    for row in rows:
        print("| " + " | ".join(fmt(row.get(c, ""), specs.get(c, "")) for c in columns) + " |")
    print()


#: The chart's lowest error: a run exact to round-off (1e-13) is drawn there.
FLOOR = 1e-3


def chart(path: Path, rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    fig, (ax_cpu, ax_nx) = plt.subplots(1, 2, figsize=(11, 5.5), constrained_layout=True)
    complete = [r for r in rows if r["status"] == "complete"]
    colours = plt.cm.tab20.colors  # one colour per method: there are more than ten
    for k, label in enumerate(dict.fromkeys(r["method"] for r in complete)):
        mine = sorted((r for r in complete if r["method"] == label), key=lambda r: r["nx"])
        getfem = mine[0]["side"] == "getfem"
        big_step = mine[0]["dt"] * mine[0]["nx"] > 0.5  # Δt = h rather than 0.04 h
        style = {
            "marker": "s" if getfem else ("D" if big_step else "o"),
            "ls": "--" if getfem else ("-." if big_step else "-"),
            "color": colours[(2 * k) % 20 if k < 10 else (2 * k + 1) % 20],
            "label": f"{mine[0]['side']}: {label}",
        }
        err = [max(r["err_u"], FLOOR) for r in mine]  # exact to round-off: drawn at the floor
        if any(r["err_u"] < FLOOR for r in mine):
            style["label"] += f" (round-off, drawn at {FLOOR:g})"
        ax_cpu.loglog([r["cpu_s"] for r in mine], err, **style)
        ax_nx.loglog([r["nx"] for r in mine], err, **style)
    ax_cpu.set(
        xlabel="CPU time of one run [s] (process time)",
        ylabel="relative max-in-time L² error of u",
        title="error against CPU time",
    )
    ax_nx.set(
        xlabel="NX (rod cells; h = 1/NX; Δt as the label says, else 0.04 h; T = 3)",
        title="error against resolution",
    )
    for ax in (ax_cpu, ax_nx):
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(ScalarFormatter())
            axis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
    ax_nx.set_xticks(sorted({r["nx"] for r in complete}))
    ax_nx.set_yticks([FLOOR, 0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2])
    ax_cpu.set_yticks([FLOOR, 0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2])
    try:
        fig.legend(*ax_nx.get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize=8)
    except ValueError:  # matplotlib < 3.7 (Debian bookworm's 3.6) has no "outside": below the figure instead
        fig.legend(
            *ax_nx.get_legend_handles_labels(), loc="upper center", bbox_to_anchor=(0.5, 0.0), ncols=2, fontsize=8
        )
    fig.suptitle(
        "GetFEM's impacting rod (demo_dynamic_contact_1D): "
        "GetFEM's schemes (squares) and stringcontact's (circles; diamonds at Δt = h)",
        fontsize=10,
    )
    tmp = path.with_name("." + path.name)
    fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)


# --- command line ---------------------------------------------------------------------------------------


# --- whole processes ------------------------------------------------------------------------------------

#: The resolutions of the process table: the wall time of a whole process (start, imports, set-up, run, errors).
PROCESS_NXS = (80, 160)


def one_row(side: str, label: str, nx: int, T: float) -> dict:
    """The row of one method at one NX, computed in this process (the child of `process_rows`)."""
    if side in ("getfem", "getfem-demo"):
        return getfem_row(next(m for m in GETFEM_METHODS if m.label == label), nx, T, demo_norms=side == "getfem-demo")
    method = next(m for m in METHODS if m.label == label)
    return ours(method, nx, method.dt_over_h, T)


def process_rows(jobs, T: float) -> list[dict]:
    """Each (side, method, NX) of `jobs` in a process of its own, timed from outside: its wall time
    (`time.perf_counter`, what a user waits for) and its CPU time (user + system, `resource.getrusage`: on a shared
    machine the steadier of the two). Side "getfem" is GetFEM's loop alone, "getfem-demo" the same with the demo's
    per-step norms (`getfem_rod`'s `demo_norms`), "stringcontact" ours."""
    rows = []
    for side, label, nx in jobs:
        cmd = [sys.executable, __file__, "--one", side, label, "--nx", str(nx), "--T", str(T)]
        cpu, wall = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        wall, after = time.perf_counter() - wall, resource.getrusage(resource.RUSAGE_CHILDREN)
        row = json.loads(out)
        rows.append(
            {
                "side": side,
                "method": label,
                "nx": nx,
                "process_s": wall,
                "process_cpu_s": after.ru_utime - cpu.ru_utime + after.ru_stime - cpu.ru_stime,
                "err_u": row["err_u"],
                "err_v": row["err_v"],
            }
        )
    return rows


def process_jobs(rows: list[dict], nxs=PROCESS_NXS) -> list[tuple]:
    """GetFEM's best method in u and in v at each NX (from `rows`), in both of GetFEM's process variants, and ours."""
    jobs = []
    for nx in nxs:
        theirs = [r for r in rows if r["side"] == "getfem" and r["nx"] == nx and r["status"] == "complete"]
        best = dict.fromkeys(min(theirs, key=lambda r: r[k])["method"] for k in ("err_u", "err_v")) if theirs else {}
        jobs += [(side, label, nx) for label in best for side in ("getfem", "getfem-demo")]
        jobs.append(("stringcontact", SIGNORINI, nx))
    return jobs


def summary_rows(rows: list[dict], processes: list[dict], nxs=PROCESS_NXS) -> list[dict]:
    """Per NX: GetFEM's best err_u and err_v (over its methods) against our headline method's, with the ratios
    (GetFEM's over ours: above 1, ours is smaller), and the whole processes' wall and CPU times: GetFEM's fastest of
    its two best methods (its loop alone, and as the demo runs it), and ours."""
    out = []
    for nx in nxs:
        theirs = [r for r in rows if r["side"] == "getfem" and r["nx"] == nx and r["status"] == "complete"]
        mine = [r for r in rows if r["method"] == SIGNORINI and r["nx"] == nx]
        if not theirs or not mine:
            continue
        best_u, best_v = min(theirs, key=lambda r: r["err_u"]), min(theirs, key=lambda r: r["err_v"])
        here = [p for p in processes if p["nx"] == nx]

        def fastest(side, key, here=here, labels=(best_u["method"], best_v["method"])):
            times = [float(p[key]) for p in here if p["side"] == side and p["method"] in labels and p.get(key) != ""]
            return min(times) if times else float("nan")

        out.append(
            {
                "nx": nx,
                "getfem_u": best_u["err_u"],
                "getfem_u_method": best_u["method"],
                "getfem_v": best_v["err_v"],
                "getfem_v_method": best_v["method"],
                "ours_u": mine[0]["err_u"],
                "ours_v": mine[0]["err_v"],
                "ratio_u": best_u["err_u"] / max(mine[0]["err_u"], 1e-300),
                "ratio_v": best_v["err_v"] / mine[0]["err_v"],
                "getfem_process_s": fastest("getfem", "process_s"),
                "getfem_demo_process_s": fastest("getfem-demo", "process_s"),
                "ours_process_s": fastest("stringcontact", "process_s", labels=(SIGNORINI,)),
                "getfem_process_cpu_s": fastest("getfem", "process_cpu_s"),
                "getfem_demo_process_cpu_s": fastest("getfem-demo", "process_cpu_s"),
                "ours_process_cpu_s": fastest("stringcontact", "process_cpu_s", labels=(SIGNORINI,)),
            }
        )
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/getfem"))
    ap.add_argument("--quick", action="store_true", help="NX = 20 only")
    ap.add_argument("--nx", type=int, nargs="+", help="rod cells (default 20 40 80)")
    ap.add_argument("--T", type=float, default=rod.PERIOD)
    ap.add_argument(
        "--getfem-rows",
        type=Path,
        metavar="CSV",
        help="GetFEM's rows from an earlier run's getfem_comparison.csv (when GetFEM is not installed here)",
    )
    ap.add_argument("--sweep", action="store_true",
                    help="the Courant sweep only: both sides at dt/h = 0.25 to 1, NX = 80 and 160 (getfem_courant.csv)")
    ap.add_argument("--getfem-side", action="store_true", help=argparse.SUPPRESS)  # the child: JSON rows on stdout
    ap.add_argument("--one", nargs=2, metavar=("SIDE", "METHOD"), help=argparse.SUPPRESS)  # a timed child: one row
    args = ap.parse_args(argv)
    if args.sweep and args.getfem_side:
        print(json.dumps(getfem_sweep_rows(args.nx or COURANT_NXS, args.T)))
        return 0
    if args.sweep:
        return sweep(args)
    nxs = args.nx or (NXS[:1] if args.quick else NXS)
    if args.one is not None:
        print(json.dumps(one_row(*args.one, nxs[0], args.T), default=float))
        return 0
    if args.getfem_rows is not None:
        rows = stored_getfem_rows(args.getfem_rows, nxs)
    elif importlib.util.find_spec("getfem") is None:
        print("bench_getfem: GetFEM is not installed (apt-get install python3-getfem); skipped")
        return 0
    elif args.getfem_side:
        print(json.dumps(getfem_rows(nxs, args.T)))
        return 0
    else:
        child = [sys.executable, __file__, "--getfem-side", "--T", str(args.T), "--nx", *map(str, nxs)]
        rows = json.loads(subprocess.run(child, check=True, capture_output=True, text=True).stdout)
    timed_nxs = PROCESS_NXS[:1] if args.quick else PROCESS_NXS
    jobs = process_jobs(rows, timed_nxs)
    processes = []
    if args.getfem_rows is not None:  # GetFEM's process times from the stored run, next to its CSV
        jobs = [job for job in jobs if job[0] == "stringcontact"]
        stored = args.getfem_rows.with_name("getfem_processes.csv")
        if stored.exists():
            with stored.open(newline="") as f:
                processes = [{**r, "nx": int(r["nx"])} for r in csv.DictReader(f) if r["side"] != "stringcontact"]
    processes += process_rows(jobs, args.T)
    rows += our_rows(nxs, args.T)
    summary = summary_rows(rows, processes, timed_nxs)
    sinking = sinking_rows(SINKING_NXS[:2] if args.quick else SINKING_NXS, args.T)
    restitution = restitution_rows(RESTITUTION_NXS[:2] if args.quick else RESTITUTION_NXS, RESTITUTION_PERIODS)
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(args.out / "getfem_comparison.csv", rows)
    write_csv(args.out / "getfem_sinking.csv", sinking)
    write_csv(args.out / "getfem_restitution.csv", restitution)
    write_csv(args.out / "getfem_processes.csv", processes)
    chart(args.out / "getfem_comparison.png", rows)
    print_table(
        summary,
        (
            "nx",
            "getfem_u",
            "getfem_u_method",
            "getfem_v",
            "getfem_v_method",
            "ours_u",
            "ours_v",
            "ratio_u",
            "ratio_v",
            "getfem_process_s",
            "getfem_demo_process_s",
            "ours_process_s",
            "getfem_process_cpu_s",
            "getfem_demo_process_cpu_s",
            "ours_process_cpu_s",
        ),
    )
    print_table(
        rows,
        (
            "side",
            "method",
            "nx",
            "r",
            "status",
            "err_u",
            "err_v",
            "energy_ratio",
            "energy_landing",
            "min_u_contact",
            "cpu_s",
        ),
    )
    print_table(sinking, ("method", "dt_over_h", "nx", "r", "min_u_contact", "err_u", "energy_ratio", "contact_loss"))
    print_table(
        restitution,
        ("method", "dt_over_h", "nx", "err_u", "energy_periods", "energy_max_deviation", "min_u_contact", "cpu_s"),
    )
    print(
        f"wrote {args.out}/getfem_comparison.csv, getfem_sinking.csv, getfem_restitution.csv, getfem_processes.csv, "
        "getfem_comparison.png"
    )
    return 0


def stored_getfem_rows(path: Path, nxs) -> list[dict]:
    """GetFEM's rows (side "getfem") at the resolutions `nxs` from a getfem_comparison.csv this script wrote."""
    keep = {nx for m in GETFEM_METHODS for nx in _resolutions(m, nxs)}  # each method's own resolutions, as run
    with path.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["side"] == "getfem" and int(r["nx"]) in keep]
    numbers = ("dt", "cpu_s", "err_u", "err_v", "energy_ratio", "energy_landing", "min_u_contact")
    return [{**r, "nx": int(r["nx"]), **{k: float(r[k]) for k in numbers}} for r in rows]


if __name__ == "__main__":
    sys.exit(main())
