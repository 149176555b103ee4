"""Pictures of meshes in space, drawn with pyvista off-screen (EGL when there is no display).

``space_time.png``: a 1-D run as the surface η(x, t) over the (x, t) plane, coloured by contact, above
the obstacle ψ. ``membrane.png``: a 2-D run, the membrane z = η(x, y, t) at the scene's output times, one
panel each, coloured by contact, above the obstacle z = ψ(x, y) (grey). A moving obstacle ψ(x, t) is drawn at
each panel's and frame's time, and as the surface ψ(x, t) in ``space_time.png``. The animation
``membrane.gif`` (:mod:`stringcontact.plot.animation`) draws the same scene (`add_membrane`) at every few rows.
A membrane whose model has a surface field (an output field whose description says ``surface``) is coloured by
that field instead (`fields.FieldScale`: one fixed scale over all stored rows, in the field's own colours, its bar
drawn by `add_field_bar`), the edge of its contact set drawn on it as a line (`contact_edge`).

VTK's scalar bar and pyvista's `show_bounds` format their labels with `std::regex`, which aborts the
process (`std::bad_alloc`) once dolfinx's C++ module is loaded (a run's pictures drawn in its own process,
`simulate(..., pictures=True)`): this module uses neither. Its axes are drawn as lines with ticks and
point labels (`add_axis`: x, t or y, and the height η, on the floor below the obstacle, along the edges
nearest the viewer), and its colours are named by a legend (`add_colour_legend`: the quantity, contact,
and what each colour means), which need no regex.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.publish import atomic_path
from .catalogue import WINDOW_SIZE
from .charts import (
    CONTACT_COLOUR,
    PNG_COMPRESSION,
    obstacle_history,
    obstacle_moves,
    obstacle_name,
    obstacle_profile,
    obstacle_range,
    panels_note,
    parameter_line,
    snapshot_rows,
    without_axes3d_warning,
)
from .colour_bar import add_field_bar
from .fields import FieldScale, info_of, surface_field
from .vtk_modules import _font_file, search_once

FREE_COLOUR = "#92c5de"
OBSTACLE_COLOUR = "#777777"
MEMBRANE_OBSTACLE_COLOUR = "#c9c9c9"  # OBSTACLE_COLOUR at opacity 0.4 on white
#: the edge of the contact set of a membrane coloured by a field: yellow, seen on blue, grey and red alike
CONTACT_EDGE_COLOUR = "#ffd400"
#: its colour in the legend's text, on white (the line's yellow is hardly read there)
CONTACT_EDGE_TEXT = "#b08f00"


#: VTK render windows that draw on an X server: without one, VTK 9 fails to make them and then crashes (SIGSEGV).
X_WINDOWS = ("vtkXOpenGLRenderWindow",)


def _pyvista():
    if "DISPLAY" not in os.environ:  # EGL needs no display; on a desktop VTK's default window works too
        window = os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        if window in X_WINDOWS:  # refused before VTK is asked: it would take the process down
            raise ValueError(f"VTK_DEFAULT_OPENGL_WINDOW={window} needs an X display and DISPLAY is not set; the "
                               "3-D pictures are left out (unset it, or set it to vtkEGLRenderWindow)")
    search_once()  # VTK's module search lists its folder once, not twice per module (vtk_modules)
    import pyvista as pv

    with without_axes3d_warning():  # pyvista's colour maps import matplotlib's projections
        import matplotlib.projections  # noqa: F401

    pv.OFF_SCREEN = True
    return pv


def _plotter(window_size, **layout):
    """An off-screen plotter; `layout`: pyvista's shape, groups, row_weights for several panels."""
    if layout:
        layout.setdefault("border", False)
    p = _pyvista().Plotter(window_size=list(window_size), off_screen=True, **layout)
    p.disable_anti_aliasing()  # pyvista's 8× MSAA: 0.71 s of llvmpipe's CPU for the surface instead of 0.39 s (bench_pictures.py)
    p.set_background("white")
    return p


#: vtkCornerAnnotation's sizing (VTK 9): the largest size up to FIT whose text fits 90 % of the panel's height,
#: then int(size ** NONLINEAR * linear), drawn only from SMALLEST up, MARGIN pixels below the top edge
ANNOTATION = {"FIT": 100, "NONLINEAR": 0.35, "SMALLEST": 6, "MARGIN": 5, "START": 12}


def _title(p, text: str, font_size: int = 9) -> None:
    """`text` centred at the top of the current panel, as pyvista's add_text(position="upper_edge") draws it.

    That annotation (vtkCornerAnnotation) picks its size by growing the font one point at a time up to 100 and
    measuring its eight corner texts at each size: the space-time picture took 0.294 against 0.249 CPU-s
    (medians of 9, `benchmarks/bench_pictures.py --title --repeats 9`). Here the same search bisects over the
    one text (about 8 measures instead of 700), and the same mapper and actor draw it at the same place:
    identical pixels (tests/plot/test_title.py).
    """
    from vtkmodules.vtkRenderingCore import vtkActor2D, vtkTextMapper

    prop = _pyvista().TextProperty(color="black", font_file=_font_file())
    prop.SetJustificationToCentered()
    prop.SetVerticalJustificationToTop()
    mapper = vtkTextMapper()
    mapper.SetInput(text)
    mapper.SetTextProperty(prop)
    width, height = p.renderer.GetSize()
    # 90 % of the panel's height; the annotation's other bound, a line's height (the panel's) per line, is never lower
    size = _annotation_size(mapper, p.renderer, int(0.9 * height))
    size = int(size ** ANNOTATION["NONLINEAR"] * (font_size // 2))  # pyvista's linear factor: font_size // 2
    if size < ANNOTATION["SMALLEST"]:  # the annotation draws nothing then
        return
    prop.SetFontSize(size)
    actor = vtkActor2D()
    actor.SetMapper(mapper)
    actor.SetPosition(width // 2, height - ANNOTATION["MARGIN"])
    p.add_actor(actor, reset_camera=False, pickable=False)


def _annotation_size(mapper, renderer, limit: int) -> int:
    """vtkCornerAnnotation's search for the mapper's font size: up from START while the text is lower than
    `limit` pixels (at most to FIT), then down while it is higher; bisected, the text's height rising with size."""
    box = [0, 0]

    def higher(size: int, than: int) -> bool:
        mapper.GetTextProperty().SetFontSize(size)
        mapper.GetSize(renderer, box)
        return box[1] > than

    size = ANNOTATION["START"]
    if not higher(size, limit - 1):  # lower than the limit: up to the first size that reaches it
        size = min(_first(size + 1, ANNOTATION["FIT"], lambda s: higher(s, limit - 1)), ANNOTATION["FIT"])
    return max(_first(0, size, lambda s: higher(s, limit)) - 1, 0) if higher(size, limit) else size


def _first(low: int, high: int, holds) -> int:
    """The first integer in [low, high] where `holds` (False below it, True from it on), else high + 1."""
    while low <= high:
        middle = (low + high) // 2
        low, high = (low, middle - 1) if holds(middle) else (middle + 1, high)
    return low


def _screenshot(p, path: Path) -> None:
    from PIL import Image

    try:
        image = p.screenshot(None, return_img=True)  # the pixels pyvista would write; Pillow writes them at our level
    finally:
        p.close()
    with atomic_path(path) as tmp:  # a picture is either complete or absent
        Image.fromarray(image).save(tmp, format="PNG", compress_level=PNG_COMPRESSION)


def nice_ticks(low: float, high: float, most: int = 5) -> np.ndarray:
    """Round tick values within [low, high] (matplotlib's MaxNLocator), at least the two ends if none fit."""
    from matplotlib.ticker import MaxNLocator

    if not high > low:
        return np.array([low])
    ticks = MaxNLocator(nbins=most, steps=[1, 2, 2.5, 5, 10]).tick_values(low, high)
    span = high - low
    ticks = np.array([float(f"{v:.12g}") for v in ticks if low - 1e-9 * span <= v <= high + 1e-9 * span])
    return ticks if ticks.size >= 2 else np.array([low, high])


def _height_text(value: float, span: float) -> str:
    """`value` to 3 digits; 0 where it lies within a millionth of `span` of 0 (a profile's 1.32e-112 is 0)."""
    return f"{0.0 if abs(value) <= 1e-6 * abs(span) else float(value):.3g}"


def _tick_label(v: float) -> str:
    return f"{0.0 if abs(v) < 1e-12 else v:g}"


@dataclass
class Axis:
    """One axis: drawn from `start` to `end` (3-D points), the values `low` … `high` along it, ticks pointing
    along `outward` (a 3-D offset: the labels sit at twice it), named `title`."""

    start: tuple
    end: tuple
    low: float
    high: float
    outward: tuple
    title: str


def add_axis(p, axis: Axis, font_size: int = 11, most: int = 5) -> list[str]:
    """An axis with ticks and labels in the plotter `p`; returns the tick labels drawn."""
    pv = _pyvista()
    start, end, out = (np.asarray(v, dtype=float) for v in (axis.start, axis.end, axis.outward))
    p.add_mesh(pv.Line(start, end), color="black", line_width=2, lighting=False)
    ticks = nice_ticks(axis.low, axis.high, most)
    where = start + np.outer((ticks - axis.low) / ((axis.high - axis.low) or 1.0), end - start)
    for point in where:
        p.add_mesh(pv.Line(point, point + out), color="black", line_width=2, lighting=False)
    labels = [_tick_label(v) for v in ticks]
    p.add_point_labels(where + 2.2 * out, labels, font_size=font_size, text_color="black", shape=None,
                       show_points=False, always_visible=True, font_family="arial", justification_horizontal="center")
    beyond = 4.5 + 0.3 * max(font_size - 11, 0)  # the axis' name clear of its tick labels, however large
    p.add_point_labels([0.5 * (start + end) + beyond * out], [axis.title], font_size=font_size + 2, text_color="black",
                       shape=None, show_points=False, always_visible=True, bold=True)
    return labels


def add_colour_legend(p, quantity: str, entries, top: float = 0.86, font_size: int = 9, left: float = 0.74,
                      step: float = 0.028) -> None:
    """A colour key at the upper right naming what the colours show: the `quantity` (its lines in black), then
    one "■ label" line per (label, colour) of `entries`, in that colour (DejaVu Sans: Greek letters too; VTK's
    legend box has no such font)."""
    lines = [*[(line, "black") for line in quantity.split("\n")], *[(f"■ {label}", colour) for label, colour in entries]]
    for k, (text, colour) in enumerate(lines):
        p.add_text(text, position=(left, top - step * k), viewport=True, font_size=font_size, color=colour,
                   font_file=_font_file())


def _every_kth(n: int, most: int) -> np.ndarray:
    """Every k-th of n indices and the last, at most about `most` of them."""
    return np.union1d(np.arange(0, n, max(1, int(np.ceil(n / most)))), [n - 1])


def space_time_picture(result, path, window_size=WINDOW_SIZE, max_columns: int = 300, max_rows: int = 200) -> Path:
    """η(x, t) as a surface over the (x, t) plane, red where in contact, above the obstacle ψ (grey): the
    surface ψ(x, t) when the obstacle moves."""
    pv = _pyvista()
    path = Path(path)
    # the surface spans ~800 pixels across and ~400 deep: finer meshes cost llvmpipe time, not detail
    cols, rows = _every_kth(result.x.size, max_columns), _every_kth(result.t.size, max_rows)
    x, t, eta = result.x[cols], result.t[rows], result.eta[np.ix_(rows, cols)]
    moves = obstacle_moves(result)
    psi = obstacle_history(result, rows, cols) if moves else obstacle_profile(result)[cols]  # ψ(x, t) or ψ(x)
    lo, hi = min(eta.min(), psi.min()), max(eta.max(), psi.max())
    length = float(x[-1] - x[0])
    depth = -0.8 * length / (float(t[-1] - t[0]) or 1.0)  # t runs out of the picture over 0.8 l: t = 0 at the back
    height = 0.4 * length / (hi - lo or 1.0)  # η is drawn 0.4 l high
    X, T = np.meshgrid(x, t * depth)
    surface = pv.StructuredGrid(X, T, eta * height)
    surface.point_data["contact"] = result.contact[np.ix_(rows, cols)].astype(float).ravel(order="F")  # points in Fortran order
    below = 0.02 * (hi - lo) * height  # under the penalty's penetration (about ε|v|), which it would otherwise hide
    if moves:  # the surface ψ(x, t) on the same grid as η
        obstacle = pv.StructuredGrid(X, T, psi * height - below)
    else:  # ψ(x) at every t: a band between t = 0 and T
        obstacle = pv.StructuredGrid(*np.meshgrid(x, t[[0, -1]] * depth), np.tile(psi * height - below, (2, 1)))

    p = _plotter(window_size)
    p.add_mesh(surface, scalars="contact", cmap=[FREE_COLOUR, CONTACT_COLOUR], clim=(0, 1), n_colors=2,
               show_scalar_bar=False, ambient=0.3)
    p.add_mesh(obstacle, color=OBSTACLE_COLOUR, opacity=0.4)
    psi_name = obstacle_name(result)
    floor = psi.min() * height - 3 * below  # the axes lie on a floor under the obstacle, never over the surface
    front, back, unit = float(t[-1]) * depth, float(t[0]) * depth, 0.035 * length
    add_axis(p, Axis((x[0], front, floor), (x[-1], front, floor), float(x[0]), float(x[-1]), (0, -unit, -0.3 * unit), "x"))
    add_axis(p, Axis((x[-1], back, floor), (x[-1], front, floor), float(t[0]), float(t[-1]), (unit, 0, 0), "t"))
    add_axis(p, Axis((x[0], front, lo * height), (x[0], front, hi * height), lo, hi, (-unit, 0, 0), "eta"))  # VTK's label font has no Greek
    add_colour_legend(p, "colour: contact", [(f"in contact, η ≤ {psi_name}", CONTACT_COLOUR),
                                             (f"free, η > {psi_name}", FREE_COLOUR), (f"obstacle {psi_name}", OBSTACLE_COLOUR)],
                      top=0.82)  # under the title's five lines
    # one short line each: at the window's width a longer title line ran off both edges
    _title(p, f"Space-time surface η(x, t): {result.scene.name}\n{parameter_line(result, sep=chr(10))}\n"
              f"η from {_height_text(result.eta.min(), hi - lo)} to {_height_text(result.eta.max(), hi - lo)} over x and t"
              + (f", {psi_name} from {_height_text(psi.min(), hi - lo)} to {_height_text(psi.max(), hi - lo)}\n"
                 if psi_name == "ψ" else "\n") +
              f"red: in contact (η ≤ {psi_name}), blue: free, grey: the obstacle")
    centre = (0.5 * length, 0.5 * float(t[-1]) * depth, 0.0)  # seen from above the late times, so that the
    p.camera_position = [(-0.2 * length, -2.2 * length, 1.9 * length), centre, (0, 0, 1)]  # high t = 0 hides no contact
    p.reset_camera()
    _screenshot(p, path)
    return path


# --- a membrane (2-D run) ---------------------------------------------------------------------------


@dataclass
class MembraneView:
    """How a membrane is drawn: heights times `scale`, within the box `bounds`, seen from `camera`; the
    contact indicator coloured through `neighbours` (`shade`)."""

    scale: float
    bounds: tuple  # (x0, x1, y0, y1, z0, z1), drawn coordinates
    camera: list
    neighbours: object = None  # the mean over each node's mesh neighbours, a sparse matrix (`neighbour_mean`)
    field: FieldScale | None = None  # the model's surface field: the membrane coloured by it on this scale
    obstacle: object = None  # a moving obstacle's PolyData last drawn by `add_membrane`: `show_row` moves it

    def shade(self, contact: np.ndarray) -> np.ndarray:
        """What the colour is drawn from: 0.6 × the nodal contact indicator + 0.4 × its mean over the node's
        neighbours. Its 0.5 iso-line (where the two colours meet, interpolated across the triangles) lies where
        that of the bare indicator lies on average, without the zigzag of the bare indicator, whose iso-line
        alternates between a triangle's corner and its edge midpoints (the staircase at the default mesh).
        A node is red if and only if it is in contact (≥ 0.6 against ≤ 0.4)."""
        c = np.asarray(contact, dtype=float)
        return c if self.neighbours is None else 0.6 * c + 0.4 * (self.neighbours @ c)


def neighbour_mean(cells: np.ndarray, nodes: int):
    """The sparse matrix of the mean over each node's neighbours along the mesh's edges."""
    from scipy.sparse import coo_matrix

    edges = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    both = np.concatenate([edges, edges[:, ::-1]])
    adjacency = coo_matrix((np.ones(len(both)), tuple(both.T)), shape=(nodes, nodes)).tocsr()
    degree = np.maximum(np.asarray(adjacency.sum(axis=1)).ravel(), 1.0)
    return adjacency.multiply(1.0 / degree[:, None]).tocsr()


def membrane_view(result) -> MembraneView:
    """Heights exaggerated (at least ×1) so that the height range is 0.3 of the domain's width; a camera
    above the front edge, looking down at 50° or so, that sees every row and the obstacle."""
    x = result.x
    psi_lo, psi_hi = obstacle_range(result)  # over all stored times: a moving obstacle stays in the box
    lo, hi = min(float(result.eta.min()), psi_lo), max(float(result.eta.max()), psi_hi)
    width = float(max(np.ptp(x[:, 0]), np.ptp(x[:, 1])))
    scale = max(1.0, 0.3 * width / (hi - lo or 1.0))
    bounds = (*_span(x[:, 0]), *_span(x[:, 1]), lo * scale - _below(lo, hi, scale), hi * scale)
    centre = np.array([0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]), 0.5 * (bounds[4] + bounds[5])])
    eye = centre + width * np.array([-0.4, -1.1, 1.5])
    field = surface_field(result)
    return MembraneView(scale, bounds, [tuple(eye), tuple(centre), (0.0, 0.0, 1.0)], neighbour_mean(result.cells, len(x)),
                        None if field is None else FieldScale.of(result.fields[field], info_of(result, field)))


def _span(v) -> tuple[float, float]:
    return float(v.min()), float(v.max())


def _below(lo: float, hi: float, scale: float) -> float:
    """How far under ψ the obstacle is drawn: a contact region lies on ψ, which would otherwise hide it."""
    return 0.01 * (hi - lo or 1.0) * scale


def triangles(result, z):
    """The membrane's triangles as a pyvista PolyData with points (x, y, z)."""
    pv = _pyvista()
    faces = np.hstack([np.full((len(result.cells), 1), 3), result.cells]).astype(np.int64).ravel()
    return pv.PolyData(np.column_stack([result.x, z]).astype(float), faces)


def add_membrane(p, result, row: int, view: MembraneView):
    """The membrane at `row` and the obstacle (grey) in the plotter `p`: coloured by contact, or by the surface
    field on `view.field`'s scale (then `add_contact_edge` draws its contact set's edge). Returns the
    membrane's PolyData, whose heights and colours `show_row` changes in place afterwards. A moving obstacle
    is drawn at the row's time (kept in `view.obstacle` for `show_row`)."""
    moves = obstacle_moves(result)
    psi = obstacle_profile(result, float(result.t[row]) if moves else 0.0)
    lo, hi = view.bounds[4] / view.scale, view.bounds[5] / view.scale
    surface = triangles(result, result.eta[row] * view.scale)
    surface.point_data["contact"] = view.shade(result.contact[row])
    # smooth (Gouraud) shading: the flat shading showed every triangle as a facet
    if view.field is None:
        p.add_mesh(surface, scalars="contact", cmap=[FREE_COLOUR, CONTACT_COLOUR], clim=(0, 1), n_colors=2,
                   show_scalar_bar=False, ambient=0.3, smooth_shading=True)
    else:
        _set_field(surface, result, row, view.field)
        p.add_mesh(surface, scalars=f"{view.field.name}_colour", cmap=view.field.colour_map(), clim=(-1, 1),
                   show_scalar_bar=False, ambient=0.3, smooth_shading=True)
    # opaque and unlit, in the colour the translucent grey of space_time.png takes on white: the membrane is never
    # below it (η ≥ ψ), so nothing would show through, and translucency costs 40 % more CPU per GIF frame
    obstacle = triangles(result, psi * view.scale - _below(lo, hi, view.scale))
    p.add_mesh(obstacle, color=MEMBRANE_OBSTACLE_COLOUR, lighting=False)
    if moves:
        view.obstacle = obstacle
    p.camera_position = view.camera
    p.reset_camera(bounds=view.bounds)
    p.camera.zoom(1.1)  # reset_camera fits the box's bounding sphere: room to spare
    return surface


def show_row(surface, result, row: int, view: MembraneView) -> None:
    """The membrane `surface` of `add_membrane` moved to `row` in place: its heights and the arrays it is coloured
    by, and a moving obstacle's heights."""
    surface.points[:, 2] = result.eta[row] * view.scale  # in place: the scene stays, the heights change
    surface.point_data["contact"][:] = view.shade(result.contact[row])
    if view.field is not None:
        _set_field(surface, result, row, view.field)
    surface.Modified()
    if view.obstacle is not None:  # a moving obstacle: where it is at this row's time
        lo, hi = view.bounds[4] / view.scale, view.bounds[5] / view.scale
        view.obstacle.points[:, 2] = obstacle_profile(result, float(result.t[row])) * view.scale - _below(lo, hi, view.scale)
        view.obstacle.Modified()


def _set_field(surface, result, row: int, scale: FieldScale) -> None:
    """NAME: the field `scale.name` at the nodes; NAME_colour: where it lies on `scale` (−1 … 1), the array drawn."""
    name, colour = scale.name, f"{scale.name}_colour"
    values = np.array(result.fields[name][row], dtype=float)  # a copy: pyvista shares the array it is given, and
    if name in surface.point_data:  # the next row written into it would overwrite the Result's row
        surface.point_data[name][:] = values
        surface.point_data[colour][:] = scale.unit(values)
    else:
        surface.point_data[name] = values
        surface.point_data[colour] = scale.unit(values)


#: the membrane axes' font size (VTK points): digits 12 px high (7 gave 6 px, too small to read)
TICK_FONT = 16


def add_membrane_axes(p, view: MembraneView, font_size: int = TICK_FONT) -> None:
    """x and y along the front and right edges of the floor under the obstacle, and the height η (in its own
    units: the ticks undo the drawing's `scale`) up the front left corner."""
    x0, x1, y0, y1, z0, z1 = view.bounds
    unit = 0.05 * max(x1 - x0, y1 - y0)
    add_axis(p, Axis((x0, y0, z0), (x1, y0, z0), x0, x1, (0, -unit, 0), "x"), font_size, most=4)
    add_axis(p, Axis((x1, y0, z0), (x1, y1, z0), y0, y1, (unit, 0, 0), "y"), font_size, most=4)
    add_axis(p, Axis((x0, y0, z0), (x0, y0, z1), z0 / view.scale, z1 / view.scale, (-unit, 0, 0), "eta"), font_size, most=3)
    margin = 5 * unit  # the ticks' labels and the axes' names
    p.reset_camera(bounds=(x0 - margin, x1 + margin, y0 - margin, y1, z0, z1))
    p.camera.zoom(1.15)


def membrane_label(result, row: int, area: float, patches: int | None = None) -> str:
    """'t = 0.2: contact area 2.17 (69%), 1 patch': the share is of the domain's area (patches left out if None)."""
    share = 100 * area / float(np.sum(result.weights))
    text = f"t = {result.t[row]:.3g}: contact area {area:.3g} ({share:.0f}%)"
    return text if patches is None else f"{text}, {patches} patch{'es' * (patches != 1)}"


def membrane_title(result, view: MembraneView, what: str, sep: str = ", ") -> str:
    """The title's lines; `sep` joins the two halves of the parameter line (a newline for a narrow picture)."""
    stretched = f"heights ×{view.scale:.2g}; " if view.scale > 1 else ""
    psi = obstacle_name(result)
    colours = (f"red: in contact (η ≤ {psi}), blue: free" if view.field is None else
               f"colour: {view.field.label} (its bar){sep}yellow line: the edge of contact (η ≤ {psi})")
    return f"{what}: {result.scene.name}\n{parameter_line(result, sep)}\n{stretched}{colours}, grey: the obstacle {psi}"


def membrane_legend(result, view: MembraneView) -> tuple[str, list]:
    """The colour key's quantity and its (label, colour) entries: contact, or the surface field."""
    psi = obstacle_name(result)
    if view.field is None:
        return "colour: contact", [(f"in contact, η ≤ {psi}", CONTACT_COLOUR), (f"free, η > {psi}", FREE_COLOUR),
                                   (f"obstacle {psi}", OBSTACLE_COLOUR)]
    return f"colour:\n{view.field.label}", [("edge of contact", CONTACT_EDGE_TEXT), (f"obstacle {psi}", OBSTACLE_COLOUR)]


#: the height of the colour bar's row in membrane.png of a membrane coloured by a field, against a panel's 1 and the title's 0.25
BAR_ROW = 0.16


def membrane_picture(result, path, window_size=WINDOW_SIZE) -> Path:
    """The membrane z = η(x, y, t) at the scene's output times (one panel each; the stored row nearest to
    each), red where in contact, above the obstacle (grey). Each panel names its time, contact area and
    number of contact patches. A membrane with a surface field is coloured by it instead, on one scale for
    all panels (its bar in a row under them), the edge of its contact set drawn in yellow."""
    path = Path(path)
    rows = snapshot_rows(result)
    ncols = 3 if len(rows) > 4 else min(len(rows), 2)
    nrows = int(np.ceil(len(rows) / ncols))
    view = membrane_view(result)
    area = result.contact_measure
    patches = dataclasses.replace(result, contact=result.contact[rows]).contact_patches()  # of these rows only
    # a title row across the top, then the panels (and the surface field's colour bar across the bottom)
    bar = view.field is not None
    p = _plotter(window_size, shape=(nrows + 1 + bar, ncols), groups=[(0, np.s_[:])] + [(nrows + 1, np.s_[:])] * bar,
                 row_weights=[0.25] + [1] * nrows + [BAR_ROW] * bar)
    p.subplot(0, 0)
    note = panels_note(result, rows)
    _title(p, membrane_title(result, view, "The membrane at the output times") + (f"; {note}" if note else ""))
    # the colour key in the title row's right corner: in a panel, the next panel cut its lines off
    add_colour_legend(p, *membrane_legend(result, view), top=0.72, font_size=7, left=0.86, step=0.2)
    for k, i in enumerate(rows):
        p.subplot(1 + k // ncols, k % ncols)
        surface = add_membrane(p, result, i, view)
        if bar:
            add_contact_edge(p, surface, view)
        add_membrane_axes(p, view)
        p.add_text(membrane_label(result, i, area[i], int(patches[k])).replace(": ", "\n", 1), position=(0.03, 0.85),
                   viewport=True, font_size=7, color="black", font_file=_font_file())
    if bar:
        p.subplot(nrows + 1, 0)
        add_field_bar(p, view.field, (0.3, 0.55, 0.7, 0.9), font_size=8)
    _screenshot(p, path)
    return path


def contact_edge(surface, view: MembraneView, into=None):
    """The edge of the contact set on the drawn membrane `surface`: the 0.5 iso-line of its "contact" shade
    (`MembraneView.shade`), lifted by 0.5 % of the drawing's height so that the surface does not hide it;
    copied into the PolyData `into` if given (a GIF's next frame). Empty when nothing is in contact."""
    line = surface.contour([0.5], scalars="contact")
    if line.n_points:
        line.points[:, 2] += 0.005 * (view.bounds[5] - view.bounds[4])
    if into is None:
        return line
    into.copy_from(line)
    return into


def add_contact_edge(p, surface, view: MembraneView):
    """The contact set's edge (`contact_edge`) on `surface` as a yellow line; returns its PolyData, which
    `contact_edge(surface, view, into=...)` updates in place. Drawn through VTK's own mapper: pyvista refuses
    an empty mesh, the edge of a membrane not in contact."""
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

    edge = contact_edge(surface, view)
    mapper = vtkPolyDataMapper()
    mapper.SetInputData(edge)
    mapper.ScalarVisibilityOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*(int(CONTACT_EDGE_COLOUR[i : i + 2], 16) / 255 for i in (1, 3, 5)))
    prop.SetLineWidth(3.0)
    prop.LightingOff()
    p.add_actor(actor, reset_camera=False, pickable=False)
    return edge


def warm_up() -> None:
    """A tiny picture with every kind of element the real one uses, so that llvmpipe compiles its shaders."""
    p = _plotter((64, 48))
    grid = _pyvista().StructuredGrid(*np.meshgrid([0.0, 1.0], [0.0, 1.0]), np.zeros((2, 2)))
    grid.point_data["contact"] = np.array([0.0, 1.0, 0.0, 1.0])
    p.add_mesh(grid, scalars="contact", cmap=[FREE_COLOUR, CONTACT_COLOUR], n_colors=2, show_scalar_bar=False)
    p.add_mesh(grid, color=OBSTACLE_COLOUR, opacity=0.4)
    p.add_mesh(grid, color=MEMBRANE_OBSTACLE_COLOUR, lighting=False)  # a membrane's obstacle
    p.add_point_labels([[0.0, 0.0, 0.0]], ["t"], shape=None, show_points=False, always_visible=True)
    _title(p, "η")
    p.screenshot(None, return_img=True)
    p.close()
