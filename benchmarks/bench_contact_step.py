"""The `projection` scheme's contact step: the primal–dual active set (the default) against PETSc's SNES VI alone.

    .venv/bin/python benchmarks/bench_contact_step.py            # Example 1 at nx = 5000 and the drum (a few minutes)
    .venv/bin/python benchmarks/bench_contact_step.py --quick    # smaller sizes, for a smoke test

On Example 1 and the drum, serial and under `mpirun -n 2`: each run's wall time (after a 20-step warm-up run), the
solve time per step, and the contact step's counters (`Result.solver["contact step"]`: solves, refactorisations
or Newton iterations a step). SNES VI alone is the active set with no iteration allowed
(`complementarity.MAX_ITERATIONS = 0`): every step goes to its fallback.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import warnings

from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis import study
from stringcontact.timestepping import complementarity


def candidates(scene, label: str) -> None:
    """The active set against SNES VI alone on `scene` (this process's ranks): wall time, cost per step."""
    out, default = {}, complementarity.MAX_ITERATIONS
    for name, cap in (("active set", default), ("SNES VI", 0)):
        complementarity.MAX_ITERATIONS = cap  # 0: every step goes straight to the fallback, SNES VI
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sc.simulate(scene.replace(T=20 * scene.dt, nt=20, output_times=[]), scheme="projection")  # warm-up
            t0 = time.perf_counter()
            res = sc.simulate(scene, scheme="projection")
            wall = MPI.COMM_WORLD.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        out[name] = (wall, res.timings["solve"] / scene.nt, res.solver["contact step"])
    complementarity.MAX_ITERATIONS = default
    if MPI.COMM_WORLD.rank == 0:
        for name, (wall, per_step, counters) in out.items():
            print(
                f"  {label}, {MPI.COMM_WORLD.size} rank(s), {name}: {wall:.2f} s ({1e3 * per_step:.3f} ms per step); "
                f"{counters}",
                flush=True,
            )


def scenes(quick: bool) -> dict:
    """Example 1 (nx = 5000, or 1250 with `quick`) and the drum (its own mesh, or a coarser one)."""
    drum = sc.load_scene("drum")
    return {
        "example1": study.example1_scene(1250 if quick else 5000),
        "drum": drum.replace(mesh_size=0.1) if quick else drum,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes")
    ap.add_argument("--ranks-only", action="store_true", help=argparse.SUPPRESS)  # the mpirun worker
    args = ap.parse_args(argv)
    for label, scene in scenes(args.quick).items():
        candidates(scene, label)
    if args.ranks_only:
        return 0
    cmd = ["mpirun", "-n", "2", "--oversubscribe", sys.executable, __file__, "--ranks-only"]
    env = dict(os.environ, OMP_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    proc = subprocess.run(cmd + (["--quick"] if args.quick else []), text=True, env=env, check=False)
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
