"""A membrane (a 2-D run) in a pyvista plotter, what ``membrane.png`` and ``membrane.gif`` share: its view, the
membrane and obstacle at a row moved to other rows in place, its axes, words, colour key and edge of contact."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..io.tables import field_info
from . import style
from .charts import obstacle_name, obstacle_range
from .fields import FieldScale
from .vtk_start import Axis, _pyvista, add_axis


@dataclass
class MembraneView:
    """How a membrane is drawn: heights times `scale` in the box `bounds` seen from `camera`, contact by `shade`."""

    scale: float
    bounds: tuple  # (x0, x1, y0, y1, z0, z1), drawn coordinates
    camera: list
    neighbours: object = None  # the mean over each node's mesh neighbours, a sparse matrix (`neighbour_mean`)
    field: FieldScale | None = None  # the model's surface field: the membrane coloured by it on this scale
    obstacle: object = None  # a moving obstacle's PolyData last drawn by `add_membrane`: `show_row` moves it

    def shade(self, contact: np.ndarray) -> np.ndarray:
        """0.6 × the contact indicator + 0.4 × its neighbours' mean: a 0.5 iso-line without staircase, red iff in contact."""
        c = np.asarray(contact, dtype=float)
        return c if self.neighbours is None else 0.6 * c + 0.4 * (self.neighbours @ c)

    def title(self, what: str) -> str:
        """The title: `what`, and how much the heights are stretched when they are."""
        return f"{what} (heights ×{self.scale:.2g})" if self.scale > 1 else what


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
    """Heights stretched (≥ ×1) to 0.3 of the domain's width; a camera above the front edge, looking down at ~50°."""
    x = result.x
    psi_lo, psi_hi = obstacle_range(result)  # over all stored times: a moving obstacle stays in the box
    lo, hi = min(float(result.eta.min()), psi_lo), max(float(result.eta.max()), psi_hi)
    width = float(max(np.ptp(x[:, 0]), np.ptp(x[:, 1])))
    scale = max(1.0, 0.3 * width / (hi - lo or 1.0))
    bounds = (*(float(f(x[:, k])) for k in (0, 1) for f in (np.min, np.max)), lo * scale - _below(lo, hi, scale),
              hi * scale)
    centre = np.asarray(bounds).reshape(3, 2).mean(axis=1)
    eye = centre + width * np.array([-0.4, -1.1, 1.5])
    info = next((info for info in field_info(result).values() if info.get("surface")), None)  # colours it, not contact
    return MembraneView(scale, bounds, [tuple(eye), tuple(centre), (0.0, 0.0, 1.0)], neighbour_mean(result.cells, len(x)),
                        None if info is None else FieldScale.of(result.fields[info["name"]], info))


def _below(lo: float, hi: float, scale: float) -> float:
    """How far under ψ the obstacle is drawn: a contact region lies on ψ, which would otherwise hide it."""
    return 0.01 * (hi - lo or 1.0) * scale


def triangles(result, z):
    """The membrane's triangles as a pyvista PolyData with points (x, y, z)."""
    pv = _pyvista()
    faces = np.hstack([np.full((len(result.cells), 1), 3), result.cells]).astype(np.int64).ravel()
    return pv.PolyData(np.column_stack([result.x, z]).astype(float), faces)


def add_membrane(p, result, row: int, view: MembraneView):
    """The membrane at `row` in `p`, coloured by contact or `view.field`, and the obstacle (grey; a moving one kept in
    `view.obstacle`): the membrane's PolyData, which `show_row` changes in place."""
    moves = result.scene.obstacle_moves
    surface = triangles(result, result.eta[row] * view.scale)
    surface.point_data["contact"] = view.shade(result.contact[row])
    drawn = {"show_scalar_bar": False, "ambient": 0.3, "smooth_shading": True}  # Gouraud: flat showed every facet
    if view.field is None:
        p.add_mesh(surface, scalars="contact", cmap=[style.FREE_COLOUR, style.CONTACT_COLOUR], clim=(0, 1),
                   n_colors=2, **drawn)
    else:
        _set_field(surface, result, row, view.field)
        p.add_mesh(surface, scalars=f"{view.field.name}_colour", cmap=view.field.colour_map(), clim=(-1, 1), **drawn)
    # opaque and unlit, in the colour the translucent grey of space_time.png takes on white: the membrane is never
    # below it (η ≥ ψ), so nothing would show through, and translucency costs 40 % more CPU per GIF frame
    obstacle = triangles(result, _obstacle_heights(result, float(result.t[row]) if moves else 0.0, view))
    p.add_mesh(obstacle, color=style.MEMBRANE_OBSTACLE_COLOUR, lighting=False)
    view.obstacle = obstacle if moves else None
    p.camera_position = view.camera
    p.reset_camera(bounds=view.bounds)
    p.camera.zoom(1.1)  # reset_camera fits the box's bounding sphere: room to spare
    return surface


def _obstacle_heights(result, t: float, view: MembraneView) -> np.ndarray:
    lo, hi = view.bounds[4] / view.scale, view.bounds[5] / view.scale
    return result.scene.obstacle_values(result.x, t) * view.scale - _below(lo, hi, view.scale)


def show_row(surface, result, row: int, view: MembraneView) -> None:
    """The membrane `surface` of `add_membrane` (and a moving obstacle) moved to `row` in place."""
    surface.points[:, 2] = result.eta[row] * view.scale
    surface.point_data["contact"][:] = view.shade(result.contact[row])
    if view.field is not None:
        _set_field(surface, result, row, view.field)
    surface.Modified()
    if view.obstacle is not None:  # a moving obstacle: where it is at this row's time
        view.obstacle.points[:, 2] = _obstacle_heights(result, float(result.t[row]), view)
        view.obstacle.Modified()


def _set_field(surface, result, row: int, scale: FieldScale) -> None:
    """NAME: the field `scale.name` at the nodes; NAME_colour: where it lies on `scale` (−1 … 1), the array drawn."""
    values = np.array(result.fields[scale.name][row], dtype=float)  # a copy: pyvista shares the array it is given
    for name, array in ((scale.name, values), (f"{scale.name}_colour", scale.unit(values))):
        if name in surface.point_data:
            surface.point_data[name][:] = array
        else:
            surface.point_data[name] = array


def rendered_rows(p, result, rows, view: MembraneView, zoom: float = 1.0, before_render=None):
    """RGB renders of the membrane at each of `rows` in `p`, the scene made once and changed in place (`show_row`),
    fonts `zoom` times a screen's; `before_render(k, row)` called before the k-th."""
    surface = add_membrane(p, result, rows[0], view)
    edge = None if view.field is None else add_contact_edge(p, surface, view)
    add_membrane_axes(p, view, zoom=zoom)
    p.screenshot(None, return_img=True)  # pyvista's first render sets the window up; later ones only draw
    for k, row in enumerate(rows):
        show_row(surface, result, row, view)
        if edge is not None:
            contact_edge(surface, view, into=edge)
        if before_render is not None:
            before_render(k, row)
        p.render()
        yield np.array(p.image)


#: the membrane axes' font size (VTK points): digits 12 px high (7 gave 6 px, too small to read)
TICK_FONT = 16


def add_membrane_axes(p, view: MembraneView, font_size: int = TICK_FONT, zoom: float = 1.0) -> None:
    """x and y along the floor's front and right edges, η (in its own units) up the front left corner."""
    x0, x1, y0, y1, z0, z1 = view.bounds
    unit = 0.05 * max(x1 - x0, y1 - y0)
    add_axis(p, Axis((x0, y0, z0), (x1, y0, z0), x0, x1, (0, -unit, 0), "x"), font_size, 4, zoom)
    add_axis(p, Axis((x1, y0, z0), (x1, y1, z0), y0, y1, (unit, 0, 0), "y"), font_size, 4, zoom)
    add_axis(p, Axis((x0, y0, z0), (x0, y0, z1), z0 / view.scale, z1 / view.scale, (-unit, 0, 0), "eta"), font_size, 3,
             zoom)
    margin = 5 * unit  # the ticks' labels and the axes' names
    p.reset_camera(bounds=(x0 - margin, x1 + margin, y0 - margin, y1, z0, z1))
    p.camera.zoom(1.15)


def membrane_labels(result, rows) -> list[str]:
    """'t = 0.2: contact 2.17 (69%), 1 patch' at each of `rows`: the contact area, its share of the domain's, and the
    patches (counted in these rows only)."""
    area, domain = result.contact_measure, float(np.sum(result.weights))
    patches = dataclasses.replace(result, contact=result.contact[rows]).contact_patches()
    return [f"t = {result.t[row]:.3g}: contact {area[row]:.3g} ({100 * area[row] / domain:.0f}%), {n} "
            f"patch{'es' * (n != 1)}" for row, n in zip(rows, np.asarray(patches).tolist())]


def membrane_colours(result, view: MembraneView, sep: str = ", ") -> str:
    """What the colours mean, in words (the GIF's key): contact, or the surface field and the edge of contact."""
    psi = obstacle_name(result)
    words = (f"red: in contact (η ≤ {psi}), blue: free" if view.field is None else
             f"colour: {view.field.label} (its bar){sep}yellow line: the edge of contact (η ≤ {psi})")
    return f"{words}, grey: the obstacle {psi}"


def colour_key(result, field=None) -> list:
    """The colour key's (label, colour) entries: contact and free, or a surface `field`'s edge of contact; the obstacle."""
    psi = obstacle_name(result)
    obstacle = (f"obstacle {psi}", style.OBSTACLE_COLOUR)
    if field is None:
        return [(f"in contact, η ≤ {psi}", style.CONTACT_COLOUR), (f"free, η > {psi}", style.FREE_COLOUR), obstacle]
    return [("edge of contact", style.CONTACT_EDGE_COLOUR), obstacle]


def contact_edge(surface, view: MembraneView, into=None):
    """The 0.5 iso-line of `surface`'s contact shade, lifted 0.5 % of the height to stay visible (copied `into` if
    given; empty without contact)."""
    line = surface.contour([0.5], scalars="contact")
    if line.n_points:
        line.points[:, 2] += 0.005 * (view.bounds[5] - view.bounds[4])
    if into is None:
        return line
    into.copy_from(line)
    return into


def add_contact_edge(p, surface, view: MembraneView):
    """The contact set's edge (`contact_edge`) on `surface` as a yellow line: its PolyData, updated in place later."""
    edge = contact_edge(surface, view)
    p.add_mesh(edge, color=style.CONTACT_EDGE_COLOUR, line_width=3.0, lighting=False, reset_camera=False,
               pickable=False)
    return edge
