"""Pictures, reading an output folder back, and `stringcontact plot`."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import xdmf_frames

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.io import readback
from stringcontact.io.result import ENERGY_KEYS
from stringcontact.plot import charts
from stringcontact.plot import run_pictures as viz
from stringcontact.plot.style import SCREEN


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A coarse Example 1 written to disk with pictures, and its in-memory result."""
    folder = tmp_path_factory.mktemp("viz") / "ex1"
    scene = sc.load_scene("example1").replace(nx=80, nt=600)
    res = sc.simulate(scene, output=sc.Output(folder), storage=sc.Storage(max_rows=60))
    return folder, res


@pytest.mark.slow
def test_read_output_matches_the_in_memory_result(run):
    folder, res = run
    back = readback.read_output(folder)
    np.testing.assert_array_equal(back.x, res.x)
    np.testing.assert_array_equal(back.t, res.t)
    np.testing.assert_array_equal(back.steps, res.steps)
    for name in ("eta", "velocity", "contact_force"):
        np.testing.assert_array_equal(getattr(back, name), getattr(res, name), err_msg=name)
    assert back.contact.dtype == bool
    np.testing.assert_array_equal(back.contact, res.contact)
    assert res.contact.any() and not res.contact.all()  # the comparison covers both states
    for key in ENERGY_KEYS:
        np.testing.assert_array_equal(back.energy[key], res.energy[key], err_msg=key)
    np.testing.assert_allclose(back.balance_residual, res.balance_residual, rtol=0, atol=1e-12 * res.total_energy[0])
    assert back.scene == res.scene
    assert (back.penalty, back.mass, back.min_eta) == (res.penalty, res.mass, res.min_eta)


def test_diagnostics_columns_read_back(run):
    folder, res = run
    with open(folder / "diagnostics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    np.testing.assert_array_equal(col["contact_length"], res.contact_length)
    np.testing.assert_array_equal(col["min_eta"], res.eta.min(axis=1))
    np.testing.assert_array_equal(col["max_contact_force"], res.contact_force.max(axis=1))


def _image(path):
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).astype(int)


def _near(img, hex_colour, tol=20):
    rgb = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)])
    return np.all(np.abs(img - rgb) <= tol, axis=-1)


def test_run_writes_legible_pictures(run):
    folder, _ = run
    for name in viz.PICTURES:
        img = _image(folder / name)
        assert img.shape[0] >= 600 and img.shape[1] >= 800, name
        assert (img < 100).all(axis=-1).sum() > 500, f"{name}: no dark text or lines"
    assert _near(_image(folder / "contact_set.png"), charts.CONTACT_COLOUR).sum() > 5000
    assert _near(_image(folder / "space_time.png"), charts.CONTACT_COLOUR, tol=60).sum() > 2000  # lit, so less exact


def _zlib_level_class(path: Path) -> int:
    """FLEVEL of the PNG's zlib stream (RFC 1950: 0 fastest, 1 fast (levels 2-5), 2 default (6), 3 best)."""
    data = path.read_bytes()
    idat = data.index(b"IDAT") + 4  # the first IDAT chunk's data: the zlib header's two bytes first
    return data[idat + 1] >> 6


def test_every_picture_is_written_at_the_chosen_compression(run):
    """Both writers (matplotlib's and the pyvista screenshot's) use PNG_COMPRESSION, not Pillow's default 6."""
    from stringcontact.plot.charts import PNG_COMPRESSION

    folder, _ = run
    assert 2 <= PNG_COMPRESSION <= 5  # zlib marks levels 2-5 as FLEVEL 1; Pillow's default 6 as 2
    assert {name: _zlib_level_class(folder / name) for name in viz.PICTURES} == dict.fromkeys(viz.PICTURES, 1)


def test_contact_set_picture_shows_the_contact_fraction(run):
    """The red share of the plotting area is the contact set's share of the (x, t) rectangle."""
    _, res = run
    from stringcontact.plot.charts import _cell_edges

    dx, dt = np.diff(_cell_edges(res.x)), np.diff(_cell_edges(res.t))
    fraction = np.sum(res.contact * dt[:, None] * dx[None, :]) / (dx.sum() * dt.sum())
    assert 0.05 < fraction < 0.5
    img = _image(run[0] / "contact_set.png")
    with SCREEN.drawn():  # where the whole (x, t) rectangle is: the upper panel, as the run's picture lays it out
        fig, axes = charts.contact_set_figure(res)
        fig.canvas.draw()
    box = axes["set"].get_window_extent()
    top, bottom = fig.bbox.height - box.y1, fig.bbox.height - box.y0  # pixel rows count from the top
    inside = _near(img[round(top) + 2 : round(bottom) - 1, round(box.x0) + 2 : round(box.x1) - 1], charts.CONTACT_COLOUR)
    assert inside.mean() == pytest.approx(fraction, abs=0.02)
    assert (img[round(top) + 1 : round(bottom) - 1, round(box.x0)] < 60).all()  # the box is the panel's frame


def test_velocity_picture_is_centred_on_zero(run):
    folder, res = run
    img = _image(folder / "velocity_field.png")
    blue = (img[..., 2] - img[..., 0] > 60).sum()
    red = (img[..., 0] - img[..., 2] > 60).sum()
    assert blue > 5000 and red > 500  # downward impact and upward rebound both visible
    speed = np.abs(res.velocity)
    # the colours clip the few fastest samples (v0 = -50 at t = 0) but not the bulk of the motion
    assert np.median(speed) < charts.velocity_clip(res) < speed.max()
    # a string at rest still gets a colour range, not ±0
    assert charts.velocity_clip(dataclasses.replace(res, velocity=np.zeros_like(res.velocity))) == 1.0


def test_contact_set_picture_is_blank_without_contact(tmp_path, run):
    folder, _ = run
    free = readback.read_output(folder)
    free.contact[:] = False
    charts.picture(charts.contact_set_figure, free, tmp_path / "c.png")
    # only the small legend patch keeps the contact colour
    assert _near(_image(tmp_path / "c.png"), charts.CONTACT_COLOUR).sum() < 2000


@pytest.mark.slow
def test_plot_command_redraws_from_files(tmp_path, run, capsys):
    folder, _ = run
    out = tmp_path / "again"
    assert main(["plot", str(folder), "--out", str(out), "--size", "900x700"]) == 0
    for name in viz.PICTURES:
        assert (out / name).stat().st_size > 10_000
    assert _image(out / "contact_set.png").shape[:2] == (700, 900)
    assert not list(out.glob(".*"))  # no temporary files left
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, words",
    [
        (["plot", "/nonexistent/folder"], "is not a folder"),
        (["plot", "{empty}"], "missing summary.json, diagnostics.csv, rows.npz"),
        (["plot", "{run}", "--size", "10x10"], "--size"),
        (["plot", "{run}", "--size", "big"], "--size"),
    ],
)
def test_plot_bad_input_is_one_line(tmp_path, run, capsys, argv, words):
    argv = [a.format(empty=tmp_path, run=run[0]) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err and "Traceback" not in err


def test_read_output_refuses_an_incomplete_folder(tmp_path, run):
    folder, _ = run
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    (copy / "diagnostics.csv").unlink()
    with pytest.raises(ValueError, match="diagnostics.csv"):
        readback.read_output(copy)


def test_a_truncated_xdmf_is_refused_in_one_line(tmp_path, run):
    from stringcontact.errors import OutputError

    folder, _ = run
    text = (folder / "solution.xdmf").read_text()
    (tmp_path / "solution.xdmf").write_text(text[: len(text) // 2])
    with pytest.raises(OutputError, match=r"solution.xdmf is not a readable XDMF file \(") as info:
        readback.read_xdmf(tmp_path / "solution.xdmf")
    assert "\n" not in str(info.value)


def test_a_picture_is_written_whole_or_not_at_all(tmp_path):
    from stringcontact.io.publish import atomic_path

    target = tmp_path / "energy.png"
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            assert tmp.parent == tmp_path and tmp.name.startswith(".energy.png.tmp-") and tmp.suffix == ".png"
            tmp.write_bytes(b"half")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"whole")
    assert target.read_bytes() == b"whole" and list(tmp_path.iterdir()) == [target]


def test_contact_components():
    x = np.linspace(0, 1, 11)
    c = np.array([1, 0, 1, 1, 1, 0, 0, 1, 1, 0, 1], dtype=bool)
    np.testing.assert_allclose(charts.contact_components(x, c), [(0.2, 0.4), (0.7, 0.8)])
    assert len(charts.contact_components(x, c, min_nodes=1)) == 4
    assert charts.contact_components(x, np.zeros(11, bool)) == []
    assert charts.contact_components(x, np.ones(11, bool)) == [(0.0, 1.0)]


def test_snapshot_rows_are_the_scene_output_times(run):
    _, res = run
    rows = charts.snapshot_rows(res)
    np.testing.assert_allclose(res.t[rows], res.scene.output_times, atol=1e-12)


@pytest.mark.slow
def test_snapshots_draw_the_scenes_profiled_obstacle(tmp_path):
    scene = sc.load_scene("loaded_string").replace(nx=40, T=0.5, nt=500, eps=0.01, output_times=[0.0, 0.5])
    res = sc.simulate(scene, model=sc.load_model(scene.model), output=sc.Output(tmp_path / "run", pictures=False))
    back = readback.read_output(tmp_path / "run")
    assert charts.obstacle_name(back) == "ψ" and charts.obstacle_name(sc.simulate(scene.replace(load=None, obstacle=None, model=None))) == "0"
    grey = "#d9d9d9"  # the shaded obstacle region
    charts.picture(charts.snapshots_figure, back, tmp_path / "bump.png")
    flat = readback.read_output(tmp_path / "run")
    flat.scene = flat.scene.replace(obstacle=None)
    charts.picture(charts.snapshots_figure, flat, tmp_path / "flat.png")
    bump, level = _near(_image(tmp_path / "bump.png"), grey, 3).sum(), _near(_image(tmp_path / "flat.png"), grey, 3).sum()
    # the bump (down to ψ = -0.8 at the ends) is shaded, not the half-plane y <= 0: a different area
    assert bump > 0 and level > 0 and abs(bump - level) > 0.2 * level
    assert res.contact.any()


def test_xdmf_holds_about_max_frames_of_the_stored_rows(tmp_path):
    """The XDMF is thinned (its writer costs O(frames²)); read back, each frame is exactly its stored row."""
    scene = sc.load_scene("example1").replace(nx=40)
    res = sc.simulate(scene, output=sc.Output(tmp_path / "out", max_frames=10, pictures=False),
                      storage=sc.Storage(max_rows=60))
    back = xdmf_frames(tmp_path / "out")
    assert 10 <= len(back.t) < len(res.t) == 61
    rows = [int(np.flatnonzero(res.t == t)[0]) for t in back.t]
    assert rows[0] == 0 and rows[-1] == len(res.t) - 1
    assert set(charts.snapshot_rows(res)) <= set(rows)  # the scene's output times are always frames
    for name in ("eta", "velocity", "contact", "contact_force"):
        np.testing.assert_array_equal(getattr(back, name), getattr(res, name)[rows], err_msg=name)
    for key in ENERGY_KEYS:
        np.testing.assert_array_equal(back.energy[key], res.energy[key][rows], err_msg=key)


FIELD_NAMES = ("eta", "velocity", "contact", "contact_force")


def _thinning_writer(folder):
    """An OutputWriter on 11 nodes whose stored rows 0 and 3 are XDMF frames, and rows 1 and 2 are not."""
    from dolfinx import mesh
    from mpi4py import MPI

    from stringcontact.fem import compat
    from stringcontact.io.folder import OutputWriter

    scene = sc.load_scene("example1").replace(nx=10, nt=20)
    V = compat.function_space(mesh.create_interval(MPI.COMM_SELF, 10, [0.0, 1.0]))
    return OutputWriter(folder, scene, V, MPI.COMM_SELF, pictures=False, frames=[True, False, False, True])


def test_a_stopped_run_ends_its_xdmf_with_the_last_stored_row(tmp_path):
    from stringcontact.io.readback import read_xdmf

    writer = _thinning_writer(tmp_path / "out")
    for k in range(3):  # the run stops after the third stored row, which is not a frame
        writer.write(0.1 * k, {name: np.full(11, float(k)) for name in FIELD_NAMES})
    writer.abort("interrupted", "stopped")
    series = read_xdmf(writer.path / "solution.xdmf")[1]
    assert [t for t, _ in series["eta"]] == pytest.approx([0.0, 0.2])


def test_the_output_module_does_not_import_the_picture_code():
    """The output folder is given the picture function by the driver; plot imports io, not the reverse."""
    import ast
    import subprocess
    import sys

    from stringcontact.io import folder as output

    tree = ast.parse(Path(output.__file__).read_text())
    imported = {node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert not {m for m in imported if m.split(".")[-1] in ("run_pictures", "charts", "mesh_pictures")}
    assert not hasattr(output, "registered_pictures")  # no entry point of its own: no circle to hide
    code = "import sys, stringcontact.plot.run_pictures; print(sorted(m for m in sys.modules if m.startswith(('pyvista', 'vtk'))))"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "[]"


def test_simulate_calls_a_given_picture_function_before_the_folder_is_published(tmp_path):
    calls = []

    def draw(result, folder):
        calls.append((result, Path(folder)))
        (Path(folder) / "mine.png").write_bytes(b"png")

    scene = sc.load_scene("example1").replace(nx=20, nt=40, eps=0.01)
    res = sc.simulate(scene, output=sc.Output(tmp_path / "out", pictures=draw, default_pictures=False))  # its own only
    [(result, folder)] = calls
    assert result is res and folder.name.startswith(".out.partial") and not folder.exists()
    assert sorted(p.name for p in (tmp_path / "out").glob("*.png")) == ["mine.png"]


def _drawn_at(figure_of, result):
    """(the figure's first axes' pixels: rows and columns as slices, the rows below it) of `figure_of(result)` laid
    out as the picture is (the screen style)."""
    with SCREEN.drawn():
        fig, ax = figure_of(result)
        fig.canvas.draw()
    box, height = ax.get_window_extent(), fig.bbox.height
    return (slice(round(height - box.y1), round(height - box.y0)), slice(round(box.x0), round(box.x1))), \
        slice(round(height - box.y0), None)


def test_the_space_time_surface_is_red_only_where_there_is_contact(tmp_path, run):
    from stringcontact.plot import mesh_pictures

    _, res = run
    free = dataclasses.replace(res, contact=np.zeros_like(res.contact))
    charts.picture(mesh_pictures.space_time_figure, free, tmp_path / "free.png")
    charts.picture(mesh_pictures.space_time_figure, res, tmp_path / "contact.png")
    render, below = _drawn_at(mesh_pictures.space_time_figure, res)
    # the render, without the colour key under it (its red square is in both)
    red = [_near(_image(tmp_path / n)[render], charts.CONTACT_COLOUR, tol=60).sum() for n in ("free.png", "contact.png")]
    assert red[0] < 50 and red[1] > 2000
    key = [_near(_image(tmp_path / n)[below], charts.CONTACT_COLOUR, tol=10).sum() for n in ("free.png", "contact.png")]
    assert min(key) > 30  # the key's red square
    img = _image(tmp_path / "free.png")
    grey = (np.ptp(img, axis=-1) < 8) & (img[..., 0] > 100) & (img[..., 0] < 230)  # the translucent obstacle
    assert grey.sum() > 5000


def test_a_stop_while_a_skipped_row_is_copied_keeps_the_previous_row_whole(tmp_path):
    from stringcontact.io.readback import read_xdmf

    class StopsAfterOneField(dict):  # Ctrl-C arriving between two fields of a row
        def items(self):
            yield next(iter(super().items()))
            raise KeyboardInterrupt

    names = FIELD_NAMES
    writer = _thinning_writer(tmp_path / "out")
    writer.write(0.0, {name: np.zeros(11) for name in names})
    writer.write(0.1, {name: np.ones(11) for name in names})  # skipped, kept whole
    with pytest.raises(KeyboardInterrupt):
        writer.write(0.2, StopsAfterOneField({name: np.full(11, 2.0) for name in names}))
    writer.abort("interrupted", "stopped")
    _, series = read_xdmf(writer.path / "solution.xdmf")
    assert [t for t, _ in series["eta"]] == pytest.approx([0.0, 0.1])
    import pyfive

    with pyfive.File(str(writer.path / "solution.h5")) as h5:
        for name in names:
            last = np.asarray(h5[series[name][-1][1].split(":", 1)[1]][:])
            np.testing.assert_array_equal(last, 1.0, err_msg=name)  # row 0.1, not a mix with row 0.2


def test_no_axes3d_warning_and_no_global_filter_where_mplot3d_warns(tmp_path):
    """pip's matplotlib beside Debian's mpl_toolkits warns "Unable to import Axes3D" when its projections load
    (issue 26): the pictures import them without the warning, and leave the process's warning filters as they were.
    Here an mplot3d that warns as matplotlib does stands first in `mpl_toolkits`."""
    import subprocess
    import sys

    fake = tmp_path / "mplot3d"
    fake.mkdir()
    (fake / "__init__.py").write_text(
        "import warnings\nfrom matplotlib.axes import Axes\n"
        "warnings.warn('Unable to import Axes3D. This may be due to multiple versions of Matplotlib', UserWarning)\n"
        "class Axes3D(Axes):\n    name = '3d'\n")
    code = ("import sys, warnings, numpy, mpl_toolkits\nmpl_toolkits.__path__ = [sys.argv[1], *mpl_toolkits.__path__]\n"
            "filters = list(warnings.filters)\nfrom stringcontact.plot import charts, vtk_start\n"
            "charts.figure((2, 2)).savefig(sys.argv[2])\nvtk_start._pyvista()\n"
            "import mpl_toolkits.mplot3d as m\nassert m.__file__.startswith(sys.argv[1]), m.__file__\n"
            "print('done', warnings.filters == filters)")
    proc = subprocess.run([sys.executable, "-W", "default", "-c", code, str(tmp_path), str(tmp_path / "f.png")],
                          capture_output=True, text=True, check=True)
    assert proc.stdout.strip() == "done True" and "Axes3D" not in proc.stderr, proc.stdout + proc.stderr


def _recorded_axes(monkeypatch):
    """The axes and colour keys the mesh pictures draw, recorded as they are drawn."""
    from stringcontact.plot import membrane, mesh_pictures

    drawn = {"axes": [], "labels": [], "keys": []}
    add_axis, add_key = mesh_pictures.add_axis, mesh_pictures._key

    def axis(p, a, *args, **kwargs):
        drawn["axes"].append(a)
        drawn["labels"].append(add_axis(p, a, *args, **kwargs))
        return drawn["labels"][-1]

    def key(ax, entries):
        drawn["keys"].append([label for label, _ in entries])
        return add_key(ax, entries)

    monkeypatch.setattr(mesh_pictures, "add_axis", axis)  # the space-time surface's
    monkeypatch.setattr(membrane, "add_axis", axis)  # a membrane's
    monkeypatch.setattr(mesh_pictures, "_key", key)
    return drawn


def test_the_space_time_surface_has_axes_with_ticks_under_the_obstacle_and_a_colour_key(tmp_path, run, monkeypatch):
    """Issue 26: x, t and eta axes with round ticks (not corner labels at the obstacle's plane), and a key naming
    the quantity the colours show."""
    from stringcontact.plot import mesh_pictures, vtk_start

    _, res = run
    drawn = _recorded_axes(monkeypatch)
    charts.picture(mesh_pictures.space_time_figure, res, tmp_path / "st.png")
    assert [a.title for a in drawn["axes"]] == ["x", "t", "eta"]
    x_labels, t_labels, eta_labels = drawn["labels"]
    assert x_labels[0] == "0" and x_labels[-1] == "1" and len(x_labels) >= 3
    assert t_labels[0] == "0" and float(t_labels[-1]) <= res.t[-1] and len(t_labels) >= 3
    assert len(eta_labels) >= 2
    x_axis, t_axis, _ = drawn["axes"]
    assert x_axis.start[2] < 0 and t_axis.start[2] < 0  # on a floor below the obstacle ψ = 0, not on its plane
    (entries,) = drawn["keys"]
    assert any("in contact" in e for e in entries) and any("free" in e for e in entries)
    np.testing.assert_array_equal(vtk_start.nice_ticks(0.0, 0.3), [0.0, 0.1, 0.2, 0.3])


@pytest.mark.slow
def test_the_membrane_panels_have_axes_and_one_colour_key(tmp_path, monkeypatch):
    from stringcontact.plot import mesh_pictures

    res = sc.simulate(sc.load_scene("drum").replace(mesh_size=0.3, T=0.3, nt=60, output_times=[0.0, 0.3]))
    drawn = _recorded_axes(monkeypatch)
    charts.picture(mesh_pictures.membrane_figure, res, tmp_path / "m.png")
    assert [a.title for a in drawn["axes"]] == ["x", "y", "eta"]  # once: the two panels are one scene's renders
    x_labels = [float(v) for v in drawn["labels"][0]]
    assert x_labels[0] < 0 < x_labels[-1] and len(x_labels) >= 3
    assert len(drawn["keys"]) == 1 and any("in contact" in e for e in drawn["keys"][0])


def test_the_membrane_animation_has_axes(tmp_path, monkeypatch):
    """Issue 26: every picture has axes, the GIF too."""
    from stringcontact.plot import animation

    res = sc.simulate(sc.load_scene("drum").replace(mesh_size=0.3, T=0.3, nt=60, output_times=[0.0, 0.3]))
    drawn = _recorded_axes(monkeypatch)
    animation.membrane_animation(res, tmp_path / "m.gif", window_size=(400, 300), max_frames=3)
    assert [a.title for a in drawn["axes"]] == ["x", "y", "eta"]  # once: the frames share the scene


def test_snapshots_have_at_most_max_panels_whatever_the_output_times(tmp_path, monkeypatch):
    """Issue 27, item 4: a panel per output time made 1000 output times (the documented maximum) hang `run`."""
    from stringcontact.plot import charts

    times = np.round(np.linspace(0.0, 0.5, 60), 10).tolist()
    res = sc.simulate(sc.load_scene("example1").replace(nx=20, T=0.5, nt=1000, output_times=times),
                      storage=sc.Storage(max_rows=100))
    assert len(charts.stored_rows_at(res, times)) == 60  # every output time is a stored row
    drawn = []
    monkeypatch.setattr(charts, "savefig", lambda fig, path, look=None: drawn.append(fig) or [path])
    charts.picture(charts.snapshots_figure, res, tmp_path / "snapshots.png")
    panels = [ax for ax in drawn[0].axes if ax.get_visible() and ax.get_title()]
    assert len(panels) == 12 == charts.MAX_PANELS
    titles = [ax.get_title() for ax in panels]
    assert titles[0].startswith("t = 0:") and titles[-1].startswith("t = 0.5:")  # the first and the last time
    assert "12 of the 60 output times" in drawn[0]._supxlabel.get_text()  # the caption says so


def test_evenly_keeps_the_ends_and_at_most_most():
    from stringcontact.plot.charts import evenly

    assert evenly(5, 12) == [0, 1, 2, 3, 4]
    for n in (13, 60, 1000):
        picks = evenly(n, 12)
        assert len(picks) == 12 and picks[0] == 0 and picks[-1] == n - 1 and picks == sorted(set(picks))
        assert max(np.diff(picks)) - min(np.diff(picks)) <= 1  # evenly spaced


def assert_same_pictures(first, second, names):
    """Each picture in folder `first` equals its namesake in `second`, pixel for pixel (a GIF frame for frame)."""
    import imageio.v3 as iio

    for name in names:
        a, b = iio.imread(first / name, index=None), iio.imread(second / name, index=None)
        assert a.shape == b.shape, f"{name}: {a.shape} against {b.shape}"
        differ = np.any(a != b, axis=-1)
        assert not differ.any(), f"{name}: {differ.mean():.2%} of the pixels differ"


@pytest.mark.slow
def test_plot_redraws_the_runs_pictures_pixel_for_pixel(tmp_path, capsys):
    """Issue 26, item 2: `plot` drew from the XDMF frames (here 12 of 121 stored rows), not the rows the run drew from."""
    scene = sc.load_scene("example1").replace(nx=80, nt=1200)
    res = sc.simulate(scene, output=sc.Output(tmp_path / "run", max_frames=12), storage=sc.Storage(max_rows=120))
    assert len(res.t) > 100
    assert main(["plot", str(tmp_path / "run"), "--out", str(tmp_path / "again")]) == 0
    assert_same_pictures(tmp_path / "run", tmp_path / "again", viz.PICTURES)
    back = readback.read_output(tmp_path / "run")
    def first_contact(r):
        return r.t[np.flatnonzero(r.contact_length > 0)[0]]

    assert (first_contact(back), back.contact_length.max()) == (first_contact(res), res.contact_length.max())


def test_contact_components_count_runs_of_two_or_more_contact_nodes():
    from stringcontact.io.result import contact_runs

    x = np.linspace(0, 1, 11)
    rows = np.array([[1, 0, 1, 1, 1, 0, 0, 1, 1, 0, 1], [0] * 11, [1] * 11, [1, 1, 0, 1, 0, 1, 1, 0, 0, 1, 1]], dtype=bool)
    counts = contact_runs(rows)
    assert counts.tolist() == [len(charts.contact_components(x, row)) for row in rows] == [2, 0, 1, 3]


@pytest.fixture(scope="module")
def example2(tmp_path_factory):
    """A coarse Example 2 written to disk: three contact components before t = 0.02, one or two later."""
    folder = tmp_path_factory.mktemp("example2") / "ex2"
    with pytest.warns(UserWarning, match="below the obstacle"):  # as the paper's Example 2 starts
        scene = sc.load_scene("example2").replace(nx=400, nt=2500)
    res = sc.simulate(scene, output=sc.Output(folder, progress=False, pictures=False))
    return folder, res


def test_the_run_reports_the_number_of_contact_components_over_time(example2):
    """Issue 26, item 4: Example 2's point is that its contact set has several components."""
    import json

    folder, res = example2
    with open(folder / "diagnostics.csv", newline="") as f:
        counts = np.array([int(row["contact_components"]) for row in csv.DictReader(f)])
    expected = [len(charts.contact_components(res.x, row)) for row in res.contact]
    np.testing.assert_array_equal(counts, expected)
    assert counts.max() == 3 and res.t[np.argmax(counts)] < 0.02  # three components early on
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["contact_components"] == {"most": 3, "first_at": float(res.t[np.argmax(counts)])}


def test_the_contact_set_picture_zooms_onto_example2s_early_components(example2):
    """Issue 26, item 4: before t = 0.02 the components were 1-3 pixels tall in contact_set.png."""
    from stringcontact.plot import charts

    _, res = example2
    fig, axes = charts.contact_set_figure(res)
    lo, hi = axes["zoom"].get_ylim()
    assert lo == 0 and hi < 0.1 * res.t[-1]  # the first 10 % of the run, over the zoomed panel's full height
    steps = axes["zoom_count"].patches[0].get_data().values  # the count strip draws the run's counts
    assert max(steps) == 3
    pixels_per_time = axes["zoom"].get_window_extent().height / (hi - lo)
    assert 0.0168 * pixels_per_time > 100  # the three components' time is over 100 pixels tall


def _boxes_overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_the_energy_legend_covers_no_panel(run):
    """Issue 26, item 5: the bump's legend covered the contact dissipation for t > 0.58."""
    from stringcontact.plot import charts

    _, res = run
    with SCREEN.drawn():
        fig, axes = charts.energy_figure(res)
        fig.canvas.draw()
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)]
    curve_legends = [legend for legend in legends if any("kinetic" in text.get_text() for text in legend.get_texts())]
    assert len(curve_legends) == 1
    box = curve_legends[0].get_window_extent()
    assert not any(_boxes_overlap(box, ax.get_window_extent()) for ax in axes.values())


def test_example2s_energies_get_a_panel_zoomed_onto_their_first_times(example2):
    """Issue 26, item 5: Example 2's dynamics took the first 5 % of the energy chart's time axis."""
    from stringcontact.plot import charts

    _, res = example2
    fig, axes = charts.energy_figure(res)
    lo, hi = axes["zoom"].get_xlim()
    assert lo == 0 and hi < 0.15 * res.t[-1]  # at this coarse nx its energies settle by t = 0.036 of 0.5
    kinetic = res.energy["kinetic"]
    assert kinetic[res.t > hi].max() < 0.05 * kinetic.max()  # the motion is over within the zoom
    fig, axes = charts.energy_figure(sc.simulate(sc.load_scene("example1").replace(nx=40, nt=600),
                                                 storage=sc.Storage(max_rows=60)))
    assert "zoom" not in axes  # Example 1 moves all the time: one panel


def test_a_residual_of_exactly_zero_is_marked_not_drawn_as_a_plunge():
    """Issue 26, item 5: a residual that drops to exactly 0 looked like a square wave on the log scale."""
    from stringcontact.plot import charts

    t = np.linspace(0.0, 1.0, 11)
    residual = np.array([0, 1e-14, 2e-14, 0, 0, 3e-14, -1e-15, 0, 2e-14, 1e-14, 1e-14])
    ax = charts.figure((6.4, 4.8)).subplots()
    charts.residual_panel(ax, t, residual)
    line, marks = ax.get_lines()
    assert np.array_equal(np.isnan(line.get_ydata()), residual == 0)  # no point where it is 0...
    np.testing.assert_array_equal(marks.get_xdata(), t[residual == 0])  # ...a mark there instead
    floor = ax.get_ylim()[0]
    assert np.all(marks.get_ydata() == floor) and 0 < floor < 1e-15 and ax.get_yscale() == "log"
    assert "exactly 0 (4 of 11 rows" in ax.get_legend().get_texts()[1].get_text()


def test_the_space_time_caption_gives_a_heights_round_off_as_0(tmp_path, monkeypatch):
    """A string held at η ≥ 1 above a narrow bump whose foot is 1e-110: the caption gives η's own range (from 1, not
    from the drawn box's bottom, which read 'height η from 1.32e-112' and then 'from 0') and the bump's, whose
    round-off foot reads 0."""
    from stringcontact.plot import mesh_pictures

    scene = sc.load_scene("example1").replace(nx=40, nt=20, T=0.01, v0="0", output_times=[],
                                              obstacle="0.05*exp(-1000*(x - 0.5)**2)", model="loaded_obstacle")
    res = sc.simulate(scene)
    assert 0 < res.scene.obstacle_values(res.x).min() < 1e-100 and res.eta.min() >= 1.0
    fig, _ = mesh_pictures.space_time_figure(res)
    (line,) = [line for line in fig._supxlabel.get_text().splitlines() if line.startswith("η from")]  # the caption
    assert line == f"η from {res.eta.min():.3g} to {res.eta.max():.3g} over x and t, ψ from 0 to 0.05", line
    assert mesh_pictures._height_text(-0.0123, 1.0) == "-0.0123" and mesh_pictures._height_text(2e-6, 1.0) == "2e-06"
