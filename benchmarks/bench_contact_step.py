"""The ε-free scheme's contact step as a complementarity problem, against the nodal maximum it replaced.

    .venv/bin/python benchmarks/bench_contact_step.py            # all of it (about 10 minutes on 2 cores)
    .venv/bin/python benchmarks/bench_contact_step.py --quick    # smaller sizes, for a smoke test

Prints, and writes to benchmarks/out/contact_step.json:
1. Example 1 (α = 0.01, Δt = Δx): the η error in L∞(0,T;L²), in L²(0,T;L²)/√T and at T, at nx = 250 ...
   2000 against `projection` at nx = 16000, for the complementarity step and for the nodal maximum (`reference.fd_projection(nodal=True)`,
   the old step, equal to the old `simulate` to 1e-10), with both wall times: the new one in this process,
   the old one from the baseline commit (`--baseline`, default the last commit with the nodal maximum) in a
   subprocess, each the best of 5 (warm JIT cache);
2. the flat landing (exact, α = 0, Δt = Δx, where the two steps give the same η): the η error and its order,
   and the velocity error at T of the centred velocity (new) and the one-sided one (old);
3. per step at nx = 5000: Example 1 (contact) and the flat landing stopped before it lands (no contact),
   new against old, alternating runs in two processes;
4. the candidates for the step: the active set (the default) against PETSc's SNES VI alone, on Example 1,
   the drum, and both under `mpirun -n 2`: wall time of the run and solves (or Newton iterations) per step.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis import study
from stringcontact.fem import compat
from stringcontact.timestepping import complementarity
from stringcontact.verification import reference

ROOT = Path(__file__).resolve().parent.parent
BASELINE = "0006a89"  # main before the contact step became a complementarity problem

#: Run in a subprocess with the baseline's or this tree's src first on sys.path: the best wall time of
#: `simulate` over REPEATS calls (after one warm-up) and the solve time per step.
TIMER = """
import json, sys, time, warnings
sys.path.insert(0, sys.argv[1])
import stringcontact as sc
from mpi4py import MPI
try:  # the layout by package; the baseline commit had flat modules
    from stringcontact.analysis import study
except ImportError:
    from stringcontact import study
kind, n, repeats = sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
scene = study.example1_scene(n) if kind == "example1" else study.flat_landing_scene(n, T=0.15)
warnings.simplefilter("ignore")
best, per_step = float("inf"), []
for k in range(repeats + 1):
    t0 = time.perf_counter()
    res = sc.simulate(scene, scheme="projection", comm=MPI.COMM_SELF, max_rows=400)
    wall = time.perf_counter() - t0
    if k:
        best = min(best, wall)
        per_step.append(res.timings["solve"] / scene.nt)
print(json.dumps({"wall_s": best, "per_step_us": 1e6 * sorted(per_step)[len(per_step) // 2],
                  "contact": bool(res.contact.any())}))
"""


def timed(src: Path, kind: str, n: int, repeats: int) -> dict:
    env = dict(os.environ, OMP_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", TIMER, str(src), kind, str(n), str(repeats)], env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def baseline_tree(rev: str) -> tuple[Path, callable]:
    """A detached worktree of `rev` (its src), and the function that removes it."""
    where = Path(tempfile.mkdtemp(prefix="stringcontact-baseline-"))
    subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", "--force", where, rev], check=True,
                   capture_output=True)
    return where / "src", lambda: subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", where],
                                                 capture_output=True, check=False)


def nodal_run(scene) -> study.Run:
    """The old step (nodal maximum) as a study Run from the NumPy reference, every step stored, with the old
    stored velocity at T, the one-sided (η^N − η^{N−1})/Δt."""
    x = scene.x()
    t, eta, _ = reference.fd_projection(scene.initial_displacement(x), scene.initial_velocity(x),
                                        length=scene.length, T=scene.T, nt=scene.nt, alpha=scene.alpha,
                                        h_left=scene.h_left, h_right=scene.h_right, nodal=True)
    return study.Run(problem=scene.name, method="nodal", penalty="none", mass="lumped", nx=scene.nx, nt=scene.nt,
                     dt=scene.dt, eps=np.inf, status="complete", wall_s=np.nan, t=t, x=x, eta=eta,
                     velocity_T=(eta[-1] - eta[-2]) / scene.dt)


def same_rows(old: study.Run, new: study.Run) -> study.Run:
    keep = study.common_rows(new.t, old.t)
    old.t, old.eta = old.t[keep], old.eta[keep]
    return old


def eta_errors(run: study.Run, ref: study.Run) -> dict:
    """‖η − η_ref‖ in L∞(0,T;L²) (the study's err_eta), in L²(0,T;L²)/√T (the time-RMS), and at T."""
    rows = study.common_rows(run.t, ref.t)
    ref_eta = np.array([np.interp(run.x, ref.x, row) for row in ref.eta[rows]])
    per_time = study.l2_norm(run.x, run.eta - ref_eta)
    rms = float(np.sqrt(compat.trapezoid(per_time**2, run.t) / (run.t[-1] - run.t[0])))
    return {"linf": float(per_time.max()), "rms": rms, "at_T": float(per_time[-1]),
            "t_of_max": float(run.t[per_time.argmax()])}


def example1_accuracy(sizes, ref_n, old_src):
    ref = study.run_method(study.example1_scene(ref_n), study.REFERENCE, rows=round(0.3 * min(sizes)))
    print(f"reference: projection nx={ref_n} ({ref.wall_s:.2f} s)")
    rows = []
    for n in sizes:
        scene = study.example1_scene(n)
        new = study.run_method(scene, study.METHODS["projection"], rows=round(0.3 * min(sizes)))
        old = same_rows(nodal_run(scene), new)
        row = {"nx": n, "new": eta_errors(new, ref), "old": eta_errors(old, ref),
               "wall_new": timed(ROOT / "src", "example1", n, 5)["wall_s"],
               "wall_old": timed(old_src, "example1", n, 5)["wall_s"]}
        rows.append(row)
        print(f"  nx={n}: eta error new/old: " + ", ".join(
            f"{k} {row['new'][k]:.3g}/{row['old'][k]:.3g} ({row['old'][k] / row['new'][k]:.2f}x)"
            for k in ("linf", "rms", "at_T")) + f" (max at t = {row['new']['t_of_max']:.3g}/{row['old']['t_of_max']:.3g});"
            f" wall new {row['wall_new']:.3f} s old {row['wall_old']:.3f} s")
    return {"reference_nx": ref_n, "rows": rows}


def flat_landing(sizes):
    rows = []
    for n in sizes:
        scene = study.flat_landing_scene(n)
        new = study.run_method(scene, study.METHODS["projection"], rows=round(0.6 * min(sizes)))
        old = same_rows(nodal_run(scene), new)
        e_new = study.errors_against_exact(new, study.flat_landing_exact)
        e_old = study.errors_against_exact(old, study.flat_landing_exact)
        rows.append({"nx": n, "err_eta": e_new["err_eta"], "err_vel_new": e_new["err_vel"],
                     "err_vel_old": e_old["err_vel"]})
        print(f"  flat landing nx={n}: eta {e_new['err_eta']:.3g}; velocity at T centred {e_new['err_vel']:.3g}, "
              f"one-sided {e_old['err_vel']:.3g}")
    h = [1 / r["nx"] for r in rows]
    orders = {k: study.fitted_order(h, [r[k] for r in rows]) for k in ("err_eta", "err_vel_new", "err_vel_old")}
    print("  orders: " + ", ".join(f"{k} {v:.2f}" for k, v in orders.items()))
    return {"rows": rows, "orders": orders}


def per_step(n, rounds, old_src):
    out = {}
    for kind in ("example1", "no-contact"):
        new, old = [], []
        for _ in range(rounds):  # alternate, so that a slow spell of the machine hits both
            new.append(timed(ROOT / "src", kind, n, 3))
            old.append(timed(old_src, kind, n, 3))
        med = lambda runs: float(np.median([r["per_step_us"] for r in runs]))
        out[kind] = {"new_us": med(new), "old_us": med(old), "ratio": med(new) / med(old), "contact": new[0]["contact"]}
        print(f"per step at nx={n}, {kind}: new {out[kind]['new_us']:.1f} us, old {out[kind]['old_us']:.1f} us "
              f"({out[kind]['ratio']:.2f}x)")
    return out


def candidates(scene, label):
    """The active set against SNES VI alone on `scene` (this process's ranks): wall time, cost per step."""
    out, default = {}, complementarity.MAX_ITERATIONS
    for name, cap in (("active set", default), ("SNES VI", 0)):
        complementarity.MAX_ITERATIONS = cap  # 0: every step goes straight to the fallback, SNES VI
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sc.simulate(scene.replace(T=20 * scene.dt, nt=20, output_times=[]), scheme="projection")  # warm-up
            t0 = time.perf_counter()
            res = sc.simulate(scene, scheme="projection")
            wall = MPI.COMM_WORLD.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        out[name] = {"wall_s": wall, "solve_s": res.timings["solve"], "steps": scene.nt,
                     "contact step": res.solver["contact step"]}
    complementarity.MAX_ITERATIONS = default
    if MPI.COMM_WORLD.rank == 0:
        for name, r in out.items():
            print(f"  {label}, {MPI.COMM_WORLD.size} rank(s), {name}: {r['wall_s']:.2f} s "
                  f"({1e3 * r['solve_s'] / r['steps']:.3f} ms per step); {r['contact step']}")
    return out


def candidate_scenes(quick):
    drum = sc.load_scene("drum")
    return {"example1": study.example1_scene(1250 if quick else 5000),
            "drum": drum.replace(mesh_size=0.1) if quick else drum}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--baseline", default=BASELINE, help="the commit with the nodal maximum (default %(default)s)")
    ap.add_argument("--out", default="benchmarks/out/contact_step.json")
    ap.add_argument("--candidates-only", action="store_true", help=argparse.SUPPRESS)  # the mpirun worker
    args = ap.parse_args()
    if args.candidates_only:
        found = {k: candidates(s, k) for k, s in candidate_scenes(args.quick).items()}
        if MPI.COMM_WORLD.rank == 0:
            print("JSON " + json.dumps(found))
        return
    study.warm_up()
    q = args.quick
    old_src, remove = baseline_tree(args.baseline)
    try:
        result = {
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "load": os.getloadavg(),
            "baseline": args.baseline,
            "example1": example1_accuracy((250, 500) if q else (250, 500, 1000, 2000), 2000 if q else 16000, old_src),
            "flat_landing": flat_landing((125, 250, 500) if q else (500, 1000, 2000, 4000)),
            "per_step": per_step(1250 if q else 5000, 1 if q else 3, old_src),
        }
    finally:
        remove()
    print("candidates, serial:")
    result["candidates_serial"] = {k: candidates(s, k) for k, s in candidate_scenes(q).items()}
    print("candidates, mpirun -n 2:")
    cmd = ["mpirun", "-n", "2", "--oversubscribe", sys.executable, __file__, "--candidates-only"]
    env = dict(os.environ, OMP_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    proc = subprocess.run(cmd + (["--quick"] if q else []), capture_output=True, text=True, env=env, check=False)
    print("\n".join(line for line in proc.stdout.splitlines() if not line.startswith("JSON ")))
    found = [line[5:] for line in proc.stdout.splitlines() if line.startswith("JSON ")]
    result["candidates_mpi2"] = json.loads(found[0]) if found else {"error": proc.stderr[-2000:]}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1, default=float))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
