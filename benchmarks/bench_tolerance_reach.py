"""`run --tol`'s pilots: the two-resolution estimate of each method as nx doubles from 50 (docs/explanation/reliability.md,
`analysis.tolerance.REACH_MARGIN`): how far the estimates from coarse pilots stray from the order's straight line.

    .venv/bin/python benchmarks/bench_tolerance_reach.py [SCENE] [NX_MAX]     (default: example1 3200)
"""

from __future__ import annotations

import sys

import stringcontact as sc
from stringcontact.analysis import tolerance
from stringcontact.analysis.problems import METHODS


def main() -> None:
    scene = sc.load_scene(sys.argv[1] if len(sys.argv) > 1 else "example1")
    nx_max = int(sys.argv[2]) if len(sys.argv) > 2 else 3200
    print("method,nx,nt,status,estimate,floor_at_64000")
    for name in tolerance.TOL_METHODS:
        method, nx = METHODS[name], 50
        rows = tolerance._scaled(scene, nx).nt
        coarse = tolerance.run_method(tolerance._scaled(scene, nx), method, rows=rows)
        while 2 * nx <= nx_max:
            fine = tolerance.run_method(scene.replace(nx=2 * coarse.nx, nt=2 * coarse.nt), method, rows=rows)
            both = coarse.status == fine.status == "complete"
            order = tolerance.TOL_ORDER[name]
            e = tolerance.richardson_estimate(coarse, fine, order) if both else float("nan")
            print(f"{name},{fine.nx},{fine.nt},{fine.status},{e:.3g},{e * (fine.nx / tolerance.NX_MAX) ** order:.3g}")
            nx, coarse = 2 * nx, fine


if __name__ == "__main__":
    main()
