"""End-to-end wall clock of `stringcontact run example1 --out DIR`, and where the time goes.

1. The command itself, as a user runs it, in a fresh process (median of a few runs, warm JIT cache).
2. The same work in a fresh process, timed by phase: import (stringcontact, dolfinx, petsc4py),
   setup (mesh, the forms' JIT-cache load and assembly, LU factorisation), solve (the time loop),
   XDMF (the stored rows streamed to solution.xdmf/h5), pictures (viz.write_pictures) and tables.
3. The XDMF cost against the number of stored rows (`max_rows`), the knob that trades time
   resolution of the output for I/O time.

    .venv/bin/python benchmarks/bench_run.py
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


def run_cli(out: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([str(EXE), "run", "example1", "--out", str(out), "--force", "--no-progress"], check=True,
                   capture_output=True)
    return time.perf_counter() - t0


def phases(out: str, max_rows: int) -> dict:
    """Run in a fresh interpreter: time the import, then simulate with output."""
    t0 = time.perf_counter()
    import dolfinx  # noqa: F401
    import petsc4py  # noqa: F401

    import stringcontact as sc

    t_import = time.perf_counter() - t0
    t1 = time.perf_counter()
    res = sc.simulate(sc.load_scene("example1"), output_dir=out, force=True, max_rows=max_rows)
    total = time.perf_counter() - t1
    summary = json.loads((Path(out) / "summary.json").read_text())
    tm = summary.get("timings", {})
    pictures = tm.get("pictures", 0.0)
    xdmf = getattr(res, "timings", {}).get("output", 0.0) - pictures
    return {
        "import": t_import,
        "setup": tm.get("setup", 0.0),
        "solve": tm.get("solve", 0.0),
        "xdmf+tables": xdmf,
        "pictures": pictures,
        "simulate": total,
        "rows": len(res.t),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        spec = json.loads(args.child)
        print(json.dumps(phases(spec["out"], spec["max_rows"])))
        return 0

    env = dict(os.environ)
    env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    tmp = Path(tempfile.mkdtemp(prefix="bench_run_"))
    try:
        run_cli(tmp / "warm")  # warms the JIT cache
        walls = [run_cli(tmp / f"run{i}") for i in range(args.repeats)]
        print(f"`stringcontact run example1 --out DIR` (N = 5000, 1500 steps), wall clock, warm JIT cache: "
              f"median {statistics.median(walls):.2f} s of {args.repeats} ({', '.join(f'{w:.2f}' for w in walls)})\n")

        def child(max_rows):
            out = tmp / f"phase{max_rows}"
            proc = subprocess.run([sys.executable, __file__, "--child", json.dumps({"out": str(out), "max_rows": max_rows})],
                                  capture_output=True, text=True, env=env, check=True)
            return json.loads(proc.stdout.strip().splitlines()[-1])

        keys = ("import", "setup", "solve", "xdmf+tables", "pictures")
        print("| max_rows | stored rows | " + " | ".join(f"{k} [s]" for k in keys) + " | sum [s] |")
        print("|---:|---:|" + "---:|" * (len(keys) + 1))
        for max_rows in (400, 200, 100):
            runs = [child(max_rows) for _ in range(args.repeats)]
            med = {k: statistics.median(r[k] for r in runs) for k in keys}
            print(f"| {max_rows} | {runs[0]['rows']} | " + " | ".join(f"{med[k]:.2f}" for k in keys)
                  + f" | {sum(med.values()):.2f} |", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
