"""Pictures of a run, and reading an output folder back.

Each picture is drawn by the library made for it: matplotlib (:mod:`stringcontact.charts`) for
``contact_set.png`` and ``velocity_field.png`` (the (x, t) plane as an image) and the line charts
``snapshots.png`` and ``energy.png``; pyvista (:mod:`stringcontact.mesh_pictures`, imported only for it)
for ``space_time.png``, the surface η(x, t) in 3-D coloured by contact.

:func:`write_pictures` draws them all; given a started :class:`~stringcontact.painter.PictureProcess`,
the pictures it was started for (`stringcontact run`: `PAINTED`) are drawn there, so that the libraries'
start-up overlaps the run. :func:`read_output` rebuilds
a :class:`Result` from an output folder alone (``stringcontact plot DIR``); the ``.h5`` is read with
pyfive (pure Python): the h5py wheel bundles its own libhdf5, which clashes with the system libhdf5
that dolfinx has already loaded ("Not a datatype").
"""

from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path

import numpy as np

from .charts import (  # noqa: F401 - the pictures and readings are used as viz.* by the demos and tests
    CONTACT_COLOUR,
    WINDOW_SIZE,
    contact_components,
    contact_set_picture,
    energy_picture,
    obstacle_name,
    parameter_line,
    snapshot_rows,
    snapshots_picture,
    stored_rows_at,
    velocity_clip,
    velocity_picture,
)
from .output import FIELDS, OutputError, read_xdmf

CHART_PICTURES = ("contact_set.png", "velocity_field.png", "snapshots.png", "energy.png")  # matplotlib
MESH_PICTURES = ("space_time.png",)  # pyvista
PICTURES = CHART_PICTURES + MESH_PICTURES
#: what `stringcontact run` hands to its painter process: the space-time pictures (the rest, the line charts,
#: are drawn by the run meanwhile; this split measured fastest, docs/performance.md)
PAINTED = ("contact_set.png", "velocity_field.png", "space_time.png")


# --- all pictures of a run ------------------------------------------------------------------------


def draw(name: str, result, folder, window_size=WINDOW_SIZE) -> Path:
    """Draw the picture `name` (one of PICTURES) of `result` into `folder`."""
    path = Path(folder) / name
    if name in MESH_PICTURES:
        from . import mesh_pictures  # pyvista: 0.5-1 s to import, so only for these

        return mesh_pictures.space_time_picture(result, path, window_size)
    if name == "contact_set.png":
        return contact_set_picture(result, path, window_size)
    if name == "velocity_field.png":
        return velocity_picture(result, path, window_size)
    return snapshots_picture(result, path) if name == "snapshots.png" else energy_picture(result, path)


def write_pictures(result, folder, window_size=WINDOW_SIZE, painter=None) -> list[Path]:
    """Write the PICTURES of `result` into `folder`; the function `simulate(..., pictures=True)` calls.

    With a started `painter.PictureProcess`, its pictures are drawn there while this process draws the
    others; whatever it fails to draw is then drawn here. The painter is stopped however this ends, so
    nothing writes into `folder` after it returns.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    handed_out, drawn = set(), set()
    try:
        if painter is not None and painter.send(result, folder, window_size):
            handed_out = set(painter.names)
        for name in PICTURES:
            if name not in handed_out:
                draw(name, result, folder, window_size)
        if handed_out and painter.wait():
            drawn = handed_out
    finally:
        if painter is not None:
            painter.cancel()
            for name in handed_out - drawn:  # a picture the process was killed while writing
                for stray in folder.glob(f".{name}.tmp-*"):
                    stray.unlink(missing_ok=True)
    for name in handed_out - drawn:
        draw(name, result, folder, window_size)
    return [folder / name for name in PICTURES]


# --- reading an output folder back ---------------------------------------------------------------


def show_pictures(folder) -> list[Path]:
    """The pictures of a run folder: displayed inline in a Jupyter notebook, otherwise their paths printed."""
    import sys

    paths = [Path(folder) / name for name in PICTURES if (Path(folder) / name).exists()]
    if "ipykernel" in sys.modules:
        from IPython.display import Image, display

        for path in paths:
            display(Image(filename=str(path)))
    else:
        print("pictures:", ", ".join(str(p) for p in paths))
    return paths


def _h5_path(ref: str) -> str:
    return ref.split(":", 1)[1]  # "solution.h5:/Function/eta/0" -> "/Function/eta/0"


def read_output(folder):
    """A :class:`Result` rebuilt from an output folder's solution.xdmf/.h5, diagnostics.csv and summary.json.

    Its rows are the XDMF frames (see `simulate`'s `max_frames`), with the diagnostics of those rows.

    Arrays are ordered by x like the in-memory result; `contact` is boolean again. Raises ValueError
    with a one-line message if the folder is not a complete output folder.
    """
    import pyfive  # pure-Python HDF5: h5py's wheel clashes with the libhdf5 that dolfinx has already loaded

    from .registry import registered
    from .result import ENERGY_KEYS, Result
    from .scene import Scene

    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"plot: {folder} is not a folder (give the --out folder of `stringcontact run`)")
    names = ("solution.xdmf", "solution.h5", "diagnostics.csv", "summary.json")
    missing = [n for n in names if not (folder / n).is_file()]
    summary = {}
    if (folder / "summary.json").is_file():
        summary = json.loads((folder / "summary.json").read_text())
        if summary.get("status", "complete") != "complete":
            raise ValueError(f"plot: {folder} holds a run that did not complete (status {summary['status']!r})")
    if missing:
        raise ValueError(f"plot: {folder} is not a stringcontact output folder (missing {', '.join(missing)})")
    try:
        geometry, series = read_xdmf(folder / "solution.xdmf")
    except OutputError as exc:
        raise ValueError(f"plot: {folder / 'solution.xdmf'} cannot be read ({exc.__cause__})") from None
    if geometry is None:
        raise ValueError(f"{folder / 'solution.xdmf'}: no mesh geometry in the XDMF file")
    absent = [f for f in FIELDS if f not in series]
    if absent:
        raise ValueError(f"plot: {folder / 'solution.xdmf'} has no time series {', '.join(absent)}")

    with open(folder / "diagnostics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"plot: {folder / 'diagnostics.csv'} has no rows")
    column = {key: np.array([float(r[key]) for r in rows]) for key in rows[0]}
    # solution.xdmf holds a subset of the stored rows (about max_frames): keep the diagnostics rows at its times
    frame_t = np.array([s[0] for s in series[FIELDS[0]]])
    tol = 1e-12 * max(1.0, float(np.max(np.abs(column["t"]))))
    right = np.searchsorted(column["t"], frame_t).clip(0, len(rows) - 1)
    left = (right - 1).clip(0, len(rows) - 1)
    at = np.where(np.abs(column["t"][left] - frame_t) <= np.abs(column["t"][right] - frame_t), left, right)
    if frame_t.size == 0 or np.any(np.abs(column["t"][at] - frame_t) > tol):
        raise ValueError(f"plot: {folder}: the times in solution.xdmf are not rows of diagnostics.csv")
    column = {key: values[at] for key, values in column.items()}
    t = column["t"]

    with pyfive.File(str(folder / "solution.h5")) as h5:
        x_all = np.asarray(h5[_h5_path(geometry)][:])[:, 0]
        order = np.argsort(x_all, kind="stable")
        fields = {}
        for name in FIELDS:
            times = np.array([s[0] for s in series[name]])
            if times.shape != t.shape or np.max(np.abs(times - t)) > 1e-12 * max(1.0, float(t[-1])):
                raise ValueError(f"plot: {folder}: the times of '{name}' in solution.xdmf differ from diagnostics.csv")
            fields[name] = np.stack([np.asarray(h5[_h5_path(ref)][:])[:, 0][order] for _, ref in series[name]])

    scene_data = dict(summary["scene"])
    if scene_data.get("model") not in registered():  # an uninstalled plugin, or a module path of an older folder:
        scene_data.pop("model", None)  # redrawing needs no model (its name stays in Result.model)
    with warnings.catch_warnings():  # the scene was already warned about when it ran
        warnings.simplefilter("ignore")
        scene = Scene.from_dict(scene_data)
    return Result(
        scene=scene,
        x=x_all[order],
        t=t,
        steps=column["step"].astype(np.int64),
        eta=fields["eta"],
        velocity=fields["velocity"],
        contact=fields["contact"] > 0.5,
        contact_force=fields["contact_force"],
        energy={key: column[key] for key in ENERGY_KEYS},
        min_eta=float(summary.get("min_eta", np.min(fields["eta"]))),
        penalty=summary.get("penalty", "explicit"),
        mass=summary.get("mass", "lumped"),
        model=summary.get("model", "inelastic"),
        status=summary.get("status", "complete"),
        timings=summary.get("timings", {}),
        message=summary.get("message", ""),
    )


# --- the `plot` subcommand ----------------------------------------------------------------------


def add_arguments(parser) -> None:
    parser.description = (
        f"Redraw the pictures of an output folder ({', '.join(PICTURES)}) "
        "from its saved files (solution.xdmf/.h5, diagnostics.csv, summary.json) alone."
    )
    parser.add_argument("folder", metavar="DIR", help="an output folder written by `stringcontact run --out DIR`")
    parser.add_argument("--out", metavar="DIR", help="write the pictures here instead of into DIR")
    parser.add_argument(
        "--size",
        metavar="WxH",
        default=f"{WINDOW_SIZE[0]}x{WINDOW_SIZE[1]}",
        help=f"pixel size of the space-time and 3-D pictures (default {WINDOW_SIZE[0]}x{WINDOW_SIZE[1]})",
    )


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' -> (W, H), each in 200..4000."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size: expected WIDTHxHEIGHT such as 1100x900, got {text!r}") from None
    if not (200 <= w <= 4000 and 200 <= h <= 4000):
        raise ValueError(f"--size: width and height must be in 200..4000 pixels, got {text!r}")
    return w, h


def command(args) -> int:
    size = parse_size(args.size)
    result = read_output(args.folder)
    out = Path(args.out) if args.out else Path(args.folder)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a folder")
    for path in write_pictures(result, out, window_size=size):
        print(f"wrote {path}")
    return 0
