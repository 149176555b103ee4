"""An output folder read back into a :class:`Result` (``read_output``): the stored rows from ``rows.npz`` (those
the run drew its pictures from), the energies from ``diagnostics.csv``, the scene, options and output fields from
``summary.json``, each checked before its data are read (a defect: one ValueError line naming the file, exit 2);
and `solution.xdmf`'s time series (``read_xdmf``: the XML only).
"""

from __future__ import annotations

import csv
import json
import warnings
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
from numpy.lib import format as npy

from ..errors import OutputError, SceneError, one_line
from ..scene.limits import MAX_MEMBRANE_NODES, MAX_STORED_BYTES
from ..scene.names import DEFAULT_MODEL, DEFAULT_SCHEME
from .publish import small_regular_file
from .result import ENERGY_KEYS, FIELDS, Result
from .tables import ROWS_FILE, field_members

FILES = ("summary.json", "diagnostics.csv", ROWS_FILE)
#: The largest summary.json read (a run's is a few kB; 1000 output times add 20 kB).
MAX_JSON_BYTES = 10_000_000
#: The most output fields a folder may name (a model has a few).
MAX_OUTPUT_FIELDS = 64
#: The keys of an output field's description in summary.json that `OutputField` takes.
FIELD_KEYS = ("label", "unit", "colours", "scale", "linear_share", "symmetric", "surface")


def read_output(folder):
    """A :class:`Result` rebuilt from an output folder written by `stringcontact run --out`: the run's own rows."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"plot: {folder} is not a folder (give the --out folder of `stringcontact run`)")
    missing = [name for name in FILES if not (folder / name).is_file()]
    if missing and (folder / "summary.json").is_file():  # an interrupted run says so before what it lacks
        _check_status(folder, _load_json(folder / "summary.json"))
    if missing:
        raise ValueError(f"plot: {folder} is not a stringcontact output folder (missing {', '.join(missing)})")
    summary, scene = _read_summary(folder / "summary.json")
    info = _field_info(folder / "summary.json", summary)
    column = _read_diagnostics(folder / "diagnostics.csv")
    x, fields, mesh = _read_rows(folder / ROWS_FILE, column, scene.dim, info)
    outputs = {name: fields.pop(name) for name in info}
    given = {key: summary.get(key, default) for key, default in (
        ("penalty", "explicit"), ("mass", "lumped"), ("model", DEFAULT_MODEL), ("scheme", DEFAULT_SCHEME),
        ("penetration_bound", None), ("energy_label", None), ("status", "complete"), ("message", ""),
        ("timings", {}), ("counters", {}), ("solver", {}), ("petsc_options", {}))}
    return Result(
        scene=scene, x=x, t=column["t"], steps=column["step"].astype(np.int64), eta=fields["eta"],
        velocity=fields["velocity"], contact=np.asarray(fields["contact"], dtype=float) > 0.5,
        contact_force=fields["contact_force"], energy={key: column[key] for key in ENERGY_KEYS},
        min_eta=float(summary.get("min_eta", np.min(fields["eta"]))), min_gap=float(summary.get("min_gap", "nan")),
        model_origin=summary.get("model_origin") or {}, law_reads_eps=bool(summary.get("law_reads_eps", True)),
        fields=outputs, field_info=info, parameters=_parameters(folder / "summary.json", summary), **given, **mesh)


def _load_json(path: Path) -> dict:
    text = small_regular_file(path, MAX_JSON_BYTES)  # never a FIFO waited on, a device read without end
    if text is None:
        raise ValueError(f"plot: {path} is not a regular file of at most {MAX_JSON_BYTES} bytes (a run's summary.json "
                         "is a few kB)")
    try:
        data = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"plot: {path} is not valid JSON ({one_line(exc, 200)})") from None
    except RecursionError:
        raise ValueError(f"plot: {path} is not a run's JSON (nested too deeply)") from None
    if not isinstance(data, dict):
        raise ValueError(f"plot: {path} holds a JSON {type(data).__name__}, not the object a run writes")  # noqa: TRY004 - bad input: exit 2
    return data


def _check_status(folder: Path, summary: dict) -> None:
    if summary.get("status", "complete") != "complete":
        raise ValueError(f"plot: {folder} holds a run that did not complete (status {summary['status']!r})")


def _read_summary(path: Path):
    from ..model.registry import registered
    from ..scene import Scene

    summary = _load_json(path)
    _check_status(path.parent, summary)
    if not isinstance(summary.get("scene"), dict):
        raise ValueError(f"plot: {path} has no 'scene' object")  # noqa: TRY004 - bad input: exit 2
    scene_data = dict(summary["scene"])
    if scene_data.get("model") not in registered():  # an uninstalled plugin: redrawing needs no model
        scene_data.pop("model", None)  # (its name stays in Result.model)
    try:
        with warnings.catch_warnings():  # the scene was already warned about when it ran
            warnings.simplefilter("ignore")
            scene = Scene.from_dict(scene_data)
    except (SceneError, TypeError, ValueError, KeyError) as exc:
        raise ValueError(f"plot: {path}: its scene is not valid ({one_line(exc, 200)})") from None
    return summary, scene


def _field_info(path: Path, summary: dict) -> dict:
    """summary.json's ``"fields"``: name -> its description, each checked by `OutputField` itself."""
    from ..model.interface import OutputField

    fields = summary.get("fields", {})
    if not isinstance(fields, dict) or len(fields) > MAX_OUTPUT_FIELDS:
        raise ValueError(f"plot: {path}: its 'fields' is not an object of at most {MAX_OUTPUT_FIELDS} output fields")
    info = {}
    for name, entry in fields.items():
        try:
            if not isinstance(entry, dict):
                raise TypeError(f"a JSON {type(entry).__name__}, not an object")
            run = {key: entry.get(key, False) for key in ("derived", "internal")}  # the run's, not the field's
            if not all(isinstance(value, bool) for value in run.values()):
                raise TypeError("its derived and internal must be true or false")
            info[name] = OutputField(name, **{key: entry[key] for key in FIELD_KEYS if key in entry}).metadata()
            info[name] |= {"derived": run["derived"]} | ({"internal": True} if run["internal"] else {})
        except (TypeError, ValueError) as exc:
            raise ValueError(f"plot: {path}: its output field {name!r} is not valid ({one_line(exc, 200)})") from None
    return info


def _parameters(path: Path, summary: dict) -> dict[str, float]:
    """summary.json's ``"parameters"``: the model's constants, each a number ({} if it has none)."""
    given = summary.get("parameters", {})
    if not isinstance(given, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in given.values()):
        raise ValueError(f"plot: {path}: its 'parameters' is not an object of numbers (the model's constants)")
    return {str(name): float(value) for name, value in given.items()}


def read_xdmf(path) -> tuple[str | None, dict[str, list[tuple[float, str]]]]:
    """``(geometry, series)`` of `solution.xdmf`: the first grid's points' HDF5 reference (None without a grid) and
    {field: [(t, "solution.h5:/eta_0"), ...]} in file order; OutputError naming the file (the parser's error its
    ``__cause__``) if it is not well-formed (a truncated write), has no temporal collection or a time no number."""
    try:
        collection = ET.parse(path).getroot().find("Domain/Grid[@CollectionType='Temporal']")
        if collection is None:
            raise ValueError("no temporal collection of grids")
        geometry, series = None, {}
        for grid in collection.findall("Grid"):
            t = float(grid.find("Time").get("Value"))
            geometry = geometry or (grid.find("Geometry/DataItem").text or "").strip() or None
            for attribute in grid.findall("Attribute"):
                series.setdefault(attribute.get("Name"), []).append((t, (attribute.find("DataItem").text or "").strip()))
    except (ET.ParseError, OSError, TypeError, ValueError, AttributeError) as exc:
        raise OutputError(f"{path} is not a readable XDMF file ({one_line(exc, 300)})") from exc
    return geometry, series


def _read_diagnostics(path: Path) -> dict[str, np.ndarray]:
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows:
            raise ValueError("it has no rows")
        return {key: np.array([float(r[key]) for r in rows]) for key in ("step", "t", *ENERGY_KEYS)}
    except KeyError as exc:
        raise ValueError(f"plot: {path} has no column {exc}") from None
    except (UnicodeDecodeError, ValueError, TypeError, csv.Error) as exc:
        raise ValueError(f"plot: {path} is not a diagnostics table ({one_line(exc, 200)})") from None


def _unreadable(path: Path, exc: BaseException) -> ValueError:
    if str(exc).startswith("plot: "):
        return exc
    return ValueError(f"plot: {path} is not a readable .npz file ({type(exc).__name__}: {one_line(exc, 200)})")


def _read_rows(path: Path, column: dict, dim: int, info: dict):
    """x, the fields and (2D) {"cells", "weights"} from `ROWS_FILE`, checked against diagnostics.csv's rows."""
    members = field_members(info)
    names = ("t", "steps", "x", *FIELDS) + (("cells", "weights") if dim == 2 else ()) + tuple(members.values())
    _check_row_headers(path, names, len(column["t"]))
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in names}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise _unreadable(path, exc) from None
    k, n = len(column["t"]), len(arrays["x"])
    shapes = {"t": (k,), "steps": (k,), "x": (n,) if dim == 1 else (n, 2), **{name: (k, n) for name in (*FIELDS, *members.values())}}
    if dim == 2:
        shapes["weights"] = (n,)
        cells = arrays["cells"]
        if cells.ndim != 2 or cells.shape[1] != 3 or not cells.size or cells.min() < 0 or cells.max() >= n:
            raise ValueError(f"plot: {path}: its cells are not triangles of its {n} nodes")
    wrong = [f"{name} {arrays[name].shape} (expected {shape})" for name, shape in shapes.items() if arrays[name].shape != shape]
    if wrong:
        raise ValueError(f"plot: {path} does not hold the {k} rows of diagnostics.csv on {n} nodes: {', '.join(wrong)}")
    if not np.array_equal(arrays["t"], column["t"]):
        raise ValueError(f"plot: {path}: its times are not those of diagnostics.csv")
    fields = {name: arrays[name] for name in FIELDS} | {name: arrays[member] for name, member in members.items()}
    arrays_and_fields = [("array", n, arrays[n]) for n in ("t", "x", "weights")[:3 if dim == 2 else 2]]
    for kind, name, values in arrays_and_fields + [("field", n, v) for n, v in fields.items()]:
        if not np.all(np.isfinite(values)):  # a NaN in eta failed half-way through the pictures
            raise ValueError(f"plot: {path}: its {kind} {name!r} holds a value that is not finite; allowed: finite numbers")
    x = arrays["x"]
    if len(x) < 2 or not np.all(np.ptp(x, axis=0) > 0) or (dim == 1 and not np.all(np.diff(x) > 0)):
        raise ValueError(f"plot: {path}: its nodes x are not {'increasing' if dim == 1 else 'spread over a domain'}; "
                         "allowed: the nodes of a mesh")
    mesh = {"cells": arrays["cells"].astype(np.int64), "weights": arrays["weights"]} if dim == 2 else {}
    return x, fields, mesh


def _check_row_headers(path: Path, names: tuple, k: int) -> None:
    """Each member's .npy header, not its data: real or integer dtypes (bool for contact), at most k rows of
    `MAX_MEMBRANE_NODES` nodes, in all the run's own stored-row budget: a zip bomb is refused undecompressed."""
    total = 0
    try:
        with zipfile.ZipFile(path) as archive:
            for name in names:
                if f"{name}.npy" not in archive.namelist():
                    raise ValueError(f"plot: {path} has no array {name!r}")
                with archive.open(f"{name}.npy") as f:
                    version = npy.read_magic(f)
                    shape, _, dtype = npy.read_array_header_1_0(f) if version == (1, 0) else npy.read_array_header_2_0(f)
                integer = name in ("steps", "cells")
                kinds = "iu" if integer else "fiu" + ("b" if name == "contact" else "")
                if dtype.kind not in kinds or dtype.fields is not None or dtype.itemsize > 8:
                    raise ValueError(f"plot: {path}: its array {name!r} holds {dtype} values; allowed: "
                                     f"{'integers' if integer else 'real numbers'}")
                if any(d > max(MAX_MEMBRANE_NODES * 2, k) for d in shape):
                    raise ValueError(f"plot: {path}: its array {name!r} declares the shape {shape}; allowed: at most {k} "
                                     f"rows (diagnostics.csv) of at most {MAX_MEMBRANE_NODES} nodes")
                total += int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, RuntimeError) as exc:
        raise _unreadable(path, exc) from None
    if total > MAX_STORED_BYTES:
        raise ValueError(f"plot: {path} declares {total / 1e9:.3g} GB of arrays; allowed: at most "
                         f"{MAX_STORED_BYTES / 1e9:g} GB (a run's stored rows)")
