"""`make demo` on a fresh machine: the first and the second run, wall clock and lines of output.

A fresh machine is simulated by an empty cache folder (XDG_CACHE_HOME: dolfinx's JIT cache, matplotlib's
font cache); .venv is kept (pip is not timed). The first `make demo` includes scripts/setup's warm-up, which
compiles the demo's forms; the second finds them. Also printed: the forms each run compiled, and whether
any compiler line reached the output.

    .venv/bin/python benchmarks/bench_first_run.py
"""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMPILER_LINES = ("INFO:root", "running build_ext", "gcc ")


def make_demo(env: dict) -> tuple[float, str]:
    t0 = time.perf_counter()
    proc = subprocess.run(["make", "-s", "demo"], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, proc.stdout + proc.stderr


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="fresh-cache-") as cache:
        env = {**os.environ, "XDG_CACHE_HOME": cache}
        forms = Path(cache) / "fenics"
        print("| run | wall [s] | forms compiled | output lines | compiler lines |")
        print("|---|---:|---:|---:|---:|")
        before = 0
        for label in ("first (fresh cache)", "second"):
            wall, out = make_demo(env)
            now = len(list(forms.glob("*.so")))
            noisy = sum(any(w in line for w in COMPILER_LINES) for line in out.splitlines())
            print(f"| {label} | {wall:.1f} | {now - before} | {len(out.splitlines())} | {noisy} |")
            before = now


if __name__ == "__main__":
    main()
