"""Pictures of meshes in space, drawn with pyvista off-screen (EGL when there is no display).

``space_time.png``: a 1-D run as the surface η(x, t) over the (x, t) plane, coloured by contact, above
the obstacle ψ. A picture of a 2-D mesh (a membrane) would be another function here on the same
`_plotter`, `_title` and `_screenshot`.

VTK's scalar bar and pyvista's `show_bounds` format their labels with `std::regex`, which aborts the
process (`std::bad_alloc`) once dolfinx's C++ module is loaded: this module uses neither. The colours
are named in the title, the axes by labels at the corners of the (x, t) plane.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .charts import CONTACT_COLOUR, WINDOW_SIZE, obstacle_name, obstacle_profile, parameter_line
from .output import atomic_path

FREE_COLOUR = "#92c5de"
OBSTACLE_COLOUR = "#777777"


def _pyvista():
    if "DISPLAY" not in os.environ:  # EGL needs no display; on a desktop VTK's default window works too
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def _font_file() -> str | None:
    """A TrueType font with Greek letters (VTK's built-in fonts have none): matplotlib's DejaVu Sans."""
    from matplotlib import font_manager

    try:
        return font_manager.findfont("DejaVu Sans", fallback_to_default=False)
    except ValueError:  # no such font: VTK's own, without Greek letters
        return None


def _plotter(window_size):
    p = _pyvista().Plotter(window_size=list(window_size), off_screen=True)
    p.disable_anti_aliasing()  # pyvista's 8× MSAA: 0.71 s of llvmpipe's CPU for the surface instead of 0.39 s (bench_pictures.py)
    p.set_background("white")
    return p


def _title(p, text: str) -> None:
    p.add_text(text, position="upper_edge", font_size=9, color="black", font_file=_font_file())


def _screenshot(p, path: Path) -> None:
    with atomic_path(path) as tmp:  # a picture is either complete or absent
        p.screenshot(str(tmp))
    p.close()


def _every_kth(n: int, most: int) -> np.ndarray:
    """Every k-th of n indices and the last, at most about `most` of them."""
    return np.union1d(np.arange(0, n, max(1, int(np.ceil(n / most)))), [n - 1])


def space_time_picture(result, path, window_size=WINDOW_SIZE, max_columns: int = 300, max_rows: int = 200) -> Path:
    """η(x, t) as a surface over the (x, t) plane, red where in contact, above the obstacle ψ (grey)."""
    pv = _pyvista()
    path = Path(path)
    # the surface spans ~800 pixels across and ~400 deep: finer meshes cost llvmpipe time, not detail
    cols, rows = _every_kth(result.x.size, max_columns), _every_kth(result.t.size, max_rows)
    x, t, eta = result.x[cols], result.t[rows], result.eta[np.ix_(rows, cols)]
    psi = obstacle_profile(result)[cols]
    lo, hi = min(eta.min(), psi.min()), max(eta.max(), psi.max())
    length = float(x[-1] - x[0])
    depth = -0.8 * length / (float(t[-1] - t[0]) or 1.0)  # t runs out of the picture over 0.8 l: t = 0 at the back
    height = 0.4 * length / (hi - lo or 1.0)  # η is drawn 0.4 l high
    X, T = np.meshgrid(x, t * depth)
    surface = pv.StructuredGrid(X, T, eta * height)
    surface.point_data["contact"] = result.contact[np.ix_(rows, cols)].astype(float).ravel(order="F")  # points in Fortran order
    below = 0.02 * (hi - lo) * height  # under the penalty's penetration (about ε|v|), which it would otherwise hide
    obstacle = pv.StructuredGrid(*np.meshgrid(x, t[[0, -1]] * depth), np.tile(psi * height - below, (2, 1)))

    p = _plotter(window_size)
    p.add_mesh(surface, scalars="contact", cmap=[FREE_COLOUR, CONTACT_COLOUR], clim=(0, 1), n_colors=2,
               show_scalar_bar=False, ambient=0.3)
    p.add_mesh(obstacle, color=OBSTACLE_COLOUR, opacity=0.4)
    ends = np.array([[x[0], t[0] * depth, lo * height], [x[-1], t[0] * depth, lo * height], [x[-1], t[-1] * depth, lo * height]])
    p.add_point_labels(ends, [f"x = {x[0]:g}, t = {t[0]:g}", f"x = {x[-1]:g}", f"t = {t[-1]:.3g}"], font_size=14,
                       text_color="black", shape=None, show_points=False, always_visible=True)
    psi_name = obstacle_name(result)
    _title(p, f"Space-time surface η(x, t): {result.scene.name}\n{parameter_line(result)}\n"
              f"height η from {lo:.3g} to {hi:.3g}; red: in contact (η ≤ {psi_name}), blue: free, grey: the obstacle")
    centre = (0.5 * length, 0.5 * float(t[-1]) * depth, 0.0)  # seen from above the late times, so that the
    p.camera_position = [(-0.2 * length, -2.2 * length, 1.9 * length), centre, (0, 0, 1)]  # high t = 0 hides no contact
    p.reset_camera()
    _screenshot(p, path)
    return path


def warm_up() -> None:
    """A tiny picture with every kind of element the real one uses, so that llvmpipe compiles its shaders."""
    p = _plotter((64, 48))
    grid = _pyvista().StructuredGrid(*np.meshgrid([0.0, 1.0], [0.0, 1.0]), np.zeros((2, 2)))
    grid.point_data["contact"] = np.array([0.0, 1.0, 0.0, 1.0])
    p.add_mesh(grid, scalars="contact", cmap=[FREE_COLOUR, CONTACT_COLOUR], n_colors=2, show_scalar_bar=False)
    p.add_mesh(grid, color=OBSTACLE_COLOUR, opacity=0.4)
    p.add_point_labels([[0.0, 0.0, 0.0]], ["t"], shape=None, show_points=False, always_visible=True)
    _title(p, "η")
    p.screenshot(None, return_img=True)
    p.close()
