"""End-to-end wall clock of `stringcontact run example1 --out DIR`, and where the time goes.

1. The command itself, as a user runs it, in a fresh process, warm JIT cache: with its pictures, and
   with `--no-pictures` for comparison, and with `--against EXE` the same command of another checkout
   (e.g. main's `.venv/bin/stringcontact`). They alternate, so that a slower spell of a shared machine
   hits all of them; medians and ranges are printed.
2. The same work in a fresh process, timed by phase: import (stringcontact, dolfinx, petsc4py),
   setup (mesh, the forms' JIT-cache load and assembly, LU factorisation), solve (the time loop),
   XDMF + tables (the XDMF frames streamed to solution.xdmf/h5, diagnostics.csv, summary.json) and
   pictures (drawn by the run after its solve, in its own process, as the CLI draws them).
3. The XDMF cost against the number of frames (`simulate(..., max_frames=...)`): dolfinx 0.5's
   XDMFFile rewrites its whole XML on every write, so the cost grows like frames².

    .venv/bin/python benchmarks/bench_run.py [--repeats 7] [--against /tmp/main/.venv/bin/stringcontact]
    git archive <commit> src | tar -x -C /tmp/before        # another checkout's source, run by this venv:
    .venv/bin/python benchmarks/bench_run.py --no-phases --repeats 20 --against-src /tmp/before

With --against-src DIR the other command is this executable with DIR/src first on PYTHONPATH (a checkout that draws
its pictures in a process of its own, say). The CPU seconds of each command (user + system of it and every process
it starts) are printed as well.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXE = Path(sys.executable).with_name("stringcontact")
KEYS = ("import", "setup", "solve", "xdmf+tables", "pictures")


def run_cli(out: Path, *extra: str, exe: Path = EXE, env: dict | None = None, cpu: list | None = None) -> float:
    """The command's wall time; its CPU seconds (user + system of it and its children) appended to `cpu`."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([str(exe), "run", "example1", "--out", str(out), "--force", "--no-progress", *extra], check=True,
                   capture_output=True, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if cpu is not None:
        cpu.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    return wall


def phases(out: str, max_frames: int) -> dict:
    """Run in a fresh interpreter: time the import, then simulate with output and pictures."""
    t0 = time.perf_counter()
    import dolfinx  # noqa: F401
    import petsc4py  # noqa: F401

    import stringcontact as sc

    t_import = time.perf_counter() - t0
    res = sc.simulate(sc.load_scene("example1"),
                      output=sc.Output(out, force=True, max_frames=max_frames, pictures=True))
    summary = json.loads((Path(out) / "summary.json").read_text())
    tm = summary.get("timings", {})
    return {
        "import": t_import,
        "setup": tm.get("setup", 0.0),
        "solve": tm.get("solve", 0.0),
        "xdmf+tables": res.timings.get("output", 0.0) - tm.get("pictures", 0.0),
        "pictures": tm.get("pictures", 0.0),
        "frames": summary["xdmf_frames"],
        "rows": len(res.t),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-sweep", action="store_true", help="phases at the default max_frames only")
    ap.add_argument("--no-phases", action="store_true", help="the commands only")
    ap.add_argument("--against", type=Path, help="another checkout's stringcontact executable, timed alternately")
    ap.add_argument("--against-src", type=Path, help="another checkout (its src/ on PYTHONPATH), timed alternately")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        spec = json.loads(args.child)
        print(json.dumps(phases(spec["out"], spec["max_frames"])))
        return 0

    env = dict(os.environ)
    env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    tmp = Path(tempfile.mkdtemp(prefix="bench_run_"))
    against, other_env = args.against, env
    if args.against_src:
        against = EXE
        other_env = dict(env, PYTHONPATH=os.pathsep.join(filter(None, [str(args.against_src / "src"), env.get("PYTHONPATH")])))
    try:
        run_cli(tmp / "warm", env=env)  # warms the JIT cache
        if against:
            run_cli(tmp / "warm-other", exe=against, env=other_env)
        walls, bare, other, cpu, other_cpu, bare_cpu = [], [], [], [], [], []
        commands = {"run": (walls, cpu, EXE, env), "other": (other, other_cpu, against, other_env)}
        order = ["run", "other"] if against else ["run"]
        for i in range(args.repeats):
            for key in order if i % 2 == 0 else order[::-1]:  # each pair in turn order: neither always first
                times, cpus, exe, command_env = commands[key]
                times.append(run_cli(tmp / f"{key}{i}", exe=exe, env=command_env, cpu=cpus))
            bare.append(run_cli(tmp / f"bare{i}", "--no-pictures", env=env, cpu=bare_cpu))

        def line(name, values, cpus):
            return (f"| {name} | {statistics.median(values):.2f} | {min(values):.2f} | {max(values):.2f} | "
                    f"{statistics.median(cpus):.2f} |")

        print(f"`stringcontact run example1 --out DIR` (N = 5000, 1500 steps), wall clock [s], warm JIT cache, "
              f"{args.repeats} alternating runs each:\n")
        print("| command | median | min | max | CPU [s], median |\n|---|---:|---:|---:|---:|")
        print(line("`run example1 --out DIR`", walls, cpu))
        print(line("`run example1 --out DIR --no-pictures`", bare, bare_cpu))
        if against:
            name = f"`run example1 --out DIR` of {args.against_src or against}"
            print(line(name, other, other_cpu))
            ratios = sorted(a / b for a, b in zip(walls, other))  # each pair ran back to back
            print(f"\npaired ratio this/other: median {statistics.median(ratios):.3f} "
                  f"(range {ratios[0]:.2f}-{ratios[-1]:.2f})")
        print(f"load average {os.getloadavg()[0]:.2f} at the end")
        if args.no_phases:
            return 0
        print()

        def child(max_frames):
            out = tmp / f"phase-{max_frames}"
            spec = json.dumps({"out": str(out), "max_frames": max_frames})
            proc = subprocess.run([sys.executable, __file__, "--child", spec], capture_output=True, text=True, env=env,
                                  check=True)
            return json.loads(proc.stdout.strip().splitlines()[-1])

        print("Phases, each in a fresh process (medians):\n")
        print("| max_frames | XDMF frames | " + " | ".join(f"{k} [s]" for k in KEYS) + " | sum [s] |")
        print("|---:|---:|" + "---:|" * (len(KEYS) + 1))
        for max_frames in (100,) if args.no_sweep else (100, 400, 200, 50):
            runs = [child(max_frames) for _ in range(args.repeats)]
            med = {k: statistics.median(r[k] for r in runs) for k in KEYS}
            print(f"| {max_frames} | {runs[0]['frames']} | " + " | ".join(f"{med[k]:.2f}" for k in KEYS)
                  + f" | {sum(med.values()):.2f} |", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
