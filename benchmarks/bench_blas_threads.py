"""Does BLAS threading slow the step? The stiff string's Example 1 (10,002 unknowns: OpenBLAS threads a dot
product of more than 10,000 entries) stepped with BLAS held to one thread while it steps (`run.stepper.one_thread`, what
the package does) and with BLAS left on all its threads, alternately (docs/explanation/performance.md).

    .venv/bin/python benchmarks/bench_blas_threads.py [--repeat 3]

Where NumPy's BLAS is single-threaded (Debian's) the two columns are the same. The figure is the solve time from
`Result.timings`; run it on a loaded machine (another process on the other core) to see what threads cost there.
"""

from __future__ import annotations

import argparse
import contextlib

import stringcontact as sc
from stringcontact.run import driver, stepper

HELD = stepper.one_thread


def _solve_time(held: bool) -> float:
    hold = HELD if held else (lambda length: contextlib.nullcontext())
    driver.one_thread = stepper.one_thread = hold
    try:
        res = sc.simulate(sc.load_scene("example1"), model="stiff_string")
    finally:
        driver.one_thread = stepper.one_thread = HELD
    return res.timings["solve"]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from threadpoolctl import threadpool_info

    threads = {lib["internal_api"]: lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}
    print(f"BLAS threads: {threads}")
    print("run,held_to_one_thread_s,all_threads_s")
    for i in range(args.repeat):
        print(f"{i + 1},{_solve_time(True):.3f},{_solve_time(False):.3f}")


if __name__ == "__main__":
    main()
