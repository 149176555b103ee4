r"""Speed against accuracy: work-precision, convergence and stability studies, and ``run --tol``.

Three studies, each a plain function returning rows (dicts of numbers) and a chart function that draws them:

* :func:`work_precision` -- error against wall-clock time, one line per :class:`Method`, on the exact
  :math:`\alpha = 0` flat landing (:func:`stringcontact.verification.exact.flat_landing`) and on the paper's Example 1
  against a fine-grid reference;
* :func:`convergence` -- observed orders under :math:`\Delta t = \Delta x \to 0` and under
  :math:`\varepsilon \to 0` (penetration and error), and how well the ``--tol`` estimate tracks the true error;
* :func:`stability_map` / :func:`alpha_sweep` -- the outcome (inelastic, spurious rebound, energy growth) over
  :math:`r = \Delta t/\varepsilon` and :math:`\Delta t`, the measured restitution, and the sweep
  :math:`\alpha \to 0`.

Sweeps are embarrassingly parallel: :func:`distribute` deals the cases over the ranks of a communicator
(each rank runs its cases on ``MPI.COMM_SELF``) and gathers the results on rank 0, which computes the errors
and writes the CSV and PNG files. ``mpirun -n K stringcontact study ...`` uses it; serial is the default.

Errors (all on the coarse run's nodes and stored times, the reference interpolated to them):

* ``err_eta``: :math:`\max_k \|\eta_h(t_k) - \eta(t_k)\|_{L^2(0,l)}`, the :math:`L^\infty(0,T;L^2)` error;
* ``err_vel``: :math:`\|\eta_{h,t}(T) - \eta_t(T)\|_{L^2(0,l)}`;
* ``err_contact``: the space-time measure of the symmetric difference of the contact sets
  :math:`\{\eta \le 0\}` (trapezoidal in x and t).
"""

from __future__ import annotations

import contextlib
import csv
import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: ε standing for the limit ε → 0 (the semi-implicit penalty is unconditionally stable, so any tiny ε works).
EPS_LIMIT = 1e-9
#: The paper's ε (Section 6).
EPS_PAPER = 5e-4
#: Flat landing (exact α = 0 solution): ends at h, η0 = h, v0 = −V, landing at t* = h/V.
FLAT_H, FLAT_V = 0.2, 1.0
#: Contact sets in the errors are {η ≤ δ}, δ = CONTACT_HEIGHT · Δx · max|η|/l, the height a grid of size Δx
#: resolves. With δ = 0 the measure is noise: a string resting on the obstacle sits at ±round-off (landing
#: exactly at a step) or is lifted by 1e-6-sized tails of the implicit elastic solve, ahead of the real wave.
CONTACT_HEIGHT = 1.0

WORK_PRECISION_COLUMNS = (
    "problem", "method", "penalty", "mass", "nx", "nt", "dt", "eps", "r", "status",
    "wall_s", "err_eta", "err_vel", "err_contact", "min_eta",
)
CONVERGENCE_COLUMNS = ("sweep", *WORK_PRECISION_COLUMNS, "order_eta")
ORDER_COLUMNS = ("sweep", "problem", "method", "quantity", "order", "from", "to")
TOLERANCE_COLUMNS = ("tol", "method", "nx", "nt", "estimate", "true_error", "ratio", "pilot_wall_s")
STABILITY_COLUMNS = (
    "penalty", "mass", "dt", "eps", "r", "outcome", "restitution", "restitution_theory",
    "energy_max_ratio", "growth_step", "min_eta",
)
ALPHA_COLUMNS = (
    "method", "alpha", "dt", "eps", "r", "restitution", "contact_dissipation", "numerical_dissipation",
    "viscous_dissipation", "final_energy",
)


# --- methods and problems -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Method:
    """A scheme, a penalty treatment, a mass matrix and a rule for ε: "fixed" (the scene's), "dt" (ε = Δt),
    "limit" (ε → 0) or "none" (the scheme uses no ε)."""

    name: str
    label: str
    penalty: str | None
    mass: str
    eps_rule: str
    scheme: str = "paper"

    def eps(self, scene_eps: float, dt: float) -> float:
        return {"fixed": scene_eps, "dt": dt, "limit": EPS_LIMIT, "none": scene_eps}[self.eps_rule]


METHODS = {
    m.name: m
    for m in (
        Method("paper", "paper: explicit, lumped, ε = 5e-4", "explicit", "lumped", "fixed"),
        Method("explicit-r1", "explicit, lumped, ε = Δt (r = 1)", "explicit", "lumped", "dt"),
        Method("semi-implicit", "semi-implicit, lumped, ε → 0", "semi-implicit", "lumped", "limit"),
        Method("consistent", "semi-implicit, consistent mass, ε → 0", "semi-implicit", "consistent", "limit"),
        Method("projection", "projection (no ε), lumped", None, "lumped", "none", scheme="projection"),
        Method("newmark", "newmark, semi-implicit, lumped, ε → 0", "semi-implicit", "lumped", "limit", scheme="newmark"),
    )
}
#: The reference for problems with no exact solution: the most accurate scheme (docs/study.md), at reference_n.
REFERENCE = Method("reference", "reference: projection, lumped", None, "lumped", "none", scheme="projection")

#: What the studies taught `run --tol` (docs/study.md): the observed L∞(L²) order of η under Δt = Δx → 0
#: on the flat landing, for the methods that converge to the inelastic limit, cheapest first. The explicit
#: penalty is left out: at a single-point contact it cannot hold the string up (docs/getfem.md).
TOL_METHODS = ("projection", "semi-implicit", "newmark")
TOL_ORDER = {"projection": 1.0, "semi-implicit": 0.5, "newmark": 0.5}


def flat_landing_scene(n: int, *, eps: float = EPS_PAPER, T: float = 0.6, alpha: float = 0.0, nt: int | None = None):
    """The exact case: l = 1, ends at h = 0.2, η0 = 0.2, v0 = −1, Δt = Δx = 1/n unless `nt` is given."""
    import stringcontact as sc

    return sc.load_scene("example1").replace(
        name="flat-landing",
        description="flat string landing on the obstacle (exact alpha = 0 solution)",
        notes="",
        eta0=str(FLAT_H),
        v0=str(-FLAT_V),
        alpha=alpha,
        eps=eps,
        T=T,
        nx=n,
        nt=nt if nt is not None else max(1, round(T * n)),
        output_times=[],
    )


def example1_scene(n: int, *, eps: float = EPS_PAPER, T: float = 0.3):
    """The paper's Example 1 with Δt = Δx = 1/n (n = 5000 is the paper's resolution)."""
    import stringcontact as sc

    return sc.load_scene("example1").replace(T=T, eps=eps, nx=n, nt=max(1, round(T * n)), output_times=[])


@dataclass(frozen=True)
class Problem:
    """A test problem: scenes at Δt = Δx = 1/n, and either an exact solution or a fine reference resolution."""

    name: str
    T: float
    sizes: tuple[int, ...]
    reference_n: int | None = None  # None: exact solution

    def scene(self, n: int, eps: float = EPS_PAPER):
        if self.name == "flat-landing":
            return flat_landing_scene(n, eps=eps, T=self.T)
        return example1_scene(n, eps=eps, T=self.T)

    @property
    def rows(self) -> int:
        """Stored rows per run: every step of the coarsest run, so that all runs share the stored times."""
        return max(1, round(self.T * min(self.sizes)))


def problems(quick: bool = False) -> dict[str, Problem]:
    """The two work-precision problems; `quick` shrinks them for tests and fast demos."""
    if quick:
        return {
            "flat-landing": Problem("flat-landing", 0.6, (125, 250, 500)),
            "example1": Problem("example1", 0.06, (250, 500), reference_n=2000),
        }
    return {
        "flat-landing": Problem("flat-landing", 0.6, (125, 250, 500, 1000, 2000, 4000)),
        "example1": Problem("example1", 0.3, (250, 500, 1000, 2000, 4000), reference_n=16000),
    }


# --- one run ----------------------------------------------------------------------------------------------


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
        return self.dt / self.eps


def _simulate_self(scene, **kwargs):
    """`simulate(scene, **kwargs)` on COMM_SELF (this rank alone), without its instability warnings.

    A study case that goes unstable is a result, not a problem: the case records it, so the warning would
    only be noise. An `InstabilityError` (refused at the start, or stopped by the running guard) still raises.
    """
    import stringcontact as sc
    from mpi4py import MPI

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sc.InstabilityWarning)
        return sc.simulate(scene, comm=MPI.COMM_SELF, **kwargs)


def run_method(scene, method: Method, *, rows: int = 400, repeat: int = 1, model=None) -> Run:
    """Simulate `scene` with `method` on COMM_SELF; the wall time is the best of `repeat` calls of `simulate`."""
    import stringcontact as sc

    scene = scene.replace(eps=method.eps(scene.eps, scene.dt))
    common = dict(
        problem=scene.name, method=method.name, penalty=method.penalty or "none", mass=method.mass,
        nx=scene.nx, nt=scene.nt, dt=scene.dt, eps=scene.eps if method.penalty else math.inf,
    )
    best, res = math.inf, None
    for _ in range(repeat):
        try:
            t0 = time.perf_counter()
            res = _simulate_self(scene, scheme=method.scheme, penalty=method.penalty, mass=method.mass, model=model,
                                 max_rows=rows)
            best = min(best, time.perf_counter() - t0)
        except sc.InstabilityError as exc:
            status = "refused" if exc.step == 0 else "unstable"
            return Run(**common, status=status, wall_s=math.nan)
    return Run(**common, status="complete", wall_s=best, min_eta=res.min_eta, t=res.t, x=res.x, eta=res.eta,
               velocity_T=res.velocity[-1])


# --- errors -----------------------------------------------------------------------------------------------


def l2_norm(x: np.ndarray, f: np.ndarray) -> np.ndarray:
    """‖f‖_{L²(0,l)} of nodal values f (rows = times), trapezoidal."""
    from ..fem import compat

    return np.sqrt(compat.trapezoid(f**2, x, axis=-1))


def _to_nodes(x_from: np.ndarray, values: np.ndarray, x_to: np.ndarray) -> np.ndarray:
    """P1 interpolation of rows of nodal values onto other nodes."""
    values = np.atleast_2d(values)
    return np.array([np.interp(x_to, x_from, row) for row in values])


def _common_rows(t_run: np.ndarray, t_ref: np.ndarray) -> np.ndarray:
    """Indices into t_ref of the run's stored times (they must be among the reference's)."""
    idx = np.searchsorted(t_ref, t_run - 1e-12 * max(1.0, t_ref[-1]))
    idx = np.minimum(idx, t_ref.size - 1)
    if not np.allclose(t_ref[idx], t_run, rtol=0, atol=1e-9 * max(1.0, t_ref[-1])):
        raise ValueError("the run's stored times are not among the reference's: use matching rows")
    return idx


def errors_against_exact(run: Run, exact) -> dict:
    """The three errors of `run` against `exact(t, x) -> (eta, velocity)`."""
    eta, _ = exact(run.t, run.x)
    _, vel_T = exact(run.t[-1], run.x)
    return _errors(run, eta, vel_T)


def errors_against_reference(run: Run, ref: Run) -> dict:
    """The three errors of `run` against a finer run `ref` (interpolated to the run's nodes and times)."""
    rows = _common_rows(run.t, ref.t)
    eta = _to_nodes(ref.x, ref.eta[rows], run.x)
    vel_T = _to_nodes(ref.x, ref.velocity_T, run.x)[0]
    return _errors(run, eta, vel_T)


def contact_set(eta: np.ndarray, delta: float) -> np.ndarray:
    """{η ≤ δ} at every node and stored time."""
    return eta <= delta


def contact_height(run: Run) -> float:
    """δ = CONTACT_HEIGHT · Δx · max|η|/l for the run's grid."""
    length = run.x[-1] - run.x[0]
    return CONTACT_HEIGHT * (length / run.nx) * float(np.max(np.abs(run.eta[0]))) / length


def _errors(run: Run, eta: np.ndarray, vel_T: np.ndarray) -> dict:
    from ..fem import compat

    delta = contact_height(run)
    sym_diff = (contact_set(run.eta, delta) != contact_set(eta, delta)).astype(float)
    measure = compat.trapezoid(sym_diff, run.x, axis=1)
    return {
        "err_eta": float(np.max(l2_norm(run.x, run.eta - eta))),
        "err_vel": float(l2_norm(run.x, run.velocity_T - vel_T)),
        "err_contact": float(compat.trapezoid(measure, run.t)) if run.t.size > 1 else float(measure[0]),
    }


def flat_landing_exact(t, x):
    from ..verification.exact import flat_landing

    return flat_landing(t, x, h=FLAT_H, V=FLAT_V, length=1.0)


def _row(run: Run, errs: dict | None) -> dict:
    errs = errs or dict.fromkeys(("err_eta", "err_vel", "err_contact"), math.nan)
    return {
        "problem": run.problem, "method": run.method, "penalty": run.penalty, "mass": run.mass,
        "nx": run.nx, "nt": run.nt, "dt": run.dt, "eps": run.eps, "r": run.r, "status": run.status,
        "wall_s": run.wall_s, **errs, "min_eta": run.min_eta,
    }


# --- MPI distribution -------------------------------------------------------------------------------------


def distribute(function, cases: list, comm=None, cost=None, busy: list | None = None) -> list | None:
    """`[function(c) for c in cases]`, the cases dealt over `comm`'s ranks; the list on rank 0, None elsewhere.

    Cases are dealt largest `cost` first, each to the least loaded rank, so the ranks finish together. Each
    rank runs its cases itself (on COMM_SELF); only the results travel, by one gather. If `busy` is a list,
    rank 0 appends each rank's CPU seconds for its cases to it: on idle cores the sweep takes about their
    maximum, so sum/max is the speed-up that the dealing allows (the wall clock of a shared machine is noisier).
    """
    t0 = time.process_time()
    if comm is None or comm.size == 1:
        out = [function(c) for c in cases]
        if busy is not None:
            busy.append(time.process_time() - t0)
        return out
    # Longest processing time first: each case, largest first, goes to the least loaded rank so far.
    order = sorted(range(len(cases)), key=lambda i: -(cost(cases[i]) if cost else 1.0))
    load = [0.0] * comm.size
    mine = []
    for i in order:
        rank = int(np.argmin(load))
        load[rank] += cost(cases[i]) if cost else 1.0
        if rank == comm.rank:
            mine.append(i)
    done = [(i, function(cases[i])) for i in mine]
    cpu = time.process_time() - t0
    # Wait for the other ranks asleep, not in MPI's busy poll: on a shared machine the poll steals the CPU
    # that the ranks still working need.
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(0.005)
    gathered = comm.gather((cpu, done), root=0)
    if comm.rank != 0:
        return None
    out = [None] * len(cases)
    for seconds, part in gathered:
        for i, value in part:
            out[i] = value
    if busy is not None:
        busy.extend(seconds for seconds, _ in gathered)
    return out


def _warm_up():
    """Compile the forms once per process (FFCx caches them), so the first timed run does not pay for it.

    One run warms every method: the forms do not depend on the mass (lumping is the row sums of the
    assembled M) nor on the penalty (evaluated at the nodes with NumPy, `stringcontact.fem.nodal`).
    """
    run_method(flat_landing_scene(8, nt=4), METHODS["semi-implicit"], rows=4)


# --- work-precision ---------------------------------------------------------------------------------------


def work_precision(quick: bool = False, problem_names=("flat-landing", "example1"), methods=tuple(METHODS),
                   repeat: int = 1, comm=None, busy: list | None = None) -> list[dict] | None:
    """Rows of `WORK_PRECISION_COLUMNS`: every method at every size of every problem (None on ranks > 0)."""
    probs = problems(quick)
    unknown = set(problem_names) - set(probs)
    if unknown:
        raise ValueError(f"problem must be among {sorted(probs)}, not {sorted(unknown)}")
    cases = [(p, m, n) for p in problem_names for m in methods for n in probs[p].sizes]
    cases += [(p, REFERENCE.name, probs[p].reference_n) for p in problem_names if probs[p].reference_n]

    def one(case):
        p, m, n = case
        method = REFERENCE if m == REFERENCE.name else METHODS[m]
        return run_method(probs[p].scene(n), method, rows=probs[p].rows, repeat=1 if m == REFERENCE.name else repeat)

    _warm_up()
    runs = distribute(one, cases, comm, cost=lambda c: probs[c[0]].T * c[2] ** 2, busy=busy)
    if runs is None:
        return None
    refs = {run.problem: run for run in runs if run.method == REFERENCE.name}
    rows = []
    for run in runs:
        if run.method == REFERENCE.name:
            continue
        errs = None
        if run.status == "complete":
            errs = (errors_against_exact(run, flat_landing_exact) if run.problem == "flat-landing"
                    else errors_against_reference(run, refs[run.problem]))
        rows.append(_row(run, errs))
    for ref in refs.values():  # the reference itself: its cost, and no error
        rows.append(_row(ref, None))
    return rows


# --- convergence ------------------------------------------------------------------------------------------


def observed_orders(h, err) -> np.ndarray:
    """Pairwise orders log(e_i/e_{i+1}) / log(h_i/h_{i+1}); NaN where an error is missing or zero."""
    h, err = np.asarray(h, float), np.asarray(err, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log(err[:-1] / err[1:]) / np.log(h[:-1] / h[1:])


def fitted_order(h, err) -> float:
    """Least-squares slope of log err against log h over the finite, positive pairs."""
    h, err = np.asarray(h, float), np.asarray(err, float)
    ok = np.isfinite(err) & (err > 0)
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(h[ok]), np.log(err[ok]), 1)[0])


def convergence(quick: bool = False, comm=None, busy: list | None = None) -> dict | None:
    """Observed orders on the flat landing: in Δt = Δx (three methods) and in ε at a fixed grid (two penalties).

    Returns {"runs": rows of CONVERGENCE_COLUMNS, "orders": rows of ORDER_COLUMNS} on rank 0.
    """
    sizes = (125, 250, 500) if quick else (125, 250, 500, 1000, 2000, 4000, 8000)
    n_eps = 400 if quick else 4000
    eps_values = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 1e-5, 1e-6, 1e-8)
    rows_per_run = round(0.6 * min(sizes))
    cases = [("dt", m, n, None) for m in ("explicit-r1", "semi-implicit", "consistent", "projection", "newmark")
             for n in sizes]
    dt_fixed = 1.0 / n_eps
    cases += [("eps", "explicit", n_eps, e) for e in eps_values if dt_fixed / e <= 1.0]
    cases += [("eps", "semi-implicit", n_eps, e) for e in eps_values]

    def one(case):
        sweep, m, n, eps = case
        if sweep == "dt":
            return run_method(flat_landing_scene(n), METHODS[m], rows=rows_per_run)
        method = Method(f"{m}, eps", m, m, "lumped", "fixed")
        return run_method(flat_landing_scene(n, eps=eps), method, rows=rows_per_run)

    _warm_up()
    runs = distribute(one, cases, comm, cost=lambda c: c[2] ** 2, busy=busy)
    if runs is None:
        return None
    rows = []
    for (sweep, *_), run in zip(cases, runs):
        errs = errors_against_exact(run, flat_landing_exact) if run.status == "complete" else None
        rows.append({"sweep": sweep, **_row(run, errs), "order_eta": math.nan})
    orders = []
    for sweep, key, variable in (("dt", "method", "dt"), ("eps", "penalty", "eps")):
        for name in dict.fromkeys(r[key] for r in rows if r["sweep"] == sweep):
            sel = [r for r in rows if r["sweep"] == sweep and r[key] == name and r["status"] == "complete"]
            sel.sort(key=lambda r: -r[variable])
            h = [r[variable] for r in sel]
            for r, p in zip(sel[1:], observed_orders(h, [r["err_eta"] for r in sel])):
                r["order_eta"] = p
            quantities = ("err_eta", "err_vel", "err_contact") if sweep == "dt" else ("err_eta", "penetration")
            for quantity in quantities:
                # In ε, only ε ≥ 10 Δt measures the ε-error; below it the Δt-error is left.
                fit = [r for r in sel if sweep == "dt" or r["eps"] >= 10 * r["dt"]]
                values = [(-r["min_eta"] if quantity == "penetration" else r[quantity]) for r in fit]
                orders.append({"sweep": sweep, "problem": "flat-landing", "method": name, "quantity": quantity,
                               "order": fitted_order([r[variable] for r in fit], values),
                               "from": max(r[variable] for r in fit), "to": min(r[variable] for r in fit)})
    return {"runs": rows, "orders": orders}


# --- stability --------------------------------------------------------------------------------------------


STABILITY_R = (0.1, 0.3, 0.5, 0.8, 1.0, 1.2, 1.5, 1.8, 2.0, 2.5, 4.0, 10.0, 30.0, 100.0)
STABILITY_DT = (1 / 100, 1 / 200, 1 / 400)
#: A post-impact upward velocity above this fraction of the impact speed is a (spurious) rebound.
REBOUND_THRESHOLD = 0.02
#: Energy above E(0)(1 + this) at any step is growth.
GROWTH_TOLERANCE = 1e-9


def restitution(t: np.ndarray, x: np.ndarray, velocity: np.ndarray, *, h: float = FLAT_H, V: float = FLAT_V,
                window: float = 0.1) -> float:
    """Post-impact upward velocity over the impact speed V at the middle node of a flat landing.

    The flat middle lands at t* = h/V and, exactly, rests until the waves from the ends reach the middle at
    t* + (l/2 − t*); the largest upward velocity in (t*, t* + window] is the rebound.
    """
    from ..verification.exact import flat_landing_time

    mid = int(np.argmin(np.abs(x - 0.5 * (x[0] + x[-1]))))
    t_star = flat_landing_time(h, V)
    sel = (t > t_star) & (t <= t_star + window)
    if not sel.any():
        raise ValueError(f"no stored time in the restitution window ({t_star}, {t_star + window}]")
    v = velocity[sel, mid]
    if not np.all(np.isfinite(v)):
        return math.inf
    return max(0.0, float(np.max(v))) / V


def restitution_theory(r: float, penalty: str) -> float:
    """Explicit penalty: v ← (1 − r) v per contact step, so no rebound for r ≤ 1 and restitution r − 1 above."""
    return max(0.0, r - 1.0) if penalty == "explicit" else 0.0


def classify(restitution_value: float, energy: np.ndarray) -> tuple[str, int]:
    """("growth" | "rebound" | "inelastic", first step at which the energy rose above E(0), or −1)."""
    E0 = energy[0]
    bad = ~np.isfinite(energy) | (energy > E0 * (1.0 + GROWTH_TOLERANCE))
    if bad.any():
        return "growth", int(np.argmax(bad))
    if restitution_value > REBOUND_THRESHOLD:
        return "rebound", -1
    return "inelastic", -1


def fd_energy(eta: np.ndarray, velocity: np.ndarray, dx: float) -> np.ndarray:
    """Discrete energy ½|v|²_M + ½ ηᵀKη of the lumped scheme, per stored row (the solver's `total_energy`)."""
    kinetic = 0.5 * dx * np.sum(velocity[:, 1:-1] ** 2, axis=1)
    elastic = 0.5 * np.sum(np.diff(eta, axis=1) ** 2, axis=1) / dx
    return kinetic + elastic


def stability_case(penalty: str, dt: float, r: float, mass: str = "lumped", T: float = 0.45) -> dict:
    """One cell of the stability map: the flat landing (α = 0, Δx = Δt) with ε = Δt/r.

    Lumped mass runs through :func:`stringcontact.verification.reference.fd_solve` -- the same scheme as `simulate`
    (tests/test_solver.py checks this to 1e-10) without the pre-run refusal of r ≥ 2, so that the map shows
    what the explicit penalty actually does there. Consistent mass runs through `simulate`, whose guards
    refuse r ≥ 2 before the start ("refused") and stop a run whose energy rises ("growth").
    """
    from ..verification.reference import fd_solve

    n = round(1.0 / dt)
    nt = round(T / dt)
    eps = dt / r
    scene = flat_landing_scene(n, eps=eps, T=T, nt=nt)
    row = {"penalty": penalty, "mass": mass, "dt": dt, "eps": eps, "r": r,
           "restitution_theory": restitution_theory(r, penalty) if mass == "lumped" else math.nan}
    if mass == "lumped":
        x = scene.x()
        with np.errstate(all="ignore"):
            t, eta, vel = fd_solve(scene.initial_displacement(x), scene.initial_velocity(x), length=1.0, T=T, nt=nt,
                                   alpha=0.0, eps=eps, h_left=scene.h_left, h_right=scene.h_right, penalty=penalty)
            energy = fd_energy(eta, vel, 1.0 / n)
            e = restitution(t, x, vel)
        outcome, step = classify(e, energy)
        finite = np.isfinite(energy)
        row.update(outcome=outcome, restitution=e, growth_step=step,
                   energy_max_ratio=float(np.max(energy) / energy[0]) if finite.all() else math.inf,
                   min_eta=float(np.nanmin(np.where(np.isfinite(eta), eta, np.nan))))
        return row
    import stringcontact as sc

    try:
        res = _simulate_self(scene, penalty=penalty, mass=mass, max_rows=nt)
    except sc.InstabilityError as exc:
        outcome = "refused" if exc.step == 0 else "growth"
        row.update(outcome=outcome, restitution=math.nan, growth_step=exc.step, energy_max_ratio=math.nan,
                   min_eta=math.nan)
        return row
    e = restitution(res.t, res.x, res.velocity)
    energy = res.total_energy
    outcome, step = classify(e, energy)
    row.update(outcome=outcome, restitution=e, growth_step=step, energy_max_ratio=float(np.max(energy) / energy[0]),
               min_eta=res.min_eta)
    return row


def stability_map(quick: bool = False, comm=None, busy: list | None = None) -> list[dict] | None:
    """Rows of STABILITY_COLUMNS over penalty × Δt × r (and the explicit penalty with consistent mass)."""
    r_values = (0.5, 1.0, 1.5, 4.0, 100.0) if quick else STABILITY_R
    dts = (1 / 100,) if quick else STABILITY_DT
    cases = [(p, "lumped", dt, r) for p in ("explicit", "semi-implicit") for dt in dts for r in r_values]
    cases += [("explicit", "consistent", dt, r) for dt in dts for r in r_values]
    cases += [("explicit spring", "lumped", 1 / 200, 200 * q) for q in ((0.5, 64.0) if quick else SPRING_Q)]

    def one(c):
        return spring_case(c[3]) if c[0] == "explicit spring" else stability_case(c[0], c[2], c[3], mass=c[1])

    return distribute(one, cases, comm, cost=lambda c: 1 / c[2] ** 2, busy=busy)


STEP_RATIOS = (0.5, 0.9, 1.0, 1.05, 1.2, 1.5, 2.0, 4.0, 10.0)
STEP_COLUMNS = ("scheme", "alpha", "dt_over_dx", "dt_max_over_dx", "outcome", "restitution", "energy_max_ratio",
                "min_eta")
#: Δt²/ε of the explicit spring (the elastic variant) at Δt = Δx = 1/200: r = Δt/ε = 200 q.
SPRING_Q = (0.005, 0.05, 0.5, 2.0, 4.0, 6.0, 8.0, 16.0, 64.0)


def step_size_case(scheme: str, alpha: float, ratio: float, n: int = 200, T: float = 0.45) -> dict:
    """The flat landing with Δt = ratio·Δx: where the schemes without ε stop being stable.

    `projection` runs through its NumPy reference (`reference.fd_projection`, equal to `simulate` to 1e-10),
    which has no pre-run refusal, so the map shows what happens beyond Δt_max; "refused" is added where
    `simulate` would refuse. `newmark` runs through `simulate` with ε → 0.
    """
    from mpi4py import MPI

    from ..model.paper import inelastic
    from ..verification.reference import fd_projection
    from ..timestepping.projection import largest_stable_dt
    from ..run.driver import discretise

    nt = max(1, round(T * n / ratio))
    scene = flat_landing_scene(n, eps=EPS_LIMIT, T=T, nt=nt, alpha=alpha)
    ops = discretise(scene, inelastic, MPI.COMM_SELF)[2]
    interior = np.ones(ops.m.size, dtype=bool)
    interior[np.argsort(ops.m)[:2]] = False  # the ends: the two nodes with half a cell of mass
    dt_max = largest_stable_dt(ops, interior)
    row = {"scheme": scheme, "alpha": alpha, "dt_over_dx": scene.dt / scene.dx, "dt_max_over_dx": dt_max / scene.dx}
    if scheme == "projection":
        x = scene.x()
        with np.errstate(all="ignore"):
            t, eta, vel = fd_projection(scene.initial_displacement(x), scene.initial_velocity(x), length=1.0, T=T,
                                        nt=nt, alpha=alpha, h_left=scene.h_left, h_right=scene.h_right)
        energy = fd_energy(eta, vel, scene.dx)  # ½|v|² + ½|η|²_K: bounded by the modified energy when stable
        e = restitution(t, x, vel, window=max(0.1, 2 * scene.dt))
        finite = np.all(np.isfinite(energy))
        growth = not finite or np.max(energy) > 2 * energy[0]
        outcome = "growth" if growth else ("rebound" if e > REBOUND_THRESHOLD else "inelastic")
        if scene.dt > dt_max and not growth:
            outcome = "refused"  # stable here, but simulate refuses it (dt_max is a sufficient bound)
        row.update(outcome=outcome, restitution=e, energy_max_ratio=float(np.max(energy) / energy[0]) if finite
                   else math.inf, min_eta=float(np.nanmin(np.where(np.isfinite(eta), eta, np.nan))))
        return row
    res = _simulate_self(scene, scheme=scheme, max_rows=nt)
    e = restitution(res.t, res.x, res.velocity, window=max(0.1, 2 * scene.dt))
    outcome, _ = classify(e, res.total_energy)
    row.update(outcome=outcome, restitution=e, energy_max_ratio=float(np.max(res.total_energy) / res.total_energy[0]),
               min_eta=res.min_eta)
    return row


def step_size_map(quick: bool = False, comm=None, busy: list | None = None) -> list[dict] | None:
    """Rows of STEP_COLUMNS: projection and newmark over Δt/Δx, with and without viscosity."""
    ratios = (0.9, 1.0, 1.2, 4.0) if quick else STEP_RATIOS
    n = 100 if quick else 200
    cases = [(scheme, a, c) for scheme in ("projection", "newmark") for a in (0.0, 0.01) for c in ratios]
    return distribute(lambda c: step_size_case(*c, n=n), cases, comm, busy=busy)


def spring_case(r: float, n: int = 200, T: float = 0.45) -> dict:
    """The elastic (spring) law, explicit, at Δt = Δx with ε = Δt/r: its own stability (the law only warns)."""
    from ..model import variants

    scene = flat_landing_scene(n, eps=1.0 / n / r, T=T)
    row = {"penalty": "explicit spring", "mass": "lumped", "dt": scene.dt, "eps": scene.eps, "r": r,
           "restitution_theory": math.nan}
    import stringcontact as sc

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sc.InstabilityWarning)
            res = _simulate_self(scene, model=variants.elastic, max_rows=scene.nt)
    except sc.InstabilityError as exc:
        row.update(outcome="growth", restitution=math.nan, growth_step=exc.step, energy_max_ratio=math.nan,
                   min_eta=math.nan)
        return row
    e = restitution(res.t, res.x, res.velocity)
    # a spring bounces by design, after ~π√ε: growth is its only failure
    outcome = "stable"
    row.update(outcome=outcome, restitution=e, growth_step=-1,
               energy_max_ratio=float(np.max(res.total_energy) / res.total_energy[0]), min_eta=res.min_eta)
    return row


def alpha_sweep(quick: bool = False, comm=None, busy: list | None = None) -> list[dict] | None:
    """Flat landing (Δt = Δx = 1/200, T = 0.6) for α from 0.1 down to 0: restitution and where the energy went."""
    alphas = (0.1, 0.01, 0.0) if quick else (0.1, 0.03, 0.01, 0.003, 0.001, 0.0)
    methods = {"explicit r=1": ("explicit", 1.0), "explicit r=1.5": ("explicit", 1.5),
               "semi-implicit eps->0": ("semi-implicit", None)}
    n = 100 if quick else 200
    cases = [(name, a) for name in methods for a in alphas]

    def one(case):
        name, alpha = case
        penalty, r = methods[name]
        dt = 1.0 / n
        eps = dt / r if r else EPS_LIMIT
        scene = flat_landing_scene(n, eps=eps, alpha=alpha)
        res = _simulate_self(scene, penalty=penalty, max_rows=scene.nt)
        E0 = res.total_energy[0]
        e = res.energy
        return {"method": name, "alpha": alpha, "dt": dt, "eps": eps, "r": dt / eps,
                "restitution": restitution(res.t, res.x, res.velocity),
                "contact_dissipation": e["contact_dissipation"][-1] / E0,
                "numerical_dissipation": e["numerical_dissipation"][-1] / E0,
                "viscous_dissipation": e["viscous_dissipation"][-1] / E0,
                "final_energy": res.total_energy[-1] / E0}

    return distribute(one, cases, comm, busy=busy)


# --- run --tol --------------------------------------------------------------------------------------------


def _scaled(scene, nx: int):
    """The scene at `nx` cells, keeping its ratio Δt/Δx."""
    nt = max(1, round(scene.nt * nx / scene.nx))
    return scene.replace(nx=nx, nt=nt)


def richardson_estimate(coarse: Run, fine: Run, order: float) -> float:
    """Error of `fine` in L∞(0,T;L²) of η: ‖η_fine − η_coarse‖ / (2^p − 1), p the method's observed order."""
    rows = _common_rows(coarse.t, fine.t)
    diff = coarse.eta - _to_nodes(fine.x, fine.eta[rows], coarse.x)
    return float(np.max(l2_norm(coarse.x, diff))) / (2.0**order - 1.0)


def estimate_for_tolerance(scene, tol: float, *, methods=TOL_METHODS, nx_start: int = 50, nx_max: int = 64000,
                           model=None) -> list[dict]:
    """For each method, double the resolution from `nx_start` until the two-resolution estimate is below `tol`.

    Returns one dict per method: method, nx, nt (of the finer run), estimate, fine_wall_s (the finer run's
    wall time), ok (whether `tol` was reached below `nx_max`) and run (the finer :class:`Run` itself).
    """
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise ValueError(f"--tol must be a positive number (an L-infinity(0,T;L2) error of eta), got {tol}")
    found = []
    budget = math.inf  # a method that costs more than the cheapest success so far cannot win: stop refining it
    for name in methods:
        method = METHODS[name]
        if method.penalty == "semi-implicit" and model is not None and model.penalty_damping is None:
            continue
        if method.scheme == "projection" and model is not None and model.gap is None:
            continue
        nx = max(2, min(nx_start, scene.nx))
        coarse_scene = _scaled(scene, nx)
        rows = coarse_scene.nt  # every coarse step; the finer run stores every second step, at the same times
        coarse = run_method(coarse_scene, method, rows=rows, model=model)
        while True:
            # Δx and Δt halve together, so every coarse step is a fine step.
            fine = run_method(scene.replace(nx=2 * coarse.nx, nt=2 * coarse.nt), method, rows=rows, model=model)
            if coarse.status != "complete" or fine.status != "complete":
                break
            estimate = richardson_estimate(coarse, fine, TOL_ORDER[name])
            ok = estimate <= tol
            if ok or 2 * nx >= nx_max or fine.wall_s > budget:
                found.append({"method": name, "nx": fine.nx, "nt": fine.nt, "estimate": estimate,
                              "fine_wall_s": fine.wall_s, "ok": ok, "run": fine})
                if ok:
                    budget = min(budget, fine.wall_s)
                break
            nx, coarse = 2 * nx, fine
    return found


def choose_for_tolerance(scene, tol: float, *, model=None):
    """`run SCENE --tol X`: the cheapest method and resolution whose estimated error of η is below X.

    The candidates are the methods that converge to the inelastic limit ε → 0 (docs/study.md: the fixed-ε
    paper scheme stops at its ε-error, which no resolution removes). Each is refined by doubling Δx and Δt
    together (keeping the scene's ratio) until the Richardson estimate from the last two resolutions,
    with the study's observed order, is below X; the cheaper of the finer runs wins. The pilot runs use
    `model` (default: the scene's, else the paper's), so pass the model the run itself will use. Under MPI,
    rank 0 decides and tells the others. Returns (scene, options for `simulate`, report).
    """
    if scene.dim != 1:  # its pilots refine nx and its error estimates are the string's
        raise ValueError(f"--tol: 1D-only (it refines the string's nx); scene {scene.name!r} has domain {scene.domain!r}: "
                         "give its scheme (--scheme) and mesh (cells, mesh_size) instead")
    if model is None and scene.model:
        from ..model.registry import load_model

        model = load_model(scene.model)
    choice = _estimate_on_rank_0(scene, tol, model=model)
    chosen, method, best = _pick(scene, tol, choice)
    others = "; ".join(f"{c['method']}: nx={c['nx']} est {c['estimate']:.3g} ({c['fine_wall_s']:.2g} s"
                       f"{'' if c['ok'] else ', stopped: above tol and already dearer'})" for c in choice)
    report = (f"--tol {tol:g}: chose {method.name} ({method.label}) at nx={chosen.nx}, nt={chosen.nt}, "
              f"eps={chosen.eps:.3g}; estimated error of eta in Linf(0,T;L2) = {best['estimate']:.3g} "
              f"(two-resolution Richardson, order {TOL_ORDER[method.name]}) [{others}]")
    return chosen, {"scheme": method.scheme, "penalty": method.penalty, "mass": method.mass}, report


def _estimate_on_rank_0(scene, tol: float, *, model=None) -> list[dict]:
    """`estimate_for_tolerance` on rank 0 of COMM_WORLD, its result (or its ValueError) broadcast to every rank.

    Every rank must call it. The other ranks get the estimates without the pilot runs' arrays ("run").
    """
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    choice = None
    if comm.rank == 0:
        try:
            choice = estimate_for_tolerance(scene, tol, model=model)
        except ValueError as exc:
            choice = exc
    if comm.size > 1:  # the other ranks need the estimates, not the pilot runs' arrays
        light = None
        if comm.rank == 0:
            light = choice if isinstance(choice, Exception) else [{k: v for k, v in c.items() if k != "run"}
                                                                  for c in choice]
        light = comm.bcast(light, root=0)
        if comm.rank != 0:
            choice = light
    if isinstance(choice, Exception):
        raise choice
    return choice


def _pick(scene, tol: float, choice: list[dict]):
    """From `estimate_for_tolerance`'s estimates: (the chosen scene, its Method, its estimate), the cheapest
    finer run among those that reached `tol`; a ValueError if none did."""
    reached = [c for c in choice if c["ok"]]
    if not reached:
        best = min(choice, key=lambda c: c["estimate"], default=None)
        where = f"; the best estimate was {best['estimate']:.3g} at nx={best['nx']}" if best else ""
        raise ValueError(f"--tol {tol:g}: no method reached the tolerance up to nx=64000{where}")
    best = min(reached, key=lambda c: c["fine_wall_s"])
    method = METHODS[best["method"]]
    chosen = scene.replace(nx=best["nx"], nt=best["nt"])
    chosen = chosen.replace(eps=method.eps(chosen.eps, chosen.dt))
    return chosen, method, best


def tolerance_tracking(tols=(3e-2, 1e-2, 3e-3), T: float = 0.6) -> list[dict]:
    """On the flat landing: the chosen run's estimate against its true error (exact solution), per tolerance.

    Serial (no MPI collective: under `mpirun` only rank 0 calls it). The true error is that of the chosen run
    itself, the finer pilot run of the estimate (every coarse step stored); pilot_wall_s is the time the choice took.
    """
    base = flat_landing_scene(100, T=T)
    rows = []
    for tol in tols:
        t0 = time.perf_counter()
        best = _pick(base, tol, estimate_for_tolerance(base, tol))[2]
        pilot = time.perf_counter() - t0
        true = errors_against_exact(best["run"], flat_landing_exact)["err_eta"]
        rows.append({"tol": tol, "method": best["method"], "nx": best["nx"], "nt": best["nt"],
                     "estimate": best["estimate"], "true_error": true, "ratio": best["estimate"] / true,
                     "pilot_wall_s": pilot})
    return rows


# --- files and charts -------------------------------------------------------------------------------------


def write_csv(path, rows: list[dict], columns) -> Path:
    """Write rows with exactly `columns`, atomically (a temporary file renamed into place)."""
    from ..io.folder import atomic_path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_fmt(row[c]) for c in columns])
    return path


def read_csv(path) -> list[dict]:
    """Rows of a study CSV, numbers as floats."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        for key, value in row.items():
            try:
                row[key] = float(value)
            except ValueError:
                pass
    return rows


def _fmt(value):
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.6g}"
    return value


@contextlib.contextmanager
def _figure(path, *args, **kwargs):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io.folder import atomic_path

    fig, axes = plt.subplots(*args, **kwargs)
    try:
        yield fig, axes
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)


STYLE = {
    "paper": dict(color="#d62728", marker="s"),
    "explicit-r1": dict(color="#ff7f0e", marker="^"),
    "semi-implicit": dict(color="#1f77b4", marker="o"),
    "consistent": dict(color="#2ca02c", marker="D"),
    "projection": dict(color="#9467bd", marker="P"),
    "newmark": dict(color="#8c564b", marker="X"),
}
ERROR_LABELS = {
    "err_eta": r"error of $\eta$ in $L^\infty(0,T;L^2)$",
    "err_vel": r"error of $\eta_t(T)$ in $L^2$",
    "err_contact": "contact-set error (space-time measure)",
}


def plot_work_precision(rows: list[dict], path) -> Path:
    """Error against wall-clock time, log-log: a row of panels per problem, a panel per error."""
    probs = list(dict.fromkeys(r["problem"] for r in rows))
    with _figure(path, len(probs), 3, figsize=(15, 4.6 * len(probs)), squeeze=False, layout="constrained") as (fig, axes):
        for i, p in enumerate(probs):
            for j, key in enumerate(ERROR_LABELS):
                ax = axes[i, j]
                for m in METHODS:
                    sel = [r for r in rows if r["problem"] == p and r["method"] == m and r["status"] == "complete"
                           and np.isfinite(r[key]) and r[key] > 0]
                    if not sel:
                        continue
                    sel.sort(key=lambda r: r["nx"])
                    style = STYLE[m]
                    ax.loglog([r["wall_s"] for r in sel], [r[key] for r in sel], "-", color=style["color"],
                              label=METHODS[m].label)
                    for r in sel:  # hollow markers: 1 < r < 2, a (spurious) rebound
                        hollow = r["r"] > 1 + 1e-9 and r["penalty"] == "explicit"
                        ax.loglog(r["wall_s"], r[key], style["marker"], color=style["color"],
                                  mfc="white" if hollow else style["color"])
                        ax.annotate(f"{int(r['nx'])}", (r["wall_s"], r[key]), fontsize=6, alpha=0.6,
                                    xytext=(3, 3), textcoords="offset points")
                ax.set_xlabel("wall-clock time of one run [s]")
                ax.set_ylabel(ERROR_LABELS[key])
                ax.grid(True, which="both", alpha=0.3)
                title = "flat landing (exact, α = 0)" if p == "flat-landing" else "Example 1 (vs fine reference)"
                ax.set_title(f"{title}", fontsize=10)
            axes[i, 0].legend(fontsize=7, loc="lower left")
        fig.suptitle("Work-precision: lower left is better; numbers are nx (Δt = Δx = 1/nx); "
                     "hollow = 1 < Δt/ε < 2 (rebounds); missing = refused (Δt/ε ≥ 2)", fontsize=10)
    return Path(path)


def plot_convergence(result: dict, path) -> Path:
    """Left: errors against Δt = Δx with reference slopes. Right: penetration and error against ε."""
    rows = result["runs"]
    with _figure(path, 1, 3, figsize=(15, 4.4)) as (fig, axes):
        ax = axes[0]
        for m in ("explicit-r1", "semi-implicit", "consistent"):
            sel = sorted((r for r in rows if r["sweep"] == "dt" and r["method"] == m and r["status"] == "complete"),
                         key=lambda r: r["dt"])
            style = STYLE[m]
            ax.loglog([r["dt"] for r in sel], [r["err_eta"] for r in sel], "-" + style["marker"], color=style["color"],
                      label=f"{METHODS[m].label}: η")
            ax.loglog([r["dt"] for r in sel], [r["err_vel"] for r in sel], ":" + style["marker"], color=style["color"],
                      mfc="white", label=f"{m}: velocity at T")
        dt_rows = [r for r in rows if r["sweep"] == "dt" and r["status"] == "complete"]
        if dt_rows:  # reference slopes through the finest η error, drawn a little below it
            dts = np.array(sorted({r["dt"] for r in dt_rows}))
            e0 = 0.6 * min(r["err_eta"] for r in dt_rows)
            for p, ls in ((0.5, "--"), (1.0, "-.")):
                ax.loglog(dts, e0 * (dts / dts[0]) ** p, "k" + ls, lw=0.8, label=f"slope {p}")
        ax.set_xlabel("Δt = Δx")
        ax.set_ylabel("error (flat landing, exact)")
        ax.legend(fontsize=6)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_title("refinement in Δt = Δx", fontsize=10)
        eps_rows = [r for r in rows if r["sweep"] == "eps" and r["status"] == "complete"]
        for ax, key, label in ((axes[1], "penetration", "penetration −min η"), (axes[2], "err_eta", ERROR_LABELS["err_eta"])):
            for p, color in (("explicit", STYLE["paper"]["color"]), ("semi-implicit", STYLE["semi-implicit"]["color"])):
                sel = sorted((r for r in eps_rows if r["penalty"] == p), key=lambda r: r["eps"])
                vals = [(-r["min_eta"] if key == "penetration" else r[key]) for r in sel]
                ax.loglog([r["eps"] for r in sel], vals, "-o", color=color, label=f"{p} penalty")
            if eps_rows:
                dt = eps_rows[0]["dt"]
                ax.axvline(dt, color="gray", ls=":", lw=1)
                ax.text(dt, ax.get_ylim()[0], " ε = Δt", fontsize=7, color="gray", va="bottom")
                if key == "penetration":
                    e = np.array(sorted({r["eps"] for r in eps_rows}))
                    ax.loglog(e, FLAT_V * e, "k--", lw=0.8, label="ε·V")
            ax.set_xlabel("ε")
            ax.set_ylabel(label)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
            ax.set_title(f"ε → 0 at Δt = Δx = {eps_rows[0]['dt']:.3g}" if eps_rows else "ε → 0", fontsize=10)
    return Path(path)


OUTCOME_COLOURS = {"inelastic": "#4daf4a", "rebound": "#ffb000", "growth": "#e41a1c", "refused": "#999999",
                   "stable": "#377eb8"}


def plot_stability(rows: list[dict], alpha_rows: list[dict] | None, path) -> Path:
    """The map (outcome over r and Δt per treatment), restitution against r with the theory, the α sweep."""
    treatments = list(dict.fromkeys((r["penalty"], r["mass"]) for r in rows))
    ncols = 2 + (1 if alpha_rows else 0)
    with _figure(path, 1, ncols, figsize=(5.2 * ncols, 4.6)) as (fig, axes):
        ax = axes[0]
        labels = []
        dts = sorted({r["dt"] for r in rows}, reverse=True)
        y = -1
        for pen, mass in treatments:
            y += 1
            for dt in dts:
                sel = [r for r in rows if (r["penalty"], r["mass"], r["dt"]) == (pen, mass, dt)]
                if not sel:  # the spring is swept at one Δt only
                    continue
                y += 1
                labels.append((y, f"{pen}, {mass}, Δt={dt:.3g}"))
                ax.scatter([r["r"] for r in sel], [y] * len(sel), s=70, marker="s", edgecolors="k", linewidths=0.3,
                           c=[OUTCOME_COLOURS[r["outcome"]] for r in sel])
        ax.set_xscale("log")
        ax.set_yticks([y for y, _ in labels], [s for _, s in labels], fontsize=7)
        for x0 in (1.0, 2.0):
            ax.axvline(x0, color="k", ls=":", lw=0.8)
        for outcome, colour in OUTCOME_COLOURS.items():
            ax.scatter([], [], marker="s", color=colour, label=outcome, edgecolors="k", linewidths=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=4)
        ax.set_xlabel("r = Δt/ε   (dotted: r = 1, r = 2)")
        ax.set_title("outcome of a flat landing (α = 0)", fontsize=10)

        ax = axes[1]
        rr = np.logspace(-1, np.log10(4), 200)
        ax.plot(rr, np.maximum(rr - 1, 0), "k-", lw=1, label="theory (explicit): max(r − 1, 0)")
        for (pen, mass), marker in zip(treatments, ("o", "x", "D")):
            sel = [r for r in rows if (r["penalty"], r["mass"]) == (pen, mass) and np.isfinite(r["restitution"])
                   and r["restitution"] <= 3]
            ax.plot([r["r"] for r in sel], [r["restitution"] for r in sel], marker, ls="none", mfc="none",
                    label=f"measured: {pen}, {mass}")
        ax.set_xscale("log")
        ax.set_xlabel("r = Δt/ε")
        ax.set_ylabel("restitution (upward / downward velocity)")
        ax.set_ylim(-0.05, 3.05)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title("restitution at the middle node", fontsize=10)

        if alpha_rows:
            ax = axes[2]
            names = list(dict.fromkeys(r["method"] for r in alpha_rows))
            for name, colour in zip(names, ("#ff7f0e", "#d62728", "#1f77b4")):
                sel = sorted((r for r in alpha_rows if r["method"] == name), key=lambda r: r["alpha"])
                a = [max(r["alpha"], 1e-4) for r in sel]
                ax.semilogx(a, [r["numerical_dissipation"] for r in sel], "-o", color=colour, label=f"{name}: numerical")
                ax.semilogx(a, [r["contact_dissipation"] for r in sel], "--s", color=colour, mfc="white",
                            label=f"{name}: contact")
                ax.semilogx(a, [r["restitution"] for r in sel], ":^", color=colour, label=f"{name}: restitution")
            ax.set_xlabel("α (α = 0 drawn at 1e-4)")
            ax.set_ylabel("fraction of E(0) dissipated by T / restitution")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=6)
            ax.set_title("α → 0: what is left is the scheme's own dissipation", fontsize=10)
    return Path(path)


def plot_step_size(rows: list[dict], path) -> Path:
    """Outcome over Δt/Δx for the schemes without ε, with each one's Δt_max from the operators."""
    keys = list(dict.fromkeys((r["scheme"], r["alpha"]) for r in rows))
    with _figure(path, 1, 1, figsize=(7.5, 3.2)) as (fig, ax):
        for y, (scheme, alpha) in enumerate(keys):
            sel = [r for r in rows if (r["scheme"], r["alpha"]) == (scheme, alpha)]
            ax.scatter([r["dt_over_dx"] for r in sel], [y] * len(sel), s=70, marker="s", edgecolors="k",
                       linewidths=0.3, c=[OUTCOME_COLOURS[r["outcome"]] for r in sel])
            if scheme == "projection":
                ax.plot([sel[0]["dt_max_over_dx"]] * 2, [y - 0.4, y + 0.4], "k-", lw=1.5)
        ax.set_xscale("log")
        ax.set_yticks(range(len(keys)), [f"{s}, α = {a:g}" for s, a in keys], fontsize=8)
        ax.set_ylim(-0.7, len(keys) - 0.3)
        for outcome, colour in OUTCOME_COLOURS.items():
            ax.scatter([], [], marker="s", color=colour, label=outcome, edgecolors="k", linewidths=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=4)
        ax.set_xlabel("Δt/Δx   (bar: projection's Δt_max from the operators)")
        ax.set_title("flat landing: where the ε-free schemes fail", fontsize=10)
    return Path(path)


# --- command line -----------------------------------------------------------------------------------------


def add_arguments(parser):
    sub = parser.add_subparsers(dest="study", required=True, metavar="{work-precision,convergence,stability}")
    specs = {
        "work-precision": "error against wall-clock time per method (flat landing and Example 1)",
        "convergence": "observed orders in dt = dx and in eps; the --tol estimate against the true error",
        "stability": "outcome over r = dt/eps per penalty and law, over dt/dx per scheme, restitution, alpha -> 0",
    }
    for name, help_text in specs.items():
        p = sub.add_parser(name, help=help_text)
        p.add_argument("--out", metavar="DIR", default="out/study", help="folder for the CSV and PNG files")
        p.add_argument("--quick", action="store_true", help="a small version (seconds), for tests and demos")
        if name == "work-precision":
            p.add_argument("--problem", choices=("flat-landing", "example1", "all"), default="all")
            p.add_argument("--repeat", type=int, default=1, help="time each run this many times, keep the best")


def command(args) -> int:
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a folder")
    t0 = time.perf_counter()
    if args.study == "work-precision" and args.repeat < 1:
        raise ValueError(f"--repeat must be >= 1, got {args.repeat}")
    busy = []
    t_sweep = time.perf_counter()
    if args.study == "work-precision":
        names = ("flat-landing", "example1") if args.problem == "all" else (args.problem,)
        result = work_precision(quick=args.quick, problem_names=names, repeat=args.repeat, comm=comm, busy=busy)
    elif args.study == "convergence":
        result = convergence(quick=args.quick, comm=comm, busy=busy)
    else:
        result = stability_map(quick=args.quick, comm=comm, busy=busy)
        alpha_rows = alpha_sweep(quick=args.quick, comm=comm, busy=busy)
        step_rows = step_size_map(quick=args.quick, comm=comm, busy=busy)
    sweep = time.perf_counter() - t_sweep
    written = []
    if result is not None:  # None on ranks > 0: rank 0 has the results
        if args.study == "work-precision":
            written = [write_csv(out / "study_work_precision.csv", result, WORK_PRECISION_COLUMNS),
                       plot_work_precision(result, out / "study_work_precision.png")]
        elif args.study == "convergence":
            tracking = tolerance_tracking((3e-2, 1e-2) if args.quick else (3e-2, 1e-2, 5e-3))
            written = [write_csv(out / "study_convergence.csv", result["runs"], CONVERGENCE_COLUMNS),
                       write_csv(out / "study_orders.csv", result["orders"], ORDER_COLUMNS),
                       write_csv(out / "study_tolerance.csv", tracking, TOLERANCE_COLUMNS),
                       plot_convergence(result, out / "study_convergence.png")]
            for o in result["orders"]:
                print(f"order in {o['sweep']:3s} {o['method']:14s} {o['quantity']:12s} {o['order']:.3f}")
            for t in tracking:
                print(f"tol {t['tol']:g}: {t['method']} nx={t['nx']} estimate {t['estimate']:.3g} "
                      f"true {t['true_error']:.3g}")
        else:
            written = [write_csv(out / "study_stability.csv", result, STABILITY_COLUMNS),
                       write_csv(out / "study_alpha.csv", alpha_rows, ALPHA_COLUMNS),
                       write_csv(out / "study_step_size.csv", step_rows, STEP_COLUMNS),
                       plot_stability(result, alpha_rows, out / "study_stability.png"),
                       plot_step_size(step_rows, out / "study_step_size.png")]
    if comm.rank == 0:
        elapsed = time.perf_counter() - t0
        per_rank = np.sum(np.reshape(busy, (-1, comm.size)), axis=0) if busy else []
        print(f"study {args.study}: {comm.size} rank(s), {elapsed:.2f} s wall-clock, of which the sweep "
              f"{sweep:.2f} s; CPU time of the cases per rank: " + ", ".join(f"{b:.2f} s" for b in per_rank))
        for path in written:
            print(f"wrote {path}")
    return 0
