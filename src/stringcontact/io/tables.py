"""An output folder's tables: `diagnostics.csv` (a row per stored time), `summary.json` and `rows.npz` (the stored
rows). A model's output fields go in by name (an array, ``min_NAME``/``max_NAME`` columns, their description under
``"fields"``); a name the file uses itself (``x``, ``eta`` beside ``min_eta``) as ``field_NAME`` (`field_key`).
"""

from __future__ import annotations

import csv
import math
import zipfile
from pathlib import Path

import numpy as np

from .result import ENERGY_KEYS, FIELDS

#: the stored rows of a run, in NumPy's .npz (a zip of .npy arrays: `numpy.load`, or any zip reader)
ROWS_FILE = "rows.npz"
#: zlib's level for rows.npz's compressed members (`write_rows`)
ZLIB_LEVEL = 1
#: rows.npz's own arrays; the output fields come after them (`field_members`)
ROW_ARRAYS = ("t", "steps", "x", *FIELDS, "cells", "weights")
DIAGNOSTIC_COLUMNS = ("step", "t", *ENERGY_KEYS, "balance_residual", "min_eta", "min_gap", "contact_length",
                      "contact_components", "max_contact_force")


def field_key(name: str, taken) -> str:
    """`name`, or ``field_NAME`` (prefixed again while that is taken too) where `name` is one of `taken`."""
    while name in taken:
        name = f"field_{name}"
    return name


def field_members(names) -> dict[str, str]:
    """The output fields `names` -> their arrays' names in rows.npz."""
    return {name: field_key(name, ROW_ARRAYS) for name in names}


def field_info(result) -> dict[str, dict]:
    """How each output field of `result` is shown: its `Result.field_info`, else a plain `OutputField`'s."""
    from ..model.interface import OutputField

    info = getattr(result, "field_info", None) or {}
    return {name: info.get(name) or OutputField(name).metadata() for name in (getattr(result, "fields", None) or {})}


def clean_json(o):
    """`o` as JSON data without NaN/Infinity (not JSON): non-finite numbers as the strings "nan", "inf", "-inf"."""
    if isinstance(o, (np.ndarray, np.generic)):
        o = o.tolist()
    if isinstance(o, dict):
        return {str(k): clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean_json(v) for v in o]
    if isinstance(o, float):
        return o if math.isfinite(o) else str(o)
    return o if o is None or isinstance(o, (bool, int, str)) else str(o)


def field_columns(names) -> dict[str, tuple[str, str]]:
    """The output fields `names` -> their (least, largest) columns of diagnostics.csv, ``min_NAME`` and ``max_NAME``."""
    core = {c.split("_", 1)[1] for c in DIAGNOSTIC_COLUMNS if c.startswith(("min_", "max_"))}
    return {name: (f"min_{field_key(name, core)}", f"max_{field_key(name, core)}") for name in names}


def write_diagnostics(path: Path, result) -> None:
    """diagnostics.csv: one row per stored time, `DIAGNOSTIC_COLUMNS` (``contact_area`` for ``contact_length`` of a
    membrane), then each output field's least and largest value (`field_columns`)."""
    measure = "contact_length" if result.dim == 1 else "contact_area"
    cols = {"step": result.steps, "t": result.t, **result.energy, "balance_residual": result.balance_residual,
            "min_eta": result.eta.min(axis=1), "min_gap": result.stored_min_gap, measure: result.contact_measure,
            "contact_components": result.contact_components, "max_contact_force": result.contact_force.max(axis=1)}
    names = [measure if c == "contact_length" else c for c in DIAGNOSTIC_COLUMNS]
    fields = getattr(result, "fields", None) or {}
    for name, (low, high) in field_columns(fields).items():
        values = np.asarray(fields[name], dtype=float)
        cols.update({low: values.min(axis=1), high: values.max(axis=1)})
        names += [low, high]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for i in range(len(result.t)):
            w.writerow([int(cols[c][i]) if c in ("step", "contact_components") else repr(float(cols[c][i])) for c in names])


def summary_dict(result) -> dict:
    """summary.json's contents: the run's status, scene, options, checks, the model's constants and how its output
    fields are shown, and the energies at its ends."""
    import dolfinx

    return {
        "status": result.status, "message": result.message, "scene": result.scene.as_dict(), "scheme": result.scheme,
        "penalty": result.penalty, "mass": result.mass, "model": result.model,
        "model_origin": result.model_origin or {"name": result.model}, "penetration_bound": result.penetration_bound,
        "law_reads_eps": bool(result.law_reads_eps), "energy_label": result.energy_label,
        "parameters": dict(result.parameters or {}), "fields": field_info(result), "r": result.scene.r,
        "dolfinx": dolfinx.__version__, "timings": result.timings, "counters": result.counters, "solver": result.solver,
        "petsc_options": result.petsc_options, "min_eta": result.min_eta, "min_gap": result.min_gap,
        "stored_rows": len(result.t), "final_energy": {k: float(v[-1]) for k, v in result.energy.items()},
        "initial_energy": float(result.total_energy[0]),
        "max_abs_balance_residual": float(np.max(np.abs(result.balance_residual))),
        **most_components(result), **(result.checks or {}),  # "energy_balance", "penetration" (run.checks)
    }


def write_rows(path: Path, result) -> None:
    """`ROWS_FILE`: t, steps, x, `FIELDS`, in 2D cells and weights, the output fields (`field_members`); eta and
    velocity stored, the rest deflated at `ZLIB_LEVEL` (np.savez: all or none): Example 1's in 41 ms against 70 at
    level 6 (`benchmarks/bench_rows.py --against-numpy 10 --fresh`)."""
    arrays = {"t": result.t, "steps": result.steps, "x": result.x, **{name: getattr(result, name) for name in FIELDS}}
    if result.dim == 2:
        arrays.update(cells=result.cells, weights=result.weights)
    fields = getattr(result, "fields", None) or {}
    arrays.update((member, fields[name]) for name, member in field_members(fields).items())
    with zipfile.ZipFile(path, "w") as archive:
        for name, values in arrays.items():
            member = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            member.compress_type = zipfile.ZIP_STORED if name in ("eta", "velocity") else zipfile.ZIP_DEFLATED
            try:  # ZipFile.open takes the level from the ZipInfo: `compress_level` from Python 3.13, before it
                member.compress_level = ZLIB_LEVEL
            except AttributeError:
                member._compresslevel = ZLIB_LEVEL
            with archive.open(member, "w", force_zip64=True) as f:
                write_npy(f, np.asarray(values))


def write_npy(f, a: np.ndarray) -> None:
    """`numpy.lib.format.write_array`'s bytes (header 1.0, then the data) written from the array's own memory, not
    copied twice on its way into a zip member: Example 1's rows.npz 69.8 against 80.7 ms (`bench_rows.py`)."""
    from numpy.lib import format as npy

    a = np.ascontiguousarray(a)
    npy.write_array_header_1_0(f, npy.header_data_from_array_1_0(a))
    f.write(memoryview(a.reshape(-1).view(np.uint8)))


def most_components(result) -> dict:
    """{"contact_components": the most components of the contact set at a stored row, and the first time with that
    many}; {} on a rank without the rows."""
    if not result.has_rows or not len(result.t):
        return {}
    counts = result.contact_components
    first = int(np.argmax(counts))
    return {"contact_components": {"most": int(counts[first]), "first_at": float(result.t[first])}}
