"""The schemes as a researcher would write them for Example 1's string (ψ = 0, finite differences = lumped FEM,
T = tridiag(−1, 2, −1), `splu` when the step matrix changes), what the benchmarks time `simulate` against;
`compiled_peer`, the paper's scheme as a plain C loop (`compiled_peer.c`). Shared by `bench_step` and
`bench_solver`; tests/verification/test_peers.py checks them against `simulate`."""

from __future__ import annotations

import ctypes
import os
import shlex
import shutil
import subprocess
import sysconfig
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from stringcontact.verification.reference import StoredRows

#: the C loop's source, beside this module
C_SOURCE = Path(__file__).resolve().parent / "compiled_peer.c"
#: the compiled limit on this machine: the compiler's best for this CPU
CFLAGS = ("-O3", "-march=native")
#: the C loop's ledger at T, in the order it fills it
LEDGER = ("kinetic", "elastic", "viscous_dissipation", "contact_dissipation", "numerical_dissipation", "min_eta")


def string_start(scene):
    """(Δt, Δx, η⁰, v⁰, T) of `scene`'s uniform string, the ends at h_left/h_right at rest, T on the interior (CSC)."""
    N, dt = scene.nx, scene.dt
    dx = scene.length / N
    x = np.linspace(0.0, scene.length, N + 1)
    eta = np.asarray(scene.initial_displacement(x), dtype=float).copy()
    eta[0], eta[-1] = scene.h_left, scene.h_right
    v = np.asarray(scene.initial_velocity(x), dtype=float) * np.ones(N + 1)
    v[[0, -1]] = 0.0
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(N - 1, N - 1), format="csc")
    return dt, dx, eta, v, T


def step_conditioning(scene) -> float:
    """r = (αΔt + Δt²)/Δx²: the paper's step matrix I + rT has a condition number of about 1 + 4r (∝ N² at fixed Δt)."""
    return (scene.alpha * scene.dt + scene.dt**2) / (scene.length / scene.nx) ** 2


def paper_peer(scene, stored_steps):
    """`paper`, explicit penalty, lumped mass: (I + rT) η¹ = 2η − η⁰ − aTη + Δt² F, F = ε⁻¹ χ{η < 0} (−v)⁺,
    v = (η − η⁰)/Δt, a = αΔt/Δx², r = a + Δt²/Δx²; the matrix never changes (one `splu`)."""
    dt, dx, eta, v0, _ = string_start(scene)
    N, r = scene.nx, step_conditioning(scene)
    lu = splu(sp.diags([-r, 1 + 2 * r, -r], [-1, 0, 1], shape=(N - 1, N - 1), format="csc"))
    eta_old = eta - dt * v0
    store = StoredRows(stored_steps, N + 1)
    store(0, eta, v0)
    a_dt, inv_eps, dt2 = scene.alpha * dt / dx**2, 1.0 / scene.eps, dt**2
    for n in range(scene.nt):
        e = eta[1:-1]
        v = (e - eta_old[1:-1]) / dt
        rhs = 2 * e - eta_old[1:-1] - a_dt * (eta[2:] - 2 * e + eta[:-2])
        rhs += dt2 * inv_eps * np.where(e < 0, np.maximum(-v, 0.0), 0.0)
        rhs[0] += r * scene.h_left
        rhs[-1] += r * scene.h_right
        eta_new = np.empty_like(eta)
        eta_new[0], eta_new[-1] = scene.h_left, scene.h_right
        eta_new[1:-1] = lu.solve(rhs)
        eta_old, eta = eta, eta_new
        if store.row < len(stored_steps) and stored_steps[store.row] == n + 1:  # v only where it is stored
            store(n + 1, eta, (eta - eta_old) / dt)
    return store.eta, store.v


def _factor(A, refactor: str):
    """The solve of a changed step matrix: `splu` (2.1 ms for Example 1's string), or "lapack" dgtsv (115 µs)."""
    if refactor == "splu":
        return splu(A.tocsc()).solve
    from scipy.linalg.lapack import dgtsv

    A = A.tocsr()
    dl, d, du = A.diagonal(-1), A.diagonal(), A.diagonal(1)
    return lambda b: dgtsv(dl, d, du, b)[3]


def _laplacian(e: np.ndarray) -> np.ndarray:
    """(T η) at the interior nodes, the ends included as neighbours."""
    return 2.0 * e[1:-1] - e[:-2] - e[2:]


def projection_peer(scene, stored_steps, refactor: str = "splu"):
    """`projection` (α > 0): (I + aT) η¹ = 2η − η⁰ + (a − r₀) Tη + F', η¹ ≥ 0, F' ≥ 0, F'·η¹ = 0, a = αΔt/Δx²,
    r₀ = Δt²/Δx², as the scheme solves it: the free step, then the primal–dual active set from {η̃ < 0} (its rows
    identity rows, refactorised when the set changes, F' = Aη − b on it) until the set stays; v centred."""
    dt, dx, eta, v0, T = string_start(scene)
    a, r0 = scene.alpha * dt / dx**2, dt**2 / dx**2
    n = eta.size - 2
    A = (sp.identity(n, format="csc") + a * T).tocsc()
    free_lu = splu(A)
    held, held_solve = None, None
    tol = -1e-14 * max(np.max(np.abs(eta)), 1.0) * (1 + 2 * a)  # the scheme's allowance for round-off in F
    store = StoredRows(stored_steps, eta.size)
    eta_old = eta - dt * v0
    levels = [eta_old, eta]  # η^{n−1}, η^n
    store(0, eta, v0)
    for step in range(scene.nt + 1):  # one step ahead: the row at n needs η^{n+1}
        e_old, e = levels
        b = 2.0 * e[1:-1] - e_old[1:-1] + (a - r0) * _laplacian(e)
        b[0] += a * e[0]
        b[-1] += a * e[-1]
        new = e.copy()
        inner = free_lu.solve(b)
        active = inner < 0.0
        while active.any():
            if held is None or not np.array_equal(active, held):
                held = active
                keep = sp.diags((~active).astype(float))
                held_solve = _factor(keep @ A + sp.diags(active.astype(float)), refactor)
            inner = held_solve(np.where(active, 0.0, b))
            R = A @ inner - b
            new_active = np.where(active, R > tol, inner < 0.0)
            if np.array_equal(new_active, active):
                break
            active = new_active
        new[1:-1] = inner
        if step >= 1:
            store(step, e, (new - e_old) / (2 * dt))
        levels = [e, new]
    return store.eta, store.v


def _damped_peer(scene, stored_steps, newmark: bool, refactor: str):
    dt, dx, eta, v, T = string_start(scene)
    a, r0, k = scene.alpha * dt / dx**2, dt**2 / dx**2, dt / scene.eps
    n = eta.size - 2
    lhs = (a / 2 + r0 / 4) if newmark else (a + r0)
    A0 = (sp.identity(n, format="csc") + lhs * T).tocsc()
    undamped = splu(A0).solve
    solve, damped = undamped, np.zeros(n, dtype=bool)
    store = StoredRows(stored_steps, eta.size)
    store(0, eta, v)
    eta_old = eta - dt * v
    for step in range(1, scene.nt + 1):
        e = eta[1:-1]
        vi = v[1:-1] if newmark else (e - eta_old[1:-1]) / dt
        chi = (e < 0.0) & (vi < 0.0)
        if newmark:
            base = e + dt * vi + (a / 2 - r0 / 4) * _laplacian(eta)
        else:
            base = 2.0 * e - eta_old[1:-1] + a * _laplacian(eta)
        while True:
            if not np.array_equal(chi, damped):  # the damping on the diagonal changed: refactorise
                damped = chi
                solve = _factor(A0 + sp.diags(k * chi), refactor) if chi.any() else undamped
            b = base + k * chi * e + ((dt * k / 2) * chi * vi if newmark else 0.0)
            b[0] += lhs * eta[0]
            b[-1] += lhs * eta[-1]
            new = eta.copy()
            new[1:-1] = solve(b)
            if not newmark:
                break
            v_new = 2.0 / dt * (new - eta) - v
            v_new[[0, -1]] = 0.0
            sticky = chi & (v_new[1:-1] > 0.0)  # a damping that would hold a node down lets it go
            if not sticky.any():
                break
            chi = chi & ~sticky
        v = v_new if newmark else (new - eta) / dt
        eta_old, eta = eta, new
        store(step, eta, v)
    return store.eta, store.v


def newmark_peer(scene, stored_steps, refactor: str = "splu"):
    """`newmark` (lumped): (I + (a/2 + r₀/4) T + kχ) η¹ = η + Δt v + (a/2 − r₀/4) Tη + kχ η + (kΔt/2) χ v with
    k = Δt/ε on χ = {η < 0, v < 0}, v¹ = 2(η¹ − η)/Δt − v; refactorised when χ changes; a node the damping would
    hold down (v¹ > 0) is released and the step solved again."""
    return _damped_peer(scene, stored_steps, True, refactor)


def semi_implicit_peer(scene, stored_steps, refactor: str = "splu"):
    """`paper` with the semi-implicit penalty: (I + rT + kχ) η¹ = 2η − η⁰ + aTη + kχ η, r = a + r₀, k = Δt/ε on
    χ = {η < 0, v < 0}, v = (η − η⁰)/Δt; refactorised when χ changes."""
    return _damped_peer(scene, stored_steps, False, refactor)


def build_compiled(cflags=CFLAGS) -> ctypes.CDLL:
    """``compiled_peer.c`` compiled with the system's C compiler and loaded; RuntimeError naming a failing compiler."""
    # the C compiler Python's own extensions are built with (what cffi uses for dolfinx's forms), else cc or gcc
    names = [shlex.split(n)[0] for n in (os.environ.get("CC"), sysconfig.get_config_var("CC")) if n]
    compiler = next(filter(None, map(shutil.which, [*names, "cc", "gcc"])), None)
    if compiler is None:
        raise RuntimeError("compiled_peer: no C compiler ($CC, Python's own CC, cc or gcc)")
    folder = Path(tempfile.mkdtemp(prefix="compiled-peer-"))
    library = folder / "compiled_peer.so"
    try:
        subprocess.run([compiler, *cflags, "-shared", "-fPIC", "-o", str(library), str(C_SOURCE)], check=True,
                       capture_output=True, text=True)
        lib = ctypes.CDLL(str(library))
    except subprocess.CalledProcessError as exc:
        raise RuntimeError(f"compiled_peer: {compiler} failed:\n{exc.stderr}") from None
    finally:
        shutil.rmtree(folder, ignore_errors=True)  # the loaded library stays mapped
    doubles = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
    longs = np.ctypeslib.ndpointer(np.int64, flags="C_CONTIGUOUS")
    lib.march.restype = integer = ctypes.c_int
    # march(N, nt, dt, dx, alpha, eps, h_left, h_right, eta, eta_old, n_stored, stored, rows_eta, rows_v, energies, ledger)
    lib.march.argtypes = [integer, integer, *[ctypes.c_double] * 6, doubles, doubles, integer, longs, doubles, doubles,
                          integer, doubles]
    return lib


def compiled_peer(lib, scene, stored_steps, energies: bool = False):
    """(rows of η, rows of v, ledger {LEDGER name: value at T, zeros without `energies`}, seconds in the loop) of the
    C loop `lib` on `scene`'s uniform string (Example 1), `stored_steps` increasing within 0 … nt."""
    N, dt = scene.nx, scene.dt
    steps = np.ascontiguousarray(stored_steps, dtype=np.int64)
    if N < 2 or np.any(np.diff(steps) <= 0) or (steps.size and (steps[0] < 0 or steps[-1] > scene.nt)):
        raise ValueError(f"compiled_peer: nx = {N} (>= 2) and stored steps increasing within 0 … {scene.nt}")
    _, dx, eta, v0, _ = string_start(scene)
    eta_old = eta - dt * v0
    rows_eta, rows_v = np.empty((len(steps), N + 1)), np.empty((len(steps), N + 1))
    ledger = np.zeros(len(LEDGER))
    t0 = time.perf_counter()
    failed = lib.march(N, scene.nt, dt, dx, scene.alpha, scene.eps, scene.h_left, scene.h_right, eta, eta_old,
                       len(steps), steps, rows_eta, rows_v, int(energies), ledger)
    seconds = time.perf_counter() - t0
    if failed:
        raise MemoryError("compiled_peer: out of memory")
    return rows_eta, rows_v, dict(zip(LEDGER, ledger.tolist())), seconds
