"""``run SCENE --tol X``: the cheapest method and resolution whose estimated error of η is below X, and how well the
estimate tracks the true error (`tolerance_tracking`)."""

from __future__ import annotations

import math
import time

from .convergence import errors_against_exact, errors_against_reference
from .problems import METHODS, Run, flat_landing_exact, flat_landing_scene, run_method

#: The methods that converge to the inelastic limit, cheapest first, and their observed L∞(L²) orders of η on the
#: flat landing (docs/explanation/study.md; not the explicit penalty, which a point contact sinks: getfem.md).
TOL_METHODS = ("projection", "semi-implicit", "newmark")
TOL_ORDER = {"projection": 1.0, "semi-implicit": 0.5, "newmark": 0.5}
#: A method stops refining when its extrapolated floor is above REACH_MARGIN * tol: coarse pilots' floors are a few
#: times too pessimistic (benchmarks/bench_tolerance_reach.py).
REACH_MARGIN = 100.0
#: The finest pilot: the last doubling of 50 below the scene's limit nx <= 1e5.
NX_MAX = 64000
TOLERANCE_COLUMNS = ("tol", "method", "nx", "nt", "estimate", "true_error", "ratio", "pilot_wall_s")


def _scaled(scene, nx: int):
    """The scene at `nx` cells, keeping its ratio Δt/Δx."""
    return scene.replace(nx=nx, nt=max(1, round(scene.nt * nx / scene.nx)))


def richardson_estimate(coarse: Run, fine: Run, order: float) -> float:
    """Error of `fine` in L∞(0,T;L²) of η: ‖η_fine − η_coarse‖ / (2^p − 1), p the method's observed order."""
    return errors_against_reference(coarse, fine)["err_eta"] / (2.0**order - 1.0)


def estimate_for_tolerance(scene, tol: float, *, methods=TOL_METHODS, nx_start: int = 50, nx_max: int = NX_MAX,
                           model=None) -> list[dict]:
    """Per method, the resolution doubled from `nx_start` until the two-resolution estimate is below `tol`: method, nx,
    nt, estimate, fine_wall_s, ok, floor (at `nx_max`), why ("out of reach", "dearer") and run (the finer `Run`)."""
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise ValueError(f"--tol must be a positive number (an L-infinity(0,T;L2) error of eta), got {tol}")
    found = []
    budget = math.inf  # a method that costs more than the cheapest success so far cannot win: stop refining it
    for name in methods:
        method = METHODS[name]
        lacks_damping = method.penalty == "semi-implicit" and model is not None and model.penalty_damping is None
        if lacks_damping or (model is not None and not _runs(method.scheme, model)):  # projection checks the gap
            continue  # a scheme the model refuses, or a law it needs that the model lacks, is no candidate
        coarse_scene = _scaled(scene, max(2, min(nx_start, scene.nx)))
        rows = coarse_scene.nt  # every coarse step; the finer run stores every second step, at the same times
        coarse = run_method(coarse_scene, method, rows=rows, model=model)
        while True:
            # Δx and Δt halve together, so every coarse step is a fine step.
            fine = run_method(scene.replace(nx=2 * coarse.nx, nt=2 * coarse.nt), method, rows=rows, model=model)
            if coarse.status != "complete" or fine.status != "complete":
                break
            estimate = richardson_estimate(coarse, fine, TOL_ORDER[name])
            floor = estimate * (fine.nx / nx_max) ** TOL_ORDER[name]
            ok = estimate <= tol
            why = None if ok else ("out of reach" if floor > REACH_MARGIN * tol or 2 * fine.nx > nx_max else
                                   "dearer" if fine.wall_s > budget else None)
            if why is not None or ok:
                found.append({"method": name, "nx": fine.nx, "nt": fine.nt, "estimate": estimate, "floor": floor,
                              "fine_wall_s": fine.wall_s, "ok": ok, "why": why, "run": fine})
                if ok:
                    budget = min(budget, fine.wall_s)
                break
            coarse = fine
    return found


def _runs(scheme: str, model) -> bool:
    """Whether `scheme` can run `model` (`timestepping.check_model`)."""
    from ..timestepping import check_model

    try:
        check_model(scheme, model)
    except ValueError:
        return False
    return True


def choose_for_tolerance(scene, tol: float, *, model=None):
    """`run SCENE --tol X`: the cheapest method and resolution whose estimate is below X: (scene, options, report)."""
    from mpi4py import MPI

    from ..fem.agree import one_outcome

    if scene.dim != 1:  # its pilots refine nx and its error estimates are the string's
        raise ValueError(f"--tol: 1D-only (it refines the string's nx); scene {scene.name!r} has domain {scene.domain!r}: "
                         "give its scheme (--scheme) and mesh (cells, mesh_size) instead")
    if model is None and scene.model:
        from ..model.registry import load_model

        model = load_model(scene.model)
    if model is not None and not any(_runs(METHODS[name].scheme, model) for name in TOL_METHODS):
        schemes = sorted({METHODS[name].scheme for name in TOL_METHODS})
        raise ValueError(f"--tol: model '{model.name}' runs with none of the schemes --tol chooses among "
                         f"({', '.join(schemes)}); give nx and nt (--nx, --nt) instead")
    comm = MPI.COMM_WORLD
    choice = one_outcome(comm, lambda: estimate_for_tolerance(scene, tol, model=model), root=0)
    if comm.size > 1:  # without the pilot runs' arrays
        light = comm.bcast([{k: v for k, v in c.items() if k != "run"} for c in choice or ()], root=0)
        choice = choice if comm.rank == 0 else light
    chosen, method, best = _pick(scene, tol, choice)
    others = "; ".join(f"{c['method']}: nx={c['nx']} est {c['estimate']:.3g} ({c['fine_wall_s']:.2g} s"
                       f"{'' if c['ok'] else _STOPPED[c.get('why')]})" for c in choice)
    report = (f"--tol {tol:g}: chose {method.name} ({method.label}) at nx={chosen.nx}, nt={chosen.nt}, "
              f"eps={chosen.eps:.3g}; estimated error of eta in Linf(0,T;L2) = {best['estimate']:.3g} "
              f"(two-resolution Richardson, order {TOL_ORDER[method.name]}) [{others}]")
    return chosen, {"scheme": method.scheme, "penalty": method.penalty, "mass": method.mass}, report


_STOPPED = {"dearer": ", stopped: above tol and already dearer", "out of reach": ", stopped: tol out of reach",
            None: ", stopped"}


def _pick(scene, tol: float, choice: list[dict]):
    """(scene, Method, estimate) of the cheapest run that reached `tol`; a ValueError if none did."""
    reached = [c for c in choice if c["ok"]]
    if not reached:
        best = min(choice, key=lambda c: c.get("floor", c["estimate"]), default=None)
        if best is None:
            raise ValueError(f"--tol {tol:g}: no pilot run of scene {scene.name!r} completed; give --scheme and nx instead")
        floor = best.get("floor", best["estimate"])
        raise ValueError(f"--tol {tol:g}: no method reached the tolerance, out of reach of the size limit nx <= {NX_MAX}: the pilots up to nx = {best['nx']} "
                         f"extrapolate to about {floor:.2g} at nx = {NX_MAX} ({best['method']}: estimate "
                         f"{best['estimate']:.2g} at nx = {best['nx']}, order {TOL_ORDER[best['method']]}); allowed: --tol >= "
                         f"{floor / REACH_MARGIN:.2g} ({1 / REACH_MARGIN:g} of that, the margin for coarse pilots)")
    best = min(reached, key=lambda c: c["fine_wall_s"])
    method = METHODS[best["method"]]
    chosen = scene.replace(nx=best["nx"], nt=best["nt"])
    return chosen.replace(eps=method.eps(chosen.eps, chosen.dt)), method, best


def tolerance_tracking(tols=(3e-2, 1e-2, 3e-3), T: float = 0.6) -> list[dict]:
    """On the flat landing, per tolerance: the chosen run's estimate against its true error (serial)."""
    base = flat_landing_scene(100, T=T)
    rows = []
    for tol in tols:
        t0 = time.perf_counter()
        best = _pick(base, tol, estimate_for_tolerance(base, tol))[2]
        pilot = time.perf_counter() - t0
        true = errors_against_exact(best["run"], flat_landing_exact)["err_eta"]
        rows.append({"tol": tol, "method": best["method"], "nx": best["nx"], "nt": best["nt"], "estimate":
                     best["estimate"], "true_error": true, "ratio": best["estimate"] / true, "pilot_wall_s": pilot})
    return rows
