"""`run --tol` refuses a tolerance the size limits cannot reach, after the first pilots, instead of refining
them for many minutes (issue 27, item 13: `--tol 1e-300` was still running pilots at nx = 51200 after 400 s)."""

import pytest

from stringcontact.analysis import tolerance
from stringcontact.cli.main import main


def assert_one_line_error(err: str, *fragments):
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("stringcontact: warning:")]
    assert len(lines) == 1 and lines[0].startswith("stringcontact: error: "), err
    assert all(f in lines[0] for f in fragments), lines[0]


@pytest.fixture
def pilots(monkeypatch):
    """The nx of every pilot run; a pilot finer than nx = 400 fails the test at once (no clock: a count)."""
    seen = []
    run_method = tolerance.run_method

    def counted(scene, method, **kw):
        seen.append(scene.nx)
        if scene.nx > 400:
            pytest.fail(f"a pilot at nx = {scene.nx} for a tolerance no nx <= 64000 can reach")
        return run_method(scene, method, **kw)

    monkeypatch.setattr(tolerance, "run_method", counted)
    return seen


@pytest.mark.parametrize("tol", ["1e-300", "1e-12"])
def test_an_unreachable_tolerance_is_refused_after_the_first_pilots(pilots, capfd, tol, tmp_path):
    assert main(["run", "example1", "--tol", tol, "--no-progress", "--out", str(tmp_path / "o")]) == 2
    err = capfd.readouterr().err
    assert_one_line_error(err, f"--tol {float(tol):g}: no method reached the tolerance, out of reach of the size limit nx <= 64000", "allowed: --tol >=")
    assert max(pilots) <= 100  # two pilots (nx 50 and 100) per method, nothing finer
    assert not (tmp_path / "o").exists()


def test_the_refusal_names_what_the_limits_allow(pilots):
    scene = tolerance.flat_landing_scene(100)
    with pytest.raises(ValueError) as info:
        tolerance.choose_for_tolerance(scene, 1e-300)
    allowed = float(str(info.value).rsplit("--tol >= ", 1)[1].split()[0])
    assert 0 < allowed < 1e-2
    # a tolerance at that bound is not refused by the extrapolation: it is tried (its pilots may go finer)
    choice = tolerance.estimate_for_tolerance(scene, 1e-300)
    assert all(c["why"] == "out of reach" and c["floor"] > tolerance.REACH_MARGIN * 1e-300 for c in choice)


def test_tol_tries_only_the_schemes_the_model_runs_with(monkeypatch):
    """`--tol` on a film scene ran its first candidate, projection, and the film's refusal of it ended the run: a
    scheme the user never chose was blamed. Candidates the model refuses are not tried; a model none of them runs
    is refused naming --tol."""
    import dataclasses

    from stringcontact.model.film import film
    from stringcontact.model.interface import inelastic

    tried = []

    def stand_in(scene, method, **kw):
        tried.append(method.scheme)
        raise StopIteration  # enough: which schemes were tried, not what they give

    monkeypatch.setattr(tolerance, "run_method", stand_in)
    with pytest.raises(StopIteration):
        tolerance.estimate_for_tolerance(tolerance.flat_landing_scene(50), 1e-2, model=film)
    assert tried == ["paper"]
    nowhere = dataclasses.replace(inelastic, name="nowhere", schemes=("no-such-scheme",), scheme_note="a test")
    with pytest.raises(ValueError, match=r"--tol: model 'nowhere' runs with none of the schemes --tol chooses among"):
        tolerance.choose_for_tolerance(tolerance.flat_landing_scene(50), 1e-2, model=nowhere)
    assert tried == ["paper"]
