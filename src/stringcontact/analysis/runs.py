"""One run of a study: `run_method` simulates a scene with a `Method` on this rank alone (`Run`)."""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

import stringcontact as sc
from .problems import METHODS, Method, flat_landing_scene


@dataclass
class Run:
    """One simulation of a study: its settings, outcome, cost and the stored arrays needed for the errors."""

    problem: str
    method: str
    penalty: str
    mass: str
    nx: int
    nt: int
    dt: float
    eps: float
    status: str  # "complete", "unstable" (the running guard fired) or "refused" (r >= 2, explicit)
    wall_s: float
    min_eta: float = math.nan
    t: np.ndarray | None = None
    x: np.ndarray | None = None
    eta: np.ndarray | None = None
    velocity_T: np.ndarray | None = None

    @property
    def r(self) -> float:
        """r = Δt/ε."""
        return self.dt / self.eps


def simulate_self(scene, **kwargs):
    """`simulate(scene, **kwargs)` on COMM_SELF without its instability warnings (a study records the outcome);
    an `InstabilityError` still raises."""
    from mpi4py import MPI

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sc.InstabilityWarning)
        return sc.simulate(scene, comm=MPI.COMM_SELF, **kwargs)


def run_method(scene, method: Method, *, rows: int = 400, repeat: int = 1, model=None) -> Run:
    """Simulate `scene` with `method` on COMM_SELF; the wall time is the best of `repeat` calls of `simulate`."""
    scene = scene.replace(eps=method.eps(scene.eps, scene.dt))
    common = dict(problem=scene.name, method=method.name, penalty=method.penalty or "none", mass=method.mass,
                  nx=scene.nx, nt=scene.nt, dt=scene.dt, eps=scene.eps if method.penalty else math.inf)
    best, res = math.inf, None
    for _ in range(repeat):
        try:
            t0 = time.perf_counter()
            res = simulate_self(scene, scheme=method.scheme, penalty=method.penalty, mass=method.mass, model=model,
                                 max_rows=rows)
            best = min(best, time.perf_counter() - t0)
        except sc.InstabilityError as exc:
            status = "refused" if exc.step == 0 else "unstable"
            return Run(**common, status=status, wall_s=math.nan)
    return Run(**common, status="complete", wall_s=best, min_eta=res.min_eta, t=res.t, x=res.x, eta=res.eta,
               velocity_T=res.velocity[-1])


def warm_up():
    """Compile the forms once per process, so the first timed run does not pay for it (one run warms every
    method: the forms depend on neither the mass nor the penalty)."""
    run_method(flat_landing_scene(8, nt=4), METHODS["semi-implicit"], rows=4)
