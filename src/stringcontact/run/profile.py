"""`stringcontact run --profile`: where a run's time went, from the clocks it keeps anyway (`Result.timings`); inside
a section, Python's profiler (docs/explanation/performance.md, "Where the time of a run goes")."""

from __future__ import annotations

import os
import sys
import time


def process_age() -> float | None:
    """Seconds since this process started (Linux: /proc); None where unknown or not started as `stringcontact run`."""
    if sys.argv[1:2] != ["run"]:
        return None
    try:
        with open("/proc/self/stat") as f:
            start_ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None


def sections(timings: dict, imports: float, started: float) -> list[tuple[str, float]]:
    """(section, seconds) of a run from start-up to the total; `imports`: the seconds loading the solver took,
    `started`: `time.perf_counter()` when the command began."""
    now = time.perf_counter()
    age = process_age()
    pictures = float(timings.get("pictures", 0.0))
    known = {"imports (dolfinx, UFL, the solver)": imports,
             "set-up (mesh, forms, assembly, factorisation)": float(timings.get("setup", 0.0)),
             "solve (time steps, stored rows)": float(timings.get("solve", 0.0)),
             "output (XDMF, CSV, JSON)": float(timings.get("output", 0.0)) - pictures, "pictures": pictures}
    command = now - started
    rows = [("start-up (Python, the command line, PETSc)", age - command)] if age is not None else []
    rows += list(known.items()) + [("other (scene, checks, report)", command - sum(known.values()))]
    return rows + [("total", sum(seconds for _, seconds in rows))]


def table(rows: list[tuple[str, float]]) -> str:
    """The sections as aligned lines with their share of the total."""
    total = rows[-1][1] or 1.0
    width = max(len(name) for name, _ in rows)
    return "\n".join(f"  {name:<{width}}  {seconds:7.3f} s  {100 * seconds / total:5.1f} %" for name, seconds in rows)
