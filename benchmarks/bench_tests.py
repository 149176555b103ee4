"""How long do `make test` and `make test-fast` take on a clean clone with an empty JIT cache, and which test files
take the time?

The committed tree (HEAD) is cloned into a temporary folder with `../shared` beside it, as CI clones it, and run
with an empty dolfinx JIT cache of its own (XDG_CACHE_HOME, which dolfinx's cache follows; pip keeps its usual
cache). `make test` runs first: its setup (the venv, the demos' forms) and then the suite, one pytest-xdist worker
per core; pytest's `--durations=0` (through PYTEST_ADDOPTS, so the command is `make test` as written) gives every
test's time. Then `make test-fast` runs on the now warm cache. Printed: each command's wall clock, its pytest time
and counts, the test-seconds (every test's set-up, call and tear-down, summed over the workers) and the files that
take most of them.

    .venv/bin/python benchmarks/bench_tests.py            # about 6 min on a 2-core VM
    .venv/bin/python benchmarks/bench_tests.py --files 20 --keep
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: a line of `--durations=0`: "12.34s call     tests/x/test_y.py::test_z[p]"
DURATION = re.compile(r"^(\d+\.\d+)s (?:setup|call|teardown)\s+(\S+?\.py)::", re.MULTILINE)
#: pytest's last line: "1552 passed, 1 skipped, 28 warnings in 280.36s (0:04:40)"
SUMMARY = re.compile(r"^=*\s*(.*?) in (\d+\.\d+)s", re.MULTILINE)


def clone(work: Path) -> Path:
    """HEAD cloned into `work`/main, the shared folder linked beside it (the layout CI runs in)."""
    subprocess.run(["git", "clone", "-q", str(ROOT), str(work / "main")], check=True)
    shared = ROOT.parent / "shared"
    if shared.is_dir():
        (work / "shared").symlink_to(shared)
    return work / "main"


def timed_make(target: str, checkout: Path, env: dict) -> dict:
    """`make TARGET` in `checkout`: its wall clock, pytest's own time and count line, and the test-seconds by file."""
    t0 = time.perf_counter()
    proc = subprocess.run(["make", target], cwd=checkout, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"make {target} failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    by_file = Counter()
    for seconds, path in DURATION.findall(proc.stdout):
        by_file[path] += float(seconds)
    summary = SUMMARY.findall(proc.stdout)
    counts, pytest_s = (summary[-1][0], float(summary[-1][1])) if summary else ("?", float("nan"))
    return {"wall": wall, "pytest": pytest_s, "counts": counts, "by_file": by_file}


def report(target: str, result: dict, files: int) -> None:
    total = sum(result["by_file"].values())
    print(f"\nmake {target}: {result['wall']:.0f} s wall clock (pytest {result['pytest']:.0f} s, the rest is setup); "
          f"{result['counts']}")
    print(f"test-seconds: {total:.0f} s, {total / max(result['pytest'], 1e-9):.2f} per second of pytest")
    print("| file | test-seconds | share |\n| --- | ---: | ---: |")
    for path, seconds in result["by_file"].most_common(files):
        print(f"| `{path}` | {seconds:.1f} | {100 * seconds / total:.0f} % |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--files", type=int, default=12, help="how many of the slowest files to list")
    parser.add_argument("--keep", action="store_true", help="keep the clone (its path is printed)")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-tests-"))
    try:
        checkout = clone(work)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "VIRTUAL_ENV"))}
        home_cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
        env.update(XDG_CACHE_HOME=str(work / "cache"), PIP_CACHE_DIR=str(home_cache / "pip"),
                   PYTEST_ADDOPTS="--durations=0")
        print(f"HEAD {subprocess.check_output(['git', '-C', str(ROOT), 'rev-parse', '--short', 'HEAD'], text=True).strip()}"
              f", {os.cpu_count()} cores, an empty JIT cache in {work / 'cache'}")
        for target in ("test", "test-fast"):
            report(target, timed_make(target, checkout, env), args.files)
    finally:
        if args.keep:
            print(f"\nthe clone: {work}")
        else:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
