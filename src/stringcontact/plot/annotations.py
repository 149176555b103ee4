"""The pyvista pictures' axes (`add_axis`): lines, ticks and point labels, because pyvista's `show_bounds` and VTK's
scalar bar format their labels with `std::regex`, which aborts a process that has loaded dolfinx (std::bad_alloc at
the first render after `import dolfinx`, VTK 9.7.2), as a run has when it draws its pictures."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vtk_start import _pyvista


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
