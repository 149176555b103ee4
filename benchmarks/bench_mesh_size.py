"""How long the set-up of a large mesh takes, the basis of the scene's nx bound (docs/explanation/reliability.md).

dolfinx builds the interval mesh, its dof map and the space in C++ (graph reordering included); a
Ctrl-C there is only seen when it returns to Python. This times `mesh.create_interval` plus the P1 space
for growing nx, so the bound on nx keeps that uninterruptible stretch to seconds.

    .venv/bin/python benchmarks/bench_mesh_size.py                   # nx = 1e4 ... 2e5
    .venv/bin/python benchmarks/bench_mesh_size.py --nx 10000 400000
"""

from __future__ import annotations

import argparse
import time


def set_up(nx: int) -> float:
    from dolfinx import mesh
    from mpi4py import MPI

    from stringcontact.fem import compat

    t0 = time.perf_counter()
    msh = mesh.create_interval(MPI.COMM_WORLD, nx, [0.0, 1.0])
    compat.function_space(msh, "Lagrange", 1)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nx", type=int, nargs="+", default=[10_000, 50_000, 100_000, 200_000])
    args = parser.parse_args()
    set_up(100)  # imports and first-call costs apart
    print("nx        set-up [s]")
    for nx in args.nx:
        print(f"{nx:<9d} {set_up(nx):.3f}")


if __name__ == "__main__":
    main()
