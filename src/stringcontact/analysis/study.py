"""The studies' public names in one place: each study a function returning rows (dicts), its CSV files (`write_csv`,
`read_csv`) and charts."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..io.publish import atomic_path
from ..plot import study_charts
from ..plot.study_charts import plot_stability, plot_step_size
from .convergence import (CONVERGENCE_COLUMNS, ORDER_COLUMNS, WORK_PRECISION_COLUMNS, convergence,
                          errors_against_exact, errors_against_reference, fitted_order, observed_orders, work_precision)
from .problems import (FLAT_H, FLAT_V, METHODS, REFERENCE, example1_scene, flat_landing_exact, flat_landing_scene,
                       run_method, warm_up)
from .stability import (ALPHA_COLUMNS, REBOUND_THRESHOLD, STABILITY_COLUMNS, STEP_COLUMNS, alpha_sweep, restitution,
                        stability_case, stability_map, step_size_map)
from .tolerance import TOL_ORDER, TOLERANCE_COLUMNS, choose_for_tolerance, estimate_for_tolerance, tolerance_tracking


def plot_work_precision(rows: list[dict], path) -> Path:
    """Error against wall-clock time (`plot.study_charts.plot_work_precision`), a line per method of `METHODS`."""
    return study_charts.plot_work_precision(rows, path, {name: m.label for name, m in METHODS.items()})


def plot_convergence(result: dict, path) -> Path:
    """Errors against Δt = Δx, penetration and error against ε (`plot.study_charts.plot_convergence`)."""
    return study_charts.plot_convergence(result, path, {name: m.label for name, m in METHODS.items()}, FLAT_V)


def write_csv(path, rows: list[dict], columns) -> Path:
    """Write rows with exactly `columns`, atomically, floats to 6 significant digits."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        csv.writer(f).writerows([columns, *([_cell(row[c]) for c in columns] for row in rows)])
    return path


def read_csv(path) -> list[dict]:
    """Rows of a study CSV, numbers as floats."""
    with open(path, newline="") as f:
        return [{key: _number(value) for key, value in row.items()} for row in csv.DictReader(f)]


def _cell(value):
    return f"{float(value):.6g}" if isinstance(value, (float, np.floating)) else value


def _number(text: str):
    try:
        return float(text)
    except ValueError:
        return text


__all__ = [
    "ALPHA_COLUMNS", "CONVERGENCE_COLUMNS", "FLAT_H", "FLAT_V", "METHODS", "ORDER_COLUMNS", "REBOUND_THRESHOLD",
    "REFERENCE", "STABILITY_COLUMNS", "STEP_COLUMNS", "TOLERANCE_COLUMNS", "TOL_ORDER", "WORK_PRECISION_COLUMNS",
    "alpha_sweep", "choose_for_tolerance", "convergence", "errors_against_exact", "errors_against_reference",
    "estimate_for_tolerance", "example1_scene", "fitted_order", "flat_landing_exact", "flat_landing_scene",
    "observed_orders", "plot_convergence", "plot_stability", "plot_step_size", "plot_work_precision", "read_csv",
    "restitution", "run_method", "stability_case", "stability_map", "step_size_map", "tolerance_tracking", "warm_up",
    "work_precision", "write_csv"]
