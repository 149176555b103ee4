"""pyvista in this process: off-screen (EGL where there is no display, `_pyvista`), a plotter on a white background
(`_plotter`), the font its text is drawn in (`_font_file`); and the axes of its pictures (`add_axis`): lines, ticks and
point labels, because pyvista's `show_bounds` and VTK's scalar bar format their labels with `std::regex`, which aborts
a process that has loaded dolfinx (std::bad_alloc at the first render after `import dolfinx`, VTK 9.7.2), as a run
has when it draws its pictures."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np


def _pyvista():
    if "DISPLAY" not in os.environ:  # VTK 9.7 would try X first and print "bad X server connection" before EGL
        window = os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        if window == "vtkXOpenGLRenderWindow":  # without a display VTK fails to make it, then crashes (SIGSEGV)
            raise ValueError(f"VTK_DEFAULT_OPENGL_WINDOW={window} needs an X display and DISPLAY is not set; the "
                             "3-D pictures are left out (unset it, or set it to vtkEGLRenderWindow)")
    from .charts import without_axes3d_warning

    with without_axes3d_warning():  # pyvista's colour maps import matplotlib's projections
        import matplotlib.projections  # noqa: F401
        import pyvista

    return pyvista


def _plotter(window_size):
    """An off-screen plotter `window_size` pixels large, on white, that takes empty meshes (an empty contact edge)."""
    p = _pyvista().Plotter(window_size=list(window_size), off_screen=True)
    p.theme.allow_empty_mesh = True
    p.disable_anti_aliasing()  # pyvista's 8× MSAA: the surface in 0.71, not 0.39 CPU-s of llvmpipe (bench_pictures.py)
    p.set_background("white")
    return p


def _font_file() -> str | None:
    """A TrueType font with Greek letters (VTK's built-in fonts have none): matplotlib's DejaVu Sans."""
    from matplotlib import font_manager

    try:
        return font_manager.findfont("DejaVu Sans", fallback_to_default=False)
    except ValueError:  # no such font: VTK's own, without Greek letters
        return None


def nice_ticks(low: float, high: float, most: int = 5) -> np.ndarray:
    """Round tick values within [low, high] (matplotlib's MaxNLocator), at least the two ends if none fit."""
    from matplotlib.ticker import MaxNLocator

    if not high > low:
        return np.array([low])
    ticks = MaxNLocator(nbins=most, steps=[1, 2, 2.5, 5, 10]).tick_values(low, high)
    span = high - low
    ticks = np.array([float(f"{v:.12g}") for v in ticks if low - 1e-9 * span <= v <= high + 1e-9 * span])
    return ticks if ticks.size >= 2 else np.array([low, high])


@dataclass
class Axis:
    """One axis from `start` to `end` (3-D), values `low` … `high`, ticks along `outward` (labels at twice it)."""

    start: tuple
    end: tuple
    low: float
    high: float
    outward: tuple
    title: str


def add_axis(p, axis: Axis, font_size: int = 11, most: int = 5, zoom: float = 1.0) -> list[str]:
    """An axis with ticks and labels in `p`, `font_size` points on a screen, `zoom` times that: the labels drawn."""
    pv = _pyvista()
    start, end, out = (np.asarray(v, dtype=float) for v in (axis.start, axis.end, axis.outward))
    p.add_mesh(pv.Line(start, end), color="black", line_width=2 * zoom, lighting=False)
    ticks = nice_ticks(axis.low, axis.high, most)
    where = start + np.outer((ticks - axis.low) / ((axis.high - axis.low) or 1.0), end - start)
    for point in where:
        p.add_mesh(pv.Line(point, point + out), color="black", line_width=2 * zoom, lighting=False)
    labels = [f"{0.0 if abs(v) < 1e-12 else v:g}" for v in ticks]
    p.add_point_labels(where + 2.2 * out, labels, font_size=round(zoom * font_size), text_color="black", shape=None,
                       show_points=False, always_visible=True, font_family="arial", justification_horizontal="center")
    beyond = 4.5 + 0.3 * max(font_size - 11, 0)  # the axis' name clear of its tick labels, however large
    p.add_point_labels([0.5 * (start + end) + beyond * out], [axis.title], font_size=round(zoom * (font_size + 2)), text_color="black",
                       shape=None, show_points=False, always_visible=True, bold=True)
    return labels
