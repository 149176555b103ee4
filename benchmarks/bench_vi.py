"""The Newton path's contact step on stiff landings: which SNES set-up converges at Δt, in how many iterations
(docs/explanation/performance.md, "The nonlinear contact step").

    .venv/bin/python benchmarks/bench_vi.py            # all methods on all scenes (a few minutes)
    .venv/bin/python benchmarks/bench_vi.py --quick    # the cubic landing at nx = 500 and film_landing at nt = 600

Each method changes one thing against PETSc's own set-up of the VI (``vinewtonrsls``, its zero tolerance 1e-8,
line search ``bt``, no second try): the VI's zero tolerance (`newton.VI_DEFAULTS`), the semismooth method, the line
search (as a scene's ``petsc_options``: it replaces a model's own, the film's ``l2``), a fresh Jacobian at every
iteration, and the second try with the other line search (`newton.RESCUE_LINE_SEARCH`). The last row is the
package's set-up. Scenes: the user's cubic foundation k3 = 20 thrown onto the obstacle under ``projection``
(tests/timestepping/test_stiff_landings.py) at nx = 500 and 1000, Δt = Δx; ``large_deflection`` on Example 1's throw
under ``projection`` (nx = 500, nt = 300); ``film_landing`` (the paper's scheme, plain Newton: the VI settings do
not touch it) at nt = 600 and its own nt = 1200.

Printed per method and scene: Newton iterations (all SNES solves, a failed one's included), failed SNES solves, the
steps taken in sub-steps after a failure (the stepper's), and the most iterations one step took. No clock: the
counts are the solver's own.
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

import ufl

import stringcontact as sc
from stringcontact.timestepping import newton

K3 = 20.0


def _cubic_form(eta, eta_t, eta_tt, force, w, p):
    return sc.inelastic.momentum_form(eta, eta_t, eta_tt, force, w, p) + K3 * eta**3 * w * ufl.dx


def _cubic_energy(eta, p):
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + K3 / 4 * eta**4


CUBIC = dataclasses.replace(sc.inelastic, name="cubic20", momentum_form=_cubic_form, stored_energy=_cubic_energy)


def _cubic(nx):
    scene = sc.load_scene("example1").replace(
        nx=nx, alpha=0.02, eta0="1 + 0.3*sin(pi*x)", v0="-3*sin(2*pi*x)", h=1.0, T=1.0, dt=1.0 / nx, output_times=[]
    )
    return scene, {"scheme": "projection", "model": CUBIC}


def _film(nt):
    scene = sc.load_scene("film_landing")
    return (scene.replace(nt=nt) if nt else scene), {}


SCENES = {
    "cubic nx=500": lambda: _cubic(500),
    "cubic nx=1000": lambda: _cubic(1000),
    "large_deflection": lambda: (
        sc.load_scene("example1").replace(nx=500, nt=300),
        {"scheme": "projection", "model": "large_deflection"},
    ),
    "film nt=600": lambda: _film(600),
    "film nt=1200": lambda: _film(0),
}
QUICK = ("cubic nx=500", "film nt=600")

#: name -> (VI_DEFAULTS, RESCUE_LINE_SEARCH, petsc_options, reuse_jacobian)
PETSC_VI = ({}, {}, None, True)
METHODS = {
    "rsls, PETSc's set-up (zero tol 1e-8, bt)": PETSC_VI,
    "rsls, zero tol 1e-12": ({"snes_vi_zero_tolerance": 1e-12}, {}, None, True),
    "rsls, line search bt": ({}, {}, {"snes_linesearch_type": "bt"}, True),
    "rsls, line search basic": ({}, {}, {"snes_linesearch_type": "basic"}, True),
    "rsls, line search l2": ({}, {}, {"snes_linesearch_type": "l2"}, True),
    "rsls, line search cp": ({}, {}, {"snes_linesearch_type": "cp"}, True),
    "rsls, fresh J every iteration": ({}, {}, None, False),
    "ssls (semismooth)": ({"snes_type": "vinewtonssls"}, {}, None, True),
    "rsls, zero tol 0": ({"snes_vi_zero_tolerance": 0.0}, {}, None, True),
    "rsls, zero tol 0, other line search on failure (package)": (
        dict(newton.VI_DEFAULTS),
        dict(newton.RESCUE_LINE_SEARCH),
        None,
        True,
    ),
}


def measure(scene_name: str, method: str) -> dict:
    """One run: the counts of the table's row."""
    vi, rescue, options, reuse = METHODS[method]
    saved = newton.VI_DEFAULTS, newton.RESCUE_LINE_SEARCH, newton.NewtonStep.reuse_jacobian, newton.NewtonStep._run
    failed, most = [0], [0]
    run = newton.NewtonStep._run

    def counted(self, snes, guess, **kw):
        reason = run(self, snes, guess, **kw)
        failed[0] += reason < 0
        most[0] = max(most[0], snes.getIterationNumber())
        return reason

    newton.VI_DEFAULTS, newton.RESCUE_LINE_SEARCH, newton.NewtonStep.reuse_jacobian = vi, rescue, reuse
    newton.NewtonStep._run = counted
    try:
        scene, kw = SCENES[scene_name]()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = sc.simulate(scene, storage=sc.Storage(max_rows=4), petsc_options=options, **kw)
    finally:
        (newton.VI_DEFAULTS, newton.RESCUE_LINE_SEARCH, newton.NewtonStep.reuse_jacobian, newton.NewtonStep._run) = (
            saved
        )
    return {
        "status": r.status,
        "iterations": r.counters.get("newton iterations", 0),
        "failed": failed[0],
        "sub-stepped": r.counters.get("sub-stepped steps", 0),
        "most": most[0],
        "steps": scene.nt,
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the cubic landing at nx = 500 and the film at nt = 600")
    parser.add_argument("--scenes", nargs="*", choices=list(SCENES), help="these scenes only")
    args = parser.parse_args(argv)
    scenes = args.scenes or (QUICK if args.quick else tuple(SCENES))
    print("Newton iterations / failed SNES solves / sub-stepped steps / most iterations in one step")
    print("| method | " + " | ".join(scenes) + " |")
    print("| --- |" + " --- |" * len(scenes))
    for method in METHODS:
        cells = []
        for name in scenes:
            m = measure(name, method)
            cell = f"{m['iterations']} / {m['failed']} / {m['sub-stepped']} / {m['most']}"
            cells.append(cell if m["status"] == "complete" else f"{cell} ({m['status']})")
        print(f"| {method} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
