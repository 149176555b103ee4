"""How long does `stringcontact run example1` take on each FEniCS stack: Debian bookworm's dolfinx 0.5.2 against
dolfinx 0.11 from PyPI's wheel (docs/explanation/platforms.md)?

Each stack is a command prefix that runs its `stringcontact` (a venv's console script, or the same inside an image);
the commands alternate, so that a busy spell of a shared machine hits each alike. The wall clock is measured from
outside, the setup and solve times are the command's own ("time:" line). Warm JIT caches: run each once first.

    .venv/bin/python benchmarks/bench_stacks.py --stack 0.5.2 .venv/bin/stringcontact \\
        --stack 0.11 "podman --runtime runc run --rm --entrypoint /opt/stringcontact/.venv/bin/stringcontact \\
        stringcontact-wheel-test" [--repeats 5] [--nx 5000]
"""

from __future__ import annotations

import argparse
import re
import shlex
import statistics
import subprocess
import time


def _once(prefix: str, name: str, nx: int) -> tuple[float, float, float]:
    cmd = [*shlex.split(prefix), "run", "example1", "--nx", str(nx), "--out", f"/tmp/bench_stacks_{name}", "--force",
           "--no-progress"]
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    wall = time.perf_counter() - t0
    found = re.search(r"time: setup ([\d.e-]+) s, solve ([\d.e-]+) s", out)
    return wall, float(found.group(1)), float(found.group(2))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--stack", nargs=2, action="append", metavar=("NAME", "COMMAND"), required=True)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--nx", type=int, default=5000)
    args = parser.parse_args()
    for name, prefix in args.stack:  # warm-up: the JIT cache and the OS's file cache
        _once(prefix, name, args.nx)
    times = {name: [] for name, _ in args.stack}
    for _ in range(args.repeats):
        for name, prefix in args.stack:
            times[name].append(_once(prefix, name, args.nx))
    print("stack,wall_median_s,wall_min_s,wall_max_s,setup_median_s,solve_median_s")
    for name, rows in times.items():
        wall, setup, solve = zip(*rows)
        print(f"{name},{statistics.median(wall):.2f},{min(wall):.2f},{max(wall):.2f},{statistics.median(setup):.3f},"
              f"{statistics.median(solve):.3f}")


if __name__ == "__main__":
    main()
