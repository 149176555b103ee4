"""Does one time step cost more instructions than another checkout's? The step of each scheme on Example 1 at the
paper's resolution, counted by valgrind's callgrind: instructions do not depend on the machine's load, so two
checkouts compare to a fraction of a percent on a busy 2-core VM where wall clocks scatter by ±30 %.

    .venv/bin/python benchmarks/bench_step_instructions.py [--against PYTHON CHECKOUT] [--steps 100 600]

Each count is a whole process (imports, set-up, `Stepper._advance` N times); the difference between two step counts
divided by their difference is the cost of one step, set-up and start-up cancelled. `--against` names another
checkout's Python (a venv with that checkout installed) and its folder. Needs Debian's valgrind.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

STEPS = r"""
import sys, stringcontact as sc
options = {"paper": {}, "semi-implicit": {"penalty": "semi-implicit"}, "projection": {"scheme": "projection"},
           "newmark": {"scheme": "newmark"}}[sys.argv[1]]
st = sc.Stepper(sc.load_scene("example1"), **options)
for _ in range(int(sys.argv[2])):
    st._advance()
"""


def instructions(python: str, folder: str, scheme: str, steps: int) -> int:
    # three times without valgrind first: dolfinx 0.5 gives some forms another signature in the next processes while
    # the JIT cache fills, and a form compiled in the counted run counts the compiler too
    for _ in range(3):
        subprocess.run([python, "-c", STEPS, scheme, "1"], capture_output=True, cwd=folder, check=True)
    out = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", python, "-c", STEPS,
                          scheme, str(steps)], capture_output=True, text=True, cwd=folder, check=True).stderr
    return int(re.search(r"Collected : (\d+)", out).group(1))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--against", nargs=2, metavar=("PYTHON", "CHECKOUT"))
    parser.add_argument("--steps", nargs=2, type=int, default=[100, 600])
    parser.add_argument("--schemes", nargs="+", default=["paper", "semi-implicit", "projection", "newmark"])
    args = parser.parse_args()
    sides = {"this": (sys.executable, str(Path(__file__).resolve().parents[1]))}
    if args.against:
        sides["against"] = tuple(args.against)
    low, high = args.steps
    print("scheme," + ",".join(f"{side}_instructions_per_step" for side in sides) + (",ratio" if args.against else ""))
    for scheme in args.schemes:
        per_step = [(instructions(*sides[side], scheme, high) - instructions(*sides[side], scheme, low)) / (high - low)
                    for side in sides]
        ratio = f",{per_step[0] / per_step[1]:.3f}" if args.against else ""
        print(f"{scheme}," + ",".join(f"{v:.0f}" for v in per_step) + ratio)


if __name__ == "__main__":
    main()
