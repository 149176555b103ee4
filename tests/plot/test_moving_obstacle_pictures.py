"""A moving obstacle ψ(x, t) in the pictures: space_time.png draws the surface ψ(x, t), membrane.png's panels
and membrane.gif's frames draw ψ at their own times, snapshots.png's panels too. Drawn with pyvista off-screen
(and matplotlib); the meshes handed to the plotter are recorded and compared with the scene's ψ."""

from __future__ import annotations

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.plot import charts, membrane, mesh_pictures, style, vtk_start

#: the piston rises from ψ = 0 to 0.3 by t = 0.15 on |x − 1/2| < 0.2; a coarse, short run
SMALL_PISTON = {"nx": 40, "T": 0.3, "nt": 75, "output_times": [0.0, 0.1, 0.15, 0.3]}
#: a coarse drum whose obstacle, a dome, rises from the plane 0 to 0.25 at its centre by t = 0.3
RISING_DOME = {"mesh_size": 0.2, "T": 0.4, "nt": 80, "output_times": [0.0, 0.1, 0.2, 0.4],
               "obstacle": "0.25*min(t/0.3, 1)*(1 - x**2 - y**2)"}


@pytest.fixture(scope="module")
def piston():
    return sc.simulate(sc.load_scene("piston").replace(**SMALL_PISTON), output=sc.Output(progress=False))


@pytest.fixture(scope="module")
def dome():
    return sc.simulate(sc.load_scene("drum").replace(**RISING_DOME), output=sc.Output(progress=False))


@pytest.fixture
def drawn(monkeypatch):
    """The (mesh, keywords) of every `add_mesh` of the pictures drawn while the test runs."""
    meshes = []
    plotter = mesh_pictures._plotter

    def recording(*args, **kwargs):
        p = plotter(*args, **kwargs)
        add_mesh = p.add_mesh

        def add(mesh, *a, **kw):
            meshes.append((mesh.copy(), kw))
            return add_mesh(mesh, *a, **kw)

        p.add_mesh = add
        return p

    monkeypatch.setattr(mesh_pictures, "_plotter", recording)
    return meshes


def _in_colour(meshes, colour):
    return [mesh for mesh, kw in meshes if kw.get("color") == colour]


def test_the_space_time_surface_draws_the_obstacle_as_the_surface_psi_x_t(piston, drawn, tmp_path):
    assert piston.scene.obstacle_moves
    charts.picture(mesh_pictures.space_time_figure, piston, tmp_path / "space_time.png")
    assert (tmp_path / "space_time.png").stat().st_size > 0
    (obstacle,) = _in_colour(drawn, style.OBSTACLE_COLOUR)
    points = np.asarray(obstacle.points)
    centre = np.abs(points[:, 0] - 0.5) < 1e-9  # the piston's middle, at every drawn time
    depth, z = points[centre, 1], points[centre, 2]
    order = np.argsort(-depth)  # t = 0 at the back (depth 0), later times in front (negative depth)
    assert np.unique(np.round(depth, 12)).size > 2, "a band over t (ψ(x, 0) at every t), not the surface ψ(x, t)"
    # z is ψ(1/2, t) on the drawing's scale: it rises with t until the piston stops, by 0.3 in η
    psi = piston.scene.obstacle_values(np.array([0.5]), 0.0)[0], piston.scene.obstacle_values(np.array([0.5]), 0.3)[0]
    assert psi == (0.0, 0.3)
    rise = z[order][-1] - z[order][0]
    assert rise > 0 and np.all(np.diff(z[order]) >= -1e-12), z[order]
    eta_surface = next(mesh for mesh, kw in drawn if kw.get("scalars") == "contact")
    eta_z = np.asarray(eta_surface.points)[:, 2]
    height = np.ptp(eta_z) / np.ptp(piston.eta[:, :])  # the drawing's scale of η (both drawn the same)
    assert np.isclose(rise, 0.3 * height, rtol=0.05), (rise, 0.3 * height)


def test_an_obstacle_at_rest_is_still_a_band_over_t(drawn, tmp_path):
    res = sc.simulate(sc.load_scene("example1").replace(nx=60, nt=600), output=sc.Output(progress=False))
    charts.picture(mesh_pictures.space_time_figure, res, tmp_path / "space_time.png")
    (obstacle,) = _in_colour(drawn, style.OBSTACLE_COLOUR)
    assert np.unique(np.round(np.asarray(obstacle.points)[:, 1], 12)).size == 2  # t = 0 and T only


def test_each_membrane_panel_draws_the_obstacle_at_its_time(dome, monkeypatch, tmp_path):
    """Each panel is rendered after `show_row` moved the membrane and the obstacle to its row: ψ at its time."""
    assert dome.scene.obstacle_moves
    shown, show_row = [], membrane.show_row

    def recording(surface, result, row, view):
        show_row(surface, result, row, view)
        shown.append((row, np.asarray(view.obstacle.points)[:, 2].copy()))

    monkeypatch.setattr(membrane, "show_row", recording)  # the panels and the GIF's frames alike
    charts.picture(mesh_pictures.membrane_figure, dome, tmp_path / "membrane.png")
    rows = charts.snapshot_rows(dome)
    assert [row for row, _ in shown] == rows
    view = membrane.membrane_view(dome)
    lo, hi = view.bounds[4] / view.scale, view.bounds[5] / view.scale
    tops = []
    for row, heights in shown:
        psi = dome.scene.obstacle_values(dome.x, float(dome.t[row]))
        expected = psi * view.scale - membrane._below(lo, hi, view.scale)
        np.testing.assert_allclose(heights, expected, atol=1e-12, err_msg=f"t = {dome.t[row]}")
        tops.append(float(np.max(expected)))
    assert tops[0] < tops[-1] - 0.2 * view.scale, tops  # the dome rose between the first and the last panel
    assert view.bounds[5] >= 0.25 * view.scale * 0.9  # the box holds the risen dome


def test_the_gifs_frames_move_the_obstacle_with_the_time(dome):
    pv = vtk_start._pyvista()
    view = membrane.membrane_view(dome)
    p = pv.Plotter(off_screen=True, window_size=(200, 150))
    try:
        surface = membrane.add_membrane(p, dome, 0, view)
        assert view.obstacle is not None
        lo, hi = view.bounds[4] / view.scale, view.bounds[5] / view.scale
        for row in (len(dome.t) // 2, len(dome.t) - 1):
            membrane.show_row(surface, dome, row, view)
            psi = dome.scene.obstacle_values(dome.x, float(dome.t[row]))
            np.testing.assert_allclose(view.obstacle.points[:, 2], psi * view.scale - membrane._below(lo, hi, view.scale), atol=1e-12)
    finally:
        p.close()


def test_the_snapshots_shade_the_obstacle_where_it_is_at_each_panels_time(piston, tmp_path, monkeypatch):
    fills = []
    import matplotlib.axes

    fill_between = matplotlib.axes.Axes.fill_between

    def recording(self, x, y1, y2=0, **kw):
        fills.append(np.array(y2, dtype=float))
        return fill_between(self, x, y1, y2, **kw)

    monkeypatch.setattr(matplotlib.axes.Axes, "fill_between", recording)
    charts.picture(charts.snapshots_figure, piston, tmp_path / "snapshots.png")
    rows = charts.snapshot_rows(piston)
    assert len(fills) >= len(rows)
    for psi, row in zip(fills, rows):
        np.testing.assert_allclose(psi, piston.scene.obstacle_values(piston.x, float(piston.t[row])))
