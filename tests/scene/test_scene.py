"""Scenes: built-in data, validation of files and of replace(), round trips."""

import math
import os
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

from stringcontact.errors import SceneError
from stringcontact.scene import (
    FILE_KEYS,
    Scene,
    SceneWarning,
    list_scenes,
    load_scene,
    scene_to_toml,
)

VALID = """\
description = "a small test scene"
T = 0.3
alpha = 0.01
nx = 50
nt = 30
eta0 = "1 + 0.5*x"
v0 = -5
"""


def write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def with_line(key, line):
    """VALID with the line for `key` replaced by `line` (or appended)."""
    lines = [ln for ln in VALID.splitlines() if not ln.startswith(f"{key} =")]
    return "\n".join(lines + [line]) + "\n"


def load_quietly(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)
        return load_scene(path)


# --- built-in scenes ---------------------------------------------------------------------------


def test_example1_as_printed():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # example 1 is clean: no warning at all
        s = load_scene("example1")
    assert s.name == "example1"
    assert (s.length, s.T, s.alpha, s.eps) == (1.0, 0.3, 0.01, 0.0005)
    assert (s.nx, s.nt) == (5000, 1500)
    assert s.dt == pytest.approx(2e-4, rel=1e-12)
    assert s.dx == pytest.approx(2e-4, rel=1e-12)
    assert s.r == pytest.approx(0.4)
    assert (s.h_left, s.h_right, s.h) == (1.0, 1.0, None)
    assert s.output_times == (0.0, 0.02, 0.04, 0.06, 0.2, 0.3)
    x = s.x()
    assert x.shape == (5001,) and x[0] == 0.0 and x[-1] == 1.0
    np.testing.assert_allclose(s.initial_displacement(x), 1 + 0.5 * np.sin(10 * np.pi * x) ** 2, atol=1e-15)
    np.testing.assert_array_equal(s.initial_velocity(x), np.full(5001, -50.0))
    assert "h_left = h_right = 1" in s.notes


def test_example2_as_printed_with_warning():
    with pytest.warns(SceneWarning, match=r"example2.*below the obstacle.*min -1 at x=0\.65"):
        s = load_scene("example2")
    assert (s.length, s.T, s.alpha, s.eps) == (1.0, 0.5, 0.01, 0.0005)
    assert (s.nx, s.nt) == (5000, 2500)
    assert s.dt == pytest.approx(2e-4, rel=1e-12)
    assert (s.h_left, s.h_right) == (0.0, 1.0)
    assert s.output_times == (0.0, 0.04, 0.08, 0.16, 0.28, 0.32)
    x = s.x()
    eta, v = s.initial_displacement(x), s.initial_velocity(x)
    i = {round(float(xi), 6): k for k, xi in enumerate(x)}
    assert eta[i[0.1]] == pytest.approx(0.1)
    assert eta[i[0.2]] == pytest.approx(0.0, abs=1e-15)  # jump 0.2 -> 0
    assert eta[i[0.65]] == pytest.approx(-1.0)  # below the obstacle
    assert eta[i[0.8]] == pytest.approx(1.2)  # jump 0 -> 1.2
    assert eta[-1] == pytest.approx(1.0)  # 2 - x extended to x = 1
    assert v[i[0.0]] == -50.0 and v[i[0.59]] == -50.0 and v[i[0.6]] == -0.5 and v[-1] == -0.5
    for fragment in ("typo", "discontinuous", "below the obstacle", "ignored", "h_right = 1"):
        assert fragment in s.notes


def test_list_scenes():
    scenes = dict(list_scenes())
    assert set(scenes) >= {"example1", "example2"}
    assert all(description and "\n" not in description for description in scenes.values())


def test_missing_path():
    with pytest.raises(SceneError, match=r"^scene 'foo': no built-in scene of that name and no such file"):
        load_scene("foo")


def test_directory_path(tmp_path):
    with pytest.raises(SceneError, match="directory"):
        load_scene(tmp_path)


# --- a valid file, defaults and round trips --------------------------------------------------


def test_valid_file_and_defaults(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = load_scene(write(tmp_path, VALID, "my-scene.toml"))
    assert s.name == "my-scene"  # default: the file stem
    assert s.length == 1.0
    assert (s.nx, s.nt) == (50, 30)
    assert s.v0 == "-5"  # numbers are accepted as constants
    assert (s.h_left, s.h_right) == (1.0, 1.5)  # eta0's end values
    assert s.h is None and s.model is None and s.output_times == () and s.notes == ""
    assert isinstance(s.T, float) and isinstance(s.nx, int)


def test_dt_gives_nt(tmp_path):
    s = load_scene(write(tmp_path, with_line("nt", "dt = 0.0002").replace("nx = 50", "nx = 5000")))
    assert s.nt == 1500  # 0.3/0.0002 = 1499.9999999999998 in floating point


def test_single_h_is_a_variable(tmp_path):
    text = with_line("eta0", 'eta0 = "h + 0.1*sin(pi*x/l)"') + "h = 0.5\nlength = 2\n"
    s = load_scene(write(tmp_path, text))
    assert (s.h, s.h_left, s.h_right, s.length) == (0.5, 0.5, 0.5, 2.0)
    np.testing.assert_allclose(s.initial_displacement([0.0, 1.0]), [0.5, 0.6])


def test_integral_float_counts_accepted(tmp_path):
    s = load_scene(write(tmp_path, with_line("nx", "nx = 100.0")))
    assert s.nx == 100 and isinstance(s.nx, int)


def test_model_is_a_registered_name(tmp_path):
    s = load_scene(write(tmp_path, VALID + 'model = "elastic"\n'))
    assert s.model == "elastic"


@pytest.mark.parametrize("name", ["example1", "example2"])
def test_toml_round_trip(tmp_path, name):
    s = load_quietly(name)
    text = scene_to_toml(s)
    assert load_quietly(write(tmp_path, text)) == s
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)
        assert Scene.from_dict(tomllib.loads(text)) == s
        assert Scene.from_dict(s.as_dict()) == s


def test_toml_round_trip_awkward_strings(tmp_path):
    s = load_scene(write(tmp_path, VALID)).replace(
        description='quotes " and \\ backslash', notes="line 1\nit's '''tricky'''\n\ttab\x7f", h=1.0, eta0="h"
    )
    assert load_scene(write(tmp_path, scene_to_toml(s), "again.toml")) == s


# --- replace -------------------------------------------------------------------------------------


def test_replace_validates():
    s = load_scene("example1")
    small = s.replace(nx=100, nt=30)
    assert (small.nx, small.nt) == (100, 30)
    assert small.dt == pytest.approx(0.01)
    assert small.eta0 == s.eta0 and small.output_times == s.output_times
    assert s.nx == 5000  # the original is unchanged
    with pytest.raises(SceneError, match=r"nx: 0 is out of range; allowed: an integer in \[2, 100000\]"):
        s.replace(nx=0)
    with pytest.raises(SceneError, match=r"eps: -1 is out of range; allowed: a number in \[1e-12, 1000000\]"):
        s.replace(eps=-1)
    with pytest.raises(SceneError, match=r"unknown key\(s\) 'colour'; allowed keys are name, description"):
        s.replace(colour="red")


def test_replace_time_rules():
    s = load_scene("example1").replace(nx=100, nt=30)
    assert s.replace(T=0.6, output_times=[]).nt == 30  # T alone keeps nt
    assert s.replace(dt=0.001).nt == 300  # dt replaces nt
    with pytest.raises(SceneError, match="^scene 'example1': dt: "):
        s.replace(dt=0.0007)
    with pytest.raises(SceneError, match="output_times"):
        s.replace(T=0.1)  # 0.2 and 0.3 are now after T


def test_replace_boundary_rules():
    s = load_scene("example1").replace(nx=100, nt=30)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        follows = s.replace(eta0="2 + x")  # the ends followed eta0, so they follow the new one
        single = s.replace(h=1.0)
    assert (follows.h_left, follows.h_right) == (2.0, 3.0)
    assert (single.h, single.h_left, single.h_right) == (1.0, 1.0, 1.0)
    with pytest.warns(SceneWarning, match="h_left = 0 differs from eta0 at x=0"):
        split = single.replace(h_left=0.0)  # h_left replaces h; h_right keeps its value
    assert (split.h, split.h_left, split.h_right) == (None, 0.0, 1.0)
    uses_h = s.replace(h=0.5, eta0="h")
    with pytest.raises(SceneError, match="eta0: name 'h' is only available"):
        uses_h.replace(h=None, h_left=0.5, h_right=0.5)


def test_direct_construction_validates():
    base = dict(name="direct", length=1.0, T=1.0, alpha=0.0, eps=1.0, nx=10, nt=10, eta0="x", v0="0",
                h_left=0.0, h_right=1.0)
    assert Scene(**base).dx == pytest.approx(0.1)
    with pytest.raises(SceneError, match="nx"):
        Scene(**{**base, "nx": 1})
    with pytest.raises(SceneError, match="h: h = 2 but h_left = 0"):
        Scene(**{**base, "h": 2.0})
    with pytest.raises(SceneError, match="v0: unknown name 'y'"):
        Scene(**{**base, "v0": "y"})


# --- warnings ----------------------------------------------------------------------------------


def test_warns_below_obstacle(tmp_path):
    pattern = r"eta0 is below the obstacle \(eta0 < 0\) at 25 of 51 nodes \(min -0.25 at x=0.5\); used as given"
    with pytest.warns(SceneWarning, match=pattern) as record:
        s = load_scene(write(tmp_path, with_line("eta0", 'eta0 = "abs(x - 0.5) - 0.25"')))
    assert len(record) == 1  # the ends default to eta0's end values: no second warning
    assert (s.h_left, s.h_right) == (0.25, 0.25)


@pytest.mark.parametrize(("lines", "message"), [
    # the ends default to eta0's: the left one inside the flat obstacle
    ('eta0 = "x - 0.5"\n', ("h_left: the left end is held at -0.5, inside the obstacle psi = 0, which is 0 at x = 0; "
                            "allowed: h_left >= the obstacle at the ends")),
    # the case: a raised obstacle above both ends
    ('eta0 = "3"\nh = 1\nobstacle = "2"\nmodel = "loaded_obstacle"\n',
     "h: the left end is held at 1, inside the obstacle '2', which is 2 at x = 0; allowed: h >= the obstacle"),
    ('eta0 = "3"\nh_left = 3\nh_right = 1\nobstacle = "2*x"\nmodel = "loaded_obstacle"\n',
     "h_right: the right end is held at 1, inside the obstacle '2\\*x', which is 2 at x = 1"),
    # a moving obstacle over the right end at the start
    ('eta0 = "1"\nobstacle = "where(x > 0.9, 2 + t, -1)"\nmodel = "loaded_obstacle"\n',
     "h_right: the right end is held at 1, inside the obstacle .* which is 2 at x = 1 at t = 0;"),
])
def test_refuses_held_ends_inside_the_obstacle(tmp_path, lines, message):
    """An end held below the obstacle is refused in one line naming the key, the end's height and the obstacle's
    value there (the CLI: exit 2, nothing written); an end on the obstacle is allowed."""
    text = "".join(line + "\n" for line in VALID.splitlines() if not line.startswith(("eta0", "h ", "h=")))
    with pytest.raises(SceneError, match=message):
        load_scene(write(tmp_path, text + lines))
    on = load_scene(write(tmp_path, text + 'eta0 = "2"\nh = 2\nobstacle = "2"\nmodel = "loaded_obstacle"\n'))
    assert (on.h_left, on.h_right) == (2.0, 2.0)


def test_warns_when_ends_differ_from_eta0(tmp_path):
    with pytest.warns(SceneWarning, match="h_right = 2 differs from eta0 at x=1") as record:
        load_scene(write(tmp_path, VALID + "h_right = 2\n"))
    assert not any("h_left" in str(w.message) for w in record)


# --- invalid files -----------------------------------------------------------------------------

INVALID = [
    # (replaced key, new line, text that the message must contain)
    ("nx", "nx = 0", r"nx: 0 is out of range; allowed: an integer in [2, 100000]"),
    ("nx", "nx = 1", "nx: 1 is out of range"),
    ("nx", "nx = 1e13", r"nx: 10000000000000 is out of range; allowed: an integer in [2, 100000]"),
    ("nx", "nx = 100_001", "nx: 100001 is out of range"),
    ("nx", "nx = 5.5", "nx: expected an integer, got 5.5"),
    ("nx", "nx = true", "nx: expected an integer, got bool"),
    ("nx", 'nx = "50"', "nx: expected an integer, got str"),
    ("nx", "nx = nan", "nx: expected an integer"),
    ("nt", "nt = 0", r"nt: 0 is out of range; allowed: an integer in [1, 100000000]"),
    ("nt", "nt = 100_000_001", "nt: 100000001 is out of range"),
    ("nt", "nt = -3", "nt: -3 is out of range"),
    ("T", "T = 0", r"T: 0 is out of range; allowed: a number in [1e-06, 10000]"),
    ("T", "T = -1", "T: -1 is out of range"),
    ("T", "T = 1e5", "T: 100000 is out of range"),
    ("T", "T = inf", "T: inf is not finite"),
    ("T", "T = nan", "T: nan is not finite"),
    ("T", "T = false", "T: expected a number, got bool"),
    ("T", 'T = "0.3"', "T: expected a number, got str"),
    ("length", "length = 0", r"length: 0 is out of range; allowed: a number in [1e-06, 10000]"),
    ("length", "length = 10001", "length: 10001 is out of range"),
    # issue 27, item 7: these were internal errors (dolfinx's "Length of interval is zero", T/nt divided by 0)
    ("length", "length = 1e-300", "length: 1e-300 is out of range; allowed: a number in [1e-06, 10000]"),
    ("length", "length = 5e-324", "is out of range; allowed: a number in [1e-06, 10000]"),
    ("T", "T = 1e-300", "T: 1e-300 is out of range; allowed: a number in [1e-06, 10000]"),
    ("alpha", "alpha = -0.01", r"alpha: -0.01 is out of range; allowed: a number in [0, 10000]"),
    ("alpha", "alpha = [0.01]", "alpha: expected a number, got list"),
    ("eps", "eps = 0", r"eps: 0 is out of range; allowed: a number in [1e-12, 1000000]"),
    ("eps", "eps = 2e6", "eps: 2000000 is out of range"),
    ("nt", "dt = 0.0007", "dt: 0.0007 does not divide T = 0.3"),
    ("nt", "dt = 0", "dt: expected a positive number"),
    ("nt", "dt = -0.01", "dt: expected a positive number"),
    ("nt", "dt = 1e-300", "dt: T/dt = 3e+299 steps"),
    ("dt", "dt = 0.01", "nt, dt: give exactly one of nt or dt"),
    ("h", "h = 1\nh_left = 1", "h: give either h (both ends) or h_left/h_right"),
    ("h", "h = 1\nh_right = 1", "h: give either h"),
    ("h", 'h = "1"', "h: expected a number, got str"),
    ("h_left", "h_left = 1e7", r"h_left: 10000000 is out of range; allowed: a number in [-1000000, 1000000]"),
    ("h_right", "h_right = nan", "h_right: nan is not finite"),
    ("colour", 'colour = "red"', "unknown key(s) 'colour'; allowed keys are " + ", ".join(FILE_KEYS)),
    ("colour", "[colour]\nred = 1", "unknown key(s) 'colour'"),
    ("output_times", "output_times = [0.1, 0.5]",
     "output_times: 0.5 is out of range; allowed: numbers in [0, T = 0.3]"),
    ("output_times", "output_times = [-0.1]", "output_times: -0.1 is out of range"),
    ("output_times", "output_times = [0.2, 0.1]", "output_times: must be sorted ascending"),
    ("output_times", "output_times = [0.1, 0.1]", "output_times: must be sorted ascending without duplicates"),
    ("output_times", 'output_times = "0.1"', "output_times: expected a list"),
    ("output_times", "output_times = [true]", "output_times: expected numbers"),
    ("eta0", 'eta0 = "y"', "eta0: unknown name 'y'; allowed names are x, l, h, pi"),
    ("eta0", 'eta0 = "h"', "eta0: name 'h' is only available"),
    ("eta0", "eta0 = \"__import__('os')\"", "eta0: double-underscore name '__import__' is not allowed"),
    ("eta0", 'eta0 = "1/x"', "eta0: '1/x' is not finite"),
    ("eta0", "eta0 = true", "eta0: expected an expression string, a number or an array of nodal values, got bool"),
    ("eta0", "eta0 = inf", "eta0: inf is not finite"),
    ("v0", 'v0 = "x.real"', "v0: attribute access"),
    ("v0", "v0 = [1]", "v0: 1 nodal values for nx = "),
    ("v0", 'v0 = ["a", "b"]', "v0: expected numbers in its array"),
    ("load", 'load = "y"', "load: unknown name 'y'; allowed names are x, l, h, pi"),
    ("load", 'load = "1/x"', "load: '1/x' is not finite"),
    ("load", "load = [1]", "load: expected an expression string or a number, got list"),
    ("obstacle", "obstacle = \"__import__('os')\"", "obstacle: double-underscore name '__import__' is not allowed"),
    ("obstacle", "obstacle = true", "obstacle: expected an expression string or a number, got bool"),
    ("model", 'model = "os.system"', "model: unknown model 'os.system'; allowed: cubic_foundation, elastic, film, inelastic, large_deflection, loaded_obstacle"),
    ("model", 'model = "stringcontact.model.variants:elastic"', "model: unknown model 'stringcontact.model.variants:elastic'"),
    ("model", "model = 1", "model: unknown model int 1; allowed: cubic_foundation, elastic"),
    ("name", 'name = ""', "name: invalid name"),
    ("name", 'name = "../evil"', "name: invalid name"),
    ("name", "name = 3", "name: invalid name int 3"),
    ("description", "description = 5", "description: expected a string, got int"),
    ("notes", "notes = [1]", "notes: expected a string, got list"),
]


@pytest.mark.parametrize("key, line, fragment", INVALID, ids=[f"{k}:{ln}" for k, ln, _ in INVALID])
def test_invalid_file(tmp_path, key, line, fragment):
    path = write(tmp_path, with_line(key, line))
    with pytest.raises(SceneError) as info:
        load_quietly(path)
    message = str(info.value)
    assert message.startswith(f"scene {str(path)!r}: ")
    assert fragment in message
    assert "\n" not in message


@pytest.mark.parametrize("key", ["T", "alpha", "nx", "nt", "eta0", "v0"])
def test_missing_required_key(tmp_path, key):
    with pytest.raises(SceneError, match=f"missing required key.*{key}"):
        load_scene(write(tmp_path, with_line(key, "")))


def test_empty_file_names_all_required_keys(tmp_path):
    with pytest.raises(SceneError) as info:
        load_scene(write(tmp_path, ""))
    assert "missing required key(s): T, alpha, nx, eta0, v0 and one of nt or dt" in str(info.value)


def test_binary_file(tmp_path):
    with pytest.raises(SceneError, match="binary file"):
        load_scene(write(tmp_path, bytes(range(256)) * 4))


def test_not_utf8(tmp_path):
    with pytest.raises(SceneError, match=r"not UTF-8 text \(byte 0xff at line 2\)"):
        load_scene(write(tmp_path, b"T = 0.3\nnotes = '\xff'\n"))


def test_invalid_toml_gives_line(tmp_path):
    with pytest.raises(SceneError) as info:
        load_scene(write(tmp_path, VALID + "nx = = 3\n"))
    message = str(info.value)
    assert "invalid TOML" in message and "line 8" in message and "\n" not in message


def test_duplicate_key_is_invalid_toml(tmp_path):
    with pytest.raises(SceneError, match="invalid TOML"):
        load_scene(write(tmp_path, VALID + "nx = 60\n"))


def test_large_file(tmp_path):
    text = VALID + "# " + "x" * 2_000_000 + "\n"
    with pytest.raises(SceneError, match="larger than 1000000 bytes"):
        load_scene(write(tmp_path, text))


def test_bool_is_not_a_number_anywhere(tmp_path):
    for key in ("length", "alpha", "eps", "h_left"):
        with pytest.raises(SceneError, match=f"{key}: expected a number, got bool"):
            load_scene(write(tmp_path, with_line(key, f"{key} = true")))


def test_nan_free_values(tmp_path):
    s = load_scene(write(tmp_path, VALID + "[scheme]\neps = 0.0005\n"))
    assert all(math.isfinite(v) for v in (s.length, s.T, s.alpha, s.eps, s.h_left, s.h_right, s.dt, s.dx, s.r))


# --- optional expression fields: load and obstacle ---------------------------------------------


def test_fields_only_the_keys_given(tmp_path):
    s = load_scene(write(tmp_path, VALID))
    assert s.fields == {} and s.load is None and s.obstacle is None
    with pytest.raises(SceneError, match=r"load: the scene gives no field 'load' \(fields given: none\)"):
        s.field_values("load", [0.0])
    loaded = load_scene(write(tmp_path, VALID + 'load = -10\nobstacle = "0.1*sin(pi*x/l)"\n', "loaded.toml"))
    assert loaded.fields == {"load": "-10", "obstacle": "0.1*sin(pi*x/l)"}
    np.testing.assert_allclose(loaded.field_values("load", [0.0, 0.5]), [-10.0, -10.0])
    np.testing.assert_allclose(loaded.field_values("obstacle", [0.0, 0.5]), [0.0, 0.1], atol=1e-15)
    np.testing.assert_allclose(loaded.obstacle_values([0.5]), [0.1])
    np.testing.assert_array_equal(s.obstacle_values([0.5, 1.0]), [0.0, 0.0])  # no obstacle key: y = 0


def test_fields_round_trip_and_replace(tmp_path):
    s = load_scene("loaded_string")
    assert s.fields == {"load": "-10", "obstacle": "0.2 - 4*(x - 0.5)**2"}
    assert s.model == "loaded_obstacle"
    assert load_scene(write(tmp_path, scene_to_toml(s))) == s
    assert Scene.from_dict(s.as_dict()) == s
    assert list(s.as_dict()).index("load") < list(s.as_dict()).index("obstacle")
    flat = s.replace(obstacle=None)
    assert flat.fields == {"load": "-10"} and "obstacle" not in flat.as_dict()
    assert s.replace(load="-20").field_values("load", [0.3]) == pytest.approx([-20.0])
    with pytest.raises(SceneError, match="load: unknown name 'y'"):
        s.replace(load="y")
    assert "load" not in load_scene("example1").as_dict()  # the paper's scenes are unchanged


def test_warns_below_a_profiled_obstacle(tmp_path):
    # eta0 = 0.05 is above y = 0 but below the bump psi = 0.1 on the middle third.
    text = with_line("eta0", 'eta0 = "0.05"') + 'obstacle = "where(abs(x - 0.5) < 0.15, 0.1, -1)"\n'
    with pytest.warns(SceneWarning, match=r"below the obstacle \(eta0 < obstacle\) at 15 of 51 nodes"):
        load_scene(write(tmp_path, text))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_scene(write(tmp_path, with_line("eta0", 'eta0 = "0.05"'), "no-obstacle.toml"))


@pytest.mark.parametrize("key,value", [("eta0", "2e6*sin(pi*x)"), ("v0", "-1e300"), ("eta0", "1 + 1e7*x*(1-x)")])
def test_huge_data_is_refused_with_the_allowed_range(key, value):
    s = load_scene("example1").replace(nx=100, nt=30)
    with pytest.raises(SceneError, match=rf"{key}: \|{key}\| reaches .*allowed: values in \[-1e\+06, 1e\+06\]"):
        s.replace(**{key: value})
    s.replace(**{key: value.replace("e6", "e5").replace("e300", "e5").replace("e7", "e5")})  # within the range: fine


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_fifo_or_device_is_not_a_regular_file(tmp_path, kind):
    """Refused from its stat alone: opening a FIFO would block, /dev/zero would never end."""
    if kind == "fifo":
        path = tmp_path / "scene.toml"
        os.mkfifo(path)
    else:
        path = Path("/dev/zero")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    expected = "a FIFO" if kind == "fifo" else "a character device"
    assert str(info.value) == f"scene {str(path)!r}: is not a regular file ({expected}); expected a .toml scene file"


@pytest.mark.parametrize("model, value, allowed", [
    ("film", "thick", r"a number in \(0, "),  # film's mu: its own range
    ("stiff_string", True, r"a number in \[0, "),  # stiff_string's beta
    (None, "thick", "a number in the range its model declares"),  # no model yet: the run checks it
])
def test_a_wrong_typed_constant_is_told_its_own_range(model, value, allowed):
    """A [parameters] value that is no number names the constant and the range its model declares, never the table's
    own bound [-1e12, 1e12]."""
    from stringcontact.model.registry import load_model

    base = load_scene("example1")
    name = load_model(model).constants[0].name if model else "mu"
    with pytest.raises(SceneError, match=f"{name}: expected a number, got .*; allowed: {allowed}") as error:
        base.replace(model=model, parameters={name: value})
    assert "-1000000000000" not in str(error.value) and "1e12" not in str(error.value)
    if model:
        assert f"allowed: {load_model(model).constants[0].allowed}" in str(error.value)


# --- the [scheme] table ---------------------------------------------------------------------------


def test_the_scheme_table_gives_the_name_and_the_options(tmp_path):
    text = VALID + '[scheme]\nname = "paper"\neps = 0.0005\npenalty = "semi-implicit"\nmass = "consistent"\n'
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = load_scene(write(tmp_path, text))
    assert s.scheme == "paper" and s.eps == 0.0005
    assert s.scheme_options == {"eps": 0.0005, "penalty": "semi-implicit", "mass": "consistent"}
    assert load_scene(write(tmp_path, scene_to_toml(s), "again.toml")) == s  # `show` writes the table back


def test_eps_at_the_top_level_works_with_one_warning(tmp_path):
    with pytest.warns(SceneWarning, match=r"eps at the top level: the scheme's option; write it in the \[scheme\] "
                                          r"table") as record:
        s = load_scene(write(tmp_path, VALID + "eps = 0.0005\n"))
    assert len(record) == 1 and s.eps == 0.0005 and s.scheme_options == {"eps": 0.0005}


def test_an_option_in_both_places_is_refused_in_one_line(tmp_path):
    with pytest.raises(SceneError, match=r"eps: given twice, at the top level and in \[scheme\]"):
        load_scene(write(tmp_path, VALID + "eps = 0.001\n[scheme]\neps = 0.0005\n"))


def test_the_scene_loads_no_scheme_and_no_dolfinx():
    """Validating a scene, with a scheme and its options, imports no time scheme, dolfinx or PETSc."""
    import subprocess
    import sys

    code = ("import sys, stringcontact as sc\n"
            "s = sc.load_scene('example1').replace(scheme={'name': 'projection', 'mass': 'lumped'}, eps=None)\n"
            "print(sorted(m for m in ('dolfinx', 'petsc4py', 'stringcontact.timestepping') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_scheme_option_the_scheme_does_not_take_is_refused_when_the_run_is_set_up(tmp_path):
    import stringcontact as sc

    s = load_scene(write(tmp_path, VALID + '[scheme]\nname = "projection"\nwobble = 3\n'))
    with pytest.raises(SceneError, match=r"scheme.wobble: scheme 'projection' takes no option 'wobble'; allowed: "
                                         r"mass, petsc_options, restitution"):
        sc.simulate(s)
    with pytest.raises(ValueError, match=r"scheme 'projection' accepts mass lumped, not 'consistent'"):
        sc.simulate(s.replace(scheme={"name": "projection", "mass": "consistent"}))


@pytest.mark.parametrize("values", [[], np.ones(41) + 0j, np.ma.masked_array(np.ones(41), mask=[True] + [False] * 40)])
def test_an_array_of_nodal_values_is_real_numbers_or_one_line(values):
    with pytest.raises(SceneError, match=r"eta0: expected numbers in its array \(real, none masked\)"):
        load_scene("example1").replace(nx=40, eta0=values)
