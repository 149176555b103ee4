"""Does MPI pay off? One simulation split over ranks, against a sweep of simulations spread over ranks.

Two ways to use `mpirun -n K` on a 1D problem:

- **one simulation, distributed**: dolfinx splits the mesh over K ranks and every step pays for halo
  exchanges, MUMPS' distributed back-substitution and the allreduces of the energy balance. In 1D each
  rank's share of the work is a few thousand nodes, so the messages cost more than they save.
- **a sweep, one simulation per rank** (what `mpirun -n K stringcontact study` does): each rank runs whole
  simulations on `COMM_SELF`, the ranks never talk during a run, so K ranks finish K runs in about the
  time of one.

The driver starts `mpirun -n K python bench_mpi.py --worker ...` for each K and prints a table of wall
times (the best of `--repeat` runs, after one warm-up that fills dolfinx's JIT cache). Output is off:
this measures the solver, not the disk.

    .venv/bin/python benchmarks/bench_mpi.py                  # Example 1 at the paper's resolution (~2 min)
    .venv/bin/python benchmarks/bench_mpi.py --nx 20000       # a finer mesh, same time steps
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time


def _scene(nx: int, nt: int):
    import stringcontact as sc

    return sc.load_scene("example1").replace(nx=nx, nt=nt)


def worker(mode: str, nx: int, nt: int, runs: int, repeat: int) -> None:
    from mpi4py import MPI

    import stringcontact as sc

    world = MPI.COMM_WORLD
    scene = _scene(nx, nt)
    sc.simulate(scene.replace(nx=100), comm=world if mode == "one" else MPI.COMM_SELF)  # JIT warm-up
    best, solve = float("inf"), float("inf")
    for _ in range(repeat):
        world.barrier()
        t0 = time.perf_counter()
        if mode == "one":
            res = sc.simulate(scene, comm=world)
            solve = min(solve, res.timings["solve"])
        else:  # runs simulations dealt round-robin to the ranks, each on its own
            for i in range(world.rank, runs, world.size):
                sc.simulate(scene, comm=MPI.COMM_SELF)
        world.barrier()
        best = min(best, time.perf_counter() - t0)
    if world.rank == 0:
        print(json.dumps({"mode": mode, "ranks": world.size, "wall": best, "solve": solve}))


def launch(ranks: int, mode: str, args) -> dict:
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [shutil.which("mpirun"), "-n", str(ranks), sys.executable, __file__, "--worker", mode,
           "--nx", str(args.nx), "--nt", str(args.nt), "--runs", str(args.runs), "--repeat", str(args.repeat)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=1800)
    if proc.returncode != 0:
        raise SystemExit(f"bench_mpi: {' '.join(cmd)} failed:\n{proc.stderr[-3000:]}")
    return json.loads([line for line in proc.stdout.splitlines() if line.startswith("{")][-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nx", type=int, default=5000, help="cells (default: the paper's 5000)")
    ap.add_argument("--nt", type=int, default=1500, help="time steps (default: the paper's 1500)")
    ap.add_argument("--runs", type=int, default=4, help="simulations in the sweep")
    ap.add_argument("--repeat", type=int, default=3, help="timed repetitions; the best is reported")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--worker", choices=("one", "sweep"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker, args.nx, args.nt, args.runs, args.repeat)
        return
    import dolfinx

    print(f"Example 1, nx={args.nx}, nt={args.nt}; dolfinx {dolfinx.__version__}; {os.cpu_count()} cores; "
          f"best of {args.repeat}")
    print()
    print("| mpirun -n | one simulation, distributed: wall (time loop) | sweep of "
          f"{args.runs} simulations, one per rank: wall (per simulation) |")
    print("| ---: | ---: | ---: |")
    rows = {}
    for k in args.ranks:
        one, sweep = launch(k, "one", args), launch(k, "sweep", args)
        rows[k] = (one, sweep)
        print(f"| {k} | {one['wall']:.2f} s ({one['solve']:.2f} s) | {sweep['wall']:.2f} s "
              f"({sweep['wall'] / args.runs:.2f} s) |", flush=True)
    if 1 in rows:
        print()
        for k, (one, sweep) in rows.items():
            if k != 1:
                print(f"n={k}: one simulation {rows[1][0]['wall'] / one['wall']:.2f}x the serial speed; "
                      f"sweep {rows[1][1]['wall'] / sweep['wall']:.2f}x the serial throughput")


if __name__ == "__main__":
    main()
