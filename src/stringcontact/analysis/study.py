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

This module is their public face: the names live in one module per concern and are re-exported here,

==========================  ================================================================================
``problems``                the methods (`Method`, `METHODS`, `REFERENCE`), the test problems, the scene
                            factories (`flat_landing_scene`, also the theorem checks', `example1_scene`)
``runs``                    one study run on this rank (`Run`, `run_method`, `warm_up`)
``norms``                   the errors against an exact solution or a finer run (`l2_norm`, `errors_against_*`)
``schedule``                `distribute`: the cases dealt over the MPI ranks, gathered on rank 0
``work_precision``          error against wall-clock time
``convergence``             observed orders in Δt = Δx and in ε
``stability``               the stability map, the step-size map, restitution, the α sweep
``tolerance``               ``run --tol`` (`choose_for_tolerance`) and how its estimate tracks the true error
``tables``                  the CSV files
``plot.study_charts``       the charts (the methods' labels are passed in by the wrappers below)
``cli.study``               ``stringcontact study`` (``mpirun -n K stringcontact study ...`` deals the cases)
==========================  ================================================================================

Errors (all on the coarse run's nodes and stored times, the reference interpolated to them):

* ``err_eta``: :math:`\max_k \|\eta_h(t_k) - \eta(t_k)\|_{L^2(0,l)}`, the :math:`L^\infty(0,T;L^2)` error;
* ``err_vel``: :math:`\|\eta_{h,t}(T) - \eta_t(T)\|_{L^2(0,l)}`;
* ``err_contact``: the space-time measure of the symmetric difference of the contact sets
  :math:`\{\eta \le 0\}` (trapezoidal in x and t).
"""

from __future__ import annotations

from pathlib import Path

from ..plot.study_charts import ERROR_LABELS, OUTCOME_COLOURS, STYLE, plot_stability, plot_step_size
from .convergence import CONVERGENCE_COLUMNS, ORDER_COLUMNS, convergence, fitted_order, observed_orders
from .norms import (
    CONTACT_HEIGHT,
    common_rows,
    contact_height,
    contact_set,
    errors_against_exact,
    errors_against_reference,
    l2_norm,
    to_nodes,
)
from .problems import (
    EPS_LIMIT,
    EPS_PAPER,
    FLAT_H,
    FLAT_V,
    METHODS,
    REFERENCE,
    Method,
    Problem,
    example1_scene,
    flat_landing_exact,
    flat_landing_scene,
    problems,
)
from .runs import Run, run_method, simulate_self, warm_up
from .schedule import distribute
from .stability import (
    ALPHA_COLUMNS,
    GROWTH_TOLERANCE,
    REBOUND_THRESHOLD,
    SPRING_Q,
    STABILITY_COLUMNS,
    STABILITY_DT,
    STABILITY_R,
    STEP_COLUMNS,
    STEP_RATIOS,
    alpha_sweep,
    classify,
    fd_energy,
    restitution,
    restitution_theory,
    spring_case,
    stability_case,
    stability_map,
    step_size_case,
    step_size_map,
)
from .tables import csv_cell, read_csv, write_csv
from .tolerance import (
    TOL_METHODS,
    TOL_ORDER,
    TOLERANCE_COLUMNS,
    choose_for_tolerance,
    estimate_for_tolerance,
    richardson_estimate,
    tolerance_tracking,
)
from .work_precision import WORK_PRECISION_COLUMNS, study_row, work_precision


def method_labels() -> dict:
    """The methods' legend labels, in the order of `METHODS`."""
    return {name: method.label for name, method in METHODS.items()}


def plot_work_precision(rows: list[dict], path) -> Path:
    """Error against wall-clock time (`plot.study_charts.plot_work_precision`), a line per method of `METHODS`."""
    from ..plot import study_charts

    return study_charts.plot_work_precision(rows, path, method_labels())


def plot_convergence(result: dict, path) -> Path:
    """Errors against Δt = Δx, penetration and error against ε (`plot.study_charts.plot_convergence`)."""
    from ..plot import study_charts

    return study_charts.plot_convergence(result, path, method_labels(), FLAT_V)


__all__ = [
    "ALPHA_COLUMNS", "CONTACT_HEIGHT", "CONVERGENCE_COLUMNS", "EPS_LIMIT", "EPS_PAPER", "ERROR_LABELS", "FLAT_H",
    "FLAT_V", "GROWTH_TOLERANCE", "METHODS", "ORDER_COLUMNS", "OUTCOME_COLOURS", "REBOUND_THRESHOLD", "REFERENCE",
    "SPRING_Q", "STABILITY_COLUMNS", "STABILITY_DT", "STABILITY_R", "STEP_COLUMNS", "STEP_RATIOS", "STYLE",
    "TOLERANCE_COLUMNS", "TOL_METHODS", "TOL_ORDER", "WORK_PRECISION_COLUMNS", "Method", "Problem", "Run",
    "alpha_sweep", "choose_for_tolerance", "classify", "common_rows", "contact_height", "contact_set", "convergence",
    "csv_cell", "distribute", "errors_against_exact", "errors_against_reference", "estimate_for_tolerance",
    "example1_scene", "fd_energy", "fitted_order", "flat_landing_exact", "flat_landing_scene", "l2_norm",
    "method_labels", "observed_orders", "plot_convergence", "plot_stability", "plot_step_size", "plot_work_precision",
    "problems", "read_csv", "restitution", "restitution_theory", "richardson_estimate", "run_method",
    "simulate_self", "spring_case", "stability_case", "stability_map", "step_size_case", "step_size_map",
    "study_row", "to_nodes", "tolerance_tracking", "warm_up", "work_precision", "write_csv",
]
