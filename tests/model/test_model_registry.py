"""A scene file never runs code: its `model` key names a registered model; nothing else is imported or called.

Each attack is a scene file with one extra line `model = "module:name"`, run by the real command line in a
process of its own. A sentinel module on the path writes a file when it is imported and another when its
function is called: neither file may appear.
"""

import os
import re
import subprocess
import sys

import pytest
from conftest import register_distribution

from stringcontact.cli.main import main
from stringcontact.errors import SceneError
from stringcontact.model import registry
from stringcontact.scene import load_scene

SCENE = 'T = 0.1\nnt = 50\nnx = 20\nalpha = 0.2\nscheme = { eps = 0.002 }\nh = 0\neta0 = "0.3*sin(pi*x)"\nv0 = 0\n'

SENTINEL = """
from pathlib import Path
Path(__file__).with_name("imported").write_text("imported")

def make():
    Path(__file__).with_name("called").write_text("called")

model = make
"""

# What each of these did before: an HTTP server, Pdb, two processes, exit 0, exit 134, the Zen of Python.
ATTACKS = ["http.server:test", "builtins:breakpoint", "os:fork", "sys:exit", "os:abort", "this:s",
           "sentinel:make", "sentinel_plugin:model"]


@pytest.fixture
def sandbox(tmp_path, monkeypatch):
    """tmp_path with the sentinel module and a package `sentinel-plugin` that registers the model `sentinel`."""
    (tmp_path / "sentinel.py").write_text(SENTINEL)
    (tmp_path / "sentinel_plugin.py").write_text(SENTINEL)
    register_distribution(tmp_path, "sentinel-plugin", registry.GROUP, "sentinel = sentinel_plugin:model")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    for name in ("sentinel", "sentinel_plugin"):
        sys.modules.pop(name, None)


def _nothing_ran(folder):
    return not (folder / "imported").exists() and not (folder / "called").exists()


def _stringcontact(folder, *argv):
    env = {**os.environ, "PYTHONPATH": str(folder), "STRINGCONTACT_TRACEBACK": ""}
    # timeout: a hang guard (a refusal that failed would leave an HTTP server or Pdb waiting), not a measurement
    return subprocess.run([sys.executable, "-m", "stringcontact", *argv], check=False, cwd=folder, env=env,
                          text=True, capture_output=True, stdin=subprocess.DEVNULL, timeout=600)


@pytest.mark.parametrize("spec", ATTACKS)
def test_a_scene_file_cannot_name_a_module(sandbox, spec):
    scene = sandbox / "attack.toml"
    scene.write_text(SCENE + f'model = "{spec}"\n')
    proc = _stringcontact(sandbox, "run", str(scene), "--no-pictures", "--no-progress")
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""  # not even the Zen of Python
    assert proc.stderr.startswith(f"stringcontact: error: scene {str(scene)!r}: model: unknown model {spec!r}")
    assert "allowed: cubic_foundation, elastic, film, inelastic, large_deflection, loaded_obstacle" in proc.stderr and proc.stderr.count("\n") == 1
    assert _nothing_ran(sandbox)


def test_checking_a_registered_name_calls_nothing(sandbox, capsys):
    """A scene naming a registered model loads that installed package to read the model's constants (the user's
    `pip install` is the trust boundary), but calls nothing in it; an object that is not a Model is refused."""
    scene = sandbox / "plugin.toml"
    scene.write_text(SCENE + 'model = "sentinel"\n')
    assert load_scene(scene).model == "sentinel"
    assert (sandbox / "imported").exists() and not (sandbox / "called").exists()
    assert main(["show", str(scene)]) == 2
    err = capsys.readouterr().err
    assert "model: 'sentinel' is registered as sentinel_plugin:model" in err and "a function" in err
    assert err.count("\n") == 1
    with pytest.raises(SceneError, match=r"model: 'sentinel' is registered as sentinel_plugin:model .* a function"):
        registry.load_model("sentinel")
    assert not (sandbox / "called").exists()


@pytest.mark.parametrize("command", [["show"], ["check", "--levels", "1"], ["run", "--tol", "0.01"]])
def test_every_command_refuses_the_scene(sandbox, capsys, command):
    scene = sandbox / "attack.toml"
    scene.write_text(SCENE + 'model = "sentinel:make"\n')
    argv = [command[0], str(scene), *command[1:]]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and "model: unknown model 'sentinel:make'" in err and err.count("\n") == 1
    assert _nothing_ran(sandbox)


@pytest.mark.parametrize("spec, kind", [("os:fork", "builtin_function_or_method"), ("sentinel:make", "function")])
def test_the_command_line_names_a_model_object_and_calls_nothing(sandbox, spec, kind):
    proc = _stringcontact(sandbox, "run", "example1", "--model", spec, "--no-pictures", "--no-progress")
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr == (f"stringcontact: error: model: {spec!r} is a {kind}, not a stringcontact.Model "
                           "(nothing is called to make one: name a Model object)\n")
    assert not (sandbox / "called").exists()


def test_a_name_registered_twice_is_refused(sandbox):
    register_distribution(sandbox, "other-plugin", registry.GROUP, "elastic = sentinel_plugin:model")
    with pytest.raises(SceneError, match=r"model: 'elastic' is registered twice, as .*sentinel_plugin:model"):
        load_scene("single_impact").replace(model="elastic")
    assert _nothing_ran(sandbox)


def test_models_command_lists_the_registered_models(capsys):
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    for name in ("inelastic", "elastic", "loaded_obstacle", "soft_ground"):
        assert any(line.startswith(f"{name} ") for line in out.splitlines()), name
    assert "stringcontact.model.variants:elastic [stringcontact]" in out
    assert "soft_ground:soft_ground [stringcontact-soft-ground]" in out


def test_the_example_package_is_what_a_user_would_copy():
    """Its pyproject registers the model by the documented route (read with tomllib, as pip reads it)."""
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    meta = tomllib.loads((root / "examples" / "soft_ground" / "pyproject.toml").read_text())
    assert meta["project"]["entry-points"][registry.GROUP] == {"soft_ground": "soft_ground:soft_ground"}
    ours = tomllib.loads((root / "pyproject.toml").read_text())["project"]["entry-points"][registry.GROUP]
    assert set(ours) == {"inelastic", "elastic", "loaded_obstacle", "cubic_foundation", "large_deflection", "film",
                         "stiff_string"}


def test_check_uses_the_scenes_model():
    from stringcontact.analysis import theorems

    scene = load_scene("single_impact").replace(nx=50, nt=800, model="elastic")
    _, finest, results = theorems.run_checks(scene, levels=1, time_levels=1)
    assert finest.model == "elastic" and [r.model for r in results] == ["elastic"]
    assert theorems.run_checks(scene.replace(model=None), levels=1, time_levels=1)[1].model == "inelastic"


def test_an_output_folder_whose_model_is_no_longer_registered_still_plots(tmp_path):
    """A folder written with an uninstalled plugin (or a module path, before model names) is redrawn."""
    import json

    import stringcontact as sc
    from stringcontact.io import readback

    scene = load_scene("single_impact").replace(nx=20, nt=1600, T=0.4, model="elastic", output_times=[])
    sc.simulate(scene, model=registry.load_model(scene.model), output=sc.Output(tmp_path / "run", pictures=False))
    assert readback.read_output(tmp_path / "run").scene.model == "elastic"
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    summary["scene"]["model"] = "stringcontact.model.variants:elastic"
    (tmp_path / "run" / "summary.json").write_text(json.dumps(summary))
    back = readback.read_output(tmp_path / "run")
    assert back.scene.model is None and back.model == "elastic"


# --- a plugin's constants: the scene's [parameters] reach its forms; unknown or out-of-range ones are refused ---------

GROUND = SCENE.replace("v0 = 0", "v0 = -5") + 'model = "soft_ground"\n'


@pytest.fixture
def soft_ground():
    if "soft_ground" not in registry.registered():
        pytest.skip("examples/soft_ground is not installed (scripts/setup installs it)")
    return registry.load_model("soft_ground")


@pytest.mark.slow
def test_a_plugins_constant_from_the_scene_reaches_its_form(tmp_path, soft_ground):
    """examples/soft_ground's spring k from a scene file's [parameters]: a softer bed lets the string sink deeper,
    and its output field spring_force is k η⁻ with the scene's k."""
    import numpy as np

    import stringcontact as sc

    (tmp_path / "soft.toml").write_text(GROUND + "\n[parameters]\nk = 1e4\n")
    soft = load_scene(tmp_path / "soft.toml")
    assert soft.parameters == (("k", 1e4),)
    default = load_scene("example1").replace(nx=100, model="soft_ground")  # the example package's own numbers
    stiff, softer = sc.simulate(default), sc.simulate(default.replace(parameters={"k": 1e4}))
    assert stiff.parameters == {"k": 250000.0, "c": soft_ground.constants[1].default}
    assert softer.parameters["k"] == 1e4 and softer.parameters["c"] == stiff.parameters["c"]
    assert stiff.min_eta == pytest.approx(-0.08455, abs=1e-4)  # examples/soft_ground at its defaults, unchanged
    assert softer.min_eta < 2 * stiff.min_eta  # depth ~ V/sqrt(k): five times softer, more than twice as deep
    for res in (stiff, softer):
        k = res.parameters["k"]
        assert np.allclose(res.fields["spring_force"], k * np.maximum(-res.eta, 0), rtol=1e-10, atol=1e-8 * k)
    run = sc.simulate(soft)
    assert run.parameters["k"] == 1e4 and run.min_eta < 0


def test_a_top_level_constant_still_works_with_a_warning(tmp_path, soft_ground):
    from stringcontact.scene import SceneWarning

    (tmp_path / "old.toml").write_text(GROUND + "k = 1e4\n")
    with pytest.warns(SceneWarning, match=r"k at the top level .* \[parameters\] table"):
        scene = load_scene(tmp_path / "old.toml")
    assert scene.parameters == (("k", 1e4),)


@pytest.mark.parametrize("name, value, message", [
    ("kk", 1.0, r"kk: model 'soft_ground' has no constant 'kk' \(its constants: k, c\); remove it from \[parameters\]"),
    ("k", -1.0, r"k: -1 is out of range; allowed: a number in \(0, 1000000000000\]"),
    ("c", -1.0, r"c: -1 is out of range; allowed: a number in \[0, 1000000000000\]"),
    ("k", "stiff", r"k: expected a number, got str 'stiff'; allowed: a number in \(0, 1000000000000\]$"),  # its own range
])
def test_an_unknown_or_out_of_range_constant_is_refused_naming_it(tmp_path, capsys, soft_ground, name, value, message):
    """In a scene file, in Scene.replace and on the command line: a one-line SceneError naming the constant."""
    path = tmp_path / "bad.toml"
    path.write_text(GROUND + f"\n[parameters]\n{name} = {value!r}\n".replace("'", '"'))
    with pytest.raises(SceneError, match=message) as error:
        load_scene(path)
    assert "\n" not in str(error.value)
    with pytest.raises(SceneError, match=message):
        load_scene("example1").replace(model="soft_ground", parameters={name: value})
    assert main(["show", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and re.search(message, err)


def test_a_model_named_on_the_command_line_checks_the_scenes_constants(tmp_path, soft_ground, capsys):
    """A scene that names no model may carry [parameters]; the model that runs (--model, a Model handed to
    simulate) checks them before anything is written."""
    import stringcontact as sc

    scene = load_scene("example1").replace(nx=20, nt=100, T=0.02, output_times=[], parameters={"kk": 1.0})
    with pytest.raises(SceneError, match=r"kk: model 'soft_ground' has no constant 'kk'"):
        sc.simulate(scene, model=soft_ground, output=sc.Output(tmp_path / "out"))
    assert not (tmp_path / "out").exists()
    (tmp_path / "plain.toml").write_text(SCENE + "\n[parameters]\nk = 0.0\n")
    code = main(["run", str(tmp_path / "plain.toml"), "--model", "soft_ground:soft_ground", "--no-pictures",
                 "--no-progress", "--out", str(tmp_path / "cli")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "k: 0 is out of range" in err, err
    assert not (tmp_path / "cli").exists()


@pytest.mark.parametrize("named", ["", 'model = "inelastic"\n'], ids=["no model", "a model without constants"])
def test_a_wrong_typed_constant_is_told_the_range_of_the_model_on_the_command_line(tmp_path, soft_ground, capsys,
                                                                                  named):
    """A scene whose own model declares no k, run with --model soft_ground:soft_ground: a k that is no number is told
    soft_ground's range for k, in one line, exit 2, nothing written."""
    (tmp_path / "plain.toml").write_text(SCENE + named + '\n[parameters]\nk = "stiff"\n')
    code = main(["run", str(tmp_path / "plain.toml"), "--model", "soft_ground:soft_ground", "--no-pictures",
                 "--no-progress", "--out", str(tmp_path / "cli")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "k: expected a number, got str 'stiff'; allowed: a number in (0, 1000000000000]" in err, err
    assert not (tmp_path / "cli").exists()
