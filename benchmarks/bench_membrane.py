"""Cost per step of scheme `projection` on square membranes, against a hand-written SciPy peer of the same scheme.

    .venv/bin/python benchmarks/bench_membrane.py                 # 1e4 ... 2.5e5 nodes (a few minutes)
    .venv/bin/python benchmarks/bench_membrane.py --big           # and 1e6 nodes (several GB)
    .venv/bin/python benchmarks/bench_membrane.py --ranks 2       # stringcontact under mpirun -n 2 as well
    .venv/bin/python benchmarks/bench_membrane.py --sizes 999     # only 1e6 nodes
    .venv/bin/python benchmarks/bench_membrane.py --solver lu cg-jacobi cg-amg auto --no-peer   # the linear solvers

Each run is a fresh process, so that its peak RSS (per rank) is its own. The scene: the unit square, cells
[n, n] (right diagonals), α = 0.01, Δt = 0.5/n (dt_max ≈ 0.7/n), the membrane thrown onto the obstacle so
that the projection acts from the first steps; `steps` steps. stringcontact's run stores its mesh (x, the
triangles) and its last η; the peer reads that mesh, assembles P1 stiffness and lumped mass itself (NumPy),
factorises A = M/Δt² + C/Δt with SuperLU and steps the same scheme. Both must agree (max |Δη| printed)
before their costs are compared. Prints a Markdown table (docs/howto/membranes.md) and writes
benchmarks/out/membrane.json.

`--solver` runs stringcontact with each linear solver (docs/explanation/linear_solvers.md): `lu` (PETSc LU, MUMPS on
several ranks), `cg-jacobi`, `cg-amg` (hypre BoomerAMG), `cg-amg-hmis` (BoomerAMG with HMIS coarsening and
ext+i interpolation), `cg-gamg` (PETSc's aggregation multigrid) or `auto` (the size rule, `LU_MAX_NODES`), set
through `simulate(petsc_options=...)`; its rows give the solver's own line (iterations per solve) and
max |η − η_LU| after the last step against the serial `lu` run of the same size in the same pass (so list
`lu` first).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "out"


#: --scene: "landed" is thrown onto the obstacle and rests on it after a few steps (the peer's comparison; an
#: iterative solve from the previous η has nothing left to do then); "flying" keeps moving, with a ripple that
#: the step's predictor does not foresee: what CG costs while a membrane is in flight.
SCENES = {
    "landed": dict(eta0="0.001*sin(pi*x)*sin(pi*y)", v0="-sin(pi*x)*sin(pi*y)"),
    "flying": dict(eta0="(0.1 + 0.001*sin(40*pi*x)*sin(40*pi*y))*sin(pi*x)*sin(pi*y)", v0="-sin(pi*x)*sin(pi*y)"),
}


def scene(n: int, steps: int, kind: str = "landed", alpha: float = 0.01):
    from stringcontact.scene import Scene

    dt = 0.5 / n
    return Scene.from_dict(dict(name=f"square{n}", domain="rectangle", cells=[n, n], T=steps * dt, nt=steps, alpha=alpha,
                                eps=1e-3, h=0, **SCENES[kind]))


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: kB


#: --solver: the PETSc options of each choice (`auto`: none, the size rule decides).
SOLVERS = {
    "lu": {"ksp_type": "preonly", "pc_type": "lu"},
    "cg-jacobi": {"ksp_type": "cg", "pc_type": "jacobi"},
    "cg-amg": {"ksp_type": "cg", "pc_type": "hypre", "pc_hypre_type": "boomeramg"},
    # Tuned multigrid, for the question whether a linear-cost solver can be the cheapest on 2 ranks (issue 28).
    "cg-amg-hmis": {"ksp_type": "cg", "pc_type": "hypre", "pc_hypre_type": "boomeramg",
                    "pc_hypre_boomeramg_coarsen_type": "HMIS", "pc_hypre_boomeramg_interp_type": "ext+i",
                    "pc_hypre_boomeramg_p_max": 4, "pc_hypre_boomeramg_strong_threshold": 0.5},
    "cg-gamg": {"ksp_type": "cg", "pc_type": "gamg", "pc_gamg_type": "agg", "pc_gamg_agg_nsmooths": 0},
    "auto": {},
}


def run_stringcontact(n: int, steps: int, out: Path, solver: str = "auto", kind: str = "landed",
                      alpha: float = 0.01) -> dict:
    from mpi4py import MPI

    import stringcontact as sc

    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    res = sc.simulate(scene(n, steps, kind, alpha), scheme="projection", storage=sc.Storage(max_rows=2),
                      petsc_options=SOLVERS[solver])
    total = time.perf_counter() - t0
    rss = comm.gather(peak_rss_mb())
    if comm.rank == 0:  # the rows are on rank 0 (simulate's gather="root")
        np.savez(out / f"sc{n}.npz", x=res.x, cells=res.cells, eta=res.eta[-1])
        np.save(out / f"eta{n}-{solver}-{comm.size}.npy", res.eta[-1])  # solver_table compares it with LU's
    return {"nodes": (n + 1) ** 2, "setup_s": res.timings["setup"], "step_ms": 1e3 * res.timings["solve"] / steps,
            "total_s": total, "ranks": comm.size, "rss_mb": rss, "solver": solver,
            "linear_solver": res.solver.get("linear solver", "")}


def p1_operators(x: np.ndarray, cells: np.ndarray):
    """P1 stiffness K (CSR) and lumped mass m on a triangle mesh, assembled with NumPy."""
    import scipy.sparse as sp

    p = x[cells]  # (k, 3, 2)
    e = np.stack([p[:, 2] - p[:, 1], p[:, 0] - p[:, 2], p[:, 1] - p[:, 0]], axis=1)  # edge opposite each vertex
    area = 0.5 * np.abs(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    local = np.einsum("kid,kjd->kij", e, e) / (4 * area)[:, None, None]  # ∫ ∇φ_i·∇φ_j = e_i·e_j / 4|T|
    rows = np.repeat(cells, 3, axis=1).ravel()
    cols = np.tile(cells, (1, 3)).ravel()
    K = sp.csr_matrix((local.ravel(), (rows, cols)), shape=(len(x), len(x)))
    m = np.bincount(cells.ravel(), weights=np.repeat(area / 3, 3), minlength=len(x))
    return K, m


def run_scipy(n: int, steps: int, out: Path, kind: str = "landed", alpha: float = 0.01) -> dict:
    """The projection scheme by hand: A η̃ = (M/Δt²)(2ηⁿ − ηⁿ⁻¹) + (C/Δt)ηⁿ − Kηⁿ, then η = max(η̃, 0) inside."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    from stringcontact.scene import Scene  # only for the scene's data (expressions), not the solver

    data = np.load(out / f"sc{n}.npz")
    s: Scene = scene(n, steps, kind, alpha)
    t0 = time.perf_counter()
    x, cells = data["x"], data["cells"]
    K, m = p1_operators(x, cells)
    dt, alpha = s.dt, s.alpha
    # dolfinx's mesh puts some rim nodes at 1 - 1e-16 (n = 499): compare with a tolerance, not ==
    rim = np.any(np.isclose(x, 0.0, rtol=0, atol=1e-12) | np.isclose(x, 1.0, rtol=0, atol=1e-12), axis=1)
    inner = ~rim
    C_dt = (alpha / dt) * K
    A = sp.diags(m / dt**2) + C_dt
    A = sp.diags(inner.astype(float)) @ A + sp.diags(rim.astype(float))  # identity rows on the rim
    lu = splu(A.tocsc())
    eta = np.where(rim, 0.0, s.initial_displacement(x))
    old = eta - dt * s.initial_velocity(x) * inner
    setup = time.perf_counter() - t0
    t1 = time.perf_counter()
    for _ in range(steps):
        rhs = m / dt**2 * (2 * eta - old) + C_dt @ eta - K @ eta
        rhs[rim] = 0.0
        new = lu.solve(rhs)
        np.maximum(new, 0.0, out=new, where=inner)  # the projection onto gap = η − 0 ≥ 0
        old, eta = eta, new
    step = (time.perf_counter() - t1) / steps
    return {"nodes": len(x), "setup_s": setup, "step_ms": 1e3 * step, "ranks": 1, "rss_mb": [peak_rss_mb()],
            "max_diff": float(np.max(np.abs(eta - data["eta"])))}


def child(argv: list[str]) -> dict:
    """Run one case in a fresh process (mpirun for ranks > 1); its JSON line."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1")
    proc = subprocess.run(argv, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--big", action="store_true", help="also n = 999 (1e6 nodes)")
    ap.add_argument("--ranks", type=int, default=1, help="also run stringcontact under mpirun -n RANKS")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", help="cells per side instead of 99 199 316 499 (999 with --big)")
    ap.add_argument("--solver", nargs="+", choices=tuple(SOLVERS), default=["auto"],
                    help="stringcontact's linear solver(s) (default: auto, the size rule)")
    ap.add_argument("--no-peer", action="store_true", help="skip the SciPy peer")
    ap.add_argument("--scene", choices=tuple(SCENES), default="landed", help="see SCENES (default: landed)")
    ap.add_argument("--alpha", type=float, default=0.01,
                    help="viscosity (default 0.01); 0 makes the step matrix diagonal: the nodal maximum, no linear solve")
    ap.add_argument("--one", nargs=2, metavar=("IMPL", "N"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    if args.one:
        impl, n = args.one[0], int(args.one[1])
        row = (run_stringcontact(n, args.steps, OUT, args.solver[0], args.scene, args.alpha) if impl == "sc"
               else run_scipy(n, args.steps, OUT, args.scene, args.alpha))
        from mpi4py import MPI

        if MPI.COMM_WORLD.rank == 0:
            print(json.dumps(row))
        return
    sizes = args.sizes or [99, 199, 316, 499] + ([999] if args.big else [])
    if args.solver != ["auto"] or args.no_peer:
        return solver_table(args, sizes)
    me = [sys.executable, str(Path(__file__).resolve()), "--steps", str(args.steps), "--alpha", str(args.alpha), "--one"]
    rows = []
    print("| nodes | stringcontact ms/step | setup s | peak RSS MB | SciPy peer ms/step | setup s | peak RSS MB | max abs diff of eta |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in sizes:
        ours = child(me + ["sc", str(n)])
        peer = child(me + ["scipy", str(n)])
        line = (f"| {ours['nodes']} | {ours['step_ms']:.2f} | {ours['setup_s']:.2f} | {max(ours['rss_mb']):.0f} | "
                f"{peer['step_ms']:.2f} | {peer['setup_s']:.2f} | {max(peer['rss_mb']):.0f} | {peer['max_diff']:.1e} |")
        if args.ranks > 1:
            par = child(["mpirun", "-n", str(args.ranks), "--oversubscribe"] + me + ["sc", str(n)])
            ours[f"ranks{args.ranks}"] = par
            line += f" {args.ranks} ranks: {par['step_ms']:.2f} ms/step, RSS/rank {'/'.join(f'{r:.0f}' for r in par['rss_mb'])} MB |"
        print(line, flush=True)
        rows.append({"n": n, "stringcontact": ours, "scipy": peer})
    (OUT / "membrane.json").write_text(json.dumps(rows, indent=1))


def difference_to_lu(n: int, solver: str, ranks: int) -> float | None:
    """max |η − η_LU| at the last step, against the serial LU run of the same size (if one ran before it)."""
    lu = OUT / f"eta{n}-lu-1.npy"
    if not lu.exists() or (solver, ranks) == ("lu", 1):
        return None
    return float(np.max(np.abs(np.load(OUT / f"eta{n}-{solver}-{ranks}.npy") - np.load(lu))))


def solver_table(args, sizes: list[int]) -> None:
    """One row per size, solver and rank count (and the peer unless --no-peer); appends to out/solvers.jsonl."""
    me = [sys.executable, str(Path(__file__).resolve()), "--steps", str(args.steps), "--scene", args.scene,
          "--alpha", str(args.alpha)]
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {os.getloadavg()[0]:.2f}, "
          f"alpha = {args.alpha}, {args.steps} steps\n")
    print("| nodes | solver | ranks | ms/step | setup s | peak RSS MB per rank | max abs Δη against LU | linear solver |")
    print("|---:|---|---:|---:|---:|---|---:|---|")
    with open(OUT / "solvers.jsonl", "a") as log:
        for n in sizes:
            (OUT / f"eta{n}-lu-1.npy").unlink(missing_ok=True)  # only this pass's LU answer is compared with
            for solver in args.solver:
                for ranks in sorted({1, args.ranks}):
                    mpi = ["mpirun", "-n", str(ranks), "--oversubscribe"] if ranks > 1 else []
                    row = child(mpi + me + ["--solver", solver, "--one", "sc", str(n)])
                    rss = " / ".join(f"{r:.0f}" for r in row["rss_mb"])
                    row["max_diff_lu"] = difference_to_lu(n, solver, ranks)
                    diff = "" if row["max_diff_lu"] is None else f"{row['max_diff_lu']:.1e}"
                    print(f"| {row['nodes']} | {solver} | {ranks} | {row['step_ms']:.2f} | {row['setup_s']:.2f} | {rss} | "
                          f"{diff} | {row['linear_solver']} |", flush=True)
                    log.write(json.dumps(dict(row, scene=args.scene, alpha=args.alpha, load=os.getloadavg())) + "\n")
            if not args.no_peer:
                peer = child(me + ["--one", "scipy", str(n)])
                print(f"| {peer['nodes']} | SciPy peer (SuperLU) | 1 | {peer['step_ms']:.2f} | {peer['setup_s']:.2f} | "
                      f"{peer['rss_mb'][0]:.0f} | max abs diff of eta {peer['max_diff']:.1e} |", flush=True)
                log.write(json.dumps(dict(peer, solver="scipy", scene=args.scene, load=os.getloadavg())) + "\n")


if __name__ == "__main__":
    main()
