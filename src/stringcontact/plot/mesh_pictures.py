"""Pictures of meshes in space, a pyvista render laid out in a matplotlib figure (vector words in a PDF or SVG):
``space_time.png``, a string's η(x, t) over the (x, t) plane above ψ; ``membrane.png``, a membrane at the output
times (`membrane`: what it shares with ``membrane.gif``); coloured by contact or by the surface field."""

from __future__ import annotations

import numpy as np

from . import charts, membrane
from .charts import titled
from .style import CONTACT_COLOUR, FREE_COLOUR, OBSTACLE_COLOUR, SCREEN, Look
from .vtk_start import Axis, _plotter, _pyvista, add_axis

#: the room (inches) a pyvista picture keeps for its title and colour key, and for the caption when it has one
KEY_ROOM, CAPTION_ROOM = 0.9, 0.5
#: the widths (pixels) of the renders the axes' font (`membrane.TICK_FONT`) was chosen for: the screen's space-time
#: picture and a membrane's panel three abreast; and the least size of their labels, in points
SCREEN_RENDER, SCREEN_PANEL, LEAST_POINTS = 1100, 367, 6.0


def _font_zoom(look: Look, width: int, screen: int) -> float:
    """The axes' font factor in a render `width` pixels wide: as on the screen's `screen`, ≤ `Look.zoom`, ≥ LEAST_POINTS."""
    return min(look.zoom, max(width / screen, LEAST_POINTS / 72 * look.dpi / membrane.TICK_FONT))


def _height_text(value: float, span: float) -> str:
    """`value` to 3 digits; 0 where it lies within a millionth of `span` of 0 (a profile's 1.32e-112 is 0)."""
    return f"{0.0 if abs(value) <= 1e-6 * abs(span) else float(value):.3g}"


def _every_kth(n: int, most: int) -> np.ndarray:
    """Every k-th of n indices and the last, at most about `most` of them."""
    return np.union1d(np.arange(0, n, max(1, int(np.ceil(n / most)))), [n - 1])


def _key(ax, entries) -> None:
    """The colour key in the axes `ax` (under the picture): a filled square per (label, colour) of `entries`."""
    from matplotlib.patches import Patch

    charts.add_key(ax, [Patch(facecolor=colour, edgecolor="0.3", label=label) for label, colour in entries])


def space_time_figure(result, look: Look = SCREEN, max_columns: int = 300, max_rows: int = 200):
    """η(x, t) over the (x, t) plane, red where in contact, above the obstacle ψ(x, t) (grey): figure and axes."""
    width, height = look.inches
    pixels = look.pixels((width, height - KEY_ROOM - CAPTION_ROOM * look.caption))
    image = space_time_render(result, pixels, _font_zoom(look, pixels[0], SCREEN_RENDER), max_columns, max_rows)
    fig = charts.figure(look.inches)
    panels, below = charts.with_key(fig, key=0.4 / height)
    ax = fig.add_subplot(panels[0])
    ax.imshow(image)
    ax.set_axis_off()
    _key(below, membrane.colour_key(result))
    titled(fig, "Surface η(x, t) over the (x, t) plane", result, look, _height_range(result))
    return fig, ax



def _height_range(result) -> str:
    """'η from A to B over x and t' (and ψ's range, for a profiled obstacle): η's own, not the drawn box's."""
    low, high = charts.obstacle_range(result)
    span = max(float(result.eta.max()), high) - min(float(result.eta.min()), low)
    text = f"η from {_height_text(result.eta.min(), span)} to {_height_text(result.eta.max(), span)} over x and t"
    if charts.obstacle_name(result) == "ψ":
        text += f", ψ from {_height_text(low, span)} to {_height_text(high, span)}"
    return text


def space_time_render(result, pixels, zoom: float = 1.0, max_columns: int = 300, max_rows: int = 200) -> np.ndarray:
    """The surface η(x, t) with its axes rendered `pixels` large, fonts `zoom` times a screen's: an RGB array."""
    pv = _pyvista()
    # the surface spans ~800 pixels across and ~400 deep: finer meshes cost llvmpipe time, not detail
    cols, rows = _every_kth(result.x.size, max_columns), _every_kth(result.t.size, max_rows)
    x, t, eta = result.x[cols], result.t[rows], result.eta[np.ix_(rows, cols)]
    moves = result.scene.obstacle_moves
    psi = np.array([result.scene.obstacle_values(x, ti) for ti in t]) if moves else result.scene.obstacle_values(x)
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

    p = _plotter(pixels)
    try:
        p.add_mesh(surface, scalars="contact", cmap=[FREE_COLOUR, CONTACT_COLOUR], clim=(0, 1), n_colors=2,
                   show_scalar_bar=False, ambient=0.3)
        p.add_mesh(obstacle, color=OBSTACLE_COLOUR, opacity=0.4)
        floor = psi.min() * height - 3 * below  # the axes lie on a floor under the obstacle, never over the surface
        front, back, unit = float(t[-1]) * depth, float(t[0]) * depth, 0.035 * length
        for axis in (Axis((x[0], front, floor), (x[-1], front, floor), float(x[0]), float(x[-1]), (0, -unit, -0.3 * unit), "x"),
                     Axis((x[-1], back, floor), (x[-1], front, floor), float(t[0]), float(t[-1]), (unit, 0, 0), "t"),
                     Axis((x[0], front, lo * height), (x[0], front, hi * height), lo, hi, (-unit, 0, 0), "eta")):  # VTK's label font has no Greek
            add_axis(p, axis, membrane.TICK_FONT, zoom=zoom)
        centre = (0.5 * length, 0.5 * float(t[-1]) * depth, 0.0)  # seen from above the late times, so that the
        p.camera_position = [(-0.2 * length, -2.2 * length, 1.9 * length), centre, (0, 0, 1)]  # high t = 0 hides no contact
        p.reset_camera()
        return p.screenshot(None, return_img=True)
    finally:
        p.close()


def membrane_figure(result, look: Look = SCREEN):
    """The membrane at the output times, a panel each (time, contact area, patches), red where in contact or coloured
    by its surface field (bar under the panels, edge of contact yellow), above the obstacle: figure and axes."""
    rows = charts.snapshot_rows(result)
    nrows, ncols = charts.panel_grid(len(rows), look.width)
    view = membrane.membrane_view(result)
    bar = view.field is not None
    width, height = look.inches
    panel = (width / ncols, (height - KEY_ROOM * (1 + bar) - CAPTION_ROOM * look.caption) / nrows)
    fig = charts.figure(look.inches)
    panels, below = charts.with_key(fig, nrows, ncols, key=0.4 / height)
    axs = panels.subplots(squeeze=False)
    labels = membrane.membrane_labels(result, rows)
    pixels = look.pixels(panel)
    p = _plotter(pixels)
    try:
        zoom = _font_zoom(look, pixels[0], SCREEN_PANEL)
        for k, image in enumerate(membrane.rendered_rows(p, result, rows, view, zoom)):
            ax = axs.flat[k]
            ax.imshow(image)
            ax.set_axis_off()
            ax.set_title(labels[k] if ncols == 3 else labels[k].replace(": ", "\n", 1), fontsize="small")  # 2 lines
    finally:
        p.close()
    for ax in axs.flat[len(rows):]:
        ax.set_visible(False)
    if bar:
        view.field.colour_bar(fig, ax=axs, location="bottom", shrink=0.6, aspect=40, label=view.field.title)
    _key(below, membrane.colour_key(result, view.field))
    titled(fig, view.title("The membrane at the output times"), result, look, charts.panels_note(result, rows))
    return fig, axs


