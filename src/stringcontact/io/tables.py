"""The small files of an output folder: `diagnostics.csv` (one row per stored time) and `summary.json`."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from .result import ENERGY_KEYS

__all__ = ["DIAGNOSTIC_COLUMNS", "clean_json", "summary_dict", "write_diagnostics"]


def clean_json(o):
    """JSON without NaN/Infinity (not JSON): non-finite numbers become the strings "nan", "inf", "-inf"."""
    if isinstance(o, dict):
        return {str(k): clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean_json(v) for v in o]
    if isinstance(o, np.ndarray):
        return clean_json(o.tolist())
    if isinstance(o, (np.bool_, bool)):
        return bool(o)
    if isinstance(o, (np.integer, int)):
        return int(o)
    if isinstance(o, (np.floating, float)):
        v = float(o)
        return v if math.isfinite(v) else str(v)
    if o is None or isinstance(o, str):
        return o
    return str(o)


DIAGNOSTIC_COLUMNS = (
    "step",
    "t",
    *ENERGY_KEYS,
    "balance_residual",
    "min_eta",
    "contact_length",
    "max_contact_force",
)


def write_diagnostics(path: Path, result) -> None:
    cols = {
        "step": result.steps,
        "t": result.t,
        **result.energy,
        "balance_residual": result.balance_residual,
        "min_eta": result.eta.min(axis=1),
        "contact_length": result.contact_length,
        "max_contact_force": result.contact_force.max(axis=1),
    }
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(DIAGNOSTIC_COLUMNS)
        for i in range(len(result.t)):
            w.writerow([int(cols[c][i]) if c == "step" else repr(float(cols[c][i])) for c in DIAGNOSTIC_COLUMNS])


def summary_dict(result) -> dict:
    import dolfinx

    scene = result.scene
    return {
        "status": result.status,
        "message": result.message,
        "scene": scene.as_dict(),
        "scheme": result.scheme,
        "penalty": result.penalty,
        "mass": result.mass,
        "model": result.model,
        "r": scene.dt / scene.eps,
        "dolfinx": dolfinx.__version__,
        "timings": result.timings,
        "min_eta": result.min_eta,
        "stored_rows": len(result.t),
        "final_energy": {k: float(v[-1]) for k, v in result.energy.items()},
        "initial_energy": float(result.total_energy[0]),
        "max_abs_balance_residual": float(np.max(np.abs(result.balance_residual))),
        **(getattr(result, "checks", None) or {}),  # "energy_balance", "penetration" (run.checks)
    }
