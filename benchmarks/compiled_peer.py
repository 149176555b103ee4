"""The compiled limit of a step: the paper's scheme on Example 1's string as a C loop (`compiled_peer.c`).

Issue 28 set the per-step target at 3× "a compiled loop (C, Thomas algorithm on the prefactorised tridiagonal
matrix)", measured once at 33.5 µs and not kept. This builds that loop from `compiled_peer.c` with the
system's C compiler (the one dolfinx's form compiler uses) into a temporary folder and runs it, two ways:

* ``energies=False``: the issue's loop, the solve alone: the right-hand side with the penalty, one Thomas
  sweep each way, and the rows of η and v copied out at the stored steps;
* ``energies=True``: the same plus what `stringcontact`'s step computes besides the solve: the terms of the
  discrete energy identity every step (K η, C v and seven dot products, fused into one sweep) summed into the
  ledger, and min η.

    .venv/bin/python benchmarks/compiled_peer.py                 # µs per step of both, and their η against simulate's
    .venv/bin/python benchmarks/compiled_peer.py --cflags=-O2    # with other compiler flags

`bench_step.py` times them beside `simulate` and the NumPy peers.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SOURCE = Path(__file__).resolve().parent / "compiled_peer.c"
#: the limit on this machine: the compiler's best for this CPU
CFLAGS = ("-O3", "-march=native")
LEDGER = ("kinetic", "elastic", "viscous_dissipation", "contact_dissipation", "numerical_dissipation", "min_eta")


def build(cflags=CFLAGS) -> ctypes.CDLL:
    """`compiled_peer.c` compiled and loaded; SystemExit naming the compiler if there is none or it fails."""
    compiler = _compiler()
    if compiler is None:
        raise SystemExit("compiled_peer: no C compiler ($CC, Python's own CC, cc or gcc)")
    folder = Path(tempfile.mkdtemp(prefix="compiled-peer-"))
    library = folder / "compiled_peer.so"
    try:
        subprocess.run([compiler, *cflags, "-shared", "-fPIC", "-o", str(library), str(SOURCE)], check=True,
                       capture_output=True, text=True)
        lib = ctypes.CDLL(str(library))
    except subprocess.CalledProcessError as exc:
        raise SystemExit(f"compiled_peer: {compiler} failed:\n{exc.stderr}") from None
    finally:
        shutil.rmtree(folder, ignore_errors=True)  # the loaded library stays mapped
    doubles = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
    longs = np.ctypeslib.ndpointer(np.int64, flags="C_CONTIGUOUS")
    real = ctypes.c_double
    lib.march.restype = ctypes.c_int
    lib.march.argtypes = [ctypes.c_int, ctypes.c_int, real, real, real, real, real, real, doubles, doubles,
                          ctypes.c_int, longs, doubles, doubles, ctypes.c_int, doubles]
    return lib


def _compiler() -> str | None:
    """The C compiler Python's own extensions are built with (what cffi uses for dolfinx's forms), else cc or gcc."""
    import os
    import shlex
    import sysconfig

    for name in (os.environ.get("CC"), sysconfig.get_config_var("CC")):
        if name and shutil.which(shlex.split(name)[0]):
            return shutil.which(shlex.split(name)[0])
    return shutil.which("cc") or shutil.which("gcc")


def compiled_peer(lib, scene, stored_steps, energies: bool = False):
    """(rows of η, rows of v, ledger {LEDGER name: value at T; zeros without `energies`}, seconds in the loop) of
    the C loop on `scene`: a uniform string, the paper's explicit penalty, lumped mass, ψ = 0, no load (Example 1).
    `stored_steps` must increase within 0 … nt, as `simulate`'s do."""
    N, dt = scene.nx, scene.dt
    steps = np.ascontiguousarray(stored_steps, dtype=np.int64)
    if N < 2 or np.any(np.diff(steps) <= 0) or (steps.size and (steps[0] < 0 or steps[-1] > scene.nt)):
        raise ValueError(f"compiled_peer: nx = {N} (>= 2) and stored steps increasing within 0 … {scene.nt}")
    sys.path.insert(0, str(SOURCE.parent))
    from bench_step import _string  # the NumPy peers' string at t = 0

    _, dx, eta, v0, _ = _string(scene)
    eta_old = eta - dt * v0
    rows_eta, rows_v = np.empty((len(steps), N + 1)), np.empty((len(steps), N + 1))
    ledger = np.zeros(len(LEDGER))
    t0 = time.perf_counter()
    failed = lib.march(N, scene.nt, dt, dx, scene.alpha, scene.eps, scene.h_left, scene.h_right, eta,
                       eta_old, len(steps), steps, rows_eta, rows_v, int(energies), ledger)
    seconds = time.perf_counter() - t0
    if failed:
        raise MemoryError("compiled_peer: out of memory")
    return rows_eta, rows_v, dict(zip(LEDGER, ledger.tolist())), seconds


def check(lib, scene, res) -> float:
    """Print both variants' max |Δη|, |Δv| against `simulate`'s rows `res`, and the ledger against its energies
    at T (relative to E(0)); returns the largest of them."""
    worst = 0.0
    E0 = res.energy["kinetic"][0] + res.energy["elastic"][0]
    for energies in (False, True):
        eta, v, ledger, _ = compiled_peer(lib, scene, res.steps, energies)
        d_eta, d_v = np.max(np.abs(eta - res.eta)), np.max(np.abs(v - res.velocity))
        line = f"compiled ({'with' if energies else 'without'} energies): max |Δη| {d_eta:.2e}, max |Δv| {d_v:.2e}"
        worst = max(worst, d_eta)
        if energies:
            gaps = {k: abs(ledger[k] - res.energy[k][-1]) / E0 for k in LEDGER[:-1]}
            line += "; ledger at T, |Δ|/E(0): " + ", ".join(f"{k} {g:.1e}" for k, g in gaps.items())
            line += f"; min η {ledger['min_eta']:.6g} (simulate {res.min_eta:.6g})"
            worst = max(worst, *gaps.values(), abs(ledger["min_eta"] - res.min_eta))
        print(line)
    return worst


def main(argv=None) -> int:
    import argparse

    from mpi4py import MPI

    import stringcontact as sc

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cflags", default=" ".join(CFLAGS), help=f"the compiler's flags (default: {' '.join(CFLAGS)})")
    args = ap.parse_args(argv)
    scene = sc.load_scene("example1")
    res = sc.simulate(scene, comm=MPI.COMM_SELF)
    lib = build(tuple(args.cflags.split()))
    worst = check(lib, scene, res)
    for energies in (False, True):
        times = [compiled_peer(lib, scene, res.steps, energies)[3] / scene.nt * 1e6 for _ in range(9)]
        print(f"compiled, {'with' if energies else 'without'} the energy identity: median {np.median(times):.1f} µs/step "
              f"(min {min(times):.1f}, 9 runs)")
    return 1 if worst > 1e-6 else 0


if __name__ == "__main__":
    sys.exit(main())
