"""The checks and legends belong to the model's contact law: the penetration bound only for a law that has
one (`Model.penetration_bound`), the stored energy's legend from `Model.energy_label`."""

from __future__ import annotations

import dataclasses
import json

import pytest
import ufl

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.cli.report import _fmt_penetration_line
from stringcontact.io.readback import read_output
from stringcontact.model.interface import penetration_bound_of
from stringcontact.model.variants import elastic, loaded_obstacle
from stringcontact.run import checks
from stringcontact.run.checks import penetration_check

QUICK = ["--no-progress", "--no-pictures"]


GROUND_K = 1e4


def _stiff_ground(eta, v, p):
    """A user's own law: a spring of stiffness 1e4 below y = 0, with no known penetration bound."""
    return GROUND_K * ufl.max_value(-eta, 0)


def _ground_energy(eta, p):
    return GROUND_K / 2 * ufl.max_value(-eta, 0) ** 2


def test_each_law_names_its_bound():
    assert penetration_bound_of(sc.inelastic) == "velocity"
    assert penetration_bound_of(loaded_obstacle) == "velocity"
    assert penetration_bound_of(elastic) == "spring"
    mine = dataclasses.replace(sc.inelastic, name="mine", penalty=_stiff_ground, penalty_damping=None)
    assert penetration_bound_of(mine) is None  # the paper's bound does not follow a replaced penalty
    assert penetration_bound_of(dataclasses.replace(mine, penetration_bound="spring")) == "spring"
    with pytest.raises(ValueError, match="penetration_bound must be one of"):
        penetration_bound_of(dataclasses.replace(mine, penetration_bound="quadratic"))


def test_soft_ground_reports_its_depth_without_the_papers_bound(capfd):
    """examples/soft_ground (a Kelvin–Voigt ground) went 0.0846 deep on Example 1 at nx = 100, beyond the
    velocity penalty's 0.0843: a bound of a law it does not have. Its run gives the depth alone."""
    assert main(["run", "example1", "--model", "soft_ground", "--nx", "100", *QUICK]) == 0
    out = capfd.readouterr()
    line = next(ln for ln in out.out.splitlines() if ln.startswith("penetration:"))
    assert "EXCEEDS" not in line and "no known penetration bound" in line and "bound 2" not in line, line
    assert "PenetrationWarning" not in out.err and "contact law allows" not in out.err


def test_the_papers_model_keeps_its_bound_and_a_law_without_one_is_not_judged(monkeypatch):
    scene = sc.load_scene("example1").replace(nx=100, nt=600)
    paper = sc.simulate(scene)
    p = penetration_check(paper)
    assert p["bound_kind"] == "velocity" and p["within_bound"] and 0 < p["depth"] < p["bound"]
    assert "eps max|v|" in _fmt_penetration_line(paper)[0]
    # a law with no known bound: the string landing at 50 sinks about 50/√k = 0.5 into a spring k = 1e4
    mine = dataclasses.replace(sc.inelastic, name="mine", penalty=_stiff_ground, penalty_damping=None,
                               stability=None, contact_energy=_ground_energy)
    res = sc.simulate(scene, model=mine)
    q = penetration_check(res)
    assert q["bound"] is None and q["within_bound"] is None and q["depth"] > 0
    # the velocity bound applied to it would call a law that has no such bound in error (its spring holds the
    # string for longer than an impact: read as a velocity penalty it is "pressed", unless no press is seen)
    as_velocity = dataclasses.replace(res, penetration_bound="velocity", checks={})
    assert penetration_check(as_velocity)["bound_kind"] == "pressed"
    monkeypatch.setattr(checks, "PRESS_SPAN", float("inf"))
    judged = penetration_check(as_velocity)
    assert judged["bound"] is not None and not judged["within_bound"]


def test_the_folder_records_the_law_and_reads_it_back(tmp_path):
    scene = sc.load_scene("example1").replace(nx=100, nt=600)
    res = sc.simulate(scene, model="elastic", output=sc.Output(dir=tmp_path / "out", pictures=False))
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["penetration_bound"] == "spring" and summary["penetration"]["bound_kind"] == "spring"
    back = read_output(tmp_path / "out")
    assert back.penetration_bound == "spring"
    assert penetration_check(back)["bound"] == pytest.approx(res.checks["penetration"]["bound"])


def test_a_users_energy_label_is_the_legend_of_energy_png(tmp_path):
    """A model's own `energy_label` names its stored energy in energy.png's legend and in summary.json."""
    from stringcontact.plot import charts

    label = r"stored $\int \frac{1}{2}\eta_x^2 + \frac{1}{2}\eta^2\,dx$ (mine)"
    mine = dataclasses.replace(sc.inelastic, name="mine", energy_label=label)
    scene = sc.load_scene("example1").replace(nx=50, nt=600)
    res = sc.simulate(scene, model=mine, output=sc.Output(dir=tmp_path / "out", pictures=False))
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["energy_label"] == label
    for result in (res, read_output(tmp_path / "out")):
        fig, _ = charts.energy_figure(result)
        labels = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]  # the key under the panels
        assert label in labels and not any(t.startswith("elastic") for t in labels), labels
    fig, _ = charts.energy_figure(sc.simulate(scene))  # the paper's model keeps the paper's label
    labels = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]  # the key under the panels
    assert r"elastic $\frac{1}{2}\int \eta_x^2\,dx$" in labels
