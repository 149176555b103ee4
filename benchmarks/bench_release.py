"""What Signorini's release (`Model.release = "signorini"`: a resting node is massless) does where the contact is not a
point: the exact flat landing and Example 1, against the paper's release.

    .venv/bin/python benchmarks/bench_release.py

Prints, for scheme `projection` at Δt = Δx: the flat landing's RMS error at t = 1 against the exact solution
(`verification.exact.flat_landing`) at nx = 200 under each release; Example 1's (α = 0.01) RMS difference at T from an
nx = 2000 run of the same release at nx = 250, 500, 1000; and each run's largest E(t)/E(0) and least contact
dissipation over E(0) (the contact account: both are at most 1 and at least 0).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

import stringcontact as sc
from stringcontact.analysis.problems import flat_landing_scene
from stringcontact.verification import exact


def run(scene, release: str):
    model = dataclasses.replace(sc.inelastic, release=release)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, scheme="projection", model=model)


def energy(res) -> str:
    E, D = res.total_energy, res.energy["contact_dissipation"]
    return f"max E/E(0) {E.max() / E[0]:.12f}, min D_con/E(0) {D.min() / E[0]:.2e}"


def main() -> None:
    for release in ("inelastic", "signorini"):
        scene = flat_landing_scene(200, 200, T=1.0)
        res = run(scene, release)
        eta, _ = exact.flat_landing(res.t[-1], res.x)
        print(f"flat landing, release {release}: RMS error at t = 1 {np.sqrt(np.mean((res.eta[-1] - eta) ** 2)):.3e}; "
              f"{energy(res)}")
    base = sc.load_scene("example1")
    for release in ("inelastic", "signorini"):
        fine = run(base.replace(nx=2000, nt=round(base.T * 2000)), release)
        diffs = []
        for nx in (250, 500, 1000):
            res = run(base.replace(nx=nx, nt=round(base.T * nx)), release)
            diffs.append(np.sqrt(np.mean((res.eta[-1] - np.interp(res.x, fine.x, fine.eta[-1])) ** 2)))
            print(f"example1 nx = {nx}, release {release}: {energy(res)}")
        print(f"example1, release {release}: RMS difference at T from nx = 2000: "
              + " / ".join(f"{d:.2e}" for d in diffs) + " at nx = 250 / 500 / 1000")


if __name__ == "__main__":
    main()
