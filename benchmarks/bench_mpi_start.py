"""Open MPI's start-up in a process run without `mpirun`: with and without `cli.process.SINGLETON`.

Each line starts a fresh interpreter that imports mpi4py (MPI_Init) or petsc4py (PETSc and MPI), alternating
the two environments, and prints the median wall time of `--rounds` pairs.

    .venv/bin/python benchmarks/bench_mpi_start.py --rounds 7
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

from stringcontact.cli.process import LAUNCHED, SINGLETON

IMPORTS = {"mpi4py": "from mpi4py import MPI", "petsc4py": "from petsc4py import PETSc"}


def wall(code: str, env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], env=env, check=True)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()
    base = {k: v for k, v in os.environ.items() if k not in SINGLETON and k not in LAUNCHED}
    envs = {"Open MPI's defaults": base, "SINGLETON settings": {**base, **SINGLETON}}
    print(f"load average {os.getloadavg()[0]:.2f}")
    print("| import | " + " | ".join(envs) + " |")
    print("|---|" + "---:|" * len(envs))
    for name, code in IMPORTS.items():
        times = {label: [] for label in envs}
        for _ in range(args.rounds):
            for label, env in envs.items():
                times[label].append(wall(code, env))
        print(f"| {name} | " + " | ".join(f"{statistics.median(t):.3f} s" for t in times.values()) + " |")


if __name__ == "__main__":
    main()
