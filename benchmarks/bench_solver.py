"""Speed and memory of `stringcontact.simulate` against a hand-written NumPy/SciPy peer.

The peer (`peers.paper_peer`, benchmarks/peers.py) is the paper's Section 6 scheme as a researcher would
write it for Example 1: the finite-difference form of the lumped scheme, a tridiagonal matrix factorised once with
`scipy.sparse.linalg.splu`, a vectorised right-hand side, the explicit velocity penalty, and the
same stored rows as `simulate`. It computes no energies; `simulate` computes the full discrete
energy balance and the energy guard at every step.

Both are run in the same process, alternating, and the median of several runs is reported. Before
timing, both must agree in η at every stored row: to 1e-10 up to N = 1000; above, where the step
matrix's conditioning (∝ N²) amplifies round-off beyond 1e-10, to 1e-10·4·r(N)/r(1000) (`tolerance`).
The table also shows the round-off floor: how far two NumPy codes of the scheme (the peer with splu
and `stringcontact.verification.reference` with LAPACK's banded solver) drift apart by round-off alone.
Peak memory is measured in a fresh subprocess per configuration (`ru_maxrss`), so each row has its own peak.

    .venv/bin/python benchmarks/bench_solver.py               # the full table (a few minutes)
    .venv/bin/python benchmarks/bench_solver.py --quick       # N = 1000, 5000 only
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time

import numpy as np
from peers import paper_peer, step_conditioning


def tolerance(scene) -> float:
    """1e-10 up to N = 1000; above, 1e-10 scaled with the conditioning r(N)/r(1000), times a margin of 4.

    The FEM form of the scheme (scaled by 1/Δt²) and the FD peer (scaled by Δt²) are the same equations
    in a different order of floating-point operations; their round-off, amplified by the step matrix's
    conditioning and accumulated over the steps, exceeds 1e-10 above N ≈ 1000 (see the floor column:
    two FD codes of the scheme already differ by 1e-9 at N = 5000).
    """
    if scene.nx <= 1000:
        return 1e-10
    return 4e-10 * step_conditioning(scene) / step_conditioning(scene.replace(nx=1000))


def round_off_floor(scene, peer_final) -> float:
    """How far two NumPy codes of the same scheme drift apart by round-off alone: the peer (splu) against
    `stringcontact.verification.reference` (LAPACK banded solve), at the last step. Above N ≈ 1000 the scheme's
    conditioning (r = (αΔt + Δt²)/Δx² grows like N²) lifts this above 1e-10."""
    from stringcontact.verification import reference

    x = np.linspace(0.0, scene.length, scene.nx + 1)
    _, ref, _ = reference.fd_solve(
        scene.initial_displacement(x),
        scene.initial_velocity(x),
        length=scene.length,
        T=scene.T,
        nt=scene.nt,
        alpha=scene.alpha,
        eps=scene.eps,
        h_left=scene.h_left,
        h_right=scene.h_right,
        store_every=scene.nt,
    )
    return float(np.max(np.abs(ref[-1] - peer_final)))


def _scene(N: int, nt: int, dt: float = 2e-4):
    import stringcontact as sc

    return sc.load_scene("example1").replace(nx=N, nt=nt, T=nt * dt, output_times=[])


def compare(N: int, nt: int, repeats: int) -> dict:
    """Agreement check, then alternating timed runs of `simulate` and the peer; medians."""
    import stringcontact as sc

    scene = _scene(N, nt)
    res = sc.simulate(scene)
    peer_eta, _ = paper_peer(scene, res.steps)
    diff = float(np.max(np.abs(res.eta - peer_eta)))
    floor = round_off_floor(scene, peer_eta[-1])
    tol = tolerance(scene)
    if not diff <= tol:
        raise SystemExit(f"N={N}: simulate and the NumPy peer differ by {diff:.3g} > {tol:.3g}; not timing")
    t_sc, t_peer, t_loop = [], [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = sc.simulate(scene)
        t_sc.append(time.perf_counter() - t0)
        t_loop.append(r.timings["solve"])
        t0 = time.perf_counter()
        paper_peer(scene, r.steps)
        t_peer.append(time.perf_counter() - t0)
    med = statistics.median
    return {
        "N": N,
        "steps": nt,
        "diff": diff,
        "floor": floor,
        "tol": tol,
        "simulate": med(t_sc),
        "loop": med(t_loop),
        "peer": med(t_peer),
        "ratios": [a / b for a, b in zip(t_sc, t_peer)],
    }


def semi_vs_explicit(N: int, nt: int, repeats: int) -> dict:
    import stringcontact as sc

    scene = _scene(N, nt)
    times = {"explicit": [], "semi-implicit": []}
    refac = 0
    for _ in range(repeats):
        for penalty, spent in times.items():
            r = sc.simulate(scene, penalty=penalty)
            spent.append(r.timings["solve"])
            refac = r.counters.get("refactorisations", refac)
    med = {k: statistics.median(v) for k, v in times.items()}
    return {"N": N, "steps": nt, **med, "refactorisations": refac}


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def child(spec: dict) -> dict:
    """One configuration in a fresh process, so that ru_maxrss is its own peak."""
    import stringcontact as sc

    if spec["kind"] == "compare":
        out = compare(spec["N"], spec["nt"], spec["repeats"])
    elif spec["kind"] == "semi":
        out = semi_vs_explicit(spec["N"], spec["nt"], spec["repeats"])
    else:  # memory of Example 1 as printed, with more steps at the same Δt
        scene = sc.load_scene("example1")
        scene = scene.replace(nt=scene.nt * spec["factor"], T=scene.T * spec["factor"])
        t0 = time.perf_counter()
        res = sc.simulate(scene)
        out = {"nt": scene.nt, "rows": len(res.t), "time": time.perf_counter() - t0}
    out["peak_rss_mb"] = peak_rss_mb()
    return out


def run_child(spec: dict) -> dict:
    proc = subprocess.run(
        [sys.executable, __file__, "--child", json.dumps(spec)], capture_output=True, text=True, check=False
    )
    if proc.returncode != 0:
        raise SystemExit(proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else f"child failed: {spec}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="N = 1000, 5000 only, fewer repeats")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per configuration (median)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(json.loads(args.child))))
        return 0

    Ns = (1000, 5000) if args.quick else (1000, 5000, 20000, 80000)
    nt = 1500
    print(
        "Example 1 (explicit penalty, lumped mass), dt = 2e-4, 1500 steps; medians of "
        f"{args.repeats} alternating runs; agreement with the peer checked first\n"
    )
    print(
        "| N | steps | stringcontact [s] | NumPy peer [s] | ratio | µs/step (loop) | µs/step/1000 nodes | peak RSS [MB] | max |Δη| vs peer | tolerance | round-off floor |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for N in Ns:
        reps = args.repeats if N <= 20000 else max(3, args.repeats // 2)
        o = run_child({"kind": "compare", "N": N, "nt": nt, "repeats": reps})
        us = o["loop"] / nt * 1e6
        print(
            f"| {N} | {nt} | {o['simulate']:.3f} | {o['peer']:.3f} | {statistics.median(o['ratios']):.2f} | "
            f"{us:.0f} | {us / (N / 1000):.1f} | {o['peak_rss_mb']:.0f} | {o['diff']:.1e} | {o['tol']:.0e} | {o['floor']:.1e} |",
            flush=True,
        )

    print("\nPeak memory of Example 1 (N = 5000, Δt = 2e-4) as the number of steps grows (storage is thinned):\n")
    print("| steps | stored rows | time [s] | peak RSS [MB] |")
    print("|---:|---:|---:|---:|")
    for factor in (1, 2, 4) if args.quick else (1, 2, 4, 8):
        o = run_child({"kind": "memory", "factor": factor})
        print(f"| {o['nt']} | {o['rows']} | {o['time']:.2f} | {o['peak_rss_mb']:.0f} |", flush=True)

    o = run_child({"kind": "semi", "N": 5000, "nt": nt, "repeats": args.repeats})
    print("\nSemi-implicit against explicit penalty, Example 1, N = 5000, 1500 steps (time loop only):\n")
    print("| explicit [s] | semi-implicit [s] | ratio | refactorisations |")
    print("|---:|---:|---:|---:|")
    print(
        f"| {o['explicit']:.3f} | {o['semi-implicit']:.3f} | {o['semi-implicit'] / o['explicit']:.2f} | {o['refactorisations']} |"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
