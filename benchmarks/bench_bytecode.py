"""`stringcontact run example1 --out DIR` with and without the bytecode that scripts/setup compiles.

Debian byte-compiles the modules it installs into the public dist-packages, but not dolfinx, petsc4py and
slepc4py (under /usr/lib/petsc and /usr/lib/slepc), and pip's editable install does not compile this package. Python then
compiles them at every import when it cannot write their `__pycache__`: as the image's user, as a user who
does not own /usr/lib, and whenever PYTHONDONTWRITEBYTECODE is set (the Makefile and the image set it).

Each variant gets its own bytecode tree through PYTHONPYCACHEPREFIX (Python then reads and writes bytecode
only there). "compiled" holds the bytecode of every module a run imports (one run writes it); "without" is
the same tree without this checkout's source and without Debian's PETSc-side packages, which is what a run
finds without scripts/setup's bytecode. The two alternate, every run a fresh process with
PYTHONDONTWRITEBYTECODE=1, so that neither tree changes; wall clock and CPU (the run and its picture
processes) are printed as medians, with the median of the paired ratios.

    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow .venv/bin/python benchmarks/bench_bytecode.py --repeats 12
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

from bench_run import EXE, run_cli

ROOT = Path(__file__).resolve().parents[1]
DEBIAN_PRIVATE = ("dolfinx", "petsc4py", "slepc4py")


def mirrored(prefix: Path, folder: Path) -> list[Path]:
    """Where PYTHONPYCACHEPREFIX=`prefix` keeps the bytecode of the sources under `folder`: the path as imported
    (/usr/lib/petsc is a symlink that Python does not resolve) and the resolved one."""
    return [prefix / Path(os.path.abspath(folder)).relative_to("/"), prefix / folder.resolve().relative_to("/")]


def trees(base: Path) -> dict[str, Path]:
    compiled, without = base / "compiled", base / "without"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    run_cli(base / "out", env={**env, "PYTHONPYCACHEPREFIX": str(compiled)})  # writes every module's bytecode
    shutil.copytree(compiled, without, symlinks=True)
    folders = [ROOT / "src", ROOT / "examples"]
    for name in DEBIAN_PRIVATE:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            folders.append(Path(spec.origin).parent)
    for folder in folders:
        for tree in mirrored(without, folder):
            shutil.rmtree(tree, ignore_errors=True)
    return {"without": without, "compiled": compiled}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=12)
    args = parser.parse_args()
    if not EXE.exists():
        sys.exit(f"no {EXE}: run scripts/setup first")
    base = Path(tempfile.mkdtemp(prefix="bench-bytecode-"))
    try:
        variants = trees(base)
        count = {k: sum(1 for _ in v.rglob("*.pyc")) for k, v in variants.items()}
        walls = {k: [] for k in variants}
        cpus = {k: [] for k in variants}
        for _ in range(args.repeats):
            for name, tree in variants.items():
                env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "PYTHONPYCACHEPREFIX": str(tree)}
                walls[name].append(run_cli(base / "out", env=env, cpu=cpus[name]))
    finally:
        shutil.rmtree(base, ignore_errors=True)
    ratios = [c / b for b, c in zip(walls["without"], walls["compiled"])]
    print(f"`stringcontact run example1 --out DIR`, {args.repeats} alternating runs each, PYTHONDONTWRITEBYTECODE=1:\n")
    print("| bytecode | modules with bytecode | wall median (min) [s] | CPU median [s] |")
    print("|---|---:|---|---:|")
    for name in variants:
        print(f"| {name} | {count[name]} | {statistics.median(walls[name]):.2f} ({min(walls[name]):.2f}) | "
              f"{statistics.median(cpus[name]):.2f} |")
    print(f"\npaired compiled/without (median of {len(ratios)}): {statistics.median(ratios):.3f}")


if __name__ == "__main__":
    main()
