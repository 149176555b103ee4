"""Reading an output folder back into a :class:`Result`: ``read_output(folder)``.

The stored rows come from ``rows.npz`` (`tables.write_rows`: every stored row, what the run drew its
pictures from, so that ``stringcontact plot`` draws the same pictures); a folder without it (written before
it existed), or ``read_output(folder, from_xdmf=True)``, gives the XDMF frames instead (about `max_frames`
of the stored rows). The XDMF frames come from ``solution.xdmf``/``.h5`` (the layout of `stringcontact.io.xdmf`), the energies from
``diagnostics.csv``, the scene and options from ``summary.json``. A membrane's folder (a 2D scene) also
gives its triangles (the HDF5 topology), and the nodal areas are computed from them. The ``.h5`` is read with pyfive (pure
Python): the h5py wheel bundles its own libhdf5, which clashes with the system libhdf5 that dolfinx has
already loaded ("Not a datatype"). Every defect of the folder is a ValueError with one line naming the
file and what is wrong with it (the CLI's exit code 2).

The model's output fields come back by name, whatever the model: their names and how each is shown from
summary.json's ``"fields"`` (checked as an `OutputField` is), their rows from rows.npz (or the XDMF's attributes
of those names), the model's constants from its ``"parameters"``. A folder whose summary.json has no
``"fields"`` (written before it had them) gives rows.npz's further arrays as plain fields.
"""

from __future__ import annotations

import csv
import json
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import OutputError, SceneError, one_line
from ..scene.limits import MAX_MEMBRANE_NODES, MAX_STORED_BYTES
from ..scene.names import DEFAULT_MODEL, DEFAULT_SCHEME
from .manifest import small_regular_file
from .result import ENERGY_KEYS, FIELDS, OBSTACLE_FIELD, Result, canonical_cells, node_sort_key
from .tables import ROW_ARRAYS, ROWS_FILE, field_members

FILES = ("solution.xdmf", "solution.h5", "diagnostics.csv", "summary.json")
#: The largest summary.json read (a run's is a few kB; 1000 output times add 20 kB).
MAX_JSON_BYTES = 10_000_000
#: The most nodes a folder may hold (the largest membrane; a string has at most 1e5 + 1) and the most bytes
#: its stored rows may take (the run's own budget, `scene.limits.MAX_STORED_BYTES`): checked from the files'
#: headers before any array is read, so a small crafted file cannot claim gigabytes.
MAX_NODES = MAX_MEMBRANE_NODES
#: The most output fields a folder may name (a model has a few).
MAX_OUTPUT_FIELDS = 64


def read_output(folder, from_xdmf: bool = False):
    """A :class:`Result` rebuilt from an output folder written by `stringcontact run --out`.

    Its rows are the run's stored rows (``rows.npz``), the same arrays as the run's Result; without that
    file, or `from_xdmf`, the XDMF frames (about `max_frames` of the stored rows) with the diagnostics of
    those rows: arrays ordered by x (2D: by x, then y) like the in-memory result, `contact` boolean again,
    in 2D `cells` the triangles in the solver's order and `weights` the lumped nodal areas.
    """
    folder = _check_folder(Path(folder))
    summary, scene = _read_summary(folder / "summary.json")
    info = _field_info(folder / "summary.json", summary)
    column = _read_diagnostics(folder / "diagnostics.csv")
    if (folder / ROWS_FILE).is_file() and not from_xdmf:
        source = folder / ROWS_FILE
        x, fields, mesh = _read_rows(source, column, scene.dim, info)
    else:
        geometry, series = _read_series(folder / "solution.xdmf")
        column = _frame_rows(column, series, folder)
        topology = _topology(folder / "solution.xdmf") if scene.dim == 2 else None
        series = _field_series(folder / "solution.xdmf", series, info)
        source = folder / "solution.h5"
        x, fields, mesh = _read_fields(source, geometry, series, topology)
    _check_fields(source, fields)
    outputs = {name: fields.pop(name) for name in list(fields) if name not in FIELDS}
    return Result(
        scene=scene,
        x=x,
        t=column["t"],
        steps=column["step"].astype(np.int64),
        eta=fields["eta"],
        velocity=fields["velocity"],
        contact=fields["contact"] > 0.5,
        contact_force=fields["contact_force"],
        energy={key: column[key] for key in ENERGY_KEYS},
        min_eta=float(summary.get("min_eta", np.min(fields["eta"]))),
        min_gap=float(summary.get("min_gap", "nan")),  # a folder written before the gap was recorded: not known
        penalty=summary.get("penalty", "explicit"),
        mass=summary.get("mass", "lumped"),
        model=summary.get("model", DEFAULT_MODEL),
        model_origin=summary.get("model_origin") or {},
        # a folder written before the model recorded its bound: the elastic variant's spring, else the velocity penalty
        penetration_bound=summary.get("penetration_bound", "spring" if summary.get("model") == "elastic" else "velocity"),
        energy_label=summary.get("energy_label"),
        law_reads_eps=bool(summary.get("law_reads_eps", True)),
        status=summary.get("status", "complete"),
        timings=summary.get("timings", {}),
        counters=summary.get("counters", {}),
        solver=summary.get("solver", {}),
        petsc_options=summary.get("petsc_options", {}),
        message=summary.get("message", ""),
        scheme=summary.get("scheme", DEFAULT_SCHEME),
        fields=outputs,
        field_info={name: _plain(name, info) for name in outputs},
        parameters=_parameters(folder / "summary.json", summary),
        **mesh,
    )


def _check_fields(path: Path, fields: dict) -> None:
    """Every field read back, η, v and a model's own alike: real numbers, finite (an inf or NaN model field was drawn,
    or failed in matplotlib's "Invalid vmin or vmax"; a string or complex one was an internal error)."""
    for name, values in fields.items():
        values = np.asarray(values)
        if values.dtype.kind not in "fiub":
            raise ValueError(f"plot: {path}: its field {name!r} holds {values.dtype} values; allowed: real numbers")
        if not np.all(np.isfinite(values)):
            raise ValueError(f"plot: {path}: its field {name!r} holds a value that is not finite; allowed: finite numbers")


def _check_folder(folder: Path) -> Path:
    if not folder.is_dir():
        raise ValueError(f"plot: {folder} is not a folder (give the --out folder of `stringcontact run`)")
    missing = [n for n in FILES if not (folder / n).is_file()]
    if missing and (folder / "summary.json").is_file():  # an interrupted run says so before what it lacks
        with_status = _load_json(folder / "summary.json")
        _check_status(folder, with_status)
    if missing:
        raise ValueError(f"plot: {folder} is not a stringcontact output folder (missing {', '.join(missing)})")
    return folder


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
    if scene_data.get("model") not in registered():  # an uninstalled plugin, or a module path of an older folder:
        scene_data.pop("model", None)  # redrawing needs no model (its name stays in Result.model)
    try:
        with warnings.catch_warnings():  # the scene was already warned about when it ran
            warnings.simplefilter("ignore")
            scene = Scene.from_dict(scene_data)
    except (SceneError, TypeError, ValueError, KeyError) as exc:
        raise ValueError(f"plot: {path}: its scene is not valid ({one_line(exc, 200)})") from None
    return summary, scene


#: The keys of an output field's description in summary.json, and the types each must have.
FIELD_KEYS = {"label": str, "unit": str, "colours": list, "scale": str, "linear_share": float, "symmetric": bool,
              "surface": bool, "derived": bool}
#: The longest label or unit read (a title's line).
MAX_LABEL = 200


def _field_info(path: Path, summary: dict) -> dict | None:
    """summary.json's ``"fields"``: name -> its description, each checked as an `OutputField` is; None for a
    folder written before summary.json had them."""
    fields = summary.get("fields")
    if fields is None:
        return None
    if not isinstance(fields, dict) or len(fields) > MAX_OUTPUT_FIELDS:
        raise ValueError(f"plot: {path}: its 'fields' is not an object of at most {MAX_OUTPUT_FIELDS} output fields")
    return {name: _field_entry(path, name, entry) for name, entry in fields.items()}


def _field_entry(path: Path, name: str, entry) -> dict:
    """One output field's description, as `OutputField.metadata` gives it; a ValueError naming what is wrong."""
    from ..model.interface import OutputField

    try:
        if not isinstance(entry, dict):
            raise TypeError(f"a JSON {type(entry).__name__}, not an object")
        given = {key: _typed(key, entry[key]) for key in FIELD_KEYS if key in entry}
        derived = given.pop("derived", False)
        if "colours" in given:
            given["colours"] = tuple(tuple(c) if isinstance(c, list) else c for c in given["colours"])
        field = OutputField(name, **given)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"plot: {path}: its output field {name!r} is not valid ({one_line(exc, 200)})") from None
    return field.metadata() | {"derived": derived}


def _typed(key: str, value):
    """`value` of the description's `key` if it has the type `FIELD_KEYS` gives (a number for a float), else a TypeError."""
    kind = FIELD_KEYS[key]
    number = kind is float and isinstance(value, (int, float)) and not isinstance(value, bool)
    if not (number or kind is not float and isinstance(value, kind)):
        raise TypeError(f"its {key} is a JSON {type(value).__name__}")
    if kind is str and len(value) > MAX_LABEL:
        raise TypeError(f"its {key} is longer than {MAX_LABEL} characters")
    return float(value) if number else value


def _plain(name: str, info: dict | None) -> dict:
    """The description of the output field `name`: summary.json's (`info`), else a plain field's."""
    from ..model.interface import OutputField

    return info[name] if info is not None else OutputField(name).metadata()


def _parameters(path: Path, summary: dict) -> dict[str, float]:
    """summary.json's ``"parameters"``: the model's constants, each a number ({} if it has none)."""
    given = summary.get("parameters", {})
    if not isinstance(given, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in given.values()):
        raise ValueError(f"plot: {path}: its 'parameters' is not an object of numbers (the model's constants)")
    return {str(name): float(value) for name, value in given.items()}


def _row_fields(path: Path, info: dict | None) -> tuple[str, ...]:
    """The output fields to read from rows.npz: those `info` names; without it (an older folder) the arrays
    beyond `ROW_ARRAYS` whose names could be a field's."""
    if info is not None:
        return tuple(info)
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            members = [name[:-4] for name in archive.namelist() if name.endswith(".npy")]
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise ValueError(f"plot: {path} is not a readable .npz file ({type(exc).__name__}: {one_line(exc, 200)})") from None
    return tuple(name for name in members if name not in ROW_ARRAYS and name.isidentifier())[:MAX_OUTPUT_FIELDS]


def _field_series(path: Path, series: dict, info: dict | None) -> dict:
    """`series` of the XDMF's `FIELDS` and of its output fields (those `info` names; without it, the attributes
    beyond `FIELDS` and the moving obstacle's), each at the times of the others."""
    names = [name for name in series if name not in FIELDS and name != OBSTACLE_FIELD] if info is None else [
        name for name in info if name in series]
    chosen = {name: series[name] for name in (*FIELDS, *names[:MAX_OUTPUT_FIELDS])}
    times = [t for t, _ in series[FIELDS[0]]]
    if any([t for t, _ in frames] != times for frames in chosen.values()):
        raise ValueError(f"plot: {path}: its fields are not given at the same times")
    return chosen


def read_xdmf(path) -> tuple[str | None, dict[str, list[tuple[float, str]]]]:
    """The mesh and the time series of `solution.xdmf`: ``(geometry, series)``.

    `geometry` is the HDF5 reference of the first grid's point coordinates (``"solution.h5:/geometry"``;
    None if there is no grid); `series` is {field: [(t, "solution.h5:/eta_0"), ...]} in file order. Raises
    OutputError naming the file, with the parser's error as its ``__cause__``, if the file is not
    well-formed XML (a truncated write), has no temporal collection, or holds a time that is not a number.
    """
    try:
        root = ET.parse(path).getroot()
        collection = root.find("Domain/Grid[@CollectionType='Temporal']")
        if collection is None:
            raise ValueError("no temporal collection of grids")
        geometry, series = None, {}
        for grid in collection.findall("Grid"):
            t = float(grid.find("Time").get("Value"))
            if geometry is None:
                geometry = (grid.find("Geometry/DataItem").text or "").strip() or None
            for attribute in grid.findall("Attribute"):
                ref = (attribute.find("DataItem").text or "").strip()
                series.setdefault(attribute.get("Name"), []).append((t, ref))
    except (ET.ParseError, OSError, TypeError, ValueError, AttributeError) as exc:
        raise OutputError(f"{path} is not a readable XDMF file ({one_line(exc, 300)})") from exc
    return geometry, series


def xdmf_series(path) -> dict[str, list[tuple[float, str]]]:
    """The time series of `solution.xdmf`, {field: [(t, "solution.h5:/eta_0"), ...]} (see `read_xdmf`)."""
    return read_xdmf(path)[1]


def _read_series(path: Path):
    try:
        geometry, series = read_xdmf(path)
    except OutputError as exc:
        raise ValueError(f"plot: {path} cannot be read ({one_line(exc.__cause__, 200)})") from None
    if geometry is None:
        raise ValueError(f"plot: {path}: no mesh geometry in the XDMF file")
    absent = [f for f in FIELDS if f not in series]
    if absent:
        raise ValueError(f"plot: {path} has no time series {', '.join(absent)}")
    times = [np.array([t for t, _ in series[name]]) for name in FIELDS]
    if times[0].size == 0 or any(not np.array_equal(times[0], other) for other in times[1:]):
        raise ValueError(f"plot: {path}: its fields are not given at the same times")
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


def _read_rows(path: Path, column: dict, dim: int, info: dict | None):
    """x, the fields (the output fields of `info` by name: `_field_info`) and (2D) {"cells", "weights"} from
    `ROWS_FILE`, checked against diagnostics.csv's rows."""
    import zipfile

    core = ("t", "steps", "x", *FIELDS) + (("cells", "weights") if dim == 2 else ())
    members = field_members(_row_fields(path, info))
    names = core + tuple(members.values())
    _check_row_headers(path, names, len(column["t"]), dim)
    try:
        with np.load(path, allow_pickle=False) as npz:
            absent = [name for name in names if name not in npz.files]
            if absent:
                raise ValueError(f"plot: {path} has no array {', '.join(map(repr, absent))}")
            arrays = {name: npz[name] for name in names}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        if str(exc).startswith("plot: "):
            raise
        raise ValueError(f"plot: {path} is not a readable .npz file ({type(exc).__name__}: {one_line(exc, 200)})") from None
    k, n = len(column["t"]), len(arrays["x"])
    shapes = {"t": (k,), "steps": (k,), "x": (n,) if dim == 1 else (n, 2),
              **{name: (k, n) for name in (*FIELDS, *members.values())}}
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
    _check_row_values(path, arrays, dim)
    fields = {name: arrays[name] for name in FIELDS} | {name: arrays[member] for name, member in members.items()}
    fields["contact"] = fields["contact"].astype(float)  # as read from the XDMF: Result takes contact > 0.5
    mesh = {"cells": arrays["cells"].astype(np.int64), "weights": arrays["weights"]} if dim == 2 else {}
    return arrays["x"], fields, mesh


def _check_row_headers(path: Path, names: tuple, k: int, dim: int) -> None:
    """Each member's .npy header read (not its data): real or integer dtypes (bool for contact), at most
    MAX_NODES nodes and k rows, and no more than the run's own stored-row budget in all. A zip bomb (1.9 MB
    declaring 1.9 GB) or a string, complex or structured member is refused before anything is decompressed."""
    import zipfile

    from numpy.lib import format as npy

    try:
        with zipfile.ZipFile(path) as archive:
            headers = {}
            for name in names:
                if f"{name}.npy" not in archive.namelist():
                    raise ValueError(f"plot: {path} has no array {name!r}")
                with archive.open(f"{name}.npy") as f:
                    version = npy.read_magic(f)
                    shape, _, dtype = (npy.read_array_header_1_0(f) if version == (1, 0) else npy.read_array_header_2_0(f))
                headers[name] = shape, dtype
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, RuntimeError) as exc:
        if str(exc).startswith("plot: "):
            raise
        raise ValueError(f"plot: {path} is not a readable .npz file ({type(exc).__name__}: {one_line(exc, 200)})") from None
    total = 0
    for name, (shape, dtype) in headers.items():
        integer = name in ("steps", "cells")
        ok = dtype.kind in ("i", "u") if integer else dtype.kind in ("f", "i", "u") or (name == "contact" and dtype.kind == "b")
        if not ok or dtype.fields is not None or dtype.itemsize > 8:
            allowed = "integers" if integer else "real numbers"
            raise ValueError(f"plot: {path}: its array {name!r} holds {dtype} values; allowed: {allowed}")
        if any(d > max(MAX_NODES * 2, k) for d in shape):
            raise ValueError(f"plot: {path}: its array {name!r} declares the shape {shape}; allowed: at most {k} rows "
                             f"(diagnostics.csv) of at most {MAX_NODES} nodes")
        total += int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
    if total > MAX_STORED_BYTES:
        raise ValueError(f"plot: {path} declares {total / 1e9:.3g} GB of arrays; allowed: at most "
                         f"{MAX_STORED_BYTES / 1e9:g} GB (a run's stored rows)")


def _check_row_values(path: Path, arrays: dict, dim: int) -> None:
    """Finite values (a NaN in eta would fail half-way through the pictures) and a grid of distinct nodes."""
    for name in ("t", "x", "eta", "velocity", "contact_force") + (("weights",) if dim == 2 else ()):
        if not np.all(np.isfinite(arrays[name])):
            raise ValueError(f"plot: {path}: its array {name!r} holds a value that is not finite; allowed: finite numbers")
    x = arrays["x"]
    spread = np.ptp(x, axis=0) if len(x) else np.zeros(1)
    if len(x) < 2 or not np.all(spread > 0) or (dim == 1 and not np.all(np.diff(x) > 0)):
        raise ValueError(f"plot: {path}: its nodes x are not {'increasing' if dim == 1 else 'spread over a domain'}; "
                         "allowed: the nodes of a mesh")


def _frame_rows(column: dict, series: dict, folder: Path) -> dict[str, np.ndarray]:
    """The diagnostics rows at the XDMF frames' times (the XDMF holds a subset of the stored rows)."""
    frame_t = np.array([t for t, _ in series[FIELDS[0]]])
    t = column["t"]
    tol = 1e-12 * max(1.0, float(np.max(np.abs(t))))
    right = np.searchsorted(t, frame_t).clip(0, len(t) - 1)
    left = (right - 1).clip(0, len(t) - 1)
    at = np.where(np.abs(t[left] - frame_t) <= np.abs(t[right] - frame_t), left, right)
    if np.any(np.abs(t[at] - frame_t) > tol):
        raise ValueError(f"plot: {folder}: the times in solution.xdmf are not rows of diagnostics.csv")
    return {key: values[at] for key, values in column.items()}


def _h5_path(ref: str) -> str:
    return ref.split(":", 1)[1]  # "solution.h5:/eta_0" -> "/eta_0"


def _read_fields(path: Path, geometry: str, series: dict, topology=None):
    """x (sorted) and each field of `series` as a (frames, nodes) array in that order, read from the HDF5 file; with a
    `topology` (2D: its HDF5 reference and nodes per cell) also {"cells", "weights"} of the sorted nodes."""
    import pyfive  # pure-Python HDF5: h5py's wheel clashes with the libhdf5 that dolfinx has already loaded

    mesh = {}
    try:
        with pyfive.File(str(path)) as h5:
            points = np.asarray(_bounded(h5[_h5_path(geometry)], 3 * MAX_NODES, path)[:], dtype=float)
            x_all = points[:, 0] if topology is None else points[:, :2]
            order = np.argsort(_sort_key(x_all), kind="stable")
            fields = {name: np.stack([_dataset(h5, ref, len(x_all), path)[order] for _, ref in frames]) for name, frames in series.items()}
            if topology is not None:
                mesh = _mesh(_cells(h5, *topology, len(x_all), path), x_all, order)
    except ValueError as exc:
        if str(exc).startswith("plot: "):
            raise
        raise ValueError(f"plot: {path} is not a readable HDF5 file ({one_line(exc, 200)})") from None
    except Exception as exc:  # noqa: BLE001 - pyfive on a damaged file fails in many ways: one line, naming the file
        raise ValueError(f"plot: {path} is not a readable HDF5 file ({type(exc).__name__}: {one_line(exc, 200)})") from None
    return x_all[order], fields, mesh


def _sort_key(x: np.ndarray) -> np.ndarray:
    """The solver's node order (`result.node_sort_key`): by x in 1D; by x, then y in 2D.

    In 2D the file's points (the dofs' coordinates, mapped from a reference cell) may differ from the mesh's
    nodes the solver sorted by an ulp, which would reorder the nodes of a column x = const of a rectangle:
    they are compared to 12 digits of the domain's width.
    """
    if x.ndim == 1:
        return x
    width = float(np.max(np.ptp(x, axis=0))) or 1.0
    return node_sort_key(np.round(x / width, 12))


def _topology(path: Path) -> tuple[str, int]:
    """The HDF5 reference of the triangles in the first grid of `solution.xdmf`, and nodes per cell (3)."""
    import xml.etree.ElementTree as ET

    try:
        item = ET.parse(path).getroot().find("Domain/Grid/Grid/Topology")
        kind, per_cell, ref = item.get("TopologyType"), int(item.get("NodesPerElement")), item.find("DataItem").text.strip()
    except (ET.ParseError, OSError, AttributeError, TypeError, ValueError):
        raise ValueError(f"plot: {path}: no triangles (Topology) in the first grid of a 2D run") from None
    if kind != "Triangle" or per_cell != 3:
        raise ValueError(f"plot: {path}: a 2D run's Topology must be Triangle with 3 nodes per element, got {kind} with {per_cell}")
    return ref, per_cell


def _cells(h5, ref: str, per_cell: int, n: int, path: Path) -> np.ndarray:
    """The triangles of the file, (k, 3) indices into its points, checked to be indices."""
    try:
        data = h5[_h5_path(ref)]
    except KeyError:
        raise ValueError(f"plot: {path} has no dataset {_h5_path(ref)} (named in solution.xdmf)") from None
    cells = np.asarray(_bounded(data, 6 * MAX_NODES, path, integer=True)[:]).reshape(-1)
    if cells.size == 0 or cells.size % per_cell or cells.min() < 0 or cells.max() >= n:
        raise ValueError(f"plot: {path}: {_h5_path(ref)} holds no triangles of its {n} points")
    return cells.astype(np.int64).reshape(-1, per_cell)


def _mesh(cells: np.ndarray, x_all: np.ndarray, order: np.ndarray) -> dict:
    """The triangles renumbered to the sorted nodes in the solver's canonical order (smallest node first,
    orientation kept, then sorted), and the lumped nodal areas: a third of each triangle's area to each
    of its corners, ∫φ_i dx for P1 (what `Result.contact_measure` sums)."""
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    cells = canonical_cells(rank[cells])
    x = x_all[order]
    a, b, c = x[cells[:, 0]], x[cells[:, 1]], x[cells[:, 2]]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    weights = np.bincount(cells.ravel(), weights=np.repeat(area / 3, 3), minlength=x.shape[0])
    return {"cells": cells, "weights": weights}


def _dataset(h5, ref: str, n: int, path: Path) -> np.ndarray:
    try:
        data = h5[_h5_path(ref)]
    except KeyError:
        raise ValueError(f"plot: {path} has no dataset {_h5_path(ref)} (named in solution.xdmf)") from None
    values = np.asarray(_bounded(data, n, path)[:], dtype=float).reshape(-1)
    if values.size != n:
        raise ValueError(f"plot: {path}: {_h5_path(ref)} holds {values.size} values, expected {n}")
    return values


def _bounded(data, most: int, path: Path, integer: bool = False):
    """The dataset `data` if its declared size and type allow reading it: at most `most` numbers, real or
    integer (a 134 kB file declaring a 4 GB dataset is refused before it is read)."""
    try:
        dtype = np.dtype(data.dtype)
    except TypeError:  # pyfive gives a tuple for variable-length strings and references
        dtype = np.dtype(object)
    size = int(np.prod(data.shape, dtype=np.float64))
    kinds = ("i", "u") if integer else ("f", "i", "u")
    if dtype.kind not in kinds or dtype.fields is not None or dtype.itemsize > 8:
        raise ValueError(f"plot: {path}: {data.name} holds {dtype} values; allowed: {'integers' if integer else 'real numbers'}")
    if size > most:
        raise ValueError(f"plot: {path}: {data.name} declares {size} values; allowed: at most {most}")
    return data
