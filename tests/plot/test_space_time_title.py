"""space_time.png's title gives η's own range, not the drawn box's (a profiled obstacle's range and its round-off:
tests/plot/test_viz.py)."""

import re

import matplotlib.image as mpimg

import stringcontact as sc
from stringcontact.plot import mesh_pictures


def _title_of(result, path, monkeypatch) -> str:
    titles = []
    draw = mesh_pictures._title
    monkeypatch.setattr(mesh_pictures, "_title", lambda p, text, *a, **k: (titles.append(text), draw(p, text, *a, **k)))
    mesh_pictures.space_time_picture(result, path)
    assert mpimg.imread(path).shape[0] > 100  # the picture itself, read back
    return titles[0]


def test_a_run_above_the_obstacle_has_its_own_height_range_in_the_title(tmp_path, monkeypatch):
    """Example 1 stopped before the landing: η ≥ 0.9 throughout, so the title's η starts there, not at the flat
    obstacle's 0 that the drawn box includes."""
    res = sc.simulate(sc.load_scene("example1").replace(nx=100, T=0.01, nt=20, output_times=[]))
    assert res.eta.min() > 0.5
    title = _title_of(res, tmp_path / "space_time.png", monkeypatch)
    low, high = (float(v) for v in re.search(r"η from (\S+) to (\S+) over x and t", title).groups())
    assert low == float(f"{res.eta.min():.3g}") and high == float(f"{res.eta.max():.3g}"), title
    assert "ψ from" not in title  # the paper's flat obstacle: no range of its own
