"""A field's colour bar in a pyvista panel: coloured rectangles and text actors (`add_field_bar`), on the field's own
scale (`fields.FieldScale`)."""

from __future__ import annotations

import numpy as np

from .fields import FieldScale
from .vtk_start import _font_file

__all__ = ["add_field_bar"]


def _actor_2d(points, polys=(), lines=(), colours=None, colour=(0.0, 0.0, 0.0), width: float = 1.0):
    """A 2-D actor of quadrilaterals and lines at `points` in the panel's coordinates (0 … 1 each way), the
    quadrilaterals coloured by the RGB rows of `colours` (0 … 255), else everything in `colour`."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkRenderingCore import vtkActor2D, vtkCoordinate, vtkPolyDataMapper2D

    vtk_points = vtkPoints()
    for x, y in points:
        vtk_points.InsertNextPoint(float(x), float(y), 0.0)
    data = vtkPolyData()
    data.SetPoints(vtk_points)
    for cells, setter in ((polys, data.SetPolys), (lines, data.SetLines)):
        array = vtkCellArray()
        for cell in cells:
            array.InsertNextCell(len(cell), [int(i) for i in cell])
        setter(array)
    mapper = vtkPolyDataMapper2D()
    if colours is not None:
        rgb = numpy_to_vtk(np.ascontiguousarray(colours, dtype=np.uint8), deep=True)
        data.GetCellData().SetScalars(rgb)
        mapper.SetScalarModeToUseCellData()
        mapper.SetColorModeToDirectScalars()
    else:
        mapper.ScalarVisibilityOff()
    mapper.SetInputData(data)
    coordinate = vtkCoordinate()
    coordinate.SetCoordinateSystemToNormalizedViewport()
    mapper.SetTransformCoordinate(coordinate)
    actor = vtkActor2D()
    actor.SetMapper(mapper)
    actor.GetProperty().SetColor(*colour)
    actor.GetProperty().SetLineWidth(width)
    return actor


def add_field_bar(p, scale: FieldScale, box: tuple, vertical: bool = False, font_size: int = 8) -> list[str]:
    """A field's colour bar in the current panel of `p` within `box` = (x0, y0, x1, y1) (the panel's 0 … 1):
    its scale's `low` at its left (bottom) end, `high` at its right (top); its ticks' labels below it (left of
    it), its name beside it (its title; above a vertical bar its label). Coloured rectangles and text actors, not VTK's scalar bar, whose labels are formatted
    with std::regex (the module's docstring). Returns the labels drawn."""
    x0, y0, x1, y1 = box
    steps = np.linspace(-1.0, 1.0, 257)
    colours = (255 * np.asarray(scale.colour_map()(0.25 * (steps[:-1] + steps[1:]) + 0.5))[:, :3]).round()

    def at(u, across):  # a point of the bar: u along it (−1 … 1), `across` 0 … 1 over its thickness
        along = 0.5 * (np.asarray(u) + 1.0)
        return (x0 + across * (x1 - x0), y0 + along * (y1 - y0)) if vertical else (x0 + along * (x1 - x0), y0 + across * (y1 - y0))

    points = [at(u, a) for u in steps for a in (0.0, 1.0)]
    quads = [(2 * k, 2 * k + 2, 2 * k + 3, 2 * k + 1) for k in range(len(steps) - 1)]
    p.add_actor(_actor_2d(points, polys=quads, colours=colours), reset_camera=False, pickable=False)
    ticks = scale.ticks()
    where = scale.unit(ticks)
    frame = [at(-1, 0), at(1, 0), at(1, 1), at(-1, 1)]
    marks = [point for u in where for point in (at(u, 0.0), at(u, -0.35))]
    lines = [(0, 1, 2, 3, 0)] + [(4 + 2 * k, 5 + 2 * k) for k in range(len(where))]
    p.add_actor(_actor_2d(frame + marks, lines=lines, width=1.5), reset_camera=False, pickable=False)
    labels = [scale.tick_label(v) for v in ticks]
    for u, label in zip(where, labels):
        text = p.add_text(label, position=at(u, -0.45), viewport=True, font_size=font_size, color="black",
                          font_file=_font_file())
        if vertical:
            text.prop.SetJustificationToRight()
            text.prop.SetVerticalJustificationToCentered()
        else:
            text.prop.SetJustificationToCentered()
            text.prop.SetVerticalJustificationToTop()
    name = p.add_text(scale.title if not vertical else scale.label, viewport=True, font_size=font_size + 1,
                      color="black", font_file=_font_file(),
                      position=(x1 + 0.02, 0.5 * (y0 + y1)) if not vertical else (x1, y1 + 0.02))
    if vertical:
        name.prop.SetJustificationToRight()
    else:
        name.prop.SetVerticalJustificationToCentered()
    return labels
