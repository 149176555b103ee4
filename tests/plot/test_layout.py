"""The pictures fit for a paper: every text inside the figure and clear of the others, a title of one line that says
what the picture shows, the run's details in a caption that names ε only for a contact law that reads it; at the
screen's size, in the paper style (7 inches wide) and at a journal column's width (3.4 inches). Measured with
matplotlib's renderer (`Artist.get_window_extent`) on the figures the pictures are saved from: Example 1 (1D),
the drum (2D) and output fields' pictures (a shipped model's and a plugin's)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.plot import charts, fields, mesh_pictures
from stringcontact.plot.style import Look

LOOKS = {"screen": Look(), "paper": Look(style="paper"), "column": Look(style="paper", size=(3.4, 2.8))}


@pytest.fixture(scope="module")
def example1():
    return sc.simulate(sc.load_scene("example1").replace(nx=80, nt=600), storage=sc.Storage(max_rows=60))


@pytest.fixture(scope="module")
def drum():
    return sc.simulate(sc.load_scene("drum").replace(mesh_size=0.2, T=0.3, nt=60, output_times=[0.0, 0.1, 0.15, 0.2, 0.3]))


@pytest.fixture(scope="module")
def stiff():
    """A string with an output field of its model (stiff_string's curvature)."""
    return sc.simulate(sc.load_scene("example1").replace(nx=60, nt=600, model="stiff_string",
                                                         parameters={"beta": 1e-4}), storage=sc.Storage(max_rows=60))


def _texts(fig) -> list:
    """Every text of `fig` that is drawn and not empty, its legends each as one box (their texts are inside them);
    of the tick labels those of the ticks drawn (`Axis._update_ticks`: within the axis' limits)."""
    from matplotlib.legend import Legend
    from matplotlib.text import Text

    legends = fig.findobj(Legend)
    inside = {id(t) for legend in legends for t in [*legend.get_texts(), legend.get_title()]}
    drawn = _tick_labels(fig)
    every = {id(label) for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)
             for tick in axis.get_major_ticks() + axis.get_minor_ticks() for label in (tick.label1, tick.label2)}
    texts = [t for t in fig.findobj(Text) if id(t) not in inside and (id(t) not in every or id(t) in drawn)
             and t.get_visible() and t.get_text().strip()]
    return texts + [legend for legend in legends if legend.get_visible()]


def _tick_labels(fig) -> set[int]:
    """The ids of the tick labels `fig` draws: they may touch each other (never anything else)."""
    return {id(label) for ax in fig.axes if ax.get_visible() and ax.axison for axis in (ax.xaxis, ax.yaxis)
            for tick in axis._update_ticks() for label in (tick.label1, tick.label2)}


def layout_problems(fig) -> list[str]:
    """What is wrong with `fig`'s words, drawn: a text outside the figure, two texts (a legend as one) that overlap
    (tick labels only among themselves may), a title of more than one line."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    whole = fig.bbox
    texts = _texts(fig)
    boxes = [(t, t.get_window_extent(renderer)) for t in texts]
    problems = []
    for t, b in boxes:
        if b.x0 < whole.x0 - 1 or b.y0 < whole.y0 - 1 or b.x1 > whole.x1 + 1 or b.y1 > whole.y1 + 1:
            problems.append(f"outside the figure: {_name(t)} {b.bounds} in {whole.bounds}")
    ticks = _tick_labels(fig)
    for (s, a), (t, b) in itertools.combinations(boxes, 2):
        if id(s) in ticks and id(t) in ticks:
            continue
        if a.overlaps(b) and min(a.width, b.width, a.height, b.height) > 0:
            overlap = min(a.x1, b.x1) - max(a.x0, b.x0), min(a.y1, b.y1) - max(a.y0, b.y0)
            if min(overlap) > 1:  # a pixel's anti-aliasing aside
                problems.append(f"overlap: {_name(s)} and {_name(t)}")
    title = fig._suptitle
    if title is None or "\n" in title.get_text() or not title.get_text().strip():
        problems.append(f"the title is not one line: {title and title.get_text()!r}")
    return problems


def _name(artist) -> str:
    text = artist.get_text() if hasattr(artist, "get_text") else "legend: " + " / ".join(t.get_text() for t in artist.get_texts())
    return repr(text[:60])


def _check(figure_of, result, look, *args):
    with look.drawn():
        made = figure_of(result, *args, look) if args else figure_of(result, look)
        fig = made[0] if isinstance(made, tuple) else made
        assert layout_problems(fig) == []


ONE_D = {"contact_set": charts.contact_set_figure, "velocity_field": charts.velocity_figure,
         "snapshots": charts.snapshots_figure, "energy": charts.energy_figure,
         "space_time": mesh_pictures.space_time_figure}
TWO_D = {"membrane": mesh_pictures.membrane_figure, "contact_area": charts.contact_area_figure,
         "energy": charts.energy_figure}


@pytest.mark.slow
@pytest.mark.parametrize("look", LOOKS, ids=list(LOOKS))
@pytest.mark.parametrize("picture", ONE_D, ids=list(ONE_D))
def test_example1s_pictures_keep_their_words_inside_and_apart(example1, picture, look):
    _check(ONE_D[picture], example1, LOOKS[look])


@pytest.mark.slow
@pytest.mark.parametrize("look", LOOKS, ids=list(LOOKS))
@pytest.mark.parametrize("picture", TWO_D, ids=list(TWO_D))
def test_the_drums_pictures_keep_their_words_inside_and_apart(drum, picture, look):
    _check(TWO_D[picture], drum, LOOKS[look])


@pytest.mark.slow
@pytest.mark.parametrize("look", LOOKS, ids=list(LOOKS))
def test_a_models_field_picture_keeps_its_words_inside_and_apart(stiff, look):
    _check(lambda result, look: fields.field_figure(result, look, name="curvature"), stiff, LOOKS[look])


def test_the_checker_finds_a_cut_title_and_a_legend_over_a_title():
    """The measure can fail: a two-line title, a text past the figure's edge, a legend over an axes' title."""
    fig = charts.figure((3.0, 2.0))
    ax = fig.add_subplot()
    fig.suptitle("two\nlines")
    ax.set_title("a title under the legend")
    ax.plot([0, 1], label="a curve with a label long enough")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, 1.15))
    fig.text(0.9, 0.5, "this text runs past the right edge of the figure")
    problems = layout_problems(fig)
    assert any(p.startswith("outside the figure: 'this text runs past") for p in problems), problems
    assert any(p.startswith("overlap:") and "a title under the legend" in p for p in problems), problems
    assert any(p.startswith("the title is not one line") for p in problems), problems


# --- the run's details --------------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["film", "cubic_foundation", None])
def test_the_details_name_the_model_and_the_scheme_once(model):
    from types import SimpleNamespace

    scene = SimpleNamespace(name="s", nx=40, dt=1e-3, alpha=0.1, eps=1e-3)
    result = SimpleNamespace(scene=scene, x=np.linspace(0, 1, 41), model=model, scheme="paper", penalty="explicit",
                             mass="lumped")
    line = charts.parameter_line(result)
    assert line.count(f"model {model or 'inelastic'}") == 1 and line.count("scheme paper") == 1, line
    assert "ε = 0.001" in line and "Δt/ε = 1" in line


def test_a_contact_law_without_eps_is_shown_without_eps(tmp_path, capsys):
    """soft_ground's ground spring reads its own k and c, not ε: its run records so (summary.json), and neither its
    pictures' caption nor the report names ε or Δt/ε; the paper's law reads ε and is shown with it."""
    import json

    from stringcontact.model.registry import registered

    if "soft_ground" not in registered():
        pytest.skip("examples/soft_ground is not installed (scripts/setup installs it)")
    scene = sc.load_scene("example1").replace(nx=40, nt=600, model="soft_ground")
    ground = sc.simulate(scene, output=sc.Output(tmp_path / "ground", pictures=False))
    paper = sc.simulate(scene.replace(model=None))
    assert not ground.law_reads_eps and paper.law_reads_eps
    assert json.loads((tmp_path / "ground" / "summary.json").read_text())["law_reads_eps"] is False
    from stringcontact.io.readback import read_output

    assert read_output(tmp_path / "ground").law_reads_eps is False
    assert "ε =" not in charts.parameter_line(ground) and "Δt/ε" not in charts.parameter_line(ground)
    assert "reads no ε" in charts.parameter_line(ground)
    assert "ε = 0.0005" in charts.parameter_line(paper)
    fig, _ = charts.contact_set_figure(ground)
    assert "ε =" not in fig._supxlabel.get_text() and "ε" not in fig._suptitle.get_text()
    from stringcontact.cli.report import report

    report(ground)
    first = capsys.readouterr().out.splitlines()[0]
    assert "eps=" not in first and " r=" not in first and "reads no eps" in first, first
    report(paper)
    assert "eps=0.0005 r=1" in capsys.readouterr().out.splitlines()[0]


def test_the_3d_pictures_axis_labels_are_the_membranes_size(example1, monkeypatch, tmp_path):
    """space_time.png's x, t and η labels were 11 points (digits 8 px high); they are the membrane's 16 (12 px)."""
    from stringcontact.plot import membrane

    sizes, draw = [], mesh_pictures.add_axis

    def spy(p, axis, font_size=11, most=5, zoom=1.0):
        sizes.append(round(font_size * zoom))
        return draw(p, axis, font_size, most, zoom)

    monkeypatch.setattr(mesh_pictures, "add_axis", spy)
    charts.picture(mesh_pictures.space_time_figure, example1, tmp_path / "space_time.png")
    assert len(sizes) == 3 and min(sizes) >= membrane.TICK_FONT == 16, sizes
