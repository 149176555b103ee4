"""ParaView view of this folder, written by the run: `pvpython view.py` or `paraview --script=view.py`.

`pvpython view.py TIME PNG [contact|velocity|FIELD] [TIME PNG [FIELD] ...]` saves screenshots instead, printing one
JSON line each of what was drawn. The numbers below were computed by the run over all its stored rows.
"""

import json
import math
import os
import sys

import paraview.simple as pv

# --- the run's numbers (the run writes its own here; the package's copy of this file holds placeholders) ---
KIND = "string"
TITLE = ""
NORMAL = [0.0, 1.0, 0.0]  # Warp By Scalar's direction: y for a string, z for a membrane
VELOCITY_RANGE = [-1.0, 1.0]  # symmetric, max |velocity| over all stored rows
BOUNDS = [0.0, 1.0, 0.0, 1.0, 0.0, 0.0]  # the warped shape and the obstacle over all times: x0, x1, y0, y1, z0, z1
OBSTACLE_POINTS = []  # x, y, z
OBSTACLE_QUADS = []  # four indices into OBSTACLE_POINTS each
OBSTACLE_MOVES = False  # psi(x, t): drawn from solution.xdmf's obstacle field
OBSTACLE_SHIFT = [0.0, 0.0, 0.0]  # the moving obstacle moved by this: behind/below the shape
FOLDER = ""  # where the run wrote this folder (for ParaView's GUI)
# the model's output fields: name: [[low, high] (fixed, over all stored rows), [[value, r, g, b], ...] (its colours)]
FIELD_MAPS = {}
# the fields on a symmetric-log scale: name: [linthresh, [[unit, r, g, b], ...] (its colours on -1 ... 1),
# [[unit, label], ...] (the colour bar's ticks: 0 and +-linthresh ... +-peak, a decade apart)]
SYMLOG = {}
# --- end of the run's numbers ---

CONTACT_RANGE = [0.0, 1.0]  # fixed: 0 free (blue), 1 in contact (red), at every time
VELOCITY_COLOURS = [[0.085, 0.4, 0.85], [0.15, 0.15, 0.15], [0.85, 0.1, 0.08]]  # at -V, 0 (dark: seen on white), V
OBSTACLE_GREY = [0.8, 0.8, 0.8]

#: the share of the picture kept free around a string's box: labels (left, bottom), colour bar (right), title (top)
MARGINS = {"left": 0.12, "right": 0.17, "top": 0.1, "bottom": 0.14}
WIDE, TALL = 1.0 - MARGINS["left"] - MARGINS["right"], 1.0 - MARGINS["top"] - MARGINS["bottom"]  # the box's share
SYMLOG_SUFFIX = " (symmetric log)"


def folder():
    """This file's folder; without __file__ (ParaView's GUI) the current one if it holds solution.xdmf, else FOLDER."""
    here = globals().get("__file__")
    for candidate in ([os.path.dirname(os.path.abspath(here))] if here else []) + [os.getcwd(), FOLDER]:
        if candidate and os.path.isfile(os.path.join(candidate, "solution.xdmf")):
            return candidate
    return os.getcwd()


def fixed_map(name, low, high, preset=None, colours=None):
    """The colour map of array `name` on [low, high], never rescaled when the time changes."""
    lut = pv.GetColorTransferFunction(name)
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
    pv.GetOpacityTransferFunction(name).RescaleTransferFunction(low, high)
    return lut


MAPS = {
    "contact": (CONTACT_RANGE, "Cool to Warm", None),
    "velocity": (VELOCITY_RANGE, None, VELOCITY_COLOURS),
    **{name: (tuple(span), None, points) for name, (span, points) in FIELD_MAPS.items()},
}


def symlog_expression(name):
    """PythonCalculator's expression of `name` on the pictures' symmetric-log scale, -1 ... 1, clipped at +-peak."""
    threshold = SYMLOG[name][0]
    peak = FIELD_MAPS[name][0][1]
    linear = 1.0 / (1.0 - 1.0 / 10.0)  # SymLogNorm's linscale / (1 - 1/base)
    top = linear + math.log10(peak / threshold)
    a, c = f"abs({name})", repr(threshold)
    inner = f"where({a} > {c}, {linear!r} + log10(where({a} > {c}, {a}, {c}) / {c}), {a} * {linear / threshold!r})"
    return f"where({name} < 0, -1.0, 1.0) * where({a} >= {peak!r}, {top!r}, {inner}) / {top!r}"


def colour_by(view, display, field):
    """Colour by `field` on its fixed range (a symmetric-log one on that scale), with its colour bar alone."""
    array = field + SYMLOG_SUFFIX if field in SYMLOG else field
    pv.ColorBy(display, ("POINTS", array))
    (low, high), preset, colours = MAPS[field]
    if field in SYMLOG:
        lut = fixed_map(array, -1.0, 1.0, None, SYMLOG[field][1])
    else:
        lut = fixed_map(field, low, high, preset, colours)  # again: ColorBy rescales to the data at this time
    for other in [*MAPS, *(name + SYMLOG_SUFFIX for name in SYMLOG)]:
        if other != array:
            pv.HideScalarBarIfNotNeeded(pv.GetColorTransferFunction(other), view)
    display.SetScalarBarVisibility(view, True)
    bar = pv.GetScalarBar(lut, view)
    bar.Title, bar.ComponentTitle, bar.RangeLabelFormat = field, "", "%-#6.3g"
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    bar.TitleFontSize = bar.LabelFontSize = 18
    if field in SYMLOG:  # the unit scale's numbers mean nothing to a reader: the field's values at the ticks
        lut.Annotations = [str(text) for tick in SYMLOG[field][2] for text in tick]
        bar.DrawTickLabels = bar.DrawTickMarks = bar.AddRangeLabels = bar.DrawNanAnnotation = 0
        bar.DrawAnnotations = 1


OBSTACLE_SCRIPT = (
    "from vtkmodules.vtkCommonCore import vtkPoints\n"
    "from vtkmodules.vtkCommonDataModel import vtkCellArray\n"
    "points, cells = vtkPoints(), vtkCellArray()\n"
    "for p in POINTS:\n    points.InsertNextPoint(p)\n"
    "for q in QUADS:\n    cells.InsertNextCell(4, q)\n"
    "out = self.GetPolyDataOutput()\nout.SetPoints(points)\nout.SetPolys(cells)\n"
)


def moving_obstacle(reader):
    """ψ(x, t) at the time shown: the mesh warped by solution.xdmf's `obstacle` (a string's extruded to the floor)."""
    source = pv.WarpByScalar(registrationName="warped by obstacle", Input=reader, Scalars=["POINTS", "obstacle"])
    source.Normal = NORMAL
    source.ScaleFactor = 1.0
    if KIND == "string":
        source = pv.LinearExtrusion(registrationName="below the obstacle", Input=pv.ExtractSurface(Input=source))
        source.Vector = [0.0, -1.0, 0.0]
        source.ScaleFactor = 2.0 * (BOUNDS[3] - BOUNDS[2]) + (BOUNDS[1] - BOUNDS[0])
        source.Capping = 0
        source = pv.Clip(registrationName="above the floor", Input=source, ClipType="Plane")
        source.ClipType.Origin = [0.0, BOUNDS[2], 0.0]
        source.ClipType.Normal = [0.0, 1.0, 0.0]
        source.Invert = 0  # keep y > the floor
    moved = pv.Transform(registrationName="obstacle", Input=source)
    moved.Transform.Translate = list(OBSTACLE_SHIFT)
    return moved


def obstacle(view, reader):
    """The obstacle ψ in grey: the region below it (a string), the surface z = ψ (a membrane)."""
    if OBSTACLE_MOVES:
        source = moving_obstacle(reader)
    else:
        source = pv.ProgrammableSource(registrationName="obstacle")
        source.OutputDataSetType = "vtkPolyData"
        source.Script = f"POINTS = {OBSTACLE_POINTS!r}\nQUADS = {OBSTACLE_QUADS!r}\n" + OBSTACLE_SCRIPT
    display = pv.Show(source, view)
    if OBSTACLE_MOVES:
        pv.ColorBy(display, None)  # one grey, not the fields' colours
    display.AmbientColor = display.DiffuseColor = list(OBSTACLE_GREY)
    display.Ambient, display.Diffuse, display.Specular = 1.0, 0.0, 0.0  # unlit: the same grey everywhere
    return display


def labels(view, scale):
    """The title, the time, the axes named and labelled with the data's values (`scale`: the heights' stretch)."""
    title = pv.Show(pv.Text(registrationName="title", Text=TITLE), view)
    title.WindowLocation, title.FontSize, title.Color = "Upper Center", 20, [0.0, 0.0, 0.0]
    clock = pv.Show(pv.AnnotateTime(registrationName="time", Format="t = {time:.4g}"), view)
    clock.WindowLocation, clock.FontSize, clock.Color = "Upper Left Corner", 20, [0.0, 0.0, 0.0]
    grid = view.AxesGrid
    grid.Visibility = 1
    grid.XTitle, grid.YTitle, grid.ZTitle = ("x", "eta", "") if KIND == "string" else ("x", "y", "eta")
    for axis in "XYZ":
        for part in ("Title", "Label"):
            setattr(grid, f"{axis}{part}Color", [0.0, 0.0, 0.0])
            setattr(grid, f"{axis}{part}FontSize", 16)
    grid.GridColor = [0.3, 0.3, 0.3]
    # the same axes at every time, around the stretched box and labelled with the heights (DataScale)
    grid.UseCustomBounds, grid.CustomBounds = 1, [BOUNDS[k] * scale[k // 2] for k in range(6)]
    grid.DataScale = list(scale)
    grid.AxesToLabel = 7  # the lower edges only (min x, min y, min z): the others would repeat them


def height_scale(size):
    """A string's stretch of the heights (1, s, 1) that fills the picture within MARGINS (a membrane: 1)."""
    if KIND != "string":
        return [1.0, 1.0, 1.0]
    width, height = (BOUNDS[1] - BOUNDS[0]) or 1.0, BOUNDS[3] - BOUNDS[2]
    stretch = (TALL * size[1] / (WIDE * size[0])) * width / height if height > 1e-9 * width else 1.0
    return [1.0, stretch, 1.0]


def build(size=(1000, 600)):
    disable = getattr(pv, "_DisableFirstRenderCameraReset", None)
    if disable is not None:  # else the first Render resets the camera to this time's shape
        disable()
    reader = pv.Xdmf3ReaderT(registrationName="solution.xdmf", FileName=[os.path.join(folder(), "solution.xdmf")])
    animation = pv.GetAnimationScene()
    animation.UpdateAnimationUsingDataTimeSteps()
    warp = pv.WarpByScalar(registrationName="warped by eta", Input=reader, Scalars=["POINTS", "eta"])
    warp.Normal = NORMAL
    warp.ScaleFactor = 1.0
    shown = warp
    for name in SYMLOG:  # each symmetric-log field also on its scale, for its colour bar
        shown = pv.PythonCalculator(registrationName=name + SYMLOG_SUFFIX, Input=shown)
        shown.Expression = symlog_expression(name)
        shown.ArrayName = name + SYMLOG_SUFFIX
    view = pv.GetActiveViewOrCreate("RenderView")
    view.ViewSize = list(size)
    view.Background = [1.0, 1.0, 1.0]
    view.UseColorPaletteForBackground = 0
    view.OrientationAxesVisibility = 0  # the named axes below say which way is which
    scale = height_scale(size)
    obstacle(view, reader).Scale = scale
    display = pv.Show(shown, view)
    display.Scale = scale
    if KIND == "string":
        display.LineWidth = 4.0
    for name, ((low, high), preset, colours) in MAPS.items():  # every field's map fixed, for the GUI's colour menu
        fixed_map(name, low, high, preset, colours)
    colour_by(view, display, "contact")
    labels(view, scale)
    frame(view, scale)
    return animation, view, display


def frame(view, scale):
    """The camera on the box of all times: a string from the front, within MARGINS; a membrane from above its front
    edge. (No max() here: ParaView runs the obstacle's script in this namespace, after vtk's `algorithms import *`.)"""
    low, high = [BOUNDS[2 * k] * scale[k] for k in range(3)], [BOUNDS[2 * k + 1] * scale[k] for k in range(3)]
    centre = [0.5 * (a + b) for a, b in zip(low, high)]
    width = sorted([b - a for a, b in zip(low, high)] + [1e-12])[-1]  # noqa: FURB192
    if KIND == "string":  # the box's length fills the width within the margins, its height the height
        aspect = view.ViewSize[0] / view.ViewSize[1]
        half = sorted([0.5 * (high[0] - low[0]) / (WIDE * aspect), 0.5 * (high[1] - low[1]) / TALL, 1e-12])[-1]  # noqa: FURB192
        # the box's centre sits in the middle of the free part of the picture, not of the picture
        shift = [(0.5 * (MARGINS["right"] - MARGINS["left"])) * 2.0 * half * aspect,
                 (0.5 * (MARGINS["top"] - MARGINS["bottom"])) * 2.0 * half]
        focal = [centre[0] + shift[0], centre[1] + shift[1], centre[2]]
        view.CameraFocalPoint = focal
        view.CameraPosition = [focal[0], focal[1], focal[2] + 3.0 * width]
        view.CameraViewUp = [0.0, 1.0, 0.0]
        view.CameraParallelProjection = 1
        view.CameraParallelScale = half
        return
    view.CameraFocalPoint = centre
    view.CameraPosition = [centre[0] - 0.4 * width, centre[1] - 1.1 * width, centre[2] + 1.5 * width]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    view.ResetCamera(*BOUNDS)


def shots(args):
    """The screenshots asked for: [(time, png, field)] from TIME PNG [FIELD] [TIME PNG [FIELD] ...]."""
    found, args = [], list(args)
    while len(args) >= 2 and args[1].lower().endswith(".png"):
        t, png, args = float(args[0]), args[1], args[2:]
        field = args.pop(0) if args and not _is_number(args[0]) else "contact"
        found.append((t, png, field))
    return found if not args else []


def _is_number(text):
    try:
        float(text)
    except ValueError:
        return False
    return True


def screenshot(animation, view, display, t, png, field):
    """Save the view at the time t coloured by `field` to `png`; the JSON report of what was drawn."""
    animation.AnimationTime = view.ViewTime = t
    colour_by(view, display, field)
    pv.Render(view)
    pv.SaveScreenshot(png, view, ImageResolution=list(view.ViewSize), TransparentBackground=0)
    cam, grid = view.GetActiveCamera(), view.AxesGrid  # the camera VTK renders with, not the proxy's copy
    source = pv.FindSource("obstacle")
    source.UpdatePipeline(view.ViewTime)  # its data information (the box drawn) is of the last update's time
    report = {"time": view.ViewTime, "field": field, "range": list(MAPS[field][0]), "scale": list(display.Scale),
              "camera": {"position": list(cam.GetPosition()), "focal_point": list(cam.GetFocalPoint()),
                         "parallel_scale": cam.GetParallelScale(), "view_angle": cam.GetViewAngle()},
              "axes": [grid.XTitle, grid.YTitle, grid.ZTitle] if grid.Visibility else [],
              "obstacle": list(source.GetDataInformation().GetBounds())}
    if field in SYMLOG:
        report["ticks"] = [label for _, label in SYMLOG[field][2]]
    return report


def main(argv):
    wanted = shots(argv[1:])  # several in one ParaView session: its start-up (seconds) is paid once
    for _, _, field in wanted:
        if field not in MAPS:
            sys.exit(f"view.py: no field {field!r} to colour by; choose one of {', '.join(MAPS)}")
    animation, view, display = build()
    for t, png, field in wanted:
        print(json.dumps(screenshot(animation, view, display, t, png, field)), flush=True)
    if wanted:
        return
    pv.Render(view)
    if argv[0]:  # pvpython view.py: a window of its own (ParaView's GUI runs the script with sys.argv == [""])
        pv.Interact(view)


main(list(getattr(sys, "argv", None) or [""]))
