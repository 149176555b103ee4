"""The time-schemes targets: accuracy, numerical dissipation, and cost of `projection` against `paper`.

    .venv/bin/python benchmarks/bench_schemes.py            # all of it (a few minutes on 2 cores)
    .venv/bin/python benchmarks/bench_schemes.py --quick    # smaller sizes, for a smoke test

Prints, and writes to benchmarks/out/schemes.json:
1. flat landing (exact, α = 0, Δt = Δx): η error in L∞(0,T;L²) of `projection` (and `paper` semi-implicit,
   ε → 0, and `newmark`) at nx = 500 ... 4000, and the fitted order;
2. Example 1 at the paper's resolution: each scheme's energy split as fractions of E(0);
3. Example 1 accuracy per cost: the reference is `projection` at nx = 16000 (Δt = Δx); the paper's own run
   (nx = 5000, ε = 5e-4, explicit) against it, and the smallest nx at which `projection` is as accurate,
   with both wall times (best of 5, same process, warm JIT cache); the paper's scheme with ε → 0 against
   the same reference (the cross-check: it closes in on the same limit);
4. cost per step at nx = 5000, paper (explicit) and projection, alternating runs.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np
from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis import study

M = study.METHODS


def flat_landing(sizes):
    rows = {}
    for name in ("projection", "semi-implicit", "newmark"):
        errs = []
        for n in sizes:
            run = study.run_method(study.flat_landing_scene(n), M[name], rows=round(0.6 * min(sizes)))
            errs.append(study.errors_against_exact(run, study.flat_landing_exact)["err_eta"])
        rows[name] = {"nx": list(sizes), "err_eta": errs, "order": study.fitted_order([1 / n for n in sizes], errs)}
        print(f"flat landing {name:14s} " + "  ".join(f"{n}: {e:.3g}" for n, e in zip(sizes, errs))
              + f"   order {rows[name]['order']:.2f}")
    return rows


def energy_split(n):
    out = {}
    for scheme, kw in (("paper", {}), ("projection", {}), ("newmark", {"penalty": "semi-implicit"})):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = sc.simulate(study.example1_scene(n), scheme=scheme, comm=MPI.COMM_SELF, **kw)
        E0 = float(res.total_energy[0])
        split = {k: float(v[-1]) / E0 for k, v in res.energy.items()}
        out[scheme] = {"E0": E0, **split, "residual": float(np.max(np.abs(res.balance_residual))) / E0}
        print(f"example1 nx={n} {scheme:10s} E0 {E0:.1f}  numerical {split['numerical_dissipation']:.2%}  "
              f"contact {split['contact_dissipation']:.2%}  viscous {split['viscous_dissipation']:.2%}  "
              f"E(T) {split['kinetic'] + split['elastic']:.2%}  residual {out[scheme]['residual']:.1e}")
    return out


def accuracy_per_cost(paper_n, sizes, ref_n, eps_limit_sizes):
    rows = round(0.3 * min(sizes))
    ref = study.run_method(study.example1_scene(ref_n), study.REFERENCE, rows=rows)
    paper = study.run_method(study.example1_scene(paper_n), M["paper"], rows=rows, repeat=5)
    e_paper = study.errors_against_reference(paper, ref)["err_eta"]
    print(f"reference: projection nx={ref_n} ({ref.wall_s:.2f} s); paper's run nx={paper_n}: error {e_paper:.3g}, "
          f"{paper.wall_s:.3f} s")
    proj = []
    for n in sizes:
        run = study.run_method(study.example1_scene(n), M["projection"], rows=rows, repeat=5)
        proj.append({"nx": n, "err_eta": study.errors_against_reference(run, ref)["err_eta"], "wall_s": run.wall_s})
        print(f"  projection nx={n}: error {proj[-1]['err_eta']:.3g}, {run.wall_s:.4f} s")
    enough = [p for p in proj if p["err_eta"] <= e_paper]
    cheapest = min(enough, key=lambda p: p["wall_s"]) if enough else None
    if cheapest:
        print(f"projection reaches the paper's accuracy at nx={cheapest['nx']}: {paper.wall_s / cheapest['wall_s']:.1f}x "
              "less wall time")
    limit = []
    for n in eps_limit_sizes:
        run = study.run_method(study.example1_scene(n), M["semi-implicit"], rows=rows)
        limit.append({"nx": n, "err_eta": study.errors_against_reference(run, ref)["err_eta"]})
        print(f"  paper, semi-implicit, eps -> 0, nx={n}: error {limit[-1]['err_eta']:.3g} against the reference")
    return {"reference_nx": ref_n, "paper": {"nx": paper_n, "err_eta": e_paper, "wall_s": paper.wall_s},
            "projection": proj, "cheapest_as_accurate": cheapest,
            "speedup": paper.wall_s / cheapest["wall_s"] if cheapest else None, "paper_eps_to_0": limit}


def per_step(n, repeats):
    scene = study.example1_scene(n)
    times = {"paper": [], "projection": []}
    for _ in range(repeats):
        for scheme in times:  # alternate, so that a slow spell of the machine hits both
            t0 = time.perf_counter()
            res = sc.simulate(scene, scheme=scheme, comm=MPI.COMM_SELF)
            times[scheme].append((time.perf_counter() - t0, res.timings["solve"]))
    out = {k: 1e6 * float(np.median([s for _, s in v])) / scene.nt for k, v in times.items()}
    print(f"per step at nx={n}: " + ", ".join(f"{k} {v:.1f} us" for k, v in out.items())
          + f"  (ratio projection/paper {out['projection'] / out['paper']:.2f})")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="benchmarks/out/schemes.json")
    args = ap.parse_args()
    study.warm_up()
    q = args.quick
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "flat_landing": flat_landing((125, 250, 500) if q else (500, 1000, 2000, 4000)),
        "energy_split": energy_split(5000),  # the paper's resolution: its explicit run needs Δt ≤ ε
        "accuracy_per_cost": accuracy_per_cost(5000, (250, 500) if q else (250, 500, 1000),
                                               2000 if q else 16000, (250, 500) if q else (1000, 2000, 4000, 8000)),
        "per_step": per_step(5000, 3 if q else 7),
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
