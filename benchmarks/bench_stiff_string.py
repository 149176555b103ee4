"""The step cost of the stiff string (model `stiff_string`, two P1 fields) against the paper's linear step.

    .venv/bin/python benchmarks/bench_stiff_string.py                  # Example 1 at nx = 5000, 1500 steps, paper
    .venv/bin/python benchmarks/bench_stiff_string.py --repeat 7 --newton      # and Newton's path, for comparison
    .venv/bin/python benchmarks/bench_stiff_string.py --quick          # nx = 500, 150 steps: a smoke test

Both models run Example 1 (the paper's string thrown onto the obstacle, the contact set spreading and shrinking)
with the same Δt, mesh and scheme (`paper`), `--repeat` rounds in turn in one process (warm JIT cache; a change in
the machine's load hits both alike). Per model: the solve time per step, ``result.timings["solve"] / nt`` (the
march, without set-up and output), its least and its median over the rounds, and the stiff string's median
against the paper's (median over median). For the stiff string also what its step solved with (the linear path's
one solve per step, or Newton's iterations); `--newton` adds the stiff string forced through Newton's path (SNES,
`Model.newton`), the way every step of a model with fields was solved before the linear path. Prints a Markdown
table and the load average. Asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import warnings

from mpi4py import MPI

import stringcontact as sc
from stringcontact.model.stiff_string import stiff_string

#: The stiff string forced through Newton's path (SNES, `Model.newton`): its step before the linear path.
NEWTON = dataclasses.replace(stiff_string, name="stiff_string_newton", newton=True)


def per_step(scene, model: str, scheme: str, beta: float) -> tuple[float, dict]:
    """One run: the solve time per step (s) and what solved its steps (`Result.solver`)."""
    stiff = model != "inelastic"
    given = NEWTON if model == NEWTON.name else None  # a Model object: run as given, the scene naming the stiff string
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = sc.simulate(scene.replace(model="stiff_string" if stiff else "inelastic",
                                           parameters={"beta": beta} if stiff else {}),
                             scheme=scheme, model=given, comm=MPI.COMM_SELF, storage=sc.Storage(max_rows=10))
    if result.status != "complete":
        raise SystemExit(f"{model}: {result.status}: {result.message}")
    return result.timings["solve"] / scene.nt, result.solver


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nx", type=int, default=5000)
    parser.add_argument("--steps", type=int, default=1500, help="time steps (Example 1's Δt = 2e-4: T = steps × Δt)")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--beta", type=float, default=1e-3)
    parser.add_argument("--scheme", default="paper")
    parser.add_argument("--quick", action="store_true", help="nx = 500, 150 steps, 3 rounds")
    parser.add_argument("--newton", action="store_true",
                        help="also the stiff string forced through Newton's path (SNES), as every step was before")
    args = parser.parse_args(argv)
    if args.quick:
        args.nx, args.steps, args.repeat = 500, 150, 3
    base = sc.load_scene("example1")
    scene = base.replace(nx=args.nx, T=args.steps * base.dt, output_times=None)
    times = {name: [] for name in ("inelastic", "stiff_string", *((NEWTON.name,) if args.newton else ()))}
    info = {}
    for model in times:  # the JIT's compilations out of the timings
        per_step(scene, model, args.scheme, args.beta)
    for _ in range(args.repeat):
        for model, values in times.items():
            t, info[model] = per_step(scene, model, args.scheme, args.beta)
            values.append(t)
    median = {m: statistics.median(v) for m, v in times.items()}
    print(f"Example 1, nx = {args.nx}, {args.steps} steps of dt = {base.dt:g}, scheme {args.scheme}, beta = {args.beta:g}, "
          f"{args.repeat} rounds\n")
    print("| model | least ms/step | median ms/step | median / paper's | how its step is solved |")
    print("| --- | --- | --- | --- | --- |")
    for model, values in times.items():
        how = info[model].get("nonlinear solver", "the paper's linear step")
        print(f"| {model} | {1e3 * min(values):.3f} | {1e3 * median[model]:.3f} | "
              f"{median[model] / median['inelastic']:.2f} | {how} |")
    print(f"\nload average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
