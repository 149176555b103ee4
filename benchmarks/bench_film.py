"""The fluid film's cost and its thickness floor (docs/explanation/film.md).

    .venv/bin/python benchmarks/bench_film.py cost --case string           # nx = 5000, film_landing's landing
    mpirun -n 2 .venv/bin/python benchmarks/bench_film.py cost --case string
    .venv/bin/python benchmarks/bench_film.py cost --case drum             # 317 x 317 = 100 489 nodes
    mpirun -n 2 .venv/bin/python benchmarks/bench_film.py cost --case drum
    .venv/bin/python benchmarks/bench_film.py floor                         # h_min's effect

`cost` runs the film's own solvers (`film.linear_options`; `--solver lu`: PETSc's LU in serial, MUMPS on several
ranks; `--solver mumps`: MUMPS' LU)
`--repeat` times and prints Newton iterations per step and the solve time per step (the driver's "solve" timing,
output apart), the minimum and the median over the repeats;
`floor` runs the flat landing and film_landing at several h_min and prints each run's thinnest gap, its
L∞(0,T;L²) distance to the run at the default floor, and whether Newton converged.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
from mpi4py import MPI

import stringcontact as sc
from stringcontact.errors import SolverError


def _run(scene, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, **kw)


#: `cost --solver`: the film's own (None) or a plain LU
SOLVERS = {"film": None, "lu": {"ksp_type": "preonly", "pc_type": "lu"},
           "mumps": {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}}


def cost(case: str, steps: int, repeat: int, solver: str = "film") -> None:
    if case == "string":  # the landing at 0.0235: steps from 0.02 on would need a restart; run from 0
        scene = sc.load_scene("film_landing").replace(nx=5000, dt=0.00025, T=steps * 0.00025, output_times=[])
    else:
        scene = sc.load_scene("film_drum").replace(cells=[316, 316], dt=0.0025, T=steps * 0.0025, output_times=[])
    times = []
    for _ in range(repeat):
        r = _run(scene, storage=sc.Storage(max_rows=2), petsc_options=SOLVERS[solver])
        times.append(r.timings["solve"] / scene.nt)
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        its = r.counters["newton iterations"]
        print(f"{case}: {scene.node_estimate} nodes, {comm.size} rank(s), solver {solver}, {scene.nt} steps: {its / scene.nt:.2f} Newton "
              f"iterations per step, {1e3 * min(times):.1f} ms per step (median {1e3 * np.median(times):.1f} of "
              f"{repeat}; setup {r.timings['setup']:.2f} s)")


def floor() -> None:
    from stringcontact.analysis.film import FILM_EPS, problem_scenes
    from stringcontact.fem.compat import trapezoid
    from stringcontact.model.film import H_MIN

    flat = problem_scenes()["flat"]
    cases = [("flat landing", flat.replace(model="film", parameters={"mu": mu}, eps=FILM_EPS), {"penalty": "semi-implicit"})
             for mu in (1e-2, 1e-3, 1e-4)]
    cases.append(("film_landing", sc.load_scene("film_landing"), {}))
    for label, scene, kw in cases:
        runs = {}
        for h_min in (1e-2, 3e-3, H_MIN, 3e-4, 1e-4):
            try:
                runs[h_min] = _run(scene.replace(parameters=dict(scene.parameters) | {"h_min": h_min}), storage=sc.Storage(max_rows=scene.nt), **kw)
            except SolverError:
                runs[h_min] = None
        base = runs[H_MIN]
        for h_min, r in runs.items():
            if r is None:
                print(f"{label} mu={dict(scene.parameters)['mu']:g} h_min={h_min:g}: Newton failed")
                continue
            d = np.sqrt(trapezoid((r.eta - base.eta) ** 2, r.x, axis=1)).max()
            print(f"{label} mu={dict(scene.parameters)['mu']:g} h_min={h_min:g}: min gap {np.min(r.eta[:, 1:-1]):.3e}, "
                  f"distance to h_min={H_MIN:g} {d:.2e}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="what", required=True)
    c = sub.add_parser("cost")
    c.add_argument("--case", choices=("string", "drum"), default="string")
    c.add_argument("--steps", type=int, default=None, help="default: 200 (string), 4 (drum)")
    c.add_argument("--repeat", type=int, default=None, help="default: 3 (string), 2 (drum)")
    c.add_argument("--solver", choices=tuple(SOLVERS), default="film",
                   help="film: the film's own (default); lu: PETSc's LU in serial, MUMPS on several ranks; mumps")
    sub.add_parser("floor")
    args = parser.parse_args()
    if args.what == "cost":
        string = args.case == "string"
        cost(args.case, args.steps or (200 if string else 4), args.repeat or (3 if string else 2), args.solver)
    else:
        floor()


if __name__ == "__main__":
    main()
