"""Safe expression evaluation: values, hostile input, and a property test on arbitrary text."""

import builtins

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stringcontact.errors import SceneError
from stringcontact.scene import Scene
from stringcontact.scene.expressions import MAX_LENGTH, evaluate

X = np.linspace(0.0, 1.0, 11)
NAMES = {"l": 1.0}


def ev(expr, x=X, names=NAMES, field="eta0"):
    return evaluate(expr, x, field=field, names=names)


# --- values --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "expr, expected",
    [
        ("1 + 0.5*sin(10*pi*x)**2", 1 + 0.5 * np.sin(10 * np.pi * X) ** 2),
        ("-50", np.full_like(X, -50.0)),
        ("2*l - x", 2.0 - X),
        ("x**2 - 3*x/2 + 1", X**2 - 1.5 * X + 1),
        ("+x", X),
        ("exp(-x) * cos(x) + sqrt(x) + abs(x - 0.5)", np.exp(-X) * np.cos(X) + np.sqrt(X) + np.abs(X - 0.5)),
        ("min(x, 0.3)", np.minimum(X, 0.3)),
        ("max(x, 0.3, 1 - x)", np.maximum(np.maximum(X, 0.3), 1 - X)),
        ("where(x < 0.6, -50, -0.5)", np.where(X < 0.6, -50.0, -0.5)),
        ("0.2 <= x < 0.8", ((X >= 0.2) & (X < 0.8)).astype(float)),
        ("0.8 > x >= 0.2", ((X >= 0.2) & (X < 0.8)).astype(float)),
        ("where(0.2 <= x < 0.8, 1, 0)", ((X >= 0.2) & (X < 0.8)).astype(float)),
        ("(x != 0.5) * 2 + (x == 0.5)", np.where(X == 0.5, 1.0, 2.0)),
        ("-(x > 0.5)", -(X > 0.5).astype(float)),
        ("2**-1 + 7/2", np.full_like(X, 4.0)),  # float semantics: no integer division or int power errors
        ("piecewise(x < 0.3, 1, x < 0.6, 2, 3)", np.select([X < 0.3, X < 0.6], [1.0, 2.0], 3.0)),
        ("piecewise(x < 0.9, 1, x < 0.3, 2, 3)", np.where(X < 0.9, 1.0, 3.0)),  # first true condition wins
    ],
)
def test_values(expr, expected):
    result = ev(expr)
    assert result.dtype == np.float64
    assert result.shape == X.shape
    np.testing.assert_allclose(result, expected, rtol=1e-14, atol=1e-14)


def test_example2_piecewise_as_printed():
    x = np.linspace(0.0, 1.0, 5001)
    eta0 = ev("piecewise(x < 0.2, x, x < 0.8, sin(pi*(x - 0.2)/0.3), 2 - x)", x=x)
    expected = np.where(x < 0.2, x, np.where(x < 0.8, np.sin(np.pi * (x - 0.2) / 0.3), 2 - x))
    np.testing.assert_allclose(eta0, expected, rtol=0, atol=1e-15)
    # Nodes at the jumps take the interval that starts there; 2 - x is extended to x = 1.
    node = {round(v, 6): i for i, v in enumerate(x)}
    assert eta0[node[0.2]] == pytest.approx(0.0, abs=1e-15)
    assert eta0[node[0.8]] == pytest.approx(1.2)
    assert eta0[-1] == pytest.approx(1.0)
    assert eta0.min() == pytest.approx(-1.0)


def test_h_only_when_given():
    np.testing.assert_allclose(ev("h + x", names={"l": 1.0, "h": 0.5}), 0.5 + X)
    with pytest.raises(SceneError, match=r"^eta0: name 'h' is only available.*single boundary height h"):
        ev("h + x")


def test_constant_broadcasts_to_shape_and_is_a_copy():
    x = np.linspace(0, 2, 7).reshape(7)
    a = evaluate("3", x, field="v0", names={"l": 2.0})
    assert a.shape == (7,) and a.dtype == np.float64 and a.flags.writeable
    a[0] = 0.0  # a broadcast view would be read-only
    b = evaluate("x", x, field="v0", names={"l": 2.0})
    b[0] = 99.0
    assert x[0] == 0.0  # the input is not aliased


def test_does_not_use_builtin_eval(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("eval/exec must never be used")

    monkeypatch.setattr(builtins, "eval", refuse)
    monkeypatch.setattr(builtins, "exec", refuse)
    np.testing.assert_allclose(ev("sin(pi*x)"), np.sin(np.pi * X))


def test_a_scene_checks_its_expressions_on_the_probe_grid():
    data = {"T": 0.1, "alpha": 0.0, "nx": 7, "nt": 10, "length": 3.0, "eta0": "sin(pi*x/l)", "v0": "0"}
    Scene.from_dict(data)
    with pytest.raises(SceneError, match="v0: .*not finite"):
        Scene.from_dict(data | {"v0": "1/(x - 1.5)"})  # 1.5 lies on the probe grid over [0, 3], not on nx's nodes


# --- hostile input -------------------------------------------------------------------------

HOSTILE = [
    "__import__('os')",
    "__import__('os').system('echo hacked')",
    "x.__class__",
    "().__class__.__bases__",
    "(1).__class__.__bases__[0].__subclasses__()",
    "x.shape",
    "sin.__globals__",
    "[i for i in x]",
    "{i: 1 for i in x}",
    "(i for i in x)",
    "lambda: 1",
    "(lambda: 1)()",
    "open('f')",
    "eval('1')",
    "exec('1')",
    "getattr(x, 'shape')",
    "import os",
    "from os import system",
    "9**9**9",
    "10**1000",
    "2**-101",
    "x**(50*3)",
    "'a'*10**9",
    "'a'",
    "b'a'",
    "f'{x}'",
    "x[0]",
    "x[0:2]",
    "sin(x, y=1)",
    "where(cond=x, a=1, b=2)",
    "sin(*x)",
    "sin()",
    "sin(x, x)",
    "where(x, 1)",
    "piecewise(x < 1, 1)",
    "max(x)",
    "x(1)",
    "sin",
    "y",
    "X",
    "l(x)",
    "x if x else 1",
    "x and 1",
    "not x",
    "x % 2",
    "x // 2",
    "x @ x",
    "~x",
    "x << 2",
    "x in x",
    "x is x",
    "(y := 2)",
    "[1, 2]",
    "(1, 2)",
    "{1}",
    "{'a': 1}",
    "True",
    "None",
    "...",
    "1j",
    "1" * 31,
    "1e999",
    "x" * 10_000,
    "+" * 10_000 + "x",
    "(" * 2000 + "x" + ")" * 2000,
    "-" * 60 + "x",
    "sin(" * 60 + "x" + ")" * 60,
    "1/0",
    "x/0",
    "sqrt(-1 - x)",
    "exp(1000)",
    "1e308 * 10",
    "0**-1",
    "",
    "   ",
    "1; 2",
    "x = 1",
    "x\0",
    "\ud800",
]


@pytest.mark.parametrize("expr", HOSTILE)
def test_hostile_refused_with_field_name(expr):
    with pytest.raises(SceneError) as info:
        evaluate(expr, X, field="my_field", names=NAMES)
    message = str(info.value)
    assert message.startswith("my_field: ")
    assert "\n" not in message
    assert len(message) < 400


@pytest.mark.parametrize(
    "expr, fragment",
    [
        ("y", "unknown name 'y'; allowed names are x, l, h, pi"),
        ("open('f')", "allowed functions are sin, cos, exp, sqrt, abs, min, max, where, piecewise"),
        ("x.__class__", "attribute access"),
        ("x[0]", "subscripts"),
        ("lambda: 1", "lambda"),
        ("[i for i in x]", "comprehensions"),
        ("'a'", "strings are not allowed"),
        ("sin(x, y=1)", "keyword arguments are not allowed"),
        ("10**1000", "allowed |exponent| <= 100"),
        ("1" * 31, "more than 30 digits"),
        ("x" * 10_000, "at most 500"),
        ("-" * 60 + "x", "nested too deeply"),
        ("1/0", "not finite"),
        ("x if x else 1", "use where(c, a, b)"),
        ("import os", "imports are not allowed"),
    ],
)
def test_hostile_messages_say_what_is_allowed(expr, fragment):
    with pytest.raises(SceneError) as info:
        ev(expr)
    assert fragment in str(info.value)


def test_limits_are_inclusive():
    ev("x**100")  # |exponent| == 100 is allowed
    ev("1" * 30 + " * 0")
    ev("-" * 49 + "x")  # 49 unary minus + the name: 50 levels
    ev("x" + " " * (MAX_LENGTH - 1))


# --- property tests ------------------------------------------------------------------------

TOKENS = [
    "x", "l", "h", "pi", "sin", "cos", "exp", "sqrt", "abs", "min", "max", "where", "piecewise",
    "(", ")", "(", ")", "**", "*", "/", "+", "-", "<", "<=", "==", ",", "9", "0", "1", ".", "e", "_",
    "__", "[", "]", "lambda", "import", " ", ":", "'", "if", "else", "for", "in", "class", "1e308",
]

NAME_SETS = st.sampled_from([{"l": 1.0}, {"l": 2.5, "h": 0.5}, {}])


def assert_finite_or_scene_error(expr, names):
    x = np.linspace(0.0, 1.0, 17)
    try:
        result = evaluate(expr, x, field="eta0", names=names)
    except SceneError as exc:
        assert str(exc).startswith("eta0: ")
        return
    assert isinstance(result, np.ndarray)
    assert result.dtype == np.float64
    assert result.shape == x.shape
    assert np.isfinite(result).all()


@settings(max_examples=300)
@given(expr=st.text(max_size=600), names=NAME_SETS)
def test_arbitrary_text(expr, names):
    assert_finite_or_scene_error(expr, names)


@settings(max_examples=300)
@given(expr=st.lists(st.sampled_from(TOKENS), max_size=80).map("".join), names=NAME_SETS)
def test_token_soup(expr, names):
    assert_finite_or_scene_error(expr, names)


# A grammar of valid-looking expressions reaches evaluation (not just the parser).
_leaf = st.sampled_from(["x", "l", "pi", "0", "1", "9", "0.5", "1e308", "100", "101", "-1"])


def _extend(children):
    binary = st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**", "<", "<=", "!="]), children).map(
        lambda t: f"({t[0]} {t[1]} {t[2]})"
    )
    unary = st.tuples(st.sampled_from(["sin", "cos", "exp", "sqrt", "abs", "-"]), children).map(
        lambda t: f"{t[0]}({t[1]})"
    )
    calls = st.tuples(st.sampled_from(["min", "max"]), children, children).map(lambda t: f"{t[0]}({t[1]}, {t[2]})")
    where = st.tuples(children, children, children).map(lambda t: f"where({t[0]}, {t[1]}, {t[2]})")
    return binary | unary | calls | where


@pytest.mark.slow
@settings(max_examples=300)
@given(expr=st.recursive(_leaf, _extend, max_leaves=30), names=NAME_SETS)
def test_grammar(expr, names):
    assert_finite_or_scene_error(expr, names)


def test_property_tests_have_no_deadline():
    """conftest's profile: no hypothesis test fails because a busy machine was slow."""
    assert settings().deadline is None
    for test in (test_arbitrary_text, test_token_soup, test_grammar):  # their own @settings keep the profile's
        assert test._hypothesis_internal_use_settings.deadline is None
