"""The tables of an output folder: `diagnostics.csv` (one row per stored time), `summary.json`, and
`rows.npz`: the stored rows themselves, what the pictures are drawn from (`write_rows`).

A model's output fields (`Result.fields`) are written by name, whatever the model: each as an array of rows.npz,
as the columns ``min_NAME`` and ``max_NAME`` of diagnostics.csv, and with how it is shown (`Result.field_info`)
under ``"fields"`` of summary.json, beside the model's constants (``"parameters"``). A name that is already one of
the file's own (a field ``x`` in rows.npz, a field ``eta`` beside the column ``min_eta``, a field ``gap`` beside ``min_gap``) is written as
``field_NAME`` (`field_key`)."""

from __future__ import annotations

import csv
import math
import struct
from pathlib import Path

import numpy as np

from .result import ENERGY_KEYS, FIELDS

__all__ = ["DIAGNOSTIC_COLUMNS", "ROWS_FILE", "ROW_ARRAYS", "clean_json", "diagnostic_columns", "field_columns",
           "field_info", "field_key", "field_members", "member_offset", "most_components", "summary_dict",
           "write_diagnostics", "write_npy", "write_rows"]

#: the stored rows of a run, in NumPy's .npz (a zip of .npy arrays: `numpy.load`, or any zip reader)
ROWS_FILE = "rows.npz"
#: zlib's level for rows.npz's compressed members (`write_rows`)
ZLIB_LEVEL = 1
#: rows.npz's own arrays; the output fields come after them (`field_members`)
ROW_ARRAYS = ("t", "steps", "x", *FIELDS, "cells", "weights")


def field_key(name: str, taken) -> str:
    """How an output field `name` is written where the names `taken` are the file's own: `name` itself, else
    ``field_NAME`` (prefixed again while that is taken too)."""
    while name in taken:
        name = f"field_{name}"
    return name


def field_members(names) -> dict[str, str]:
    """The output fields `names` -> their arrays' names in rows.npz (`field_key` past `ROW_ARRAYS`)."""
    return {name: field_key(name, ROW_ARRAYS) for name in names}


def field_info(result) -> dict[str, dict]:
    """How each output field of `result` is shown: its `Result.field_info`, or a plain field's
    (`model.interface.OutputField` of that name) where the result has none."""
    from ..model.interface import OutputField

    info = getattr(result, "field_info", None) or {}
    return {name: info.get(name) or OutputField(name).metadata() for name in (getattr(result, "fields", None) or {})}


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
    "min_gap",
    "contact_length",
    "contact_components",
    "max_contact_force",
)


INTEGER_COLUMNS = ("step", "contact_components")


def diagnostic_columns(dim: int = 1) -> tuple[str, ...]:
    """diagnostics.csv's columns for a run in `dim` dimensions: the contact measure is ``contact_length`` for a
    string (1D) and ``contact_area`` for a membrane (2D); the others are `DIAGNOSTIC_COLUMNS`."""
    measure = "contact_length" if dim == 1 else "contact_area"
    return tuple(measure if c == "contact_length" else c for c in DIAGNOSTIC_COLUMNS)


def field_columns(names, dim: int = 1) -> dict[str, tuple[str, str]]:
    """The output fields `names` -> their (least, largest) columns after `diagnostic_columns(dim)`: ``min_NAME``
    and ``max_NAME``, or of ``field_NAME`` where those are core columns (`field_key`)."""
    core = {c.split("_", 1)[1] for c in diagnostic_columns(dim) if c.startswith(("min_", "max_"))}
    keys = {name: field_key(name, core) for name in names}
    return {name: (f"min_{key}", f"max_{key}") for name, key in keys.items()}


def write_diagnostics(path: Path, result) -> None:
    """diagnostics.csv: one row per stored time, `diagnostic_columns`, then each output field's least and largest
    value over the nodes (`field_columns`)."""
    cols = {
        "step": result.steps,
        "t": result.t,
        **result.energy,
        "balance_residual": result.balance_residual,
        "min_eta": result.eta.min(axis=1),
        "min_gap": result.stored_min_gap,
        "contact_length": result.contact_measure,
        "contact_area": result.contact_measure,
        "contact_components": result.contact_components,
        "max_contact_force": result.contact_force.max(axis=1),
    }
    names = diagnostic_columns(result.dim)
    fields = getattr(result, "fields", None) or {}
    for name, (low, high) in field_columns(fields, result.dim).items():
        values = np.asarray(fields[name], dtype=float)
        cols.update({low: values.min(axis=1), high: values.max(axis=1)})
        names = (*names, low, high)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for i in range(len(result.t)):
            w.writerow([int(cols[c][i]) if c in INTEGER_COLUMNS else repr(float(cols[c][i])) for c in names])


def summary_dict(result) -> dict:
    """summary.json's contents: the run's status, scene, options and checks, the model's constants
    (``parameters``) and how its output fields are shown (``fields``), and the energies at its ends."""
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
        "model_origin": getattr(result, "model_origin", None) or {"name": result.model},
        "penetration_bound": getattr(result, "penetration_bound", "velocity"),
        "law_reads_eps": bool(getattr(result, "law_reads_eps", True)),
        "energy_label": getattr(result, "energy_label", None),
        "parameters": dict(getattr(result, "parameters", None) or {}),
        "fields": field_info(result),
        "r": scene.r,  # nan without eps (scheme projection)
        "dolfinx": dolfinx.__version__,
        "timings": result.timings,
        "counters": getattr(result, "counters", {}),
        "solver": getattr(result, "solver", {}),
        "petsc_options": getattr(result, "petsc_options", {}),
        "min_eta": result.min_eta,
        "min_gap": getattr(result, "min_gap", math.nan),
        "stored_rows": len(result.t),
        "final_energy": {k: float(v[-1]) for k, v in result.energy.items()},
        "initial_energy": float(result.total_energy[0]),
        "max_abs_balance_residual": float(np.max(np.abs(result.balance_residual))),
        **most_components(result),
        **(getattr(result, "checks", None) or {}),  # "energy_balance", "penetration" (run.checks)
    }


def write_rows(path: Path, result) -> None:
    """The stored rows, as the run holds them: `ROWS_FILE` with t, steps, x and the fields `FIELDS` (eta,
    velocity, contact_force in float64, contact as bool), in 2D also cells and weights, then the model's output
    fields (`Result.fields`, named by `field_members`).

    The pictures are drawn from these rows; solution.xdmf holds about `max_frames` of them, so `stringcontact
    plot` reads them back from here to draw the same pictures (`readback.read_output`).

    The .npz layout is NumPy's (a zip of .npy files, read by `numpy.load`), written member by member because
    np.savez compresses all members or none: zlib shrinks contact and contact_force (zero off the contact set)
    to 3 %, but eta and velocity, float64 noise, only by a fifth in ten times the time (Example 1: 47 MB stored,
    24.6 MB all compressed in 0.85 s, 30.6 MB this way). The compressed members are deflated at zlib's level 1
    (`ZLIB_LEVEL`): Example 1's rows.npz in a median 41 against 70 ms at zlib's default level 6, 30.56 against
    30.50 MB (each write the first of a fresh process, as in a run: `benchmarks/bench_rows.py --against-numpy 10
    --fresh`). The pictures wait for this file (`plot.handover` maps eta and velocity from it).
    """
    import zipfile

    arrays = {"t": result.t, "steps": result.steps, "x": result.x, **{name: getattr(result, name) for name in FIELDS}}
    if result.dim == 2:
        arrays.update(cells=result.cells, weights=result.weights)
    fields = getattr(result, "fields", None) or {}
    arrays.update((member, fields[name]) for name, member in field_members(fields).items())
    with zipfile.ZipFile(path, "w") as archive:
        for name, values in arrays.items():
            member = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            member.compress_type = zipfile.ZIP_STORED if name in ("eta", "velocity") else zipfile.ZIP_DEFLATED
            _set_compress_level(member, ZLIB_LEVEL)
            with archive.open(member, "w", force_zip64=True) as f:
                write_npy(f, np.asarray(values))


def _set_compress_level(member, level: int) -> None:
    """A zip member's deflate level: `ZipInfo.compress_level` from Python 3.13, `_compresslevel` before (the
    attribute `ZipFile.write` itself sets there; `ZipFile.open` with a ZipInfo takes the level from it)."""
    try:
        member.compress_level = level
    except AttributeError:  # Python 3.11 and 3.12: ZipInfo has __slots__ and the older name
        member._compresslevel = level


def write_npy(f, a: np.ndarray) -> None:
    """`numpy.lib.format.write_array`'s bytes for a C-ordered array (header 1.0, then the data), the data written
    from the array's own memory. write_array copies an array twice on its way into a zip member (an `nditer`
    buffer, then `tobytes`, in fresh 16 MB chunks whose pages are each faulted in): Example 1's rows.npz took a
    median 80.7 against 69.8 ms this way, both at level 6 (`bench_rows.py --against-numpy 10 --fresh`)."""
    from numpy.lib import format as npy

    a = np.ascontiguousarray(a)
    npy.write_array_header_1_0(f, npy.header_data_from_array_1_0(a))
    f.write(memoryview(a.reshape(-1).view(np.uint8)))


def member_offset(raw, info) -> int | None:
    """Where the bytes of the zip member `info` (a `zipfile.ZipInfo`) begin in the open binary file `raw`: past
    its local header (APPNOTE 4.3.7: 30 bytes, then the name and extra fields, whose lengths differ from the
    central directory's); None if no local header is there. The bytes are the member's compressed ones."""
    raw.seek(info.header_offset)
    local = raw.read(30)
    if local[:4] != b"PK\x03\x04":
        return None
    name_length, extra_length = struct.unpack("<HH", local[26:30])
    return info.header_offset + 30 + name_length + extra_length


def most_components(result) -> dict:
    """{"contact_components": the most components of the contact set at a stored row, and the first time
    with that many}; {} on a rank without the rows (rank 0 writes summary.json)."""
    if not result.has_rows or not len(result.t):
        return {}
    counts = result.contact_components
    first = int(np.argmax(counts))
    return {"contact_components": {"most": int(counts[first]), "first_at": float(result.t[first])}}
