"""The pyvista pictures' title (`annotations._title`) is pyvista's add_text(position="upper_edge"), pixel for
pixel, at the size vtkCornerAnnotation would pick, whether the search stops at its cap or at the panel's height."""

from __future__ import annotations

import numpy as np
import pytest

from stringcontact.plot import annotations, vtk_start

pytest.importorskip("pyvista")

TEXTS = {
    "one line": "Space-time surface η(x, t): example1",
    "four lines": "Space-time surface η(x, t): example1\nα = 0.1, ε = 0.001\nheight η from -0.1 to 1\nred: η ≤ ψ",
    "ten lines": "\n".join(f"line {k}: η ≤ ψ" for k in range(10)),
}


def _shot(window_size, text, draw, panels=None):
    """The picture of `text` drawn by `draw(p, text)` in a white plotter (in its title row if `panels`)."""
    layout = {} if panels is None else {"shape": (panels, 1), "groups": [(0, np.s_[:])], "row_weights": [0.25] + [1] * (panels - 1)}
    p = vtk_start._plotter(window_size, **layout)
    p.subplot(0, 0)
    draw(p, text)
    image = p.screenshot(None, return_img=True)
    p.close()
    return image


def _pyvistas(p, text):
    p.add_text(text, position="upper_edge", font_size=9, color="black", font_file=vtk_start._font_file())


@pytest.mark.parametrize("text", TEXTS, ids=list(TEXTS))
@pytest.mark.parametrize(("window_size", "panels"), [((1100, 900), None), ((1100, 900), 3), ((300, 200), None), ((64, 48), None)])
def test_the_title_is_pyvistas_upper_edge_text_pixel_for_pixel(window_size, panels, text):
    ours = _shot(window_size, TEXTS[text], annotations._title, panels)
    theirs = _shot(window_size, TEXTS[text], _pyvistas, panels)
    assert np.array_equal(ours, theirs), f"{int((ours != theirs).any(axis=-1).sum())} pixels differ"


@pytest.mark.parametrize(("window_size", "panels", "capped"), [((1100, 900), None, True), ((1100, 900), 3, False)])
def test_the_search_ends_at_its_cap_or_at_the_panels_height(window_size, panels, capped):
    """Both ends of the annotation's search are taken: the full window lets the four lines grow to the cap,
    the title row of three panels (a fifth of the height) stops them below it."""
    from vtkmodules.vtkRenderingCore import vtkTextMapper

    p = vtk_start._plotter(window_size, **({} if panels is None else {"shape": (panels, 1)}))
    mapper = vtkTextMapper()
    mapper.SetInput(TEXTS["four lines"])
    mapper.SetTextProperty(vtk_start._pyvista().TextProperty(font_file=vtk_start._font_file()))
    height = p.renderer.GetSize()[1]
    size = annotations._annotation_size(mapper, p.renderer, int(0.9 * height))
    p.close()
    assert (size == annotations.ANNOTATION["FIT"]) is capped, size
    assert 0 < size <= annotations.ANNOTATION["FIT"]


@pytest.mark.parametrize("model", ["film", "cubic_foundation", None])
def test_the_parameter_line_names_the_model_and_the_scheme_once(model):
    from types import SimpleNamespace

    from stringcontact.plot.charts import parameter_line

    scene = SimpleNamespace(nx=40, dt=1e-3, alpha=0.1, eps=1e-3)
    result = SimpleNamespace(scene=scene, x=np.linspace(0, 1, 41), model=model, scheme="paper", penalty="explicit",
                             mass="lumped")
    line = parameter_line(result)
    assert line.count(f"model {model or 'inelastic'}") == 1 and line.count("scheme paper") == 1, line
