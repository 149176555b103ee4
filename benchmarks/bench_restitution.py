"""Scheme projection with a restitution coefficient e: the numbers of docs/explanation/restitution.md.

    .venv/bin/python benchmarks/bench_restitution.py            # about a minute
    .venv/bin/python benchmarks/bench_restitution.py --quick    # coarser grids

Prints three tables (markdown):

1. the flat landing (α = 0, η0 = h = 0.2, v0 = −1, Δt = 0.8 Δx) against its exact solution
   (`verification.exact.flat_landing(..., restitution=e)`) at t = 1, inside the window t ≤ l + 3h/V = 1.6:
   the RMS nodal error of η, the middle's velocity at t = 0.3 (exact: e V), and the contact work over the
   landing part's kinetic energy ½V²(l − 2h/V) (exact: 1 − e²);
2. what viscosity does: the same landing with α = 0, 0.001, 0.01 to T = 1.6: the middle's velocity at
   t = 0.4 and the contact and viscous dissipation;
3. Example 1's throw with e = 1 to T = 2.4 (eight times the paper's T, about one period of the string), with
   α = 0.01 and α = 0: E(T)/E(0), the contact work and the viscous dissipation over E(0).

No assertion: the tests are in tests/timestepping/test_restitution.py.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings

import numpy as np

H, V, L = 0.2, 1.0, 1.0


def _simulate(scene, e):
    import stringcontact as sc

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, scheme="projection", restitution=e, storage=sc.Storage(max_rows=scene.nt))


def landing_table(sizes) -> None:
    from stringcontact.analysis.problems import flat_landing_scene
    from stringcontact.verification import exact

    print("| e | " + " | ".join(f"error, nx = {n}" for n in sizes) + " | order | v(0.5, 0.3) / V | contact work / "
          f"landing energy (nx = {sizes[-1]}) | 1 − e² |")
    print("|---:|" + "---:|" * (len(sizes) + 4))
    for e in (0.0, 0.25, 0.5, 1.0):
        errors = []
        for n in sizes:
            res = _simulate(flat_landing_scene(n, round(1.25 * n), T=1.0), e)
            eta, _ = exact.flat_landing(res.t[-1], res.x, h=H, V=V, length=L, restitution=e)
            errors.append(float(np.sqrt(np.mean((res.eta[-1] - eta) ** 2))))
        order = math.log(errors[0] / errors[-1]) / math.log(sizes[-1] / sizes[0])
        speed = res.velocity[int(np.argmin(np.abs(res.t - 0.3))), res.x.size // 2] / V
        work = res.energy["contact_dissipation"][-1] / exact.flat_landing_energy_loss(H, V, L)
        print(f"| {e:g} | " + " | ".join(f"{x:.2e}" for x in errors) + f" | {order:.2f} | {speed:.4f} | {work:.4f} | "
              f"{1 - e * e:.4f} |")
    print()


def viscous_table(sizes) -> None:
    from stringcontact.analysis.problems import flat_landing_scene

    print("| α | e | nx | v(0.5, 0.4) / (e V) | contact work | viscous dissipation |")
    print("|---:|---:|---:|---:|---:|---:|")
    for alpha in (0.0, 0.001, 0.01):
        for e in (0.5, 1.0):
            for n in sizes:
                res = _simulate(flat_landing_scene(n, round(1.6 * 1.25 * n), T=1.6, alpha=alpha), e)
                speed = res.velocity[int(np.argmin(np.abs(res.t - 0.4))), res.x.size // 2] / (e * V)
                en = res.energy
                print(f"| {alpha:g} | {e:g} | {n} | {speed:.4f} | {en['contact_dissipation'][-1]:.4f} | "
                      f"{en['viscous_dissipation'][-1]:.4f} |")
    print()


def throw_table(sizes) -> None:
    from stringcontact.analysis import study

    print("| α | nx | Δt | E(T)/E(0) | contact work / E(0) | viscous / E(0) | min η |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for alpha in (0.01, 0.0):
        for n in sizes:
            scene = study.example1_scene(n)
            scene = scene.replace(T=8 * scene.T, nt=8 * scene.nt, output_times=[], alpha=alpha)
            res = _simulate(scene, 1.0)
            E0, en = res.total_energy[0], res.energy
            print(f"| {alpha:g} | {n} | {scene.dt:.3g} | {res.total_energy[-1] / E0:.4f} | "
                  f"{en['contact_dissipation'][-1] / E0:+.4f} | {en['viscous_dissipation'][-1] / E0:.4f} | "
                  f"{res.min_eta:.2e} |")
    print()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="coarser grids")
    args = ap.parse_args(argv)
    landing_table((50, 100, 200) if args.quick else (100, 200, 400, 800))
    viscous_table((100, 200) if args.quick else (200, 400, 800, 1600))
    throw_table((250, 500) if args.quick else (500, 1000, 2000, 4000))
    return 0


if __name__ == "__main__":
    sys.exit(main())
