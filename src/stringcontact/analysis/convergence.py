"""The accuracy studies: their errors ``err_eta`` (L∞(0,T;L²) of η), ``err_vel`` (L² of η_t at T) and ``err_contact``
(the contact sets' symmetric difference in space-time) at the run's nodes and times (docs/explanation/study.md),
work-precision (error against wall-clock time per `Method`) and convergence (observed orders in Δt = Δx → 0 and in
ε → 0 on the flat landing)."""

from __future__ import annotations

import math

import numpy as np

from .problems import (METHODS, REFERENCE, Method, Run, distribute, flat_landing_exact, flat_landing_scene, problems,
                       run_method, warm_up)

WORK_PRECISION_COLUMNS = ("problem", "method", "penalty", "mass", "nx", "nt", "dt", "eps", "r", "status", "wall_s",
                          "err_eta", "err_vel", "err_contact", "min_eta")
CONVERGENCE_COLUMNS = ("sweep", *WORK_PRECISION_COLUMNS, "order_eta")
ORDER_COLUMNS = ("sweep", "problem", "method", "quantity", "order", "from", "to")
#: Contact sets in the errors are {η ≤ δ}, δ = CONTACT_HEIGHT · Δx · max|η|/l, the height a grid resolves (with δ = 0
#: a string resting on the obstacle at ±round-off is noise).
CONTACT_HEIGHT = 1.0


def l2_norm(x: np.ndarray, f: np.ndarray) -> np.ndarray:
    """‖f‖_{L²(0,l)} of nodal values f (rows = times), trapezoidal."""
    from ..fem import compat

    return np.sqrt(compat.trapezoid(f**2, x, axis=-1))


def to_nodes(x_from: np.ndarray, values: np.ndarray, x_to: np.ndarray) -> np.ndarray:
    """P1 interpolation of rows of nodal values onto other nodes."""
    values = np.atleast_2d(values)
    return np.array([np.interp(x_to, x_from, row) for row in values])


def common_rows(t_run: np.ndarray, t_ref: np.ndarray) -> np.ndarray:
    """Indices into t_ref of the run's stored times (they must be among the reference's)."""
    idx = np.searchsorted(t_ref, t_run - 1e-12 * max(1.0, t_ref[-1]))
    idx = np.minimum(idx, t_ref.size - 1)
    if not np.allclose(t_ref[idx], t_run, rtol=0, atol=1e-9 * max(1.0, t_ref[-1])):
        raise ValueError("the run's stored times are not among the reference's: use matching rows")
    return idx


def errors_against_exact(run: Run, exact) -> dict:
    """The three errors of `run` against `exact(t, x) -> (eta, velocity)`."""
    return _errors(run, exact(run.t, run.x)[0], exact(run.t[-1], run.x)[1])


def errors_against_reference(run: Run, ref: Run) -> dict:
    """The three errors of `run` against a finer run `ref` (interpolated to the run's nodes and times)."""
    eta = to_nodes(ref.x, ref.eta[common_rows(run.t, ref.t)], run.x)
    return _errors(run, eta, to_nodes(ref.x, ref.velocity_T, run.x)[0])


def _errors(run: Run, eta: np.ndarray, vel_T: np.ndarray) -> dict:
    from ..fem import compat

    length = run.x[-1] - run.x[0]
    delta = CONTACT_HEIGHT * (length / run.nx) * float(np.max(np.abs(run.eta[0]))) / length
    sym_diff = ((run.eta <= delta) != (eta <= delta)).astype(float)
    measure = compat.trapezoid(sym_diff, run.x, axis=1)
    return {
        "err_eta": float(np.max(l2_norm(run.x, run.eta - eta))),
        "err_vel": float(l2_norm(run.x, run.velocity_T - vel_T)),
        "err_contact": float(compat.trapezoid(measure, run.t)) if run.t.size > 1 else float(measure[0])}


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


def study_row(run: Run, errs: dict | None) -> dict:
    """The row of `WORK_PRECISION_COLUMNS` of `run` and its errors (NaN if None)."""
    errs = errs or dict.fromkeys(("err_eta", "err_vel", "err_contact"), math.nan)
    return {"problem": run.problem, "method": run.method, "penalty": run.penalty, "mass": run.mass, "nx": run.nx,
            "nt": run.nt, "dt": run.dt, "eps": run.eps, "r": run.r, "status": run.status, "wall_s": run.wall_s, **errs,
            "min_eta": run.min_eta}


def work_precision(quick: bool = False, problem_names=("flat-landing", "example1"), methods=tuple(METHODS),
                   repeat: int = 1, comm=None, busy: list | None = None) -> list[dict] | None:
    """Rows of `WORK_PRECISION_COLUMNS`: every method at every size of every problem (None on ranks > 0)."""
    probs = problems(quick)
    if unknown := set(problem_names) - set(probs):
        raise ValueError(f"problem must be among {sorted(probs)}, not {sorted(unknown)}")
    cases = [(p, m, n) for p in problem_names for m in methods for n in probs[p].sizes]
    cases += [(p, REFERENCE.name, probs[p].reference_n) for p in problem_names if probs[p].reference_n]

    def one(case):
        p, m, n = case
        method = REFERENCE if m == REFERENCE.name else METHODS[m]
        return run_method(probs[p].scene(n), method, rows=probs[p].rows, repeat=1 if m == REFERENCE.name else repeat)

    warm_up()
    runs = distribute(one, cases, comm, cost=lambda c: probs[c[0]].T * c[2] ** 2, busy=busy)
    if runs is None:
        return None
    refs = {run.problem: run for run in runs if run.method == REFERENCE.name}
    rows = []
    for run in (r for r in runs if r.method != REFERENCE.name):
        errs = None if run.status != "complete" else (
            errors_against_exact(run, flat_landing_exact) if run.problem == "flat-landing"
            else errors_against_reference(run, refs[run.problem]))
        rows.append(study_row(run, errs))
    return rows + [study_row(ref, None) for ref in refs.values()]  # the references: their cost, no error


def convergence(quick: bool = False, comm=None, busy: list | None = None) -> dict | None:
    """Observed orders on the flat landing in Δt = Δx per method and in ε per penalty: {"runs", "orders"} on rank 0."""
    sizes = (125, 250, 500) if quick else (125, 250, 500, 1000, 2000, 4000, 8000)
    n_eps = 400 if quick else 4000
    eps_values = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 1e-5, 1e-6, 1e-8)
    rows_per_run = round(0.6 * min(sizes))
    cases = [("dt", m, n, None) for m in ("explicit-r1", "semi-implicit", "consistent", "projection", "newmark")
             for n in sizes]
    cases += [("eps", "explicit", n_eps, e) for e in eps_values if (1.0 / n_eps) / e <= 1.0]
    cases += [("eps", "semi-implicit", n_eps, e) for e in eps_values]

    def one(case):
        sweep, m, n, eps = case
        if sweep == "dt":
            return run_method(flat_landing_scene(n), METHODS[m], rows=rows_per_run)
        method = Method(f"{m}, eps", m, m, "lumped", "fixed")
        return run_method(flat_landing_scene(n, eps=eps), method, rows=rows_per_run)

    warm_up()
    runs = distribute(one, cases, comm, cost=lambda c: c[2] ** 2, busy=busy)
    if runs is None:
        return None
    rows = []
    for (sweep, *_), run in zip(cases, runs):
        errs = errors_against_exact(run, flat_landing_exact) if run.status == "complete" else None
        rows.append({"sweep": sweep, **study_row(run, errs), "order_eta": math.nan})
    orders = []
    for sweep, key, variable in (("dt", "method", "dt"), ("eps", "penalty", "eps")):
        for name in dict.fromkeys(r[key] for r in rows if r["sweep"] == sweep):
            sel = sorted((r for r in rows if r["sweep"] == sweep and r[key] == name and r["status"] == "complete"),
                         key=lambda r: -r[variable])
            for r, p in zip(sel[1:], observed_orders([r[variable] for r in sel], [r["err_eta"] for r in sel])):
                r["order_eta"] = p
            fit = [r for r in sel if sweep == "dt" or r["eps"] >= 10 * r["dt"]]  # below 10 Δt the Δt-error is left
            for quantity in ("err_eta", "err_vel", "err_contact") if sweep == "dt" else ("err_eta", "penetration"):
                values = [(-r["min_eta"] if quantity == "penetration" else r[quantity]) for r in fit]
                orders.append({"sweep": sweep, "problem": "flat-landing", "method": name, "quantity": quantity,
                               "order": fitted_order([r[variable] for r in fit], values),
                               "from": max(r[variable] for r in fit), "to": min(r[variable] for r in fit)})
    return {"runs": rows, "orders": orders}
