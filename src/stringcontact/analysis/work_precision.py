"""The work-precision study: error against wall-clock time per `Method`, on the exact α = 0 flat landing and on
the paper's Example 1 against a fine-grid reference."""

from __future__ import annotations

import math

from .norms import errors_against_exact, errors_against_reference
from .problems import METHODS, REFERENCE, flat_landing_exact, problems
from .runs import Run, run_method, warm_up
from .schedule import distribute

WORK_PRECISION_COLUMNS = ("problem", "method", "penalty", "mass", "nx", "nt", "dt", "eps", "r", "status", "wall_s",
                          "err_eta", "err_vel", "err_contact", "min_eta")


def study_row(run: Run, errs: dict | None) -> dict:
    """The row of `WORK_PRECISION_COLUMNS` of `run` and its errors (NaN if None)."""
    errs = errs or dict.fromkeys(("err_eta", "err_vel", "err_contact"), math.nan)
    return {
        "problem": run.problem, "method": run.method, "penalty": run.penalty, "mass": run.mass,
        "nx": run.nx, "nt": run.nt, "dt": run.dt, "eps": run.eps, "r": run.r, "status": run.status,
        "wall_s": run.wall_s, **errs, "min_eta": run.min_eta,
    }


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

    warm_up()
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
        rows.append(study_row(run, errs))
    for ref in refs.values():  # the reference itself: its cost, and no error
        rows.append(study_row(ref, None))
    return rows
