"""The cost of a nonlinear model's Newton step against the linear path, and Newton's iteration counts.

    .venv/bin/python benchmarks/bench_nonlinear.py                 # Example 1 at nx = 5000, 1500 steps, scheme paper
    .venv/bin/python benchmarks/bench_nonlinear.py --scheme paper projection newmark --repeat 5
    .venv/bin/python benchmarks/bench_nonlinear.py --quick         # nx = 500, a smoke test

For each scheme, the models (the paper's linear `inelastic`, `cubic_foundation`, `large_deflection`) run in
turn, `--repeat` rounds, in one process (warm JIT cache), so that a change in the machine's load hits them
alike. Per model: the solve time per step (the driver's "solve" timing: the march without set-up and output),
its least and its median over the rounds; the step's cost against the linear model's (least over least);
Newton's iterations per step (all steps, retries included), the most in one step, the Jacobian
assemblies per step, and the floor: what the calls no Newton step can skip cost on the run's own forms (two
residual assemblies, one stored-energy assembly, one back-substitution; `floor_timings`), in ms and against the
linear step, and one residual assembly with its packed coefficients against dolfinx packing them afresh.
Prints a Markdown table and `uptime`'s load; writes benchmarks/out/nonlinear.json.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import timeit
import warnings
from pathlib import Path

import dolfinx.fem.petsc
from mpi4py import MPI

import stringcontact as sc
from stringcontact.timestepping import newton as nonlinear

MODELS = ("inelastic", "cubic_foundation", "large_deflection")


def floor_timings(newton) -> tuple[float, float, float]:
    """The calls no Newton step can skip, timed on the run's own Newton step after its last step: the residual
    assembled twice (at the guess and to confirm the root), the stored energy once, and one solve with the kept
    LU factor; least of 5 rounds of 200. Returns that floor, and one residual assembly with the packed
    coefficients (`PackedForm`) and with dolfinx packing them afresh, in ms."""
    b = newton.work_vec
    x = b.duplicate()
    ksp = newton.snes.getKSP()

    def residual(assemble):
        def call():
            with b.localForm() as local:
                local.set(0.0)
            assemble(b)
        return call

    def least(call):
        return min(timeit.repeat(call, number=200, repeat=5)) / 200

    packed = least(residual(newton.G.assemble_vector))
    repacked = least(residual(lambda vec: dolfinx.fem.petsc.assemble_vector(vec, newton.G.form)))
    floor = 2 * packed + least(newton.energy.assemble_scalar) + least(lambda: ksp.solve(b, x))
    return 1e3 * floor, 1e3 * packed, 1e3 * repacked


def run_once(scene, scheme: str, model: str) -> dict:
    """One run: the solve time per step, Newton's iterations of every step, and the floor (`floor_timings`)."""
    counts, steps = [], []
    original = nonlinear.NewtonStep.solve

    def counting(self, guess):  # the iterations of every step, not only their sum
        before = self.iterations
        out = original(self, guess)
        counts.append(self.iterations - before)
        steps[:] = [self]
        return out

    nonlinear.NewtonStep.solve = counting
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = sc.simulate(scene, scheme=scheme, model=model, comm=MPI.COMM_SELF, storage=sc.Storage(max_rows=10))
    finally:
        nonlinear.NewtonStep.solve = original
    return {"step_ms": 1e3 * res.timings["solve"] / scene.nt, "counts": counts, "status": res.status,
            "jacobians": res.counters.get("jacobian assemblies", 0),
            "timings": floor_timings(steps[0]) if steps else (0.0, 0.0, 0.0)}


def measure(scene, scheme: str, repeat: int) -> list[dict]:
    """Every model of MODELS `repeat` times, in turn; one row per model."""
    runs = {model: [] for model in MODELS}
    for _ in range(repeat):
        for model in MODELS:
            runs[model].append(run_once(scene, scheme, model))
    rows = []
    for model, done in runs.items():
        times = [r["step_ms"] for r in done]
        counts = done[-1]["counts"]
        rows.append({"model": model, "scheme": scheme, "step_ms": min(times), "median_ms": statistics.median(times),
                     "newton_per_step": sum(counts) / len(counts) if counts else 0.0,
                     "newton_max": max(counts, default=0), "jacobians_per_step": done[-1]["jacobians"] / scene.nt,
                     "status": done[-1]["status"], "floor_ms": min(r["timings"][0] for r in done),
                     "residual_ms": [min(r["timings"][i] for r in done) for i in (1, 2)]})
    linear = rows[0]["step_ms"]
    for r in rows:
        r["ratio"] = r["step_ms"] / linear
        r["floor_ratio"] = r["floor_ms"] / linear
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheme", nargs="+", default=["paper"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    scene = sc.load_scene("example1")
    if args.quick:
        scene = scene.replace(nx=500)
    load_before = os.getloadavg()
    rows = [row for scheme in args.scheme for row in measure(scene, scheme, args.repeat)]
    load_after = os.getloadavg()
    print(f"Example 1, nx = {scene.nx}, {scene.nt} steps, {args.repeat} rounds; {platform.node()} "
          f"({platform.processor() or platform.machine()}); load average {load_before[0]:.1f} before, "
          f"{load_after[0]:.1f} after")
    print("| scheme | model | step (ms), least | median | × linear | Newton iterations per step | most in one step "
          "| Jacobian assemblies per step | floor (ms), × linear | residual (ms): packed, by dolfinx |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        linear = r["model"] == "inelastic"
        newton = "none (linear)" if linear else f"{r['newton_per_step']:.2f}"
        most = "-" if linear else str(r["newton_max"])
        jac = "-" if linear else f"{r['jacobians_per_step']:.2f}"
        floor = "-" if linear else f"{r['floor_ms']:.3f}, {r['floor_ratio']:.1f}"
        residual = "-" if linear else "{:.3f}, {:.3f}".format(*r["residual_ms"])
        print(f"| {r['scheme']} | {r['model']} | {r['step_ms']:.3f} | {r['median_ms']:.3f} | {r['ratio']:.1f} | "
              f"{newton} | {most} | {jac} | {floor} | {residual} |")
    out = Path(__file__).with_name("out")
    out.mkdir(exist_ok=True)
    (out / "nonlinear.json").write_text(json.dumps({"nx": scene.nx, "nt": scene.nt, "repeat": args.repeat,
                                                    "load": [load_before, load_after], "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
