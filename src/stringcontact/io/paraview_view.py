"""`view.py`: a ready ParaView view of an output folder, opened with one command.

    pvpython view.py                         # a window (or, with arguments, a screenshot, see below)
    paraview --script=view.py                # the same view in ParaView's GUI

The file is data, not code of this package: it imports only `paraview.simple` (and the standard library's
`json`, `os` and `sys`), and every number it needs (the colour ranges, the box the camera frames) is written into it
as a literal by the run, computed over all stored rows:

- `solution.xdmf` opened with Xdmf3ReaderT, Warp By Scalar on `eta` along (0, 1, 0) for a string and
  (0, 0, 1) for a membrane;
- coloured by `contact` on the fixed range 0 … 1 (Cool to Warm: blue free, red in contact), whatever the time;
- `velocity` on the symmetric range −V … V, V = max |velocity| over every stored row (pick it in the
  colouring menu: its range is fixed too);
- the camera framing the warped shape at all times, so that nothing leaves the view.

`pvpython view.py TIME PNG [contact|velocity]` saves a screenshot at time TIME instead of opening a window and
prints one JSON line: the time, the field and its colour range.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .publish import atomic_path

VIEW_NAME = "view.py"
CONTACT_RANGE = (0.0, 1.0)


def view_numbers(result) -> dict:
    """What view.py needs, from the stored rows: the kind, the warp's normal, the velocity's symmetric range
    and the warped shape's bounds over all times (x0, x1, y0, y1, z0, z1)."""
    x = np.asarray(result.x, dtype=float)
    eta = np.asarray(result.eta, dtype=float)
    speed = float(np.nanmax(np.abs(result.velocity))) if np.size(result.velocity) else 0.0
    lo, hi = (float(np.nanmin(eta)), float(np.nanmax(eta))) if eta.size else (0.0, 0.0)
    if x.ndim == 1 or x.shape[1] == 1:
        xs = x.reshape(-1)
        kind, normal = "string", (0.0, 1.0, 0.0)
        bounds = (float(xs.min()), float(xs.max()), min(lo, 0.0), max(hi, 0.0), 0.0, 0.0)
    else:
        kind, normal = "membrane", (0.0, 0.0, 1.0)
        bounds = (float(x[:, 0].min()), float(x[:, 0].max()), float(x[:, 1].min()), float(x[:, 1].max()),
                  min(lo, 0.0), max(hi, 0.0))
    pressure = getattr(result, "pressure", None)  # model "film": its symmetric range, like the velocity's
    peak = float(np.nanmax(np.abs(pressure))) if pressure is not None and np.size(pressure) else 0.0
    return {"kind": kind, "normal": normal, "velocity_range": (-(speed or 1.0), speed or 1.0), "bounds": bounds,
            "times": [float(t) for t in result.t],
            "pressure_range": (-(peak or 1.0), peak or 1.0) if pressure is not None else None}


def _literal(value) -> str:
    """A Python literal of floats written so that they read back exactly (repr)."""
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_literal(v) for v in value) + "]"
    if isinstance(value, str):
        return repr(value)
    return repr(float(value))


def view_script(numbers: dict) -> str:
    """The text of view.py for `numbers` (`view_numbers`)."""
    head = f'''"""ParaView view of this folder, written by the run: `pvpython view.py` or `paraview --script=view.py`.

`pvpython view.py TIME PNG [contact|velocity|pressure]` saves a screenshot at time TIME instead (pressure: a
film's run).
The numbers below were computed by the run over all its stored rows.
"""

import json
import os
import sys

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetAnimationScene, GetColorTransferFunction,
                             GetOpacityTransferFunction, GetScalarBar, HideScalarBarIfNotNeeded, Interact, Render, SaveScreenshot, Show,
                             WarpByScalar, Xdmf3ReaderT)

KIND = {_literal(numbers["kind"])}
NORMAL = {_literal(numbers["normal"])}  # Warp By Scalar's direction: y for a string, z for a membrane
CONTACT_RANGE = {_literal(CONTACT_RANGE)}  # fixed: 0 free (blue), 1 in contact (red), at every time
VELOCITY_RANGE = {_literal(numbers["velocity_range"])}  # symmetric, max |velocity| over all stored rows
BOUNDS = {_literal(numbers["bounds"])}  # the warped shape over all times: x0, x1, y0, y1, z0, z1
FOLDER = {_literal(numbers.get("folder") or "")}  # where the run wrote this folder (for ParaView's GUI)
PRESSURE_RANGE = {_literal(numbers["pressure_range"]) if numbers.get("pressure_range") else None}  # a film's p - p_a
'''
    return head + _BODY


_BODY = '''

def folder():
    """This file's folder; ParaView's GUI (`paraview --script`) runs it without __file__: then the current
    folder if it holds solution.xdmf, else the folder the run wrote."""
    here = globals().get("__file__")
    for candidate in ([os.path.dirname(os.path.abspath(here))] if here else []) + [os.getcwd(), FOLDER]:
        if candidate and os.path.isfile(os.path.join(candidate, "solution.xdmf")):
            return candidate
    return os.getcwd()


def fixed_map(name, low, high, preset):
    """The colour map of array `name` on [low, high], never rescaled when the time changes."""
    lut = GetColorTransferFunction(name)
    lut.ApplyPreset(preset, True)
    lut.AutomaticRescaleRangeMode = "Never"
    lut.ScalarRangeInitialized = 1  # so that colouring by it keeps this range instead of the data's at this time
    lut.RescaleTransferFunction(low, high)
    GetOpacityTransferFunction(name).RescaleTransferFunction(low, high)
    return lut


RANGES = {"contact": CONTACT_RANGE, "velocity": VELOCITY_RANGE, **({"pressure": PRESSURE_RANGE} if PRESSURE_RANGE else {})}


def colour_by(view, display, field):
    """Colour by `field` on its fixed range, with its colour bar (and no other)."""
    ColorBy(display, ("POINTS", field))
    lut = fixed_map(field, RANGES[field][0], RANGES[field][1], "Cool to Warm")
    for other in RANGES:
        if other != field:
            HideScalarBarIfNotNeeded(GetColorTransferFunction(other), view)
    display.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(lut, view)
    bar.Title = field
    bar.ComponentTitle = ""
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    bar.RangeLabelFormat = "%-#6.3g"


def build(size=(1000, 600)):
    reader = Xdmf3ReaderT(registrationName="solution.xdmf", FileName=[os.path.join(folder(), "solution.xdmf")])
    animation = GetAnimationScene()
    animation.UpdateAnimationUsingDataTimeSteps()
    warp = WarpByScalar(registrationName="warped by eta", Input=reader, Scalars=["POINTS", "eta"])
    warp.Normal = NORMAL
    warp.ScaleFactor = 1.0
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = list(size)
    view.Background = [1.0, 1.0, 1.0]
    try:
        view.UseColorPaletteForBackground = 0
    except AttributeError:  # ParaView before 5.10
        pass
    view.OrientationAxesVisibility = 1
    display = Show(warp, view)
    if KIND == "string":
        display.LineWidth = 3.0
    for name, (low, high) in RANGES.items():
        fixed_map(name, low, high, "Cool to Warm")
    colour_by(view, display, "contact")
    frame(view)
    return animation, view, display


def frame(view):
    """The camera on the box of all times: a string from the front, a membrane from above its front edge."""
    centre = [0.5 * (BOUNDS[0] + BOUNDS[1]), 0.5 * (BOUNDS[2] + BOUNDS[3]), 0.5 * (BOUNDS[4] + BOUNDS[5])]
    width = max(BOUNDS[1] - BOUNDS[0], BOUNDS[3] - BOUNDS[2], BOUNDS[5] - BOUNDS[4], 1e-12)
    view.CameraFocalPoint = centre
    if KIND == "string":
        view.CameraPosition = [centre[0], centre[1], centre[2] + 3.0 * width]
        view.CameraViewUp = [0.0, 1.0, 0.0]
        view.CameraParallelProjection = 1
    else:
        view.CameraPosition = [centre[0] - 0.4 * width, centre[1] - 1.1 * width, centre[2] + 1.5 * width]
        view.CameraViewUp = [0.0, 0.0, 1.0]
    view.ResetCamera(*BOUNDS)


def show_at(animation, view, display, t, field="contact"):
    animation.AnimationTime = t
    view.ViewTime = t
    colour_by(view, display, field)
    frame(view)
    Render(view)


def main(argv):
    animation, view, display = build()
    if len(argv) >= 3 and argv[2].lower().endswith(".png"):  # pvpython view.py TIME PNG [contact|velocity|pressure]
        field = argv[3] if len(argv) > 3 else "contact"
        show_at(animation, view, display, float(argv[1]), field)
        SaveScreenshot(argv[2], view, ImageResolution=list(view.ViewSize), TransparentBackground=0)
        points = GetColorTransferFunction(field).RGBPoints
        print(json.dumps({"time": view.ViewTime, "field": field, "range": [points[0], points[-4]],
                          "camera": list(view.CameraPosition)}), flush=True)
        return
    Render(view)
    if argv[0]:  # pvpython view.py: a window of its own (ParaView's GUI runs the script with sys.argv == [""])
        Interact(view)


main(list(getattr(sys, "argv", None) or [""]))
'''


def write_view(result, folder, target=None) -> Path:
    """Write `folder`/view.py for `result` (rank 0's rows); returns its path. `target`: where the folder will
    be once published (view.py falls back to it when ParaView's GUI does not say where the script is)."""
    path = Path(folder) / VIEW_NAME
    numbers = view_numbers(result)
    numbers["folder"] = str(Path(target).resolve()) if target is not None else ""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(view_script(numbers), encoding="utf-8")
    return path
