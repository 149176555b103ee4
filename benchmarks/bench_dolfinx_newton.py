"""The Newton path against dolfinx's own `NonlinearProblem` + `NewtonSolver` (LU), on the same nonlinear string.

    .venv/bin/python benchmarks/bench_dolfinx_newton.py              # Example 1, nx = 5000, 1500 steps, 3 rounds
    .venv/bin/python benchmarks/bench_dolfinx_newton.py --quick      # nx = 500, one round: a smoke test

The peer is the loop a FEniCSx user writes by hand for the paper's scheme (implicit Euler in η and η_t) on Example
1's data with the shipped cubic foundation (`cubic_foundation`: k η + k3 η³, k = k3 = 1): the residual in UFL,
consistent mass, the ends held by a Dirichlet condition, the penalty (1/ε) χ{η^n < 0} (v^n)⁻ explicit from the
previous step as a P1 source term set by NumPy, and each step solved by dolfinx's `NewtonSolver` with PETSc's LU
(the relative step 1e-9, as stringcontact's `snes_stol`). stringcontact runs the same model, scheme, penalty and mass
(`simulate(..., penalty="explicit", mass="consistent")`; it lumps the penalty on the nodes where the peer
integrates it as a P1 source, the difference in η at T in the last column). Per step: the peer's loop time over the steps, and
stringcontact's `timings["solve"]` (its steps and stored rows); the rounds alternate, each in a fresh process;
medians, and the largest |Δη| at T between the two. Prints a Markdown table row. Asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
import warnings


def peer(nx: int, nt: int) -> dict:
    """The hand-written dolfinx loop: seconds per step and η at T."""
    import numpy as np
    import ufl
    from dolfinx import fem, mesh
    from dolfinx.fem.petsc import NonlinearProblem
    from dolfinx.nls.petsc import NewtonSolver
    from mpi4py import MPI
    from petsc4py import PETSc

    import stringcontact as sc

    scene = sc.load_scene("example1").replace(nx=nx, nt=nt) if nt else sc.load_scene("example1").replace(nx=nx)
    msh = mesh.create_interval(MPI.COMM_SELF, nx, [0.0, scene.length])
    V = fem.FunctionSpace(msh, ("Lagrange", 1)) if hasattr(fem, "FunctionSpace") else fem.functionspace(msh, ("Lagrange", 1))
    u, e0, em, force = (fem.Function(V) for _ in range(4))
    w = ufl.TestFunction(V)
    dt, alpha, eps = scene.dt, scene.alpha, scene.eps
    x = V.tabulate_dof_coordinates()[:, 0]
    e0.x.array[:] = scene.initial_displacement(x)
    em.x.array[:] = e0.x.array - dt * scene.initial_velocity(x)
    ends = fem.locate_dofs_geometrical(V, lambda p: np.isclose(p[0], 0.0) | np.isclose(p[0], scene.length))
    em.x.array[ends] = e0.x.array[ends]
    height = fem.Function(V)
    height.x.array[:] = scene.h_left
    bc = fem.dirichletbc(height, ends)
    R = ((u - 2 * e0 + em) / dt**2 * w + alpha * ufl.inner(ufl.grad((u - e0) / dt), ufl.grad(w))
         + ufl.inner(ufl.grad(u), ufl.grad(w)) + (u + u**3) * w - force * w) * ufl.dx
    problem = NonlinearProblem(R, u, bcs=[bc])
    solver = NewtonSolver(MPI.COMM_SELF, problem)
    solver.rtol, solver.atol, solver.convergence_criterion = 1e-9, 1e-12, "incremental"  # as snes_stol
    ksp = solver.krylov_solver
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    iterations = 0
    t0 = time.perf_counter()
    for _ in range(scene.nt):
        v = (e0.x.array - em.x.array) / dt
        force.x.array[:] = np.where(e0.x.array < 0, np.maximum(-v, 0.0) / eps, 0.0)
        u.x.array[:] = 2 * e0.x.array - em.x.array  # the linear predictor
        n, converged = solver.solve(u)
        if not converged:
            raise RuntimeError("dolfinx's Newton did not converge")
        iterations += n
        em.x.array[:], e0.x.array[:] = e0.x.array, u.x.array
    seconds = time.perf_counter() - t0
    order = np.argsort(x)
    return {"per_step": seconds / scene.nt, "eta": e0.x.array[order].tolist(), "iterations": iterations}


def ours(nx: int, nt: int) -> dict:
    """stringcontact's Newton path on the same problem: seconds per step (`timings["solve"]`) and η at T."""
    import stringcontact as sc

    scene = sc.load_scene("example1").replace(nx=nx, nt=nt) if nt else sc.load_scene("example1").replace(nx=nx)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = sc.simulate(scene, scheme="paper", penalty="explicit", mass="consistent", model="cubic_foundation",
                        storage=sc.Storage(max_rows=10))
    return {"per_step": r.timings["solve"] / scene.nt, "eta": r.eta[-1].tolist(),
            "iterations": r.counters["newton iterations"]}


def _fresh(which: str, nx: int, nt: int) -> dict:
    """One run in a fresh process (the JIT cache warm: a first run compiles the forms)."""
    out = subprocess.run([sys.executable, __file__, "--one", which, "--nx", str(nx), "--nt", str(nt)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nx", type=int, default=5000)
    ap.add_argument("--nt", type=int, default=0, help="steps (0: Example 1's 1500)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="nx = 500, one round")
    ap.add_argument("--one", choices=("peer", "ours"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.quick:
        args.nx, args.nt, args.rounds = 500, 0, 1
    if args.one:
        print(json.dumps((peer if args.one == "peer" else ours)(args.nx, args.nt)))
        return
    _fresh("peer", args.nx, args.nt), _fresh("ours", args.nx, args.nt)  # the forms compiled once
    runs = {"peer": [], "ours": []}
    for r in range(args.rounds):
        for which in (("peer", "ours") if r % 2 == 0 else ("ours", "peer")):
            runs[which].append(_fresh(which, args.nx, args.nt))
    import numpy as np

    per = {k: statistics.median(r["per_step"] for r in v) for k, v in runs.items()}
    gap = float(np.max(np.abs(np.array(runs["peer"][-1]["eta"]) - np.array(runs["ours"][-1]["eta"]))))
    print(f"load average {os.getloadavg()[0]:.2f}; {args.rounds} rounds, nx = {args.nx}\n")
    print("| nx | dolfinx NonlinearProblem + NewtonSolver (LU) [ms/step] | stringcontact [ms/step] | ratio | "
          "Newton iterations (dolfinx, ours) | max abs(Δη) at T |")
    print("|---:|---:|---:|---:|---|---:|")
    print(f"| {args.nx} | {1e3 * per['peer']:.3f} | {1e3 * per['ours']:.3f} | {per['peer'] / per['ours']:.1f} | "
          f"{runs['peer'][-1]['iterations']}, {runs['ours'][-1]['iterations']} | {gap:.1e} |")


if __name__ == "__main__":
    main()
