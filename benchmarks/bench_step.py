"""Per step of every scheme at the paper's resolution, against the NumPy peer and (optionally) another checkout.

    .venv/bin/python benchmarks/bench_step.py                          # this checkout, 3 rounds
    .venv/bin/python benchmarks/bench_step.py --against /tmp/before    # and a checkout's src/ alternately
    .venv/bin/python benchmarks/bench_step.py --law                    # the contact law alone: all nodes or candidates
    PYTHONPATH=/tmp/before/src .venv/bin/python benchmarks/bench_step.py --save before.npz   # every stored array,
    .venv/bin/python benchmarks/bench_step.py --save after.npz                               # then: bit for bit?
    .venv/bin/python benchmarks/bench_step.py --same before.npz after.npz

Example 1 (nx = 5000, Δt = 2e-4, 1500 steps). Each round starts one fresh process per checkout, alternately; in it
each scheme (paper explicit, paper semi-implicit, projection, newmark) and the NumPy peer of the paper's scheme
(`bench_solver.numpy_peer`: splu, vectorised right-hand side, the same stored rows) run `--repeats` times,
alternately. "µs/step" is `simulate`'s time loop (`timings["solve"]`: the steps and the stored rows, no output)
over the steps; the peer's is its whole loop. Medians over all runs; "ratio to peer" is the median of the ratios
of runs made next to each other. The compiled limit (a C Thomas-algorithm loop, docs/performance.md) is 33.5 µs.
Prints a Markdown table, with `uptime`'s load before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUNS = (("paper", {}), ("paper semi-implicit", {"penalty": "semi-implicit"}), ("projection", {}), ("newmark", {}))


def child(repeats: int) -> dict:
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    sys.path.insert(0, str(HERE))
    from bench_solver import numpy_peer

    scene = sc.load_scene("example1")
    times = {name: [] for name, _ in RUNS} | {"peer": []}
    for _ in range(repeats + 1):  # the first round warms up (JIT cache, page faults) and is not counted
        for name, kw in RUNS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = sc.simulate(scene, scheme=name.split()[0], comm=MPI.COMM_SELF, **kw)
            times[name].append(res.timings["solve"] / scene.nt * 1e6)
        t0 = time.perf_counter()
        numpy_peer(scene, res.steps)
        times["peer"].append((time.perf_counter() - t0) / scene.nt * 1e6)
    return {"file": sc.__file__, **{k: v[1:] for k, v in times.items()}}


def run_child(src: str | None, repeats: int) -> dict:
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = str(Path(src) / "src") + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.run([sys.executable, __file__, "--child", str(repeats)], capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise SystemExit(proc.stderr)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def law_timing(repeats: int) -> None:
    """The penalty F(η^n, v^n) on every node (the UFL graph's closures) against the candidate path, at the states
    of Example 1's stored rows, alternately."""
    import timeit

    import numpy as np
    from mpi4py import MPI

    import stringcontact as sc
    from stringcontact.run import driver

    scene = sc.load_scene("example1")
    res = sc.simulate(scene, comm=MPI.COMM_SELF)
    model = driver._resolve_model(None, scene)
    V, params, ops = driver.discretise(scene, model, MPI.COMM_SELF)
    s = driver._setting(scene, model, V, params, ops, "explicit", "lumped", MPI.COMM_SELF)
    law = s.laws.compile(model.penalty(s.laws.eta, s.laws.quotient, params))
    full, sub = [], []
    for row in range(1, len(res.t)):
        s.laws.set(eta=res.eta[row].copy(), eta_old=res.eta[row] - scene.dt * res.velocity[row])
        with np.errstate(all="ignore"):
            for _ in range(repeats):
                full.append(min(timeit.repeat(lambda: np.where(True, law._f(s.laws.env), 0.0), number=20, repeat=3)) / 20)
                sub.append(min(timeit.repeat(lambda: law.evaluate_env(s.laws.env), number=20, repeat=3)) / 20)
    print(f"penalty at {len(res.t) - 1} stored states of Example 1 (mean over them): every node "
          f"{1e6 * statistics.mean(full):.1f} µs, candidates only {1e6 * statistics.mean(sub):.1f} µs")


def save_fields(path: str) -> None:
    """Every stored array of Example 1's runs (fields, energies, series) of each scheme into `path` (.npz)."""
    import warnings

    import numpy as np
    from mpi4py import MPI

    import stringcontact as sc

    arrays = {}
    for name, kw in RUNS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = sc.simulate(sc.load_scene("example1"), scheme=name.split()[0], comm=MPI.COMM_SELF, **kw)
        for field in ("eta", "velocity", "contact", "contact_force"):
            arrays[f"{name}/{field}"] = getattr(res, field)
        arrays.update({f"{name}/energy/{k}": v for k, v in res.energy.items()})
        arrays.update({f"{name}/series/{k}": v for k, v in res.series.items()})
    np.savez(path, **arrays)
    print(f"{sc.__file__}: {len(arrays)} arrays into {path}")


def same_bits(first: str, second: str) -> int:
    """Compare two `--save` files byte for byte (NaN and -0.0 included); 0 if every array is identical."""
    import numpy as np

    a, b = np.load(first), np.load(second)
    differ = [k for k in a.files if k not in b.files or a[k].shape != b[k].shape
              or a[k].tobytes() != b[k].tobytes()]
    print(f"{len(a.files) - len(differ)} of {len(a.files)} arrays bit-identical" + "".join(f"\n  differs: {k}" for k in differ))
    return 1 if differ else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="fresh processes per checkout, alternately")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each scheme per process")
    ap.add_argument("--against", help="another checkout (its src/ is put first on PYTHONPATH)")
    ap.add_argument("--law", action="store_true", help="time the contact law alone")
    ap.add_argument("--save", metavar="FILE.npz", help="save every stored array of the four runs, then stop")
    ap.add_argument("--same", nargs=2, metavar="FILE.npz", help="compare two --save files bit for bit")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.save:
        save_fields(args.save)
        return 0
    if args.same:
        return same_bits(*args.same)
    if args.child is not None:
        print(json.dumps(child(args.child)))
        return 0
    if args.law:
        law_timing(args.repeats)
        return 0
    checkouts = {"this checkout": None} | ({f"{args.against}": args.against} if args.against else {})
    load_before = os.getloadavg()
    results = {label: [] for label in checkouts}
    for _ in range(args.rounds):
        for label, src in checkouts.items():
            results[label].append(run_child(src, args.repeats))
    load_after = os.getloadavg()
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average before {load_before[0]:.2f}, after "
          f"{load_after[0]:.2f}; {args.rounds} rounds × {args.repeats} runs\n")
    for label, rounds in results.items():
        print(f"{label}: {rounds[0]['file']}")
    print()
    print("| checkout | scheme | µs/step | ratio to NumPy peer | ratio to compiled (33.5 µs) |")
    print("|---|---|---:|---:|---:|")
    for label, rounds in results.items():
        peer = [t for r in rounds for t in r["peer"]]
        for name, _ in RUNS:
            mine = [t for r in rounds for t in r[name]]
            ratios = [a / b for a, b in zip(mine, peer)]
            print(f"| {label} | {name} | {statistics.median(mine):.0f} | {statistics.median(ratios):.2f} | "
                  f"{statistics.median(mine) / 33.5:.1f} |")
        print(f"| {label} | NumPy peer (paper) | {statistics.median(peer):.0f} | 1.00 | {statistics.median(peer) / 33.5:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
