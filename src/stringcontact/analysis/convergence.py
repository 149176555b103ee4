"""The accuracy studies: work-precision (error against wall-clock time per `Method`) and convergence (observed orders
in Δt = Δx → 0 and in ε → 0 on the flat landing)."""

from __future__ import annotations

import math

import numpy as np

from .norms import errors_against_exact, errors_against_reference
from .problems import (METHODS, REFERENCE, Method, Run, flat_landing_exact, flat_landing_scene, problems, run_method,
                       warm_up)
from .schedule import distribute

WORK_PRECISION_COLUMNS = ("problem", "method", "penalty", "mass", "nx", "nt", "dt", "eps", "r", "status", "wall_s",
                          "err_eta", "err_vel", "err_contact", "min_eta")
CONVERGENCE_COLUMNS = ("sweep", *WORK_PRECISION_COLUMNS, "order_eta")
ORDER_COLUMNS = ("sweep", "problem", "method", "quantity", "order", "from", "to")


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
