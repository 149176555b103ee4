"""space_time.png's caption gives η's own range, not the drawn box's (a profiled obstacle's range and its round-off:
tests/plot/test_viz.py)."""

import re

import matplotlib.image as mpimg

import stringcontact as sc
from stringcontact.plot import charts, mesh_pictures


def test_a_run_above_the_obstacle_has_its_own_height_range_in_the_caption(tmp_path):
    """Example 1 stopped before the landing: η ≥ 0.9 throughout, so the caption's η starts there, not at the flat
    obstacle's 0 that the drawn box includes."""
    res = sc.simulate(sc.load_scene("example1").replace(nx=100, T=0.01, nt=20, output_times=[]))
    assert res.eta.min() > 0.5
    fig, _ = mesh_pictures.space_time_figure(res)
    text = fig._supxlabel.get_text()
    low, high = (float(v) for v in re.search(r"η from (\S+) to (\S+) over x and t", text).groups())
    assert low == float(f"{res.eta.min():.3g}") and high == float(f"{res.eta.max():.3g}"), text
    assert "ψ from" not in text  # the paper's flat obstacle: no range of its own
    charts.picture(mesh_pictures.space_time_figure, res, tmp_path / "space_time.png")
    assert mpimg.imread(tmp_path / "space_time.png").shape[:2] == (900, 1100)  # the picture itself, read back
