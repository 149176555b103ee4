"""A run's closing lines (cli/report.py) read back: the least gap to the obstacle beside the least height, the
penetration line's bound only where its assumptions hold, and the note on a large numerical dissipation."""

import csv
import json
import re

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.cli.main import main

QUIET = ["--no-progress", "--no-pictures"]
NUMBER = r"(-?[0-9.]+(?:e[-+]?[0-9]+)?)"


def _minima(out: str) -> tuple[float, float]:
    """(min gap, min eta) from the report's line "min gap eta - psi = G (min eta = E); ..."."""
    match = re.search(rf"min gap eta - psi = {NUMBER} \(min eta = {NUMBER}\)", out)
    assert match, out
    return float(match[1]), float(match[2])


@pytest.mark.slow
def test_loaded_string_reports_the_gap_and_the_penalty_creep(tmp_path, capfd):
    """The shipped loaded_string (a string draped over a bump of top 0.2 under gravity): the gap reaches −0.009
    (the penalty's creep into the bump) where η's least value is −0.095, far from the bump's top; and the depth is
    explained by the press (ε × the contact force's integral), not judged against the impact bound, with no
    PenetrationWarning."""
    out = tmp_path / "ls"
    assert main(["run", "loaded_string", *QUIET, "--out", str(out)]) == 0
    captured = capfd.readouterr()
    gap, low = _minima(captured.out)
    assert gap == pytest.approx(-0.0090, abs=3e-4) and low == pytest.approx(-0.0955, abs=1e-3)
    line = next(ln for ln in captured.out.splitlines() if ln.startswith("penetration:"))
    assert "EXCEEDS" not in line and "pressed" in line and "does not apply" in line, line
    depth = float(re.search(rf"max depth {NUMBER}", line)[1])
    creep = float(re.search(rf"integral over time = {NUMBER}", line)[1])
    force = float(re.search(rf"a contact force {NUMBER} at a node", line)[1])
    assert depth == pytest.approx(-gap, rel=1e-3)
    assert creep == pytest.approx(depth, rel=0.15)  # ε∫F dt: the depth the press explains
    assert force == pytest.approx(18.0, rel=0.02)  # the closed form's contact pressure λ = −ψ'' − f = 18
    assert "further below the obstacle" not in captured.err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["min_gap"] == pytest.approx(gap, rel=1e-5) and summary["min_eta"] == pytest.approx(low, rel=1e-5)
    assert summary["penetration"]["bound_kind"] == "pressed" and summary["penetration"]["bound"] is None
    with open(out / "diagnostics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    gaps = np.array([float(r["min_gap"]) for r in rows])
    heights = np.array([float(r["min_eta"]) for r in rows])
    assert gaps.min() == pytest.approx(gap, abs=1e-4) and heights.min() == pytest.approx(low, abs=1e-3)
    assert gaps[0] == pytest.approx(0.1, abs=1e-3)  # η0 = 0.3 sin(πx) over ψ = 0.2 − 4(x − 0.5)²


def _travelling_bump() -> sc.Scene:
    """A string at rest at height 0.1 and a bump rising to 0.3 within t = 0.1 while it travels under it, the penalty
    scheme: the bump pushes into the string (a penalty against a moving obstacle never restores the gap)."""
    return sc.Scene.from_dict(
        {
            "name": "travelling_bump",
            "T": 0.3,
            "nt": 600,
            "nx": 100,
            "alpha": 0.01,
            "scheme": {"eps": 0.001},
            "eta0": "0.1",
            "v0": 0,
            "h": 0.1,
            "model": "loaded_obstacle",
            "obstacle": "min(t/0.1, 1)*0.3*exp(-((x - 0.3 - t)/0.05)**2)",
        }
    )


def test_a_travelling_bump_reports_the_gap_not_the_height(capsys):
    """η stays near 0.1 while the bump passes under it: min η is about 0.1, but the gap η − ψ at each step's time
    goes below 0. `Result.min_gap` covers every step (at least as deep as the stored rows), the report prints it,
    and diagnostics.csv's column (`stored_min_gap`) is the rows' η − ψ(x, t)."""
    res = sc.simulate(_travelling_bump(), scheme="paper")
    scene = res.scene
    rows = np.array([np.min(eta - scene.obstacle_values(res.x, t)) for t, eta in zip(res.t, res.eta)])
    np.testing.assert_allclose(res.stored_min_gap, rows, rtol=0, atol=1e-12)
    assert res.min_gap <= rows.min() + 1e-12 and res.min_gap == pytest.approx(rows.min(), abs=0.02)
    assert res.min_gap < -1e-3 and res.min_eta > 0.05  # min η alone says "above the obstacle"
    from stringcontact.cli.report import report

    report(res)
    gap, low = _minima(capsys.readouterr().out)
    assert gap == pytest.approx(res.min_gap, rel=1e-5) and low == pytest.approx(res.min_eta, rel=1e-5)


@pytest.mark.slow
def test_film_landing_flags_its_numerical_dissipation(capfd):
    """film_landing books a third of E(0) as the scheme's own dissipation: the report says so, with what to change;
    Example 1 (0.3 %) gets no such note."""
    assert main(["run", "film_landing", *QUIET]) == 0
    out = capfd.readouterr().out
    note = re.search(rf"note: the scheme's own numerical dissipation {NUMBER} is {NUMBER} % of the energy", out)
    assert note, out
    assert float(note[2]) == pytest.approx(34, abs=2)
    assert "a run at --nt 2x" in out and ": closes" in out
    assert "scheme newmark" not in out  # newmark refuses the film (no velocity damping): not advised
    assert main(["run", "example1", "--nx", "200", "--nt", "40", "--eps", "0.01", *QUIET]) == 0
    assert "numerical dissipation" not in capfd.readouterr().out


@pytest.fixture(scope="module")
def example1():
    """A coarse Example 1: the string lands at t ≈ 0.015 and breaks into several contact components later."""
    return sc.simulate(sc.load_scene("example1").replace(nx=80, nt=600), storage=sc.Storage(max_rows=600))


def test_the_components_note_says_when_contact_began_and_when_the_most_components_first_occurred(example1, capsys):
    """"first contact at" is the first stored time with any contact, "first at" the first with the most components:
    a string that touches in one interval at row 100 and in three at row 300 is told both times."""
    import dataclasses

    from stringcontact.cli.report import report

    contact = np.zeros_like(example1.contact)
    contact[100:, 30:50] = True  # one interval from row 100 on
    contact[300:310, 10:15] = contact[300:310, 60:70] = True  # three from row 300 to 309
    res = dataclasses.replace(example1, contact=contact)
    report(res)
    out = capsys.readouterr().out
    match = re.search(rf"first contact at t = {NUMBER}; at most (\d+) contact components at once \(first at t = {NUMBER}\)", out)
    assert match, out
    began, most, first = float(match[1]), int(match[2]), float(match[3])
    assert began == pytest.approx(res.t[100], rel=1e-3) and most == 3 and first == pytest.approx(res.t[300], rel=1e-3)


@pytest.mark.parametrize("model, advised", [("inelastic", True), ("soft_ground", False), ("film", False)])
def test_the_numerical_dissipation_note_advises_newmark_only_for_a_model_newmark_runs(example1, monkeypatch, model, advised):
    """The note names scheme newmark only where newmark takes the model (`timestepping.check_model`): not for the
    film or a plugin without a velocity damping (soft_ground), which newmark refuses."""
    import dataclasses

    from stringcontact.cli import report as closing
    from stringcontact.model.registry import load_model, registered
    from stringcontact.run import checks
    from stringcontact.timestepping import check_model

    if model not in registered():
        pytest.skip(f"{model} is not installed (scripts/setup installs examples/soft_ground)")
    monkeypatch.setattr(checks, "NUMERICAL_SHARE", -1.0)  # every run gets the note
    res = dataclasses.replace(example1, model=model, model_origin={"name": model, "source": "built-in"})
    note = closing._fmt_numerical_line(res)
    assert note is not None and "--nt 2x" in note  # how to measure it; no "refine dt" that one run cannot know
    assert "a smaller dt" not in note and "falls like dt" not in note
    assert ("scheme newmark" in note) is advised
    if not advised:
        with pytest.raises(ValueError, match="newmark"):
            check_model("newmark", load_model(model))


def test_show_names_the_models_constants_without_a_stray_quote(capsys):
    assert main(["show", "film_landing"]) == 0
    out = capsys.readouterr().out
    assert "[parameters]  # the constants of model film (`stringcontact models`)" in out
    assert "''s" not in out and "'s constants" not in out
