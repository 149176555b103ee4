"""The pictures of a 2D run (issue 15): membrane.png, contact_area.png, energy.png and membrane.gif, drawn
by a run (`simulate` and the command line), and by `stringcontact plot` from a membrane's output folder."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import plot_refusal, xdmf_frames

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.io import readback
from stringcontact.plot import animation, charts, mesh_pictures
from stringcontact.plot import run_pictures as viz
from stringcontact.plot.style import Look
from stringcontact.scene import scene_to_toml

#: a coarse drum (about 100 nodes) that lands at t = 0.12 and is in contact until T; its rim starts at 0.3
SMALL_DRUM = {"mesh_size": 0.2, "T": 0.4, "nt": 80, "output_times": [0.0, 0.1, 0.2, 0.4]}


def small_drum():
    return sc.load_scene("drum").replace(**SMALL_DRUM)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The coarse drum written to disk with its pictures (drawn in this process), and its in-memory result."""
    folder = tmp_path_factory.mktemp("membrane") / "drum"
    res = sc.simulate(small_drum(), output=sc.Output(folder, progress=False))
    return folder, res


def _image(path):
    from PIL import Image

    with Image.open(path) as im:
        assert im.format == "PNG"
        return np.asarray(im.convert("RGB")).astype(int)


def _gif_frames(path):
    import imageio.v3 as iio

    return iio.imread(path, index=None)[..., :3].astype(int)


def _red(img, tol=60):
    """Pixels of the contact colour, lit (the surfaces are shaded, so less exact than in the charts)."""
    rgb = np.array([int(charts.CONTACT_COLOUR[i : i + 2], 16) for i in (1, 3, 5)])
    return np.all(np.abs(img - rgb) <= tol, axis=-1)


@pytest.mark.slow
def test_a_membrane_run_writes_its_four_pictures(run):
    folder, res = run
    assert res.contact[0].sum() == 0 and res.contact[-1].sum() > 0  # the comparisons below see both states
    drawn = sorted(p.name for p in folder.iterdir() if p.suffix in (".png", ".gif"))
    assert drawn == sorted(viz.MEMBRANE_PICTURES)  # and none of the (x, t) pictures of a string
    assert _image(folder / "membrane.png").shape == (viz.WINDOW_SIZE[1], viz.WINDOW_SIZE[0], 3)
    for name in ("contact_area.png", "energy.png"):
        img = _image(folder / name)
        assert img.shape[0] >= 600 and img.shape[1] >= 800, name
        assert (img < 100).all(axis=-1).sum() > 500, f"{name}: no dark text or lines"
    assert not list(folder.glob(".*"))  # no temporary file left
    assert [p.name for p in viz.show_pictures(folder)] == list(viz.MEMBRANE_PICTURES)


@pytest.mark.slow
def test_the_gif_has_a_frame_per_drawn_row_and_shows_the_landing(run):
    folder, res = run
    frames = _gif_frames(folder / "membrane.gif")
    width, height = animation.gif_size(viz.WINDOW_SIZE)
    assert frames.shape == (len(animation.frame_rows(res)), height, width, 3)
    assert 30 <= len(frames) <= 80
    assert np.all(frames[:, -1, -1] >= 240)  # the background stays white in every frame (the palette kept it)
    red = [int(_red(frame).sum()) for frame in frames]
    assert red[0] == 0 and red[-1] > 2000  # free at the start (η = 0.3), a contact patch at the end
    rows = animation.frame_rows(res)
    first = int(np.argmax(res.contact_measure[rows] > 0))
    assert max(red[:first]) == 0 and min(red[first + 1 :]) > 0  # red exactly while in contact (a frame's slack)


def test_frames_are_every_kth_row_and_the_last():
    res = dataclasses.make_dataclass("Rows", ["t"])(np.linspace(0, 1, 201))
    rows = animation.frame_rows(res)
    assert len(rows) == 41 and rows[0] == 0 and rows[-1] == 200 and set(np.diff(rows)) == {5}
    assert len(animation.frame_rows(res, max_frames=300)) == 201


def panel_boxes(result, figure_of=None):
    """The pixel boxes (rows, columns: slices) of membrane.png's panels as the picture lays them out (the screen
    style), and the rows under them (the colour key)."""
    from stringcontact.plot.style import SCREEN

    with SCREEN.drawn():
        fig, axs = (figure_of or mesh_pictures.membrane_figure)(result)
        fig.canvas.draw()
    height = fig.bbox.height
    boxes = [ax.get_window_extent() for ax in axs.flat if ax.get_visible()]
    below = round(height - min(b.y0 for b in boxes))
    return [(slice(round(height - b.y1), round(height - b.y0)), slice(round(b.x0), round(b.x1))) for b in boxes], below


def _panels(img, result):
    """The panels of membrane.png `img` of `result`."""
    return [img[box] for box in panel_boxes(result)[0]]


def test_the_membrane_panels_are_red_only_where_there_is_contact(run, tmp_path):
    folder, res = run
    rows = charts.snapshot_rows(res)
    assert res.t[rows] == pytest.approx(SMALL_DRUM["output_times"])
    panels = _panels(_image(folder / "membrane.png"), res)
    red = [int(_red(panel).sum()) for panel in panels]
    assert red[0] == 0 and red[1] == 0  # t = 0 and 0.1: not landed yet
    assert red[2] > 2000 and red[3] > 2000
    key = _image(folder / "membrane.png")[panel_boxes(res)[1]:]
    assert int(_red(key).sum()) > 30  # the key's red square, once, under the panels
    free = dataclasses.replace(res, contact=np.zeros_like(res.contact))
    assert sum(_red(p).sum() for p in _panels(_image(viz.draw("membrane.png", free, tmp_path)), free)) == 0
    img = _image(folder / "membrane.png")
    grey = (np.ptp(img, axis=-1) < 8) & (img[..., 0] > 100) & (img[..., 0] < 230)  # the grey obstacle
    assert grey.sum() > 5000


def test_the_contact_area_chart_draws_the_results_numbers(run):
    _, res = run
    fig = charts.contact_area_figure(res)
    area_axes, patch_axes = fig.axes
    lines = {line.get_label(): line for line in area_axes.get_lines()}
    np.testing.assert_array_equal(lines["contact area |{η ≤ 0}|"].get_ydata(), res.contact_measure)
    np.testing.assert_array_equal(lines["contact area |{η ≤ 0}|"].get_xdata(), res.t)
    assert lines[f"area of the domain = {res.weights.sum():.4g}"].get_ydata()[0] == pytest.approx(np.pi, rel=0.05)
    [patches] = patch_axes.get_lines()
    np.testing.assert_array_equal(patches.get_ydata(), res.contact_patches())
    assert res.contact_patches().max() == 1
    assert fig._suptitle.get_text() == "Contact area and contact patches over time"
    assert patch_axes.get_legend() is not None and area_axes.get_legend() is not None


def test_energy_labels_say_gradient_in_2d_and_eta_x_in_1d(run, tmp_path, monkeypatch):
    _, res = run
    labels = []
    def keep_labels(fig, path, look):
        labels.extend(t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts())
        return [path]

    monkeypatch.setattr(charts, "savefig", keep_labels)
    charts.picture(charts.energy_figure, res, tmp_path / "e.png")
    assert any(r"|\nabla\eta|^2" in label for label in labels) and not any("eta_x" in label for label in labels)


# --- reading a membrane's folder back ---------------------------------------------------------------


@pytest.fixture(scope="module", params=["drum", "bump"])
def written(request, tmp_path_factory):
    """A coarse drum (gmsh's disk) or bump (a rectangle: columns of nodes with the same x) written to disk."""
    scene = small_drum() if request.param == "drum" else sc.load_scene("bump").replace(cells=[16, 16], T=0.3, nt=60, output_times=[0.2])
    folder = tmp_path_factory.mktemp("readback2d") / request.param
    res = sc.simulate(scene, output=sc.Output(folder, pictures=False, max_frames=20, progress=False))
    return folder, res


def test_read_output_of_a_membrane_gives_the_in_memory_rows(written):
    folder, res = written
    stored = readback.read_output(folder)  # rows.npz: every stored row, as the run held it
    for name in ("t", "x", "cells", "weights", "eta", "velocity", "contact", "contact_force"):
        np.testing.assert_array_equal(getattr(stored, name), getattr(res, name), err_msg=name)
    back = xdmf_frames(folder)
    rows = [int(np.argmin(np.abs(res.t - t))) for t in back.t]
    np.testing.assert_array_equal(res.t[rows], back.t)
    assert 10 <= len(rows) < len(res.t)  # the XDMF frames: a subset of the stored rows
    np.testing.assert_allclose(back.x, res.x, rtol=0, atol=1e-14)  # the dofs' coordinates, to an ulp
    np.testing.assert_array_equal(back.cells, res.cells)
    for name in ("eta", "velocity", "contact"):
        np.testing.assert_array_equal(getattr(back, name), getattr(res, name)[rows], err_msg=name)
    assert res.contact[rows].any() and not res.contact[rows].all()
    np.testing.assert_allclose(back.weights, res.weights, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.contact_measure, res.contact_measure[rows], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.contact_patches(), res.contact_patches()[rows])


@pytest.mark.slow
def test_plot_of_a_membrane_folder_writes_the_membrane_pictures(run, tmp_path, capsys):
    folder, _ = run
    out = tmp_path / "again"
    assert main(["plot", str(folder), "--out", str(out), "--size", "800x600"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted([*viz.MEMBRANE_PICTURES, "pictures.json", "manifest.json"])  # its marker, the manifest
    assert _image(out / "membrane.png").shape == (600, 800, 3)
    assert _gif_frames(out / "membrane.gif").shape[1:3] == (360, 480)  # 0.6 of --size
    printed = capsys.readouterr().out
    assert all(f"wrote {out / name}" in printed for name in viz.MEMBRANE_PICTURES)


def _cells(change):
    def damage(p):
        with np.load(p) as npz:
            arrays = {key: npz[key] for key in npz.files}
        arrays["cells"] = change(arrays["cells"])
        np.savez(p, **arrays)

    return damage


def _random(p):
    p.write_bytes(np.random.default_rng(1).bytes(p.stat().st_size))


DAMAGED = {
    "a node index past the nodes": (_cells(lambda c: np.where(c == c.max(), 10**6, c)), "its cells are not triangles"),
    "quadrilaterals": (_cells(lambda c: np.column_stack([c, c[:, :1]])), "its cells are not triangles"),
    "no cells": (_cells(lambda c: c[:0]), "its cells are not triangles"),
    "random rows": (_random, "is not a readable .npz file"),
}


@pytest.mark.parametrize("case", DAMAGED)
def test_plot_of_a_damaged_membrane_folder_exits_2_naming_the_file(run, tmp_path, capsys, case):
    folder, _ = run
    damage, words = DAMAGED[case]
    copy, err = plot_refusal(folder, lambda copy: damage(copy / "rows.npz"), tmp_path, capsys)
    assert str(copy / "rows.npz") in err and words in err, err


@pytest.mark.slow
def test_stringcontact_run_of_a_membrane_draws_its_pictures_after_the_run(tmp_path, monkeypatch, capsys):
    """The real CLI: the run draws every picture of a membrane itself, after its solve, one after the other."""
    drawn_here = []
    draw = viz.draw
    monkeypatch.setattr(viz, "draw", lambda name, *args, **kw: drawn_here.append(name) or draw(name, *args, **kw))
    path = tmp_path / "small_drum.toml"
    path.write_text(scene_to_toml(small_drum()))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--no-progress"]) == 0
    assert drawn_here == list(viz.MEMBRANE_PICTURES)
    assert {p.name for p in out.iterdir()} >= set(viz.MEMBRANE_PICTURES)
    assert _red(_gif_frames(out / "membrane.gif")[-1]).sum() > 2000


@pytest.mark.slow
def test_the_membrane_picture_has_at_most_max_panels_whatever_the_output_times(monkeypatch, tmp_path):
    """Issue 27, item 4: membrane.png drew one pyvista panel per output time."""
    from stringcontact.plot import mesh_pictures

    times = np.round(np.linspace(0.0, 0.4, 41), 10).tolist()
    res = sc.simulate(small_drum().replace(output_times=times), output=sc.Output(progress=False))
    assert len(charts.stored_rows_at(res, times)) == 41
    drawn = []
    monkeypatch.setattr(charts, "savefig", lambda fig, path, look: drawn.append(fig) or [path])
    charts.picture(mesh_pictures.membrane_figure, res, tmp_path / "membrane.png", Look(size=(4, 3)))
    panels = [ax for ax in drawn[0].axes if ax.get_visible() and ax.get_title()]
    assert len(panels) == 12 == charts.MAX_PANELS  # one for each of 12 of the 41 output times (3 columns)


@pytest.mark.slow
def test_plot_redraws_a_membranes_pictures_pixel_for_pixel(tmp_path, capsys):
    """Issue 26, item 2: the drum's first contact moved from 0.12 to 0.125 and its largest area from 2.25 to
    2.24 in `plot`'s pictures, drawn from the XDMF frames (here 10 of 81 stored rows)."""
    from test_viz import assert_same_pictures

    res = sc.simulate(small_drum(), output=sc.Output(tmp_path / "run", max_frames=10, progress=False))
    assert main(["plot", str(tmp_path / "run"), "--out", str(tmp_path / "again")]) == 0
    assert_same_pictures(tmp_path / "run", tmp_path / "again", viz.MEMBRANE_PICTURES)
    back, area = readback.read_output(tmp_path / "run"), res.contact_measure
    assert back.t[np.flatnonzero(back.contact_measure > 0)[0]] == res.t[np.flatnonzero(area > 0)[0]]
    assert back.contact_measure.max() == area.max()
    np.testing.assert_array_equal(back.contact_patches(), res.contact_patches())


def _boundary_length(result, values) -> float:
    """The length of the 0.5 iso-line of `values` (one per node) interpolated across the flat triangles."""
    from stringcontact.plot import membrane

    flat = membrane.triangles(result, np.zeros(len(result.x)))
    flat.point_data["c"] = values
    line = flat.contour([0.5], scalars="c")
    return float(line.compute_cell_sizes(length=True, area=False, volume=False).cell_data["Length"].sum())


def test_the_contact_patch_is_drawn_without_the_meshs_staircase():
    """Issue 26, item 6: the membrane's patches had staircase edges at the default mesh (mesh_size 0.05)."""
    from stringcontact.plot import membrane

    res = sc.simulate(sc.load_scene("drum").replace(T=0.3, nt=60, output_times=[0.3]), output=sc.Output(progress=False))
    row = int(np.argmax(res.contact_measure))
    view = membrane.membrane_view(res)
    shade = view.shade(res.contact[row])
    contact = res.contact[row]
    assert shade[contact].min() >= 0.6 and shade[~contact].max() <= 0.4  # each node in the colour of its state
    bare, drawn = _boundary_length(res, contact.astype(float)), _boundary_length(res, shade)
    radius = np.sqrt(res.contact_measure[row] / np.pi)  # the patch is about a disk
    assert bare > 1.07 * drawn  # the zigzag of the bare indicator's iso-line is gone (6.8 against 6.2)
    assert drawn < 1.25 * 2 * np.pi * radius  # ...and the line drawn is about the round patch's circumference


def test_the_gifs_caption_is_at_least_14_pixels_high(run):
    """Issue 26, item 6: the caption (time, contact area, patches) was about 8 px high."""
    folder, _ = run
    frame = _gif_frames(folder / "membrane.gif")[0]
    rows = (frame[: frame.shape[0] // 4] < 90).all(axis=-1).any(axis=1)  # pixel rows with dark text, at the top
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], rows.astype(int), [0]]))))[::2]  # heights of the text lines
    assert runs.size and runs[0] >= 14, runs  # the first line, from its tallest letter's top to its lowest descender (was 10)


def _label_height(font_size: int) -> int:
    """The height in pixels of the tick label "0.5" drawn as `vtk_start.add_axis` draws it, at `font_size`."""
    from stringcontact.plot import vtk_start

    p = vtk_start._plotter((300, 200))
    p.add_point_labels(np.array([[0.0, 0.0, 0.0]]), ["0.5"], font_size=font_size, text_color="black", shape=None,
                       show_points=False, always_visible=True, font_family="arial", justification_horizontal="center")
    image = p.screenshot(None, return_img=True)[..., :3].astype(int)
    p.close()
    rows = np.flatnonzero((image < 128).all(axis=-1).any(axis=1))
    return int(rows.max() - rows.min() + 1) if rows.size else 0


@pytest.mark.slow
def test_the_membrane_pictures_tick_labels_are_at_least_12_pixels_high(run, tmp_path, monkeypatch):
    """membrane.png's and membrane.gif's axes: their tick labels were about 6 px high (font size 7 and 8)."""
    from stringcontact.plot import membrane, mesh_pictures

    _, res = run
    sizes = []
    draw = membrane.add_axis

    def spy(p, axis, font_size=11, most=5, zoom=1.0):
        sizes.append(round(font_size * zoom))
        return draw(p, axis, font_size, most, zoom)

    monkeypatch.setattr(membrane, "add_axis", spy)  # the axes of membrane.png and membrane.gif alike
    charts.picture(mesh_pictures.membrane_figure, res, tmp_path / "membrane.png")
    picture = set(sizes)
    sizes.clear()
    animation.membrane_animation(res, tmp_path / "membrane.gif", max_frames=2)
    gif = set(sizes)
    assert picture and gif, (picture, gif)
    for where, used in (("membrane.png", picture), ("membrane.gif", gif)):
        heights = {size: _label_height(size) for size in used}
        assert min(heights.values()) >= 12, f"{where}: tick labels {heights} px high (font size: height)"
