"""The cost of a nonlinear model's Newton step against the linear path, and Newton's iteration counts.

    .venv/bin/python benchmarks/bench_nonlinear.py                 # Example 1 at nx = 5000, 1500 steps, scheme paper
    .venv/bin/python benchmarks/bench_nonlinear.py --scheme projection newmark --repeat 3
    .venv/bin/python benchmarks/bench_nonlinear.py --quick         # nx = 500, a smoke test

For each model (the paper's linear `inelastic`, `cubic_foundation`, `large_deflection`) and scheme: the solve
time per step (the driver's "solve" timing: the march without set-up and output; best of `--repeat` runs in
one process, warm JIT cache), Newton's iterations per step (all steps), the most in one step, and the step's
cost against the linear model's. Prints a Markdown table; writes benchmarks/out/nonlinear.json.
"""

from __future__ import annotations

import argparse
import json
import platform
import warnings
from pathlib import Path

from mpi4py import MPI

import stringcontact as sc
from stringcontact.timestepping import nonlinear

MODELS = ("inelastic", "cubic_foundation", "large_deflection")


def measure(scene, scheme: str, model: str, repeat: int) -> dict:
    """Best solve time per step over `repeat` runs, and Newton's counts (from the last run)."""
    best, most = float("inf"), 0
    counts = []
    original = nonlinear.NewtonStep.solve

    def counting(self, guess):  # the iterations of every step, not only their sum
        out = original(self, guess)
        counts.append(self.snes.getIterationNumber())
        return out

    nonlinear.NewtonStep.solve = counting
    try:
        for _ in range(repeat):
            counts.clear()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = sc.simulate(scene, scheme=scheme, model=model, comm=MPI.COMM_SELF, max_rows=10)
            best = min(best, res.timings["solve"] / scene.nt)
            most = max(counts, default=0)
    finally:
        nonlinear.NewtonStep.solve = original
    return {"model": model, "scheme": scheme, "step_ms": 1e3 * best,
            "newton_per_step": sum(counts) / len(counts) if counts else 0.0, "newton_max": most,
            "status": res.status}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheme", nargs="+", default=["paper"])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    scene = sc.load_scene("example1")
    if args.quick:
        scene = scene.replace(nx=500)
    rows = []
    for scheme in args.scheme:
        for model in MODELS:
            rows.append(measure(scene, scheme, model, args.repeat))
            linear = next(r for r in rows if r["scheme"] == scheme and r["model"] == "inelastic")
            rows[-1]["ratio"] = rows[-1]["step_ms"] / linear["step_ms"]
    print(f"Example 1, nx = {scene.nx}, {scene.nt} steps; {platform.node()} ({platform.processor() or platform.machine()})")
    print("| scheme | model | step (ms) | × linear | Newton iterations per step | most in one step |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        newton = f"{r['newton_per_step']:.2f}" if r["model"] != "inelastic" else "none (linear)"
        most = str(r["newton_max"]) if r["model"] != "inelastic" else "-"
        print(f"| {r['scheme']} | {r['model']} | {r['step_ms']:.3f} | {r['ratio']:.0f} | {newton} | {most} |")
    out = Path(__file__).with_name("out")
    out.mkdir(exist_ok=True)
    (out / "nonlinear.json").write_text(json.dumps({"nx": scene.nx, "nt": scene.nt, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
