"""`view.py`: a ready ParaView view of an output folder, opened with one command.

    pvpython view.py                         # a window (or, with arguments, a screenshot, see below)
    paraview --script=view.py                # the same view in ParaView's GUI

The file is data, not code of this package: it imports only `paraview.simple` (and the standard library's
`json`, `os` and `sys`), and every number it needs (the colour ranges, the box the camera frames, the
obstacle) is written into it as a literal by the run, computed over all stored rows:

- `solution.xdmf` opened with Xdmf3ReaderT, Warp By Scalar on `eta` along (0, 1, 0) for a string and
  (0, 0, 1) for a membrane;
- coloured by `contact` on the fixed range 0 … 1 (Cool to Warm: blue free, red in contact), whatever the time;
- `velocity` on the symmetric range −V … V, V = max |velocity| over every stored row, in a diverging map
  whose middle (v = 0) is a dark grey: a string at rest stands out on the white background (pick it in the
  colouring menu, or name it on the command line: its range is fixed too);
- each output field of the model (`Result.fields`) on its own fixed range over every stored row and in its own
  colours (`Result.field_info`, `field_range` and `field_points`): −P … P, P its largest |value|, for a
  symmetric field, on a symmetric-log scale for a ``"symlog"`` one (`symlog_unit`, as the pictures: a peak
  1e3 times the rest would leave every other time in the middle colour), else its least … largest value;
  picked like the velocity;
- the obstacle ψ of the scene (the plane 0 unless the scene gives a profile), in grey: for a string the
  region below ψ(x), for a membrane the surface z = ψ(x, y) just below the membrane's contact patch; an
  obstacle at rest from literal points, a moving one (ψ(x, t)) as `solution.xdmf` warped by its `obstacle`
  field, so that it is drawn where it is at the time shown;
- a title (scene, model, scheme), the time t in the upper left corner and axes named x and eta (x, y and
  eta for a membrane), with ticks;
- one camera for all times: it frames the box of the warped shape and of the obstacle over all stored rows,
  and `paraview.simple`'s reset of the camera on the first render is switched off, so that frames at
  different times line up (an animation does not jump).

`pvpython view.py TIME PNG [contact|velocity|FIELD]` saves a screenshot at time TIME instead of opening a window
and prints one JSON line: the time, the field, its colour range, the camera, the axes' titles and the box of the
obstacle drawn at that time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .manifest import atomic_path
from .tables import field_info

VIEW_NAME = "view.py"
CONTACT_RANGE = (0.0, 1.0)
#: velocity's colours at −V, 0 and V (RGB in 0 … 1): blue, a dark grey, red. The middle is dark so that a
#: string at rest (v = 0) is seen on the white background (Cool to Warm's light grey middle vanishes there).
VELOCITY_COLOURS = ((0.085, 0.40, 0.85), (0.15, 0.15, 0.15), (0.85, 0.10, 0.08))
#: control points of a symmetric-log field's colours per decade of its |value| (ParaView interpolates between them)
POINTS_PER_DECADE = 4
#: the obstacle's grey, and the white background
OBSTACLE_GREY = (0.80, 0.80, 0.80)
#: at most this many samples of the obstacle per direction (its profile; a flat one needs 2)
OBSTACLE_SAMPLES = 200
#: a membrane's obstacle is drawn this share of the height range below ψ (a patch on ψ would flicker with it)
_MEMBRANE_DROP = 0.01


def symlog_unit(values, peak: float, share: float) -> np.ndarray:
    """`values` from −peak … peak onto −1 … 1 on a symmetric-log scale (clipped beyond): matplotlib's
    SymLogNorm (base 10, linscale 1) with linthresh = share·peak, which a field's picture uses; linear within
    ±linthresh."""
    c = share * peak
    linear = 1.0 / (1.0 - 1.0 / 10.0)  # SymLogNorm's linscale / (1 - 1/base)

    def forward(v):
        a = np.abs(v)
        return np.sign(v) * np.where(a > c, linear + np.log10(np.maximum(a, c) / c), a * linear / c)

    return np.clip(forward(np.asarray(values, dtype=float)) / forward(peak), -1.0, 1.0)


def field_range(values, info: dict) -> tuple[float, float]:
    """The fixed colour range of an output field's rows `values` shown as `info` says (`OutputField.metadata`):
    −P … P, P the largest finite |value|, for a symmetric (or ``"symlog"``) field, else its least … largest
    finite value; a range of width 0 (a field all 0) widened to one."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if info.get("symmetric") or info.get("scale") == "symlog":
        peak = float(np.max(np.abs(v))) if v.size else 0.0
        return (-(peak or 1.0), peak or 1.0)
    low, high = (float(v.min()), float(v.max())) if v.size else (0.0, 0.0)
    pad = 0.0 if high > low else 0.5 * (abs(low) or 1.0)
    return low - pad, high + pad


def blend(colours, unit) -> np.ndarray:
    """The RGB rows at `unit` (−1 … 1) of the colours `colours` spread evenly from −1 to 1, blended linearly in
    RGB (matplotlib's `LinearSegmentedColormap.from_list`)."""
    stops = np.linspace(-1.0, 1.0, len(colours))
    rgb = np.asarray(colours, dtype=float)
    return np.column_stack([np.interp(np.asarray(unit, dtype=float), stops, rgb[:, k]) for k in range(3)])


def field_points(low: float, high: float, info: dict) -> list:
    """ParaView's control points (value, r, g, b) of an output field's colours on `low` … `high`: a linear field's
    colours at evenly spaced values; a ``"symlog"`` one's at −1, 0 and 1 of `symlog_unit` and between, at 0,
    ±linthresh and `POINTS_PER_DECADE` values per decade up to ±high."""
    colours = info["colours"]
    if info.get("scale") != "symlog":
        values = np.linspace(low, high, len(colours))
        return [(float(v), *(float(x) for x in c)) for v, c in zip(values, colours)]
    share = float(info.get("linear_share", 1e-3))
    decades = -float(np.log10(share))
    above = high * 10.0 ** -np.linspace(decades, 0.0, round(decades * POINTS_PER_DECADE) + 1)
    values = np.concatenate([-above[::-1], [0.0], above])
    rgb = blend(colours, symlog_unit(values, high, share))
    return [(float(v), *(float(x) for x in c)) for v, c in zip(values, rgb)]


def field_maps(result) -> dict:
    """Each output field of `result` -> ``[[low, high], points]``: its fixed range (`field_range`) and colour
    points (`field_points`) in view.py."""
    fields = getattr(result, "fields", None) or {}
    maps = {}
    for name, info in field_info(result).items():
        low, high = field_range(fields[name], info)
        maps[name] = [[low, high], field_points(low, high, info)]
    return maps


def view_numbers(result) -> dict:
    """What view.py needs, from the stored rows: the kind, the warp's normal, the velocity's symmetric range,
    the obstacle (points and quadrilaterals) and the box the camera frames over all times (x0, x1, y0, y1, z0,
    z1: the warped shape and the obstacle), the title, and each output field's range and colour points."""
    x = np.asarray(result.x, dtype=float)
    eta = np.asarray(result.eta, dtype=float)
    speed = float(np.nanmax(np.abs(result.velocity))) if np.size(result.velocity) else 0.0
    lo, hi = (float(np.nanmin(eta)), float(np.nanmax(eta))) if eta.size else (0.0, 0.0)
    moves = bool(getattr(result.scene, "obstacle_moves", False))
    if moves:  # the box holds the obstacle at every stored time, not only at t = 0
        lo, hi = _moving_range(result.scene, x, result.t, lo, hi)
    if x.ndim == 1 or x.shape[1] == 1:
        kind, normal = "string", (0.0, 1.0, 0.0)
        points, quads, (lo, hi) = _string_obstacle(result.scene, x.reshape(-1), lo, hi)
        xs = x.reshape(-1)
        bounds = (float(xs.min()), float(xs.max()), lo, hi, 0.0, 0.0)
        shift = (0.0, 0.0, points[0][2])  # behind the string, as the obstacle at rest
    else:
        kind, normal = "membrane", (0.0, 0.0, 1.0)
        points, quads, (lo, hi) = _membrane_obstacle(result.scene, x, lo, hi)
        bounds = (float(x[:, 0].min()), float(x[:, 0].max()), float(x[:, 1].min()), float(x[:, 1].max()), lo, hi)
        shift = (0.0, 0.0, -_MEMBRANE_DROP * max(hi - lo, 1e-12))
    return {"kind": kind, "normal": normal, "velocity_range": (-(speed or 1.0), speed or 1.0), "bounds": bounds,
            "times": [float(t) for t in result.t],
            # a moving obstacle is drawn from solution.xdmf's `obstacle` field: no literal points then
            "obstacle_points": [] if moves else points, "obstacle_quads": [] if moves else quads,
            "obstacle_moves": moves, "obstacle_shift": shift,
            "title": view_title(result), "fields": field_maps(result)}


def view_title(result) -> str:
    """The view's title: the scene, the model and the scheme."""
    return f"{result.scene.name}: model {result.model}, scheme {getattr(result, 'scheme', 'paper')}"


def _psi(scene, points, t: float = 0.0) -> np.ndarray:
    """ψ at `points` at the time t; a value the expression does not give there (outside its domain) is ψ's lowest value."""
    psi = np.asarray(scene.obstacle_values(points, t), dtype=float).reshape(-1)
    finite = np.isfinite(psi)
    return np.where(finite, psi, psi[finite].min() if finite.any() else 0.0)


def _moving_range(scene, x, times, lo, hi) -> tuple[float, float]:
    """The height range (lo, hi) widened to ψ's values at `times` where the view draws a moving obstacle: a
    string's sample grid, a membrane's nodes (at most OBSTACLE_SAMPLES² / 16 of them, evenly picked)."""
    if x.ndim == 1 or x.shape[1] == 1:
        xs = x.reshape(-1)
        grid = np.linspace(xs.min(), xs.max(), min(OBSTACLE_SAMPLES, len(xs)))
    else:
        grid = x[:: max(1, len(x) * 16 // OBSTACLE_SAMPLES**2), :2]
    for t in np.unique(np.asarray(times, dtype=float)):
        psi = _psi(scene, grid, float(t))
        lo, hi = min(lo, float(psi.min())), max(hi, float(psi.max()))
    return lo, hi


def _string_obstacle(scene, xs, lo, hi):
    """The grey region below y = ψ(x) down to a floor under everything, as a strip of quadrilaterals at z
    slightly behind the string (drawn under it); and the shape's (and obstacle's) height range."""
    flat = getattr(scene, "obstacle", None) is None
    grid = np.linspace(xs.min(), xs.max(), 2 if flat else min(OBSTACLE_SAMPLES, len(xs)))
    psi = _psi(scene, grid)
    lo, hi = min(lo, float(psi.min())), max(hi, float(psi.max()))
    floor = lo - 0.08 * max(hi - lo, 1e-12)
    z = -1e-3 * max(xs.max() - xs.min(), 1e-12)
    n = len(grid)
    points = [(float(g), float(p), z) for g, p in zip(grid, psi)] + [(float(g), floor, z) for g in grid]
    quads = [(i, i + 1, n + i + 1, n + i) for i in range(n - 1)]
    return points, quads, (floor, hi)


def _membrane_obstacle(scene, x, lo, hi):
    """The surface z = ψ(x, y) over the mesh's bounding box, 1 % of the height range lower (a patch in contact
    lies on ψ and would flicker with it otherwise); and the height range with it."""
    flat = getattr(scene, "obstacle", None) is None
    n = 2 if flat else min(OBSTACLE_SAMPLES // 4, int(np.sqrt(len(x))) + 1)
    gx, gy = np.meshgrid(np.linspace(x[:, 0].min(), x[:, 0].max(), n), np.linspace(x[:, 1].min(), x[:, 1].max(), n))
    psi = _psi(scene, np.column_stack([gx.ravel(), gy.ravel()]))
    lo, hi = min(lo, float(psi.min())), max(hi, float(psi.max()))
    psi = psi - _MEMBRANE_DROP * max(hi - lo, 1e-12)
    points = [(float(a), float(b), float(c)) for a, b, c in zip(gx.ravel(), gy.ravel(), psi)]
    quads = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i) for j in range(n - 1) for i in range(n - 1)]
    return points, quads, (min(lo, float(psi.min())), hi)


def _literal(value) -> str:
    """A Python literal of floats written so that they read back exactly (repr); integers stay integers."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_literal(k)}: {_literal(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_literal(v) for v in value) + "]"
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return str(int(value))
    return repr(float(value))


def view_script(numbers: dict) -> str:
    """The text of view.py for `numbers` (`view_numbers`)."""
    head = f'''"""ParaView view of this folder, written by the run: `pvpython view.py` or `paraview --script=view.py`.

`pvpython view.py TIME PNG [contact|velocity|FIELD]` saves a screenshot at time TIME instead (FIELD: one of
FIELD_MAPS, the model's output fields).
The numbers below were computed by the run over all its stored rows.
"""

import json
import os
import sys

import paraview.simple
from paraview.simple import (AnnotateTime, ColorBy, GetActiveViewOrCreate, GetAnimationScene, GetColorTransferFunction,
                             GetOpacityTransferFunction, GetScalarBar, HideScalarBarIfNotNeeded, Interact,
                             ProgrammableSource, Render, SaveScreenshot, Show, Text, WarpByScalar, Xdmf3ReaderT)

KIND = {_literal(numbers["kind"])}
TITLE = {_literal(numbers.get("title") or "")}
NORMAL = {_literal(numbers["normal"])}  # Warp By Scalar's direction: y for a string, z for a membrane
CONTACT_RANGE = {_literal(CONTACT_RANGE)}  # fixed: 0 free (blue), 1 in contact (red), at every time
VELOCITY_RANGE = {_literal(numbers["velocity_range"])}  # symmetric, max |velocity| over all stored rows
VELOCITY_COLOURS = {_literal(VELOCITY_COLOURS)}  # at -V, 0 (dark: seen on white), V
BOUNDS = {_literal(numbers["bounds"])}  # the warped shape and the obstacle over all times: x0, x1, y0, y1, z0, z1
OBSTACLE_GREY = {_literal(OBSTACLE_GREY)}
OBSTACLE_POINTS = {_literal(numbers.get("obstacle_points") or [])}  # x, y, z
OBSTACLE_QUADS = {_literal(numbers.get("obstacle_quads") or [])}  # four indices into OBSTACLE_POINTS each
OBSTACLE_MOVES = {bool(numbers.get("obstacle_moves"))}  # psi(x, t): drawn from solution.xdmf's obstacle field
OBSTACLE_SHIFT = {_literal(numbers.get("obstacle_shift") or (0.0, 0.0, 0.0))}  # the moving obstacle moved by this: behind/below the shape
FOLDER = {_literal(numbers.get("folder") or "")}  # where the run wrote this folder (for ParaView's GUI)
# the model's output fields: name: [[low, high] (fixed, over all stored rows), [[value, r, g, b], ...] (its colours)]
FIELD_MAPS = {_literal(numbers.get("fields") or {})}
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


def fixed_map(name, low, high, preset=None, colours=None):
    """The colour map of array `name` on [low, high], never rescaled when the time changes."""
    lut = GetColorTransferFunction(name)
    if colours and len(colours[0]) == 4:  # (value, r, g, b): each colour at its value
        lut.RGBPoints = [v for point in colours for v in point]
        lut.ColorSpace = "RGB"
        # not 256 table values: their bins (2·peak/256) are wider than a symmetric-log map's linear part near 0,
        # and the texture drew 0 in stripes of both ends' colours
        lut.Discretize = 0
    elif colours:  # evenly spaced colours from low to high
        step = (high - low) / (len(colours) - 1)
        lut.RGBPoints = [v for k, c in enumerate(colours) for v in (low + k * step, *c)]
        lut.ColorSpace = "Lab"
    else:
        lut.ApplyPreset(preset, True)
    lut.AutomaticRescaleRangeMode = "Never"
    lut.ScalarRangeInitialized = 1  # so that colouring by it keeps this range instead of the data's at this time
    lut.RescaleTransferFunction(low, high)
    GetOpacityTransferFunction(name).RescaleTransferFunction(low, high)
    return lut


MAPS = {"contact": (CONTACT_RANGE, "Cool to Warm", None), "velocity": (VELOCITY_RANGE, None, VELOCITY_COLOURS),
        **{name: (tuple(span), None, points) for name, (span, points) in FIELD_MAPS.items()}}


def colour_by(view, display, field):
    """Colour by `field` on its fixed range, with its colour bar (and no other)."""
    ColorBy(display, ("POINTS", field))
    (low, high), preset, colours = MAPS[field]
    lut = fixed_map(field, low, high, preset, colours)  # again: ColorBy rescales to the data at this time
    for other in MAPS:
        if other != field:
            HideScalarBarIfNotNeeded(GetColorTransferFunction(other), view)
    display.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(lut, view)
    bar.Title = field
    bar.ComponentTitle = ""
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    bar.TitleFontSize = bar.LabelFontSize = 18
    bar.RangeLabelFormat = "%-#6.3g"


OBSTACLE_SCRIPT = (
    "from vtkmodules.vtkCommonCore import vtkPoints\\n"
    "from vtkmodules.vtkCommonDataModel import vtkCellArray\\n"
    "points, cells = vtkPoints(), vtkCellArray()\\n"
    "for p in POINTS:\\n    points.InsertNextPoint(p)\\n"
    "for q in QUADS:\\n    cells.InsertNextCell(4, q)\\n"
    "out = self.GetPolyDataOutput()\\nout.SetPoints(points)\\nout.SetPolys(cells)\\n"
)


def moving_obstacle(reader):
    """ψ(x, t) from solution.xdmf's `obstacle` field, where it is at the time shown: the mesh warped by it, for a
    string extruded downwards and cut at the box's floor (the region below ψ, as an obstacle at rest), moved
    by OBSTACLE_SHIFT."""
    from paraview.simple import Clip, ExtractSurface, LinearExtrusion, Transform

    source = WarpByScalar(registrationName="warped by obstacle", Input=reader, Scalars=["POINTS", "obstacle"])
    source.Normal = NORMAL
    source.ScaleFactor = 1.0
    if KIND == "string":
        source = LinearExtrusion(registrationName="below the obstacle", Input=ExtractSurface(Input=source))
        source.Vector = [0.0, -1.0, 0.0]
        source.ScaleFactor = 2.0 * (BOUNDS[3] - BOUNDS[2]) + (BOUNDS[1] - BOUNDS[0])
        source.Capping = 0
        source = Clip(registrationName="above the floor", Input=source, ClipType="Plane")
        source.ClipType.Origin = [0.0, BOUNDS[2], 0.0]
        source.ClipType.Normal = [0.0, 1.0, 0.0]
        source.Invert = 0  # keep y > the floor
    moved = Transform(registrationName="obstacle", Input=source)
    moved.Transform.Translate = list(OBSTACLE_SHIFT)
    return moved


def obstacle(view, reader):
    """The obstacle ψ in grey: the region below it (a string), the surface z = ψ (a membrane)."""
    if OBSTACLE_MOVES:
        source = moving_obstacle(reader)
    else:
        source = ProgrammableSource(registrationName="obstacle")
        source.OutputDataSetType = "vtkPolyData"
        source.Script = f"POINTS = {OBSTACLE_POINTS!r}\\nQUADS = {OBSTACLE_QUADS!r}\\n" + OBSTACLE_SCRIPT
    display = Show(source, view)
    if OBSTACLE_MOVES:
        ColorBy(display, None)  # one grey, not the fields' colours
    display.AmbientColor = display.DiffuseColor = list(OBSTACLE_GREY)
    display.Ambient, display.Diffuse, display.Specular = 1.0, 0.0, 0.0  # unlit: the same grey everywhere
    return display


def labels(view):
    """The title (scene, model, scheme) at the top, the time in the upper left corner, the axes named."""
    title = Show(Text(registrationName="title", Text=TITLE), view)
    title.WindowLocation, title.FontSize, title.Color = "Upper Center", 20, [0.0, 0.0, 0.0]
    clock = Show(AnnotateTime(registrationName="time", Format="t = {time:.4g}"), view)
    clock.WindowLocation, clock.FontSize, clock.Color = "Upper Left Corner", 20, [0.0, 0.0, 0.0]
    grid = view.AxesGrid
    grid.Visibility = 1
    grid.XTitle, grid.YTitle, grid.ZTitle = ("x", "eta", "") if KIND == "string" else ("x", "y", "eta")
    for axis in "XYZ":
        for part in ("Title", "Label"):
            setattr(grid, f"{axis}{part}Color", [0.0, 0.0, 0.0])
            setattr(grid, f"{axis}{part}FontSize", 16)
    grid.GridColor = [0.3, 0.3, 0.3]
    grid.UseCustomBounds, grid.CustomBounds = 1, list(BOUNDS)  # the same axes at every time
    grid.AxesToLabel = 7  # the lower edges only (min x, min y, min z): the others would repeat them


def build(size=(1000, 600)):
    disable = getattr(paraview.simple, "_DisableFirstRenderCameraReset", None)
    if disable is not None:  # else the first Render resets the camera to this time's shape
        disable()
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
    view.OrientationAxesVisibility = 0  # the named axes below say which way is which
    obstacle(view, reader)
    display = Show(warp, view)
    if KIND == "string":
        display.LineWidth = 4.0
    for name, ((low, high), preset, colours) in MAPS.items():  # every field's map fixed, for the GUI's colour menu
        fixed_map(name, low, high, preset, colours)
    colour_by(view, display, "contact")
    labels(view)
    frame(view)
    return animation, view, display


def frame(view):
    """The camera on the box of all times: a string from the front, a membrane from above its front edge."""
    # no max() here: ParaView runs the obstacle's script in this module's namespace, after
    # `from vtkmodules.numpy_interface.algorithms import *`, whose max and min take arrays
    centre = [0.5 * (BOUNDS[0] + BOUNDS[1]), 0.5 * (BOUNDS[2] + BOUNDS[3]), 0.5 * (BOUNDS[4] + BOUNDS[5])]
    width = sorted([BOUNDS[1] - BOUNDS[0], BOUNDS[3] - BOUNDS[2], BOUNDS[5] - BOUNDS[4], 1e-12])[-1]
    view.CameraFocalPoint = centre
    if KIND == "string":  # the box's height, or its width at the view's aspect, and room for the labels
        aspect = view.ViewSize[0] / view.ViewSize[1]
        half = sorted([0.5 * (BOUNDS[3] - BOUNDS[2]), 0.5 * (BOUNDS[1] - BOUNDS[0]) / aspect])[-1]
        view.CameraPosition = [centre[0], centre[1], centre[2] + 3.0 * width]
        view.CameraViewUp = [0.0, 1.0, 0.0]
        view.CameraParallelProjection = 1
        view.CameraParallelScale = 1.2 * half
        return
    view.CameraPosition = [centre[0] - 0.4 * width, centre[1] - 1.1 * width, centre[2] + 1.5 * width]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    view.ResetCamera(*BOUNDS)


def show_at(animation, view, display, t, field="contact"):
    animation.AnimationTime = t
    view.ViewTime = t
    colour_by(view, display, field)
    Render(view)


def camera(view):
    """The camera VTK renders with (not the proxy's copy): position, focal point, parallel scale, view angle."""
    cam = view.GetActiveCamera()
    return {"position": list(cam.GetPosition()), "focal_point": list(cam.GetFocalPoint()),
            "parallel_scale": cam.GetParallelScale(), "view_angle": cam.GetViewAngle()}


def axes(view):
    """The titles of the axes shown (none when they are hidden)."""
    grid = view.AxesGrid
    return [grid.XTitle, grid.YTitle, grid.ZTitle] if grid.Visibility else []


def obstacle_bounds(t):
    """The box of the obstacle drawn at the time t: x0, x1, y0, y1, z0, z1."""
    from paraview.simple import FindSource

    source = FindSource("obstacle")
    source.UpdatePipeline(t)  # its data information is of the last update's time
    return list(source.GetDataInformation().GetBounds())


def main(argv):
    shot = len(argv) >= 3 and argv[2].lower().endswith(".png")  # pvpython view.py TIME PNG [contact|velocity|FIELD]
    field = argv[3] if shot and len(argv) > 3 else "contact"
    if field not in MAPS:
        sys.exit(f"view.py: no field {field!r} to colour by; choose one of {', '.join(MAPS)}")
    animation, view, display = build()
    if shot:
        show_at(animation, view, display, float(argv[1]), field)
        SaveScreenshot(argv[2], view, ImageResolution=list(view.ViewSize), TransparentBackground=0)
        points = GetColorTransferFunction(field).RGBPoints
        print(json.dumps({"time": view.ViewTime, "field": field, "range": [points[0], points[-4]],
                          "camera": camera(view), "axes": axes(view),
                          "obstacle": obstacle_bounds(view.ViewTime)}), flush=True)
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
