"""Peak memory per rank of one membrane run as the mesh grows, and how much of it the stored rows take.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_memory.py                  # 1e4 ... 1e6 nodes, 1 and 2 ranks
    PYTHONPATH=src .venv/bin/python benchmarks/bench_memory.py --sizes 99 316   # some sizes only
    PYTHONPATH=/work/main/src ... --label before                                # another checkout's code
    PYTHONPATH=src ... --sizes 999 --ranks 2 --row-budget 5e8                   # the row budget at work

Each case is a fresh process (`mpirun -n 2` for 2 ranks), so that its peak RSS (ru_maxrss, gathered from
every rank) is its own. The scene: a square membrane (cells [n, n]) under gravity onto a bump, scheme
`projection`, model `loaded_obstacle` (as the `bump` scene), Δt = 0.5/n, `steps` steps. Each case runs
twice: storing every step (`max_rows` = 400 > steps, so steps + 1 rows), and storing 2 rows (0 and T).
The difference of their peak RSS is what storage costs, whatever the linear solver takes; `held MB` is
the bytes of the per-node arrays the rank's Result holds (eta, velocity, contact_force, contact).
Prints a Markdown table (docs/explanation/memory.md) and appends JSON lines to benchmarks/out/memory.jsonl.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

from bench_membrane import child  # one case in a fresh process (mpirun for 2 ranks), its JSON line

HERE = Path(__file__).resolve().parent
OUT = HERE / "out"
PER_NODE = ("eta", "velocity", "contact_force", "contact")


def scene(n: int, steps: int):
    from stringcontact.scene import Scene

    dt = 0.5 / n
    bump = "0.2*exp(-((x - 0.3)**2 + (y - 0.5)**2)/0.01) + 0.2*exp(-((x - 0.7)**2 + (y - 0.5)**2)/0.01) - 0.1"
    return Scene.from_dict(dict(name=f"square{n}", domain="rectangle", cells=[n, n], T=steps * dt, nt=steps,
                                alpha=0.02, eps=5e-4, h=0, eta0="0.3*sin(pi*x)*sin(pi*y)", v0=0, load="-10",
                                obstacle=bump, model="loaded_obstacle", scheme="projection", output_times=[0.0]))


def held_bytes(res) -> int:
    """Bytes of the per-node rows this rank's Result holds (none where they are absent)."""
    return sum(getattr(getattr(res, name, None), "nbytes", 0) for name in PER_NODE)


def one(n: int, steps: int, max_rows: int, row_budget: int | None = None) -> dict:
    from mpi4py import MPI

    import stringcontact as sc

    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    budget = {} if row_budget is None else {"row_budget": row_budget}  # main's simulate has no row_budget
    res = sc.simulate(scene(n, steps), storage=sc.Storage(max_rows=max_rows), **budget)
    total = time.perf_counter() - t0
    rss = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)  # Linux: kB
    held = comm.gather(held_bytes(res) / 2**20)
    return {"n": n, "ranks": comm.size, "max_rows": max_rows, "rows": len(res.t), "nodes": (n + 1) ** 2,
            "rss_mb": rss, "held_mb": held, "total_s": total, "setup_s": res.timings["setup"]}


def fmt(values) -> str:
    return " / ".join(f"{v:.0f}" for v in values)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[99, 316, 499, 999], help="cells per side")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--row-budget", type=float, help="simulate's row_budget in bytes (default: ROW_BUDGET)")
    ap.add_argument("--label", default="after", help="a name for this code (before/after) in the JSON lines")
    ap.add_argument("--one", nargs=2, type=int, metavar=("N", "MAX_ROWS"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        row = one(args.one[0], args.steps, args.one[1], None if args.row_budget is None else int(args.row_budget))
        from mpi4py import MPI

        if MPI.COMM_WORLD.rank == 0:
            print(json.dumps(row))
        return
    OUT.mkdir(exist_ok=True)
    me = [sys.executable, str(Path(__file__).resolve()), "--steps", str(args.steps)]
    me += (["--row-budget", str(args.row_budget)] if args.row_budget else []) + ["--one"]
    print("| code | nodes | ranks | rows | peak RSS MB per rank | with 2 rows | storage = difference | held MB per rank |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for n in args.sizes:
        for ranks in args.ranks:
            mpi = ["mpirun", "-n", str(ranks), "--oversubscribe", "-x", "PYTHONPATH"] if ranks > 1 else []
            full = child(mpi + me + [str(n), "400"])
            small = child(mpi + me + [str(n), "2"])
            diff = [a - b for a, b in zip(full["rss_mb"], small["rss_mb"])]
            print(f"| {args.label} | {full['nodes']} | {ranks} | {full['rows']} | {fmt(full['rss_mb'])} | "
                  f"{fmt(small['rss_mb'])} | {fmt(diff)} | {fmt(full['held_mb'])} |", flush=True)
            with open(OUT / "memory.jsonl", "a") as f:
                f.write(json.dumps({"label": args.label, "full": full, "small": small}) + "\n")


if __name__ == "__main__":
    main()
