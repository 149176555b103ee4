"""The text and axes of the pyvista pictures, none of it drawn with VTK's scalar bar or pyvista's `show_bounds`.

Those two format their labels with `std::regex`, which aborts the process (`std::bad_alloc`) once dolfinx's C++
module is loaded (a run's pictures drawn in its own process, `simulate(..., pictures=True)`). Here the axes are
lines with ticks and point labels (`add_axis`), the colours are named by a legend (`add_colour_legend`: the
quantity and what each colour means), and a title is drawn as pyvista's upper-edge annotation would draw it
(`_title`), none of which needs a regex.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vtk_start import _font_file, _pyvista

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



def nice_ticks(low: float, high: float, most: int = 5) -> np.ndarray:
    """Round tick values within [low, high] (matplotlib's MaxNLocator), at least the two ends if none fit."""
    from matplotlib.ticker import MaxNLocator

    if not high > low:
        return np.array([low])
    ticks = MaxNLocator(nbins=most, steps=[1, 2, 2.5, 5, 10]).tick_values(low, high)
    span = high - low
    ticks = np.array([float(f"{v:.12g}") for v in ticks if low - 1e-9 * span <= v <= high + 1e-9 * span])
    return ticks if ticks.size >= 2 else np.array([low, high])



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

