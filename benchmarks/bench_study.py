"""Speed-up of the study sweeps on 2 MPI ranks: serial and `mpirun -n 2` runs, alternated, best of N.

    .venv/bin/python benchmarks/bench_study.py [--repeat 3] [--study stability]

Prints, per run, the whole command's wall-clock time, the sweep's (the cases and the gather, without
start-up and charts), the CPU seconds of the cases on each rank, and the load average (the machine is
shared: a high load makes the wall-clock numbers worse and the speed-up noisy).
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXE = ROOT / ".venv" / "bin" / "stringcontact"


def timed(cmd, env):
    """(whole wall-clock, the sweep's wall-clock, its CPU seconds per rank) of one study command."""
    t0 = time.perf_counter()
    out = subprocess.run(cmd, check=True, env=env, capture_output=True, text=True, cwd=ROOT).stdout
    whole = time.perf_counter() - t0
    m = re.search(r"of which the sweep ([\d.]+) s; CPU time of the cases per rank: (.*)", out)
    return whole, float(m.group(1)), m.group(2).strip()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--study", choices=("stability", "work-precision", "convergence"), default="stability")
    parser.add_argument("--ranks", type=int, default=2)
    args = parser.parse_args(argv)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1")
    serial, parallel = [], []
    with tempfile.TemporaryDirectory() as tmp:
        base = [str(EXE), "study", args.study, "--out"]
        mpi = ["mpirun", "-n", str(args.ranks), "--oversubscribe"]
        for i in range(args.repeat):
            for label, cmd, store in (("serial", base, serial), (f"{args.ranks} ranks", [*mpi, *base], parallel)):
                whole, sweep, cpu = timed([*cmd, f"{tmp}/{len(store)}{label[0]}"], env)
                store.append((whole, sweep))
                print(f"run {i} {label:8s}: command {whole:6.2f} s, sweep {sweep:6.2f} s, case CPU per rank {cpu}; "
                      f"load average {os.getloadavg()[0]:.2f}", flush=True)
    best = lambda runs, k: min(r[k] for r in runs)  # noqa: E731
    print(f"study {args.study}: best command {best(serial, 0):.2f} s serial, {best(parallel, 0):.2f} s on {args.ranks} "
          f"ranks (speed-up {best(serial, 0) / best(parallel, 0):.2f}); best sweep {best(serial, 1):.2f} s serial, "
          f"{best(parallel, 1):.2f} s on {args.ranks} ranks (speed-up {best(serial, 1) / best(parallel, 1):.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
