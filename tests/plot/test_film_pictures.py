"""A membrane on a fluid film (model "film"): membrane.png and membrane.gif coloured by the film's pressure
p − p_a (its surface output field) on one fixed symmetric-log scale with its colour bar, the contact set's edge
drawn in yellow; a membrane without a surface field drawn as before (coloured by contact). The pictures' code
names no model: the pressure's colours and scale come from its `OutputField` (`Result.field_info`)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.io.paraview_view import field_points, symlog_unit
from stringcontact.model.film import PRESSURE
from stringcontact.plot import animation, charts, membrane, mesh_pictures, vtk_start
from stringcontact.plot import run_pictures as viz
from stringcontact.plot.fields import FieldScale
from stringcontact.scene import scene_to_toml

#: the pressure's colours at −P, 0 and P, as the pictures and ParaView's view have drawn them: blue, a middle
#: grey (seen on white and on the grey obstacle), red
PRESSURE_COLOURS = ((0.085, 0.40, 0.85), (0.55, 0.55, 0.55), (0.85, 0.10, 0.08))
#: how the film's pressure is shown (summary.json's "fields")
INFO = PRESSURE.metadata()

#: a coarse film drum (81 nodes): pressure p = p_a at t = 0, building up (red) at 0.1, first contact at 0.11,
#: in contact at 0.15 (under high pressure) and at 0.3 (under suction, p < p_a)
SMALL_FILM_DRUM = {"cells": [8, 8], "T": 0.3, "nt": 120, "output_times": [0.0, 0.1, 0.15, 0.3]}


def small_film_drum():
    return sc.load_scene("film_drum").replace(**SMALL_FILM_DRUM)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The coarse film drum written with its pictures (drawn in this process), and its in-memory result."""
    folder = tmp_path_factory.mktemp("film_membrane") / "film_drum"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sc.simulate(small_film_drum(), output=sc.Output(folder, progress=False))
    return folder, res


def _image(path):
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).astype(int)


def _rgb(colour) -> np.ndarray:
    return np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)]) if isinstance(colour, str) else np.round(255 * np.array(colour))


def _near(img, colour, tol: int) -> np.ndarray:
    return np.all(np.abs(img - _rgb(colour)) <= tol, axis=-1)


def _reddish(img):
    return (img[..., 0] - np.maximum(img[..., 1], img[..., 2])) > 50


def _bluish(img):
    return (img[..., 2] - np.maximum(img[..., 0], img[..., 1])) > 50


def _yellow(img):
    """The contact edge's yellow (#ffd400, unlit), not the legend's darker text (#b08f00)."""
    return (img[..., 0] > 200) & (img[..., 1] > 150) & (img[..., 2] < 90)


def _layout(result):
    """The pixel boxes (rows, columns: slices) of membrane.png's panels and of its colour bar with its labels, as the
    picture lays them out (the screen style)."""
    from stringcontact.plot.style import SCREEN

    with SCREEN.drawn():
        fig, axs = mesh_pictures.membrane_figure(result)
        fig.canvas.draw()
    height = fig.bbox.height

    def box(b):
        return slice(round(height - b.y1), round(height - b.y0)), slice(round(b.x0), round(b.x1))

    panels = [box(ax.get_window_extent()) for ax in axs.flat if ax.get_visible()]
    (bar,) = [box(ax.get_tightbbox(fig.canvas.get_renderer())) for ax in fig.axes if hasattr(ax, "_colorbar")]
    return panels, bar


# --- the scale ---------------------------------------------------------------------------------------


def test_the_pressure_is_described_by_the_colours_and_scale_it_was_drawn_in():
    assert INFO["colours"] == [list(c) for c in PRESSURE_COLOURS]
    assert (INFO["scale"], INFO["linear_share"], INFO["symmetric"], INFO["surface"]) == ("symlog", 1e-3, True, True)


def test_the_pressure_scale_is_symmetric_centred_at_zero_and_fixed_by_the_peak():
    scale = FieldScale.of(np.array([[0.0, 2.0], [-381.0, 50.0]]), INFO)
    assert (scale.low, scale.high) == (-381.0, 381.0)
    np.testing.assert_allclose(scale.unit([-381.0, 0.0, 381.0, 1e4]), [-1.0, 0.0, 1.0, 1.0])
    values = np.linspace(-381, 381, 201)
    units = scale.unit(values)
    assert np.all(np.diff(units) > 0) and np.allclose(units, -scale.unit(-values))  # increasing and odd
    assert scale.unit(0.381) == pytest.approx(0.27, abs=0.01)  # symmetric-log: 1e-3 of the peak is still coloured
    ticks = scale.ticks()
    np.testing.assert_array_equal(ticks, [-381, -10, -1, 0, 1, 10, 381])  # 100 lies too close to 381 for its label
    assert [scale.tick_label(v) for v in ticks] == ["−381", "−10", "−1", "0", "1", "10", "381"]
    assert FieldScale.of(np.zeros((3, 4)), INFO).high == 1.0  # a film never squeezed: a scale all the same
    colours = np.asarray(scale.colour_map()([0.0, 0.5, 1.0]))[:, :3]
    np.testing.assert_allclose(colours, PRESSURE_COLOURS, atol=4e-3)  # to one of the 256 steps  # ParaView's view has the same colours


@pytest.mark.parametrize("peak", [1.0, 381.0, 2.5e4])
def test_the_symmetric_log_scale_is_pressure_pngs_and_paraviews(peak):
    """The pictures' and ParaView's scale is matplotlib's SymLogNorm, which pressure.png draws with; ParaView's
    control points give the pictures' colours at their values."""
    from matplotlib.colors import SymLogNorm

    values = np.concatenate([np.linspace(-peak, peak, 101), peak * np.logspace(-5, 0, 41)])
    norm = SymLogNorm(linthresh=1e-3 * peak, vmin=-peak, vmax=peak, base=10)
    np.testing.assert_allclose(symlog_unit(values, peak, 1e-3), 2 * np.asarray(norm(values)) - 1, atol=1e-12)
    points = np.array(field_points(-peak, peak, INFO))
    assert points[0, 0] == -peak and points[-1, 0] == peak and 0.0 in points[:, 0]
    assert np.all(np.diff(points[:, 0]) > 0) and len(points) == 2 * 13 + 1  # 0, and 4 a decade over 3 decades each way
    scale = FieldScale.of([peak], INFO)
    pictures = np.asarray(scale.colour_map()(0.5 * (scale.unit(points[:, 0]) + 1)))[:, :3]
    np.testing.assert_allclose(points[:, 1:], pictures, atol=4e-3)  # to one of the colour map's 256 steps


# --- the scene in a plotter --------------------------------------------------------------------------


def _surface_actor(p, surface):
    (actor,) = [a for a in p.actors.values() if getattr(a.mapper, "dataset", None) is not None
                and a.mapper.dataset.n_points == surface.n_points and a.mapper.array_name]
    return actor


@pytest.mark.slow
def test_the_film_membranes_mesh_carries_its_pressure_and_is_coloured_by_it(run):
    _, res = run
    pressure = res.fields["pressure"]
    view = membrane.membrane_view(res)
    assert view.field == FieldScale.of(pressure, INFO) and view.field.high == float(np.abs(pressure).max())
    row, later = 40, 60  # t = 0.1 (free), 0.15 (in contact)
    kept = pressure.copy()
    p = vtk_start._plotter((300, 200))
    try:
        surface = membrane.add_membrane(p, res, row, view)
        np.testing.assert_array_equal(surface.point_data["pressure"], pressure[row])
        np.testing.assert_array_equal(surface.point_data["pressure_colour"], view.field.unit(pressure[row]))
        actor = _surface_actor(p, surface)
        assert actor.mapper.array_name == "pressure_colour" and tuple(actor.mapper.scalar_range) == (-1.0, 1.0)
        edge = membrane.add_contact_edge(p, surface, view)
        assert edge.n_points == 0  # not in contact yet: no edge
        membrane.show_row(surface, res, later, view)  # a GIF's next frame: the arrays follow the row
        membrane.contact_edge(surface, view, into=edge)
        np.testing.assert_array_equal(surface.point_data["pressure"], pressure[later])
        np.testing.assert_array_equal(pressure, kept)  # the mesh's arrays are copies: the Result's rows stay
        np.testing.assert_array_equal(surface.points[:, 2], res.eta[later] * view.scale)
        assert res.contact[later].any() and edge.n_points > 4
        inside = res.x[res.contact[later]]  # the edge surrounds the nodes in contact
        lo, hi = edge.points[:, :2].min(axis=0), edge.points[:, :2].max(axis=0)
        assert np.all(inside >= lo) and np.all(inside <= hi)
        assert edge.points[:, 2].min() > 0  # lifted above the surface lying on the obstacle
    finally:
        p.close()


def test_a_membrane_without_a_surface_field_is_coloured_by_contact_as_before(run):
    _, res = run
    bare = dataclasses.replace(res, field_info={"pressure": INFO | {"surface": False}})  # its pressure kept, not on the membrane
    view = membrane.membrane_view(bare)
    assert view.field is None
    p = vtk_start._plotter((300, 200))
    try:
        surface = membrane.add_membrane(p, bare, 60, view)
        assert set(surface.point_data.keys()) == {"contact"}
        assert _surface_actor(p, surface).mapper.array_name == "contact"
    finally:
        p.close()
    assert "red: in contact" in membrane.membrane_colours(bare, view)
    assert [label for label, _ in membrane.colour_key(bare, view.field)] == ["in contact, η ≤ 0", "free, η > 0", "obstacle 0"]


# --- the pictures ------------------------------------------------------------------------------------


def test_membrane_png_colours_the_film_by_its_pressure_with_its_bar_and_contact_edge(run, tmp_path):
    folder, res = run
    rows = charts.snapshot_rows(res)
    img = _image(folder / "membrane.png")
    assert img.shape == (viz.WINDOW_SIZE[1], viz.WINDOW_SIZE[0], 3)
    boxes, bar_box = _layout(res)
    bar = img[bar_box]
    for end in (PRESSURE_COLOURS[0], PRESSURE_COLOURS[-1]):  # the bar's ends, unlit: the map's own colours
        assert _near(bar, end, 6).sum() > 20, end
    assert (bar.max(axis=-1) < 80).sum() > 100  # its labels and frame in black
    panels = [img[box] for box in boxes]
    peak = np.abs(res.fields["pressure"][rows]).max(axis=1)
    red, blue, yellow = ([int(f(p).sum()) for p in panels] for f in (_reddish, _bluish, _yellow))
    assert peak[0] == 0 and red[0] == blue[0] == yellow[0] == 0  # t = 0: p = p_a everywhere, a grey membrane
    assert red[1] > 3000 and yellow[1] == 0  # t = 0.1: the squeezed film pushes up, nothing in contact yet
    assert res.contact[rows[2]].any() and res.contact[rows[3]].any()
    assert red[2] > 3000 and yellow[2] > 100  # t = 0.15: landed under high pressure, the patch's edge drawn
    assert blue[3] > 1000 > red[3] and yellow[3] > 100  # t = 0.3: in contact, mostly under suction
    # the same rows without the pressure: the contact colours, no bar and no yellow edge
    plain = _image(viz.draw("membrane.png", dataclasses.replace(res, fields={}, field_info={}), tmp_path))
    assert _yellow(plain).sum() == 0 and _near(plain, PRESSURE_COLOURS[-1], 6).sum() == 0
    assert _near(plain, charts.CONTACT_COLOUR, 60).sum() > 500


def test_membrane_gif_colours_each_frame_by_its_pressure_with_the_edge_of_its_contact(run):
    import imageio.v3 as iio

    folder, res = run
    frames = iio.imread(folder / "membrane.gif", index=None)[..., :3].astype(int)
    rows = animation.frame_rows(res)
    assert len(frames) == len(rows)
    width = frames.shape[2]
    x0, _, x1, _ = animation.FIELD_BAR
    bar = frames[:, :, int(x0 * width) - 2 : int(x1 * width) + 3]
    for end in (PRESSURE_COLOURS[0], PRESSURE_COLOURS[-1]):  # the bar in every frame (the palette kept its ends)
        assert all(_near(frame, end, 25).sum() > 10 for frame in bar), end
    scene = frames[:, :, : int(0.9 * width)]  # the membrane, left of the bar
    red = np.array([_reddish(f).sum() for f in scene])
    yellow = np.array([_yellow(f).sum() for f in scene])
    touching = res.contact[rows].any(axis=1)
    assert touching.any() and not touching.all()
    assert np.all((yellow > 0) == touching), (yellow, touching)  # the edge exactly while in contact
    assert red[0] == 0 and red.max() > 2000  # p = p_a at t = 0, then the film's pressure shows


@pytest.mark.slow
def test_stringcontact_run_draws_the_film_membranes_pictures(run, tmp_path):
    """The CLI draws the same membrane.png (coloured by the pressure) as `simulate` did."""
    folder, _ = run
    path = tmp_path / "small_film_drum.toml"
    path.write_text(scene_to_toml(small_film_drum()))
    out = tmp_path / "out"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["run", str(path), "--out", str(out), "--no-progress"]) == 0
    np.testing.assert_array_equal(_image(out / "membrane.png"), _image(folder / "membrane.png"))
