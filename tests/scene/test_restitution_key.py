"""The scene key `restitution`: a number in [0, 1], kept when given (TOML out, `show`), refused in one line."""

import pytest

import stringcontact as sc
from stringcontact.cli import main as cli
from stringcontact.scene.toml import scene_to_toml

BASE = 'T = 0.1\nalpha = 0\nnx = 20\nnt = 10\neta0 = "0.1"\nv0 = -1\n[scheme]\nname = "projection"\neps = 0.001\n'


def _file(tmp_path, extra=""):
    """A scene with `extra` lines in its [scheme] table (restitution is a scheme option)."""
    path = tmp_path / "s.toml"
    path.write_text(BASE + extra)
    return path


def test_default_is_none_and_not_written(tmp_path):
    scene = sc.load_scene(_file(tmp_path))
    assert scene.restitution is None
    assert "restitution" not in scene_to_toml(scene)


@pytest.mark.parametrize("value", [0, 0.5, 1])
def test_given_value_round_trips(tmp_path, value):
    scene = sc.load_scene(_file(tmp_path, f"restitution = {value}\n"))
    assert scene.restitution == value and isinstance(scene.restitution, float)
    text = scene_to_toml(scene)
    assert f"restitution = {float(value)}" in text
    again = tmp_path / "again.toml"
    again.write_text(text)
    assert sc.load_scene(again) == scene


@pytest.mark.parametrize("value, fragment", [
    ("1.5", "restitution: 1.5 is out of range; allowed: a number in [0, 1]"),
    ("-0.1", "restitution: -0.1 is out of range; allowed: a number in [0, 1]"),
    ('"half"', "restitution: expected a number, got str 'half'; allowed: a number in [0, 1]"),
    ("true", "restitution: expected a number, got bool True; allowed: a number in [0, 1]"),
])
def test_out_of_range_is_one_line_naming_the_key(tmp_path, capsys, value, fragment):
    path = _file(tmp_path, f"restitution = {value}\n")
    with pytest.raises(sc.SceneError) as info:
        sc.load_scene(path)
    assert fragment in str(info.value) and "\n" not in str(info.value)
    assert cli.main(["show", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and fragment in err


def test_show_prints_it_when_set(tmp_path, capsys):
    assert cli.main(["show", str(_file(tmp_path, "restitution = 0.25\n"))]) == 0
    assert "restitution = 0.25" in capsys.readouterr().out
    assert cli.main(["show", str(_file(tmp_path))]) == 0
    shown = capsys.readouterr().out
    assert "restitution =" not in shown  # not set: only show's comment on the keys a scene does not give
    assert "# restitution: not given" in shown


def test_replace_checks_it():
    scene = sc.load_scene("example1")
    assert scene.replace(restitution=0.5).restitution == 0.5
    assert scene.replace(restitution=0.5).replace(restitution=None).restitution is None
    with pytest.raises(sc.SceneError, match=r"restitution: 3 is out of range"):
        scene.replace(restitution=3)


def test_run_refuses_it_for_another_scheme_and_out_of_range(tmp_path, capsys):
    path = _file(tmp_path)
    assert cli.main(["run", str(path), "--scheme", "paper", "--restitution", "0.5", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "only scheme 'projection'" in err
    assert cli.main(["run", str(path), "--restitution", "1.5", "--no-progress"]) == 2
    assert "restitution: 1.5 is out of range; allowed: a number in [0, 1]" in capsys.readouterr().err
    assert cli.main(["check", str(path), "--scheme", "newmark", "--restitution", "0.5", "--levels", "1"]) == 2
    assert "only scheme 'projection'" in capsys.readouterr().err


def test_run_reports_it(tmp_path, capsys):
    assert cli.main(["run", str(_file(tmp_path)), "--restitution", "0.5", "--no-progress"]) == 0
    assert "scheme projection" in (out := capsys.readouterr().out) and "restitution=0.5" in out
