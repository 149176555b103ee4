"""The studies' methods, test problems and scene factories, one study run (`run_method`: a `Run` on this rank), and
a sweep's cases dealt over the ranks of ``mpirun -n K stringcontact study ...`` (`distribute`)."""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

import stringcontact as sc

from ..verification.exact import flat_landing

#: ε standing for the limit ε → 0 (the semi-implicit penalty is unconditionally stable, so any tiny ε works).
EPS_LIMIT = 1e-9
#: The paper's ε (Section 6).
EPS_PAPER = 5e-4
#: Flat landing (exact α = 0 solution): ends at h, η0 = h, v0 = −V, landing at t* = h/V.
FLAT_H, FLAT_V = 0.2, 1.0


@dataclass(frozen=True)
class Method:
    """A scheme, a penalty, a mass and a rule for ε: "fixed" (the scene's), "dt" (ε = Δt), "limit" (ε → 0), "none"."""

    name: str
    label: str
    penalty: str | None
    mass: str
    eps_rule: str
    scheme: str = "paper"

    def eps(self, scene_eps: float, dt: float) -> float:
        """The run's ε by the rule, from the scene's ε and the run's Δt."""
        return {"fixed": scene_eps, "dt": dt, "limit": EPS_LIMIT, "none": scene_eps}[self.eps_rule]


METHODS = {m.name: m for m in (
    Method("paper", "paper: explicit, lumped, ε = 5e-4", "explicit", "lumped", "fixed"),
    Method("explicit-r1", "explicit, lumped, ε = Δt (r = 1)", "explicit", "lumped", "dt"),
    Method("semi-implicit", "semi-implicit, lumped, ε → 0", "semi-implicit", "lumped", "limit"),
    Method("consistent", "semi-implicit, consistent mass, ε → 0", "semi-implicit", "consistent", "limit"),
    Method("projection", "projection (no ε), lumped", None, "lumped", "none", scheme="projection"),
    Method("newmark", "newmark, semi-implicit, lumped, ε → 0", "semi-implicit", "lumped", "limit", scheme="newmark"))}
#: The reference of the problems without an exact solution, at reference_n: the most accurate scheme (study.md).
REFERENCE = Method("reference", "reference: projection, lumped", None, "lumped", "none", scheme="projection")


def flat_landing_scene(n: int, nt: int | None = None, *, eps: float | None = None, r: float | None = None,
                       T: float = 0.6, alpha: float = 0.0):
    """The exact case (`verification.exact.flat_landing`): l = 1, ends at h = 0.2, η0 = 0.2, v0 = −1, Δt = Δx = 1/n
    unless `nt` is given; ε is `eps` (default 5e-4), or Δt/`r`."""
    if eps is not None and r is not None:
        raise ValueError("flat_landing_scene: give eps or r = dt/eps, not both")
    nt = nt if nt is not None else max(1, round(T * n))
    eps = T / nt / r if r is not None else EPS_PAPER if eps is None else eps
    return sc.load_scene("example1").replace(
        name="flat-landing", description="flat string landing on the obstacle (exact alpha = 0 solution)", notes="",
        eta0=str(FLAT_H), v0=str(-FLAT_V), alpha=alpha, eps=eps, T=T, nx=n, nt=nt, output_times=[])


def example1_scene(n: int, *, eps: float = EPS_PAPER, T: float = 0.3):
    """The paper's Example 1 with Δt = Δx = 1/n (n = 5000 is the paper's resolution)."""
    return sc.load_scene("example1").replace(T=T, eps=eps, nx=n, nt=max(1, round(T * n)), output_times=[])


@dataclass(frozen=True)
class Problem:
    """A test problem: scenes at Δt = Δx = 1/n, and either an exact solution or a fine reference resolution."""

    name: str
    T: float
    sizes: tuple[int, ...]
    reference_n: int | None = None  # None: exact solution

    def scene(self, n: int, eps: float = EPS_PAPER):
        """The problem's scene at Δt = Δx = 1/n."""
        return (flat_landing_scene if self.name == "flat-landing" else example1_scene)(n, eps=eps, T=self.T)

    @property
    def rows(self) -> int:
        """Stored rows per run: every step of the coarsest run, so that all runs share the stored times."""
        return max(1, round(self.T * min(self.sizes)))


def problems(quick: bool = False) -> dict[str, Problem]:
    """The two work-precision problems; `quick` shrinks them for tests and fast demos."""
    if quick:
        return {"flat-landing": Problem("flat-landing", 0.6, (125, 250, 500)),
                "example1": Problem("example1", 0.06, (250, 500), reference_n=2000)}
    return {"flat-landing": Problem("flat-landing", 0.6, (125, 250, 500, 1000, 2000, 4000)),
            "example1": Problem("example1", 0.3, (250, 500, 1000, 2000, 4000), reference_n=16000)}


def flat_landing_exact(t, x):
    """(η, η_t) of the exact flat landing at times t and points x (`verification.exact.flat_landing`)."""
    return flat_landing(t, x, h=FLAT_H, V=FLAT_V, length=1.0)


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
    """`simulate(scene, **kwargs)` on COMM_SELF without instability warnings (an `InstabilityError` still raises)."""
    from mpi4py import MPI

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sc.InstabilityWarning)
        return sc.simulate(scene, comm=MPI.COMM_SELF, **kwargs)


def run_method(scene, method: Method, *, rows: int = 400, repeat: int = 1, model=None) -> Run:
    """Simulate `scene` with `method` on COMM_SELF; the wall time is the best of `repeat` calls of `simulate`."""
    scene = scene.replace(eps=method.eps(scene.eps, scene.dt))
    common = {"problem": scene.name, "method": method.name, "penalty": method.penalty or "none", "mass": method.mass,
              "nx": scene.nx, "nt": scene.nt, "dt": scene.dt, "eps": scene.eps if method.penalty else math.inf}
    best, res = math.inf, None
    for _ in range(repeat):
        try:
            t0 = time.perf_counter()
            res = simulate_self(scene, scheme=method.scheme, penalty=method.penalty, mass=method.mass, model=model,
                                 storage=sc.Storage(max_rows=rows))
            best = min(best, time.perf_counter() - t0)
        except sc.InstabilityError as exc:
            return Run(**common, status="refused" if exc.step == 0 else "unstable", wall_s=math.nan)
    return Run(**common, status="complete", wall_s=best, min_eta=res.min_eta, t=res.t, x=res.x, eta=res.eta,
               velocity_T=res.velocity[-1])


def warm_up():
    """Compile the forms once per process, so that the first timed run does not pay for it."""
    run_method(flat_landing_scene(8, nt=4), METHODS["semi-implicit"], rows=4)


def distribute(function, cases: list, comm=None, cost=None, busy: list | None = None) -> list | None:
    """`[function(c) for c in cases]` dealt over `comm`'s ranks, largest `cost` first to the least loaded rank: the
    list on rank 0, None elsewhere; each rank's CPU seconds appended to `busy` on rank 0, if given."""
    t0 = time.process_time()
    if comm is None or comm.size == 1:
        out = [function(c) for c in cases]
        if busy is not None:
            busy.append(time.process_time() - t0)
        return out
    weight = cost or (lambda case: 1.0)
    load, mine = [0.0] * comm.size, []
    for i in sorted(range(len(cases)), key=lambda i: -weight(cases[i])):
        rank = int(np.argmin(load))
        load[rank] += weight(cases[i])
        mine += [i] if rank == comm.rank else []
    done = [(i, function(cases[i])) for i in mine]
    cpu = time.process_time() - t0
    # wait asleep, not in MPI's busy poll, which steals the CPU of the ranks still working
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(0.005)
    gathered = comm.gather((cpu, done), root=0)
    if comm.rank != 0:
        return None
    if busy is not None:
        busy.extend(seconds for seconds, _ in gathered)
    out = dict(pair for _, part in gathered for pair in part)
    return [out[i] for i in range(len(cases))]
