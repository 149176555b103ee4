"""Pictures of meshes in space, drawn with pyvista off-screen (EGL when there is no display).

``space_time.png``: a 1-D run as the surface η(x, t) over the (x, t) plane, coloured by contact, above
the obstacle ψ. ``membrane.png``: a 2-D run, the membrane z = η(x, y, t) at the scene's output times, one
panel each, coloured by contact, above the obstacle z = ψ(x, y) (grey). A moving obstacle ψ(x, t) is drawn at
each panel's and frame's time, and as the surface ψ(x, t) in ``space_time.png``. The animation
``membrane.gif`` (:mod:`stringcontact.plot.animation`) draws the same scene (`add_membrane`) at every few rows.
A membrane whose model has a surface field (an output field whose description says ``surface``) is coloured by
that field instead (`fields.FieldScale`: one fixed scale over all stored rows, in the field's own colours, its bar
drawn by `add_field_bar`), the edge of its contact set drawn on it as a line (`contact_edge`).

The axes (`annotations.add_axis`: x, t or y, and the height η, on the floor below the obstacle, along the edges
nearest the viewer), the colour key and the titles are `annotations`' (drawn without VTK's scalar bar, whose
`std::regex` aborts a process that has loaded dolfinx); the membrane's drawing is `membrane`'s, VTK's start-up
`vtk_start`'s.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..io.manifest import atomic_path
from .annotations import Axis, _title, add_axis, add_colour_legend
from .charts import (
    PNG_COMPRESSION,
    obstacle_history,
    obstacle_moves,
    obstacle_name,
    obstacle_profile,
    panels_note,
    parameter_line,
    snapshot_rows,
)
from .colour_bar import add_field_bar
from .colours import CONTACT_COLOUR, FREE_COLOUR, MEMBRANE_OBSTACLE_COLOUR, OBSTACLE_COLOUR
from .membrane import (
    add_contact_edge,
    add_membrane,
    add_membrane_axes,
    membrane_label,
    membrane_legend,
    membrane_title,
    membrane_view,
)
from .picture_names import WINDOW_SIZE
from .vtk_start import _font_file, _plotter, _pyvista


def _screenshot(p, path: Path) -> None:
    from PIL import Image

    try:
        image = p.screenshot(None, return_img=True)  # the pixels pyvista would write; Pillow writes them at our level
    finally:
        p.close()
    with atomic_path(path) as tmp:  # a picture is either complete or absent
        Image.fromarray(image).save(tmp, format="PNG", compress_level=PNG_COMPRESSION)


def _height_text(value: float, span: float) -> str:
    """`value` to 3 digits; 0 where it lies within a millionth of `span` of 0 (a profile's 1.32e-112 is 0)."""
    return f"{0.0 if abs(value) <= 1e-6 * abs(span) else float(value):.3g}"


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
