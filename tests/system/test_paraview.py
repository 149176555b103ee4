"""The README's ParaView recipe, in ParaView: `pvpython` (Debian's python3-paraview) under `xvfb-run`.

`scripts/setup --test` (run by `make test`) installs both; `make test` sets STRINGCONTACT_REQUIRE_PARAVIEW=1,
so there the test fails instead of skipping when they are missing.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import xdmf_frames

import stringcontact as sc
from stringcontact.io.result import FIELDS

SCRIPT = Path(__file__).with_name("paraview_readme.py")
CONTACT_RGB = (180, 4, 38)  # the top of ParaView's default map (Cool to Warm): contact = 1
FREE_RGB = (59, 76, 192)  # its bottom: contact = 0


def pvpython() -> list[str]:
    missing = [tool for tool in ("pvpython", "xvfb-run") if shutil.which(tool) is None]
    if missing:
        why = f"{' and '.join(missing)} not found (scripts/setup --test installs python3-paraview and xvfb)"
        if os.environ.get("STRINGCONTACT_REQUIRE_PARAVIEW"):
            pytest.fail(why)
        pytest.skip(why)
    return ["xvfb-run", "-a", "-s", XVFB_ARGS, "pvpython"]


# 24-bit colour for GLX. -noreset: pvpython's MPI start-up (hwloc's GL probe, in pvpython and in its orted)
# opens and closes the display before VTK does; when that was the last client, Xvfb resets, and a connection
# arriving during the reset is dropped: VTK's "bad X server connection ... Aborting" (CI, 2026-11). Measured:
# 8 of 30 single runs on a loaded machine, 14 of 24 with 8 at once; with -noreset none (docs/explanation/visualisation.md).
XVFB_ARGS = "-screen 0 1280x1024x24 -noreset"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("paraview") / "run"
    res = sc.simulate(sc.load_scene("example1").replace(nx=200, nt=600),
                      output=sc.Output(out, max_frames=10, pictures=False))
    return out, res


def _pixels_near(img, rgb, tol=40):
    return int(np.all(np.abs(img[..., :3].astype(int) - np.array(rgb)) <= tol, axis=-1).sum())


@pytest.mark.slow
def test_the_readme_recipe_colours_the_warped_string_by_contact(tmp_path, run):
    from PIL import Image

    command = pvpython()
    out, res = run
    back = xdmf_frames(out)  # the frames ParaView reads
    k = int(np.argmax([0.3 < c.mean() < 1 for c in back.contact]))  # a frame with contact on part of the string
    t = float(back.t[k])
    row = int(np.flatnonzero(res.t == t)[0])
    solver_fraction = float(res.contact[row].mean())
    assert 0.3 < solver_fraction < 1

    png = tmp_path / "contact.png"
    proc = subprocess.run(
        [*command, str(SCRIPT), str(out / "solution.xdmf"), repr(t), str(png)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[:2000] + " ... " + proc.stderr[-1000:]
    reports = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert [r["reader"] for r in reports] == ["Xdmf3ReaderT", "Xdmf3ReaderS", "XDMFReader"]
    for r in reports:
        assert r["class"] == "vtkUnstructuredGrid", r  # one grid, not a block per field
        assert r["points"] == len(res.x) and set(r["arrays"]) == set(FIELDS), r
        np.testing.assert_allclose(r["times"], back.t, rtol=1e-12, atol=0)
        assert r["eta_type"] == "double"  # Precision="8"
        assert r["contact_range"] == [0.0, 1.0]
        assert r["contact_fraction"] == pytest.approx(solver_fraction, abs=1e-12), r["reader"]
        assert r["max_warp_error"] < 1e-6  # the points were moved by eta ...
        assert r["max_y_in_contact"] <= 1e-6  # ... and those marked in contact lie on or below the obstacle

    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[:2] == (450, 900)
    assert _pixels_near(img, CONTACT_RGB) > 300, "no string drawn in the contact colour"
    assert _pixels_near(img, FREE_RGB) > 100, "no free part of the string drawn"


@pytest.mark.slow
def test_the_readme_membrane_recipe_shows_the_drum_patch(tmp_path):
    """A membrane's solution.xdmf in ParaView: triangles warped by eta (z), the solver's contact nodes, the patch drawn."""
    from PIL import Image

    command = pvpython()
    out = tmp_path / "drum"
    res = sc.simulate(sc.load_scene("drum").replace(mesh_size=0.2),
                      output=sc.Output(out, max_frames=10, pictures=False))
    back = xdmf_frames(out)  # the frames ParaView reads
    k = int(np.argmax(back.contact_measure))  # the frame with the largest patch
    t = float(back.t[k])
    row = int(np.flatnonzero(res.t == t)[0])
    assert 0 < res.contact[row].sum() < len(res.x)

    png = tmp_path / "membrane.png"
    proc = subprocess.run(
        [*command, str(SCRIPT.with_name("paraview_membrane.py")), str(out / "solution.xdmf"), repr(t), str(png)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[:2000] + " ... " + proc.stderr[-1000:]
    (report,) = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert report["class"] == "vtkUnstructuredGrid"
    assert (report["points"], report["cells"]) == (len(res.x), len(res.cells)), report
    assert report["cell_types"] == [5]  # VTK_TRIANGLE
    np.testing.assert_allclose(report["times"], back.t, rtol=1e-12, atol=0)
    assert report["max_warp_error"] < 1e-6  # the points were lifted by eta along z (ParaView stores them as float32)
    assert report["contact_nodes"] == int(res.contact[row].sum())
    assert report["max_z_in_contact"] <= 1e-6  # the nodes marked in contact lie on the floor
    img = np.asarray(Image.open(png).convert("RGB"))
    assert _pixels_near(img, CONTACT_RGB) > 500, "no contact patch drawn in the contact colour"
    bluish = (
        img[..., 2].astype(int) - np.maximum(img[..., 0], img[..., 1]).astype(int)
    ) > 60  # lit: shades of FREE_RGB
    assert int(bluish.sum()) > 1000, "no free membrane drawn"


# --- the folder's own view.py: `pvpython view.py TIME PNG [contact|velocity]` --------------------------------

MIDDLE = (slice(40, 560), slice(120, 850))  # the picture without the colour bar (right) and the axes (lower left)


def _views(command, folder, shots):
    """`pvpython view.py TIME PNG FIELD [TIME PNG FIELD ...]`: every (t, png, field) of `shots` in one ParaView
    session; returns [(report, image)]."""
    from PIL import Image

    groups = [str(a) for t, png, field in shots for a in (float(t), png, field)]
    proc = subprocess.run([*command, str(folder / "view.py"), *groups], capture_output=True, text=True, check=False,
                          cwd=folder)
    assert proc.returncode == 0, proc.stderr[:2000] + " ... " + proc.stderr[-1000:]
    reports = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert len(reports) == len(shots), proc.stdout
    return [(r, np.asarray(Image.open(png).convert("RGB"))) for r, (_, png, _) in zip(reports, shots)]


def _drawn_box(img):
    """The rows and columns of the picture's non-white pixels within MIDDLE's columns."""
    ink = np.any(img[:, MIDDLE[1]].astype(int) < 235, axis=-1)
    rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    return rows.min(), rows.max(), cols.min(), cols.max()


def test_view_py_is_the_packages_program_with_the_runs_numbers(run):
    """The folder's view.py is the package's io/paraview/view.py (a Python file that ruff lints, shipped as
    package data) with only its numbers' lines changed, and it compiles."""
    import fnmatch
    import tomllib
    from importlib import resources

    out, res = run
    program = resources.files("stringcontact.io").joinpath("paraview", "view.py").read_text()
    written = (out / "view.py").read_text()
    compile(written, "view.py", "exec")
    start, end = "# --- the run's numbers", "# --- end of the run's numbers ---"
    assert program.split(start)[0] == written.split(start)[0]
    assert program.split(end)[1] == written.split(end)[1]
    changed = [line for line in written.split(start)[1].split(end)[0].splitlines() if line not in program]
    assert {line.split(" = ")[0] for line in changed} >= {"TITLE", "VELOCITY_RANGE", "BOUNDS", "FOLDER"}, changed
    assert f"VELOCITY_RANGE = [{-float(np.abs(res.velocity).max())!r}" in written
    data = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())
    patterns = data["tool"]["setuptools"]["package-data"]["stringcontact"]
    assert any(fnmatch.fnmatch("io/paraview/view.py", pattern) for pattern in patterns), patterns


@pytest.mark.slow
def test_the_folders_view_keeps_fixed_colour_ranges_at_every_time(tmp_path, run):
    """view.py written by the run: contact on 0 … 1 at t = 0 (all blue) and in contact (red and blue), velocity on
    ±max|v| over all stored rows, the string inside the picture at every time."""
    command = pvpython()
    out, res = run
    text = (out / "view.py").read_text()
    imports = {line.split()[1] for line in text.splitlines() if line.startswith(("import ", "from "))}
    assert imports == {"json", "math", "os", "sys", "paraview.simple"}, imports  # data, not this package's code
    # the folder's own path is data (the image's user is called stringcontact: /tmp/pytest-of-stringcontact/...)
    code = "\n".join(line for line in text.splitlines() if not line.startswith("FOLDER = "))
    assert "stringcontact" not in code.replace("stringcontact run", "")
    speed = float(np.abs(res.velocity).max())
    back = xdmf_frames(out)  # the frames ParaView reads
    k = int(np.argmax([0.3 < c.mean() < 1 for c in back.contact]))  # a frame with contact on part of the string
    times = [0.0, float(back.t[k]), float(back.t[-1])]
    shots = [(t, tmp_path / f"{field}_{t:g}.png", field) for t in times for field in ("contact", "velocity")]
    for (t, _, field), (report, img) in zip(shots, _views(command, out, shots)):
        assert report["field"] == field and report["time"] == pytest.approx(t), report
        top, bottom, _, _ = _drawn_box(img)
        assert top > 0 and bottom < img.shape[0] - 1, f"t = {t}: the string leaves the picture"
        if field == "velocity":
            np.testing.assert_allclose(report["range"], [-speed, speed], rtol=1e-12)
            continue
        assert report["range"] == [0.0, 1.0], report
        middle = img[MIDDLE]
        red, blue = _pixels_near(middle, CONTACT_RGB), _pixels_near(middle, FREE_RGB)
        assert blue > 100, f"t = {t}: no free string drawn"
        if t == 0.0:
            assert red == 0, "t = 0: the string touches nowhere, yet is drawn in the contact colour"
        if t == times[1]:
            assert red > 300, f"t = {t}: no contact drawn in red"


@pytest.mark.slow
def test_the_folders_view_shows_a_membranes_patch_on_the_fixed_range(tmp_path):
    command = pvpython()
    out = tmp_path / "drum"
    res = sc.simulate(sc.load_scene("drum").replace(mesh_size=0.2),
                      output=sc.Output(out, max_frames=10, pictures=False))
    text = (out / "view.py").read_text()
    assert "NORMAL = [0.0, 0.0, 1.0]" in text and "KIND = 'membrane'" in text
    back = xdmf_frames(out)  # the frames ParaView reads
    k = int(np.argmax(back.contact_measure))
    t_k = float(back.t[k])
    shots = [
        (0.0, tmp_path / "drum_0.png", "contact"),
        (t_k, tmp_path / "drum_k.png", "contact"),
        (t_k, tmp_path / "drum_velocity.png", "velocity"),
    ]
    (r0, img0), (rk, imgk), (rv, _) = _views(command, out, shots)
    for t, touching, report, img in ((0.0, False, r0, img0), (t_k, True, rk, imgk)):
        assert report["range"] == [0.0, 1.0], report
        reddish = (img[MIDDLE][..., 0].astype(int) - np.maximum(img[MIDDLE][..., 1], img[MIDDLE][..., 2])) > 60
        bluish = (img[MIDDLE][..., 2].astype(int) - np.maximum(img[MIDDLE][..., 0], img[MIDDLE][..., 1])) > 60
        assert int(bluish.sum()) > 1000, f"t = {t}: no free membrane drawn"
        assert (int(reddish.sum()) > 1000) == touching, f"t = {t}: contact patch {int(reddish.sum())} red pixels"
    speed = float(np.abs(res.velocity).max())
    np.testing.assert_allclose(rv["range"], [-speed, speed], rtol=1e-12)


# --- one camera, the obstacle, the time, the axes, a string at rest seen in velocity ---------------------------

ZERO_RGB = (38, 38, 38)  # view.py's velocity map at v = 0 (its VELOCITY_COLOURS[1])
GREY_RGB = (204, 204, 204)  # the obstacle (view.py's OBSTACLE_GREY)


def _columns(img, rgb, tol=12, least=10):
    """The first and last column left of the colour bar holding at least `least` pixels of colour `rgb` (not a
    letter's smoothed edge)."""
    near = np.all(np.abs(img[:, :850].astype(int) - np.array(rgb)) <= tol, axis=-1)
    cols = np.flatnonzero(near.sum(axis=0) >= least)
    return (int(cols.min()), int(cols.max())) if cols.size else None


def _ink(img, rows, cols):
    """Dark pixels (text, ticks) in the rows and columns given."""
    return int((img[rows, cols].max(axis=-1) < 100).sum())


@pytest.fixture(scope="module")
def drum(tmp_path_factory):
    out = tmp_path_factory.mktemp("paraview") / "drum"
    res = sc.simulate(sc.load_scene("drum").replace(mesh_size=0.2),
                      output=sc.Output(out, max_frames=10, pictures=False))
    return out, res


@pytest.mark.slow
@pytest.mark.parametrize("which", ["string", "membrane"])
def test_the_folders_view_keeps_one_camera_and_draws_the_obstacle_time_and_axes(tmp_path, run, drum, which):
    """The camera frames every time step and does not move (paraview.simple's reset on the first render is
    off); the obstacle is drawn in grey, the time in the upper left corner, the title and the named axes."""
    command = pvpython()
    out, res = run if which == "string" else drum
    times = [0.0, float(res.t[len(res.t) // 4]), float(res.t[-1])]
    shots = [(t, tmp_path / f"{which}_{k}.png", "contact") for k, t in enumerate(times)]
    views = _views(command, out, shots)
    cameras = [report["camera"] for report, _ in views]
    assert cameras[0] == cameras[1] == cameras[2], cameras
    obstacle = [_columns(img, GREY_RGB) for _, img in views]
    assert obstacle[0] is not None and obstacle[0] == obstacle[1] == obstacle[2], obstacle  # drawn, and in place
    for (report, img), t in zip(views, times):
        assert report["axes"] == (["x", "eta", ""] if which == "string" else ["x", "y", "eta"]), report
        grey = int(np.all(np.abs(img.astype(int) - np.array(GREY_RGB)) <= 12, axis=-1).sum())
        assert grey > 5000, f"t = {t}: obstacle {grey} pixels"
        assert _ink(img, slice(0, 30), slice(0, 120)) > 20, f"t = {t}: no time label in the upper left corner"
        assert _ink(img, slice(0, 30), slice(300, 700)) > 100, f"t = {t}: no title"
    labels = [img[0:30, 0:120] for _, img in views]
    assert not np.array_equal(labels[0], labels[1]) and not np.array_equal(labels[1], labels[2]), (
        "the time label does not change"
    )
    if which == "string":
        # the string spans x = 0 ... 1 at every time: the same columns (the camera used to follow the shape)
        strings = [_string_columns(img) for _, img in views]
        assert np.ptp(np.array(strings), axis=0).max() <= 3, (
            strings
        )  # to the line's round ends (was 537 against 420 px wide)
        # the 1D string fills the picture's width left of the colour bar (its heights stretched to fit), not a
        # narrow column of it
        left, right = strings[0]
        assert (right - left) / img.shape[1] > 0.65, strings
        assert views[0][0]["scale"][1] != 1.0 and views[0][0]["scale"][::2] == [1.0, 1.0], views[0][0]["scale"]
        left, _ = obstacle[0]
        assert _ink(img, slice(40, 560), slice(0, left - 5)) > 50, "no tick labels left of the string"


def _string_columns(img):
    """The first and last column of the string drawn in the contact map (blue free, red in contact)."""
    strong = np.abs(img[..., 0].astype(int) - img[..., 2].astype(int)) > 80
    cols = np.flatnonzero(strong[40:560].any(axis=0)[:850])
    return int(cols.min()), int(cols.max())


@pytest.mark.slow
def test_a_string_at_rest_is_seen_when_coloured_by_velocity(tmp_path, run):
    """Coloured by velocity, where v = 0 (the string lying on the obstacle) the string is drawn in the map's
    dark middle, which stands out on the white background and on the grey obstacle."""
    command = pvpython()
    out, res = run
    back = xdmf_frames(out)  # the frames ParaView reads
    resting = back.contact & (np.abs(back.velocity) < 0.02 * np.abs(res.velocity).max())
    k = int(np.argmax(resting.sum(axis=1)))  # the frame with the most nodes lying at rest on the obstacle
    nodes = np.flatnonzero(resting[k])
    assert len(nodes) > 20, resting.sum(axis=1)
    ((_, img),) = _views(command, out, [(float(back.t[k]), tmp_path / "velocity.png", "velocity")])
    left, right = _columns(img, GREY_RGB)
    x = back.x[nodes[len(nodes) // 2]]  # a node at rest, in the middle of the resting ones
    column = img[:, round(left + (x - back.x[0]) / (back.x[-1] - back.x[0]) * (right - left))].astype(int)
    grey_rows = np.flatnonzero(np.all(np.abs(column - np.array(GREY_RGB)) <= 12, axis=-1))
    top = int(grey_rows.min())  # the obstacle's top edge, where the string lies
    string = column[max(top - 8, 0) : top + 9]  # the line lies on ψ, half of it over the grey
    contrast = np.abs(string - 255).sum(axis=-1).max()  # the string's darkest pixel against the white background
    assert contrast > 450, f"the string at rest ({string.tolist()}) is hardly seen on white"
    thick = int((np.abs(string - np.array(ZERO_RGB)).max(axis=-1) <= 40).sum())
    assert thick >= 3, f"the string at rest is {thick} px thick in v = 0's colour: {string.tolist()}"


# --- a film's membrane coloured by its pressure ----------------------------------------------------------------


@pytest.mark.slow
def test_the_folders_view_colours_a_film_membrane_by_its_pressure(tmp_path):
    """A membrane on a fluid film (model "film"): `view.py T PNG pressure` colours it by p − p_a on ±max|p − p_a|
    over all stored rows, in the colours its output field declares: a middle grey where p = p_a (all of it at
    t = 0, where contact colours it blue), red where the squeezed film pushes it up."""
    command = pvpython()
    out = tmp_path / "film_drum"
    res = sc.simulate(
        sc.load_scene("film_drum").replace(cells=[8, 8], T=0.12, nt=48, output_times=[]),
        output=sc.Output(out, max_frames=7, pictures=False),
    )
    assert 'Attribute Name="pressure"' in (out / "solution.xdmf").read_text()
    back = xdmf_frames(out)  # the frames ParaView reads
    pressure = res.fields["pressure"]
    k = int(np.argmax([np.abs(pressure[np.flatnonzero(res.t == t)[0]]).max() for t in back.t]))
    t_k = float(back.t[k])
    shots = [
        (0.0, tmp_path / "pressure_0.png", "pressure"),
        (0.0, tmp_path / "contact_0.png", "contact"),
        (t_k, tmp_path / "pressure_k.png", "pressure"),
    ]
    (r0, img0), (_, contact0), (rk, imgk) = _views(command, out, shots)
    peak = float(np.abs(pressure).max())
    for report in (r0, rk):
        assert report["field"] == "pressure"
        np.testing.assert_allclose(report["range"], [-peak, peak], rtol=1e-12)

    def counts(img):
        img = img[MIDDLE].astype(int)
        red = (img[..., 0] - np.maximum(img[..., 1], img[..., 2])) > 60
        blue = (img[..., 2] - np.maximum(img[..., 0], img[..., 1])) > 60
        grey = (
            (np.ptp(img, axis=-1) < 12) & (img.max(axis=-1) > 50) & (img.max(axis=-1) < 185)
        )  # lit; not the obstacle's 204
        return int(red.sum()), int(blue.sum()), int(grey.sum())

    assert np.abs(pressure[0]).max() == 0.0
    red0, blue0, grey0 = counts(img0)
    assert red0 == blue0 == 0 and grey0 > 5000, (red0, blue0, grey0)  # p = p_a: the whole membrane grey, and seen
    assert counts(contact0)[1] > 5000  # the same frame coloured by contact: blue (free)
    redk, _, _ = counts(imgk)
    assert redk > 500, redk  # the film's peak pressure under the falling skin
    # its colour bar is on its symmetric-log scale: ticks at 0, +-linthresh and a decade apart up to +-peak, evenly
    # spaced on the bar, each named by the pressure there
    ticks = [float(label) for label in rk["ticks"]]
    above = [t for t in ticks if t > 0]
    assert ticks == sorted(ticks) and 0.0 in ticks and above[-1] == pytest.approx(peak, rel=1e-2), ticks
    np.testing.assert_allclose(np.array(above[1:]) / np.array(above[:-1]), 10.0, rtol=1e-2)
    assert ticks == [-t for t in reversed(ticks)]
    rows = _bar_label_rows(imgk)
    assert len(rows) == len(ticks), (rows, ticks)
    assert np.ptp(np.diff(rows)) <= 3, rows  # a decade takes the same length of the bar


def _bar_label_rows(img):
    """The first row of each label left of the colour bar (the bar: the right part's strongly coloured columns)."""
    from scipy import ndimage

    colour = (img.max(axis=-1).astype(int) - img.min(axis=-1)) > 60
    bar = np.flatnonzero(colour[:, 850:].sum(axis=0) > 100) + 850
    ink = (img[:, bar.min() - 75 : bar.min() - 2].max(axis=-1) < 120).any(axis=1)
    labels, n = ndimage.label(ink)
    return [int(np.flatnonzero(labels == k).min()) for k in range(1, n + 1)]


@pytest.mark.slow
def test_a_users_output_field_is_in_paraview_and_coloured_by_its_own_range_and_colours(tmp_path):
    """A model of the user's with a derived output field `reaction` (η², from black to pure red): solution.xdmf
    carries it, every reader of the README's recipe gives its values at the time shown, and `view.py T PNG
    reaction` colours the string by it on its least … largest value over all stored rows, red where it is large."""
    import dataclasses

    from stringcontact.model.interface import OutputField
    from stringcontact.model.interface import inelastic

    command = pvpython()
    field = OutputField("reaction", expression=lambda U, p: U[0] ** 2, label="reaction", colours=((0, 0, 0), (1, 0, 0)))
    out = tmp_path / "reacting"
    res = sc.simulate(
        sc.load_scene("example1").replace(nx=200, nt=600),
        output=sc.Output(out, max_frames=10, pictures=False),
        model=dataclasses.replace(inelastic, name="reacting", outputs=(field,)),
    )
    assert 'Attribute Name="reaction"' in (out / "solution.xdmf").read_text()
    back = xdmf_frames(out)  # the frames ParaView reads
    t = float(back.t[0])
    proc = subprocess.run(
        [*command, str(SCRIPT), str(out / "solution.xdmf"), repr(t), str(tmp_path / "readme.png")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[:2000] + " ... " + proc.stderr[-1000:]
    reports = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert len(reports) == 3
    at_t = res.fields["reaction"][0]
    for report in reports:
        assert set(report["arrays"]) == {*FIELDS, "reaction"}, report["reader"]
        np.testing.assert_allclose(report["ranges"]["reaction"], [at_t.min(), at_t.max()], rtol=1e-12)
    ((report, img),) = _views(command, out, [(t, tmp_path / "reaction.png", "reaction")])
    np.testing.assert_allclose(
        report["range"], [res.fields["reaction"].min(), res.fields["reaction"].max()], rtol=1e-12
    )
    middle = img[MIDDLE].astype(int)
    red = (middle[..., 0] > 150) & (middle[..., 1] < 40) & (middle[..., 2] < 40)
    assert red.sum() > 100, "no string drawn in the field's high colour"


@pytest.mark.slow
def test_the_folders_view_draws_a_moving_obstacle_where_it_is_at_the_time_shown(tmp_path, piston_folder):
    """The piston rises from ψ = 0 to 0.3 by t = 0.15: the top of the grey region is where ψ is at each time
    (from solution.xdmf's `obstacle` field), under one camera whose box holds the obstacle at every time."""
    command = pvpython()
    out, res = piston_folder
    times = [0.0, 0.1, 0.3]
    views = _views(command, out, [(t, tmp_path / f"piston_{k}.png", "contact") for k, t in enumerate(times)])
    cameras = [report["camera"] for report, _ in views]
    assert cameras[0] == cameras[1] == cameras[2], cameras
    tops = []
    for (report, img), t in zip(views, times):
        grey = np.all(np.abs(img[MIDDLE[0], :850].astype(int) - np.array(GREY_RGB)) <= 12, axis=-1)  # not the title
        centre = int(np.argmax(grey.sum(axis=0)))  # a column through the piston: the tallest grey column
        rows = np.flatnonzero(grey[:, centre])
        # the longest grey run (from the floor up), not an axis line's or a tick label's smoothed edge
        runs = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
        top = MIDDLE[0].start + int(max(runs, key=len)[0])
        cam, half = report["camera"], img.shape[0] / 2
        psi = float(res.scene.obstacle_values(np.array([0.5]), t)[0])
        expected = half - (psi * report["scale"][1] - cam["focal_point"][1]) * half / cam["parallel_scale"]
        assert abs(top - expected) <= 4, (
            f"t = {t}: the obstacle's top at row {top}, psi = {psi} is at row {expected:.1f}"
        )
        tops.append(top)
    assert tops[0] - tops[2] > 50, tops  # it rose on the picture


@pytest.mark.slow
def test_the_folders_view_draws_a_membranes_moving_obstacle_at_the_time_shown(tmp_path):
    """A dome rising under a coarse drum (ψ = 0.25 min(t/0.3, 1)(1 − r²)): the grey surface ParaView draws at each
    time (its box, reported by view.py) has ψ's top at that time, 1 % of the height range lower."""
    command = pvpython()
    out = tmp_path / "dome"
    scene = sc.load_scene("drum").replace(
        mesh_size=0.2, T=0.4, nt=80, output_times=[0.0, 0.2, 0.4], obstacle="0.25*min(t/0.3, 1)*(1 - x**2 - y**2)"
    )
    res = sc.simulate(scene, output=sc.Output(out, max_frames=6, pictures=False))
    times = [0.0, 0.2, 0.4]
    views = _views(command, out, [(t, tmp_path / f"dome_{k}.png", "contact") for k, t in enumerate(times)])
    assert views[0][0]["camera"] == views[-1][0]["camera"]
    bounds = json.loads((out / "view.py").read_text().split("BOUNDS = ", 1)[1].split("  #", 1)[0])
    drop = 0.01 * (bounds[5] - bounds[4])
    tops = []
    for (report, _), t in zip(views, times):
        top = float(res.scene.obstacle_values(res.x, t).max())
        assert abs(report["obstacle"][5] - (top - drop)) < 1e-6, (t, report["obstacle"], top - drop)
        tops.append(report["obstacle"][5])
    assert tops[-1] - tops[0] > 0.2, tops
    assert bounds[5] >= tops[-1]  # the camera's box holds the risen dome
