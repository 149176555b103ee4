"""Safe, vectorised evaluation of user expressions in ``x`` (a scene's initial data and fields).

The text of a scene file is untrusted, so it is never given to ``eval``/``exec``: it is parsed with :mod:`ast`,
checked against a whitelist and evaluated by a restricted :class:`simpleeval.SimpleEval` whose operators are NumPy
ufuncs. Allowed: the names ``x``, ``y`` (2D only, so that a 1D scene cannot silently read ``y = 0``), ``l`` (the
string's length), ``h`` (only when the scene gives a single boundary height), ``t`` (a moving obstacle) and ``pi``;
numbers (an int of at most 30 digits); ``+ - * / **``, unary ``-``/``+``, comparisons ``< <= > >= == !=`` (chains
such as ``0.2 <= x < 0.8`` act elementwise); the functions ``sin cos exp sqrt abs``, ``min max`` (two or more
arguments), ``where(cond, a, b)`` and ``piecewise(c1, v1, c2, v2, ..., default)`` (the first true condition wins).
Anything else is refused with a one-line :class:`SceneError` naming the field and what is allowed.

>>> evaluate("where(x < 0.6, -50, -0.5)", np.array([0.0, 1.0]), field="v0", names={"l": 1.0})
array([-50. ,  -0.5])
"""

from __future__ import annotations

import ast
import functools
import math
import re
import warnings

import numpy as np
from simpleeval import SimpleEval

from ..errors import SceneError, one_line

__all__ = ["ALLOWED_FUNCTIONS", "ALLOWED_NAMES", "MAX_DEPTH", "MAX_LENGTH", "evaluate", "uses_name"]

MAX_LENGTH = 500  # characters in one expression
MAX_DEPTH = 50  # nesting of operators and calls; also keeps the recursive evaluator far from Python's limit
MAX_EXPONENT = 100.0  # |b| in a**b; beyond this the result is inf/0 for any sensible base
MAX_INT_DIGITS = 30  # integer literals; longer ones are almost surely a mistake (or an attack)
PROBE_POINTS = 101  # the grid of `Scene.probe_points` on the interval

ALLOWED_NAMES = ("x", "y", "l", "h", "t", "pi")
ALLOWED_FUNCTIONS = ("sin", "cos", "exp", "sqrt", "abs", "min", "max", "where", "piecewise")

_OPERATORS_TEXT = "+ - * / **, unary -, comparisons < <= > >= == !="
_FUNCTIONS_TEXT = ", ".join(ALLOWED_FUNCTIONS)
_ALLOWED_TEXT = (f"allowed are numbers, names {', '.join(ALLOWED_NAMES)}, operators {_OPERATORS_TEXT} and functions "
                 f"{_FUNCTIONS_TEXT}")


class _Refused(Exception):
    """Raised inside evaluation with a user-facing reason; turned into SceneError with the field."""


def _num(a):
    """Booleans (from comparisons) take part in arithmetic as 0.0/1.0; numpy refuses e.g. -bool."""
    a = np.asarray(a)
    return a.astype(np.float64) if a.dtype == np.bool_ else a


def _arith(ufunc):
    return lambda *args: ufunc(*(_num(a) for a in args))


def _power(base, exponent):
    exponent = _num(exponent)
    with np.errstate(invalid="ignore"):  # checked before np.power: a huge exponent makes an evaluator hang
        too_big = np.abs(exponent) > MAX_EXPONENT
    if np.any(too_big):
        bad = float(np.asarray(exponent)[too_big].flat[0]) if np.ndim(exponent) else float(exponent)
        raise _Refused(f"exponent {bad:g} is too large; allowed |exponent| <= {MAX_EXPONENT:g}")
    return np.power(_num(base), exponent)


def _piecewise(*args):
    result = _num(args[-1])  # from the last pair backwards, so that the FIRST true condition wins
    for i in range(len(args) - 3, -1, -2):
        result = np.where(_num(args[i]) != 0, _num(args[i + 1]), result)
    return result


_BINARY = {ast.Add: _arith(np.add), ast.Sub: _arith(np.subtract), ast.Mult: _arith(np.multiply),
           ast.Div: _arith(np.true_divide), ast.Pow: _power}
_UNARY = {ast.USub: _arith(np.negative), ast.UAdd: _arith(np.positive)}
_COMPARE = {op: _arith(f) for op, f in ((ast.Lt, np.less), (ast.LtE, np.less_equal), (ast.Gt, np.greater),
                                        (ast.GtE, np.greater_equal), (ast.Eq, np.equal), (ast.NotEq, np.not_equal))}
# name -> (function, least number of arguments, most (None: unbounded), usage)
_FUNCTIONS = {
    **{name: (_arith(f), 1, 1, f"{name}(a)") for name, f in (("sin", np.sin), ("cos", np.cos), ("exp", np.exp),
                                                             ("sqrt", np.sqrt), ("abs", np.abs))},
    "min": (lambda *a: functools.reduce(np.minimum, map(_num, a)), 2, None, "min(a, b, ...)"),
    "max": (lambda *a: functools.reduce(np.maximum, map(_num, a)), 2, None, "max(a, b, ...)"),
    "where": (lambda c, a, b: np.where(_num(c) != 0, _num(a), _num(b)), 3, 3, "where(cond, a, b)"),
    "piecewise": (_piecewise, 3, None, "piecewise(c1, v1, c2, v2, ..., default)"),
}
_NODE_REASONS = {
    ast.Attribute: "attribute access (a.b) is not allowed", ast.Subscript: "subscripts/indexing (a[i]) are not allowed",
    ast.Lambda: "lambda is not allowed", ast.IfExp: "'a if c else b' is not allowed; use where(c, a, b)",
    ast.BoolOp: "'and'/'or' are not allowed; use where/piecewise or chained comparisons",
    ast.NamedExpr: "assignment (:=) is not allowed", ast.Starred: "* unpacking is not allowed",
    ast.Slice: "slices are not allowed", ast.JoinedStr: "f-strings are not allowed",
    ast.FormattedValue: "f-strings are not allowed", ast.Await: "await is not allowed",
    **dict.fromkeys((ast.Yield, ast.YieldFrom), "yield is not allowed"),
    **dict.fromkeys((ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp), "comprehensions are not allowed"),
    **{kind: f"{kind.__name__.lower()}s are not allowed" for kind in (ast.List, ast.Tuple, ast.Set, ast.Dict)},
}
_SYMBOLS = {ast.Mod: "%", ast.FloorDiv: "//", ast.MatMult: "@", ast.LShift: "<<", ast.RShift: ">>", ast.BitAnd: "&",
            ast.BitOr: "|", ast.BitXor: "^", ast.Invert: "~", ast.Not: "not", ast.Is: "is", ast.IsNot: "is not",
            ast.In: "in", ast.NotIn: "not in"}


def _validate_tree(tree: ast.Expression, names: dict) -> None:
    """Refuse every node outside the whitelist, with a reason a user can act on (iterative: a deep tree's depth is
    checked here, not by a RecursionError)."""
    stack = [(tree.body, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise _Refused(f"expression is nested too deeply (more than {MAX_DEPTH} levels)")
        children = []
        if isinstance(node, ast.Constant):
            _check_constant(node.value)
        elif isinstance(node, ast.Name):
            _check_name(node.id, names)
        elif isinstance(node, (ast.UnaryOp, ast.BinOp, ast.Compare)):
            ops, table = ((node.ops, _COMPARE) if isinstance(node, ast.Compare) else
                          ([node.op], _UNARY if isinstance(node, ast.UnaryOp) else _BINARY))
            for op in ops:
                if type(op) not in table:
                    shown = repr(_SYMBOLS.get(type(op), type(op).__name__))
                    raise _Refused(f"operator {shown} is not allowed; allowed operators are {_OPERATORS_TEXT}")
            children = [child for child in ast.iter_child_nodes(node) if isinstance(child, ast.expr)]
        elif isinstance(node, ast.Call):
            _check_call(node)
            children = list(node.args)
        else:
            reason = _NODE_REASONS.get(type(node), f"{type(node).__name__} is not allowed")
            raise _Refused(f"{reason}; {_ALLOWED_TEXT}")
        stack.extend((child, depth + 1) for child in children)


def _check_constant(value) -> None:
    if isinstance(value, bool) or value is None or value is Ellipsis:
        raise _Refused(f"literal {value!r} is not allowed; only numbers are")
    if isinstance(value, (str, bytes)):
        raise _Refused("strings are not allowed; only numbers, names and functions are")
    if isinstance(value, complex):
        raise _Refused("complex numbers are not allowed")
    # bit_length first: str() of a huge int is slow (and limited to 4300 digits since 3.11)
    if isinstance(value, int) and (value.bit_length() > 4 * MAX_INT_DIGITS or len(str(abs(value))) > MAX_INT_DIGITS):
        raise _Refused(f"integer literal has more than {MAX_INT_DIGITS} digits")
    if isinstance(value, float) and not math.isfinite(value):
        raise _Refused("number literal is too large (it overflows to inf)")


def _check_name(name: str, names: dict) -> None:
    allowed = ", ".join(n for n in ALLOWED_NAMES if n in names or n == "h")
    if name.startswith("__") or name.endswith("__"):
        raise _Refused(f"double-underscore name {name!r} is not allowed; allowed names are {allowed}")
    if name in names:
        return
    if name == "h":
        raise _Refused("name 'h' is only available when the scene gives a single boundary height h "
                       f"(not h_left/h_right); allowed names are {allowed}")
    if name in _FUNCTIONS:
        raise _Refused(f"{name!r} is a function; call it as {_FUNCTIONS[name][3]}")
    raise _Refused(f"unknown name {name!r}; allowed names are {allowed}")


def _check_call(node: ast.Call) -> None:
    if not isinstance(node.func, ast.Name):
        raise _Refused(f"only direct calls of the functions {_FUNCTIONS_TEXT} are allowed")
    name = node.func.id
    if name in ALLOWED_NAMES:
        raise _Refused(f"{name!r} is a variable, not a function; allowed functions are {_FUNCTIONS_TEXT}")
    if name not in _FUNCTIONS:
        if name.startswith("__") or name.endswith("__"):
            raise _Refused(f"double-underscore name {name!r} is not allowed; allowed functions are {_FUNCTIONS_TEXT}")
        raise _Refused(f"unknown function {name!r}; allowed functions are {_FUNCTIONS_TEXT}")
    _, lo, hi, usage = _FUNCTIONS[name]
    if node.keywords:
        raise _Refused(f"keyword arguments are not allowed; use {usage}")
    if any(isinstance(a, ast.Starred) for a in node.args):
        raise _Refused(f"* unpacking is not allowed; use {usage}")
    n = len(node.args)
    if n < lo or (hi is not None and n > hi) or (name == "piecewise" and n % 2 == 0):
        raise _Refused(f"{name} got {n} argument(s); use {usage}")


class _ArrayEval(SimpleEval):
    """SimpleEval on a tree `_validate_tree` passed, with NumPy semantics: its operators are ufuncs (its guards on
    huge Python ints do not work on arrays: `_power` guards instead), and only the whitelisted nodes are dispatched."""

    def __init__(self, names: dict):
        functions = {name: spec[0] for name, spec in _FUNCTIONS.items()}
        super().__init__(operators={**_BINARY, **_UNARY, **_COMPARE}, functions=functions, names=names)
        self.nodes = {ast.Expression: lambda node: self._eval(node.body), ast.Constant: self._eval_constant,
                      ast.Name: self._eval_name, ast.UnaryOp: self._eval_unaryop, ast.BinOp: self._eval_binop,
                      ast.Compare: self._eval_compare, ast.Call: self._eval_call}

    @staticmethod
    def _eval_constant(node):
        _check_constant(node.value)
        return np.float64(node.value)  # floats: NumPy's ints wrap around silently, and 2**-1 would fail

    def _eval_compare(self, node):
        # a < b < c is (a < b) & (b < c), each operand evaluated once; no short-circuit: "false" varies by point
        left, result = self._eval(node.left), None
        for op, comparator in zip(node.ops, node.comparators):
            right = self._eval(comparator)
            value = self.operators[type(op)](left, right)
            result = value if result is None else np.logical_and(result, value)
            left = right
        return result


def evaluate(expr: str, x: np.ndarray, *, field: str, names: dict[str, float], y: np.ndarray | None = None) -> np.ndarray:
    """``expr`` at the points ``x`` (and ``y`` on a 2D domain), a float64 array of ``x``'s shape; ``names`` gives the
    scalars ``l``, ``t`` (a moving obstacle) and ``h`` (a single boundary height). Any problem with the expression
    raises :class:`SceneError` with a one-line message naming ``field``."""
    unknown = set(names) - {"l", "h", "t"}
    if unknown:  # a programming error, not a user error
        raise ValueError(f"evaluate: names may only contain 'l', 'h' and 't', got {sorted(unknown)}")
    x = np.asarray(x, dtype=np.float64)
    if not isinstance(expr, str):
        raise SceneError(f"{field}: expected an expression string (or a number), got {type(expr).__name__}")
    if len(expr) > MAX_LENGTH:
        raise SceneError(f"{field}: expression is {len(expr)} characters long; at most {MAX_LENGTH} are allowed")
    if not expr.strip():
        raise SceneError(f"{field}: expression is empty; give a number or an expression in x")
    variables = {"x": x, "pi": np.float64(np.pi)} | ({"y": np.asarray(y, dtype=np.float64)} if y is not None else {})
    variables |= {k: np.float64(v) for k, v in names.items() if v is not None}
    short = repr(expr if len(expr) <= 60 else expr[:60] + "...")
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():  # non-finite results are reported below
            warnings.simplefilter("ignore", SyntaxWarning)  # "9if": the user gets an error or a result instead
            tree = ast.parse(expr.strip(), mode="eval")
            _validate_tree(tree, variables)
            value = np.asarray(_num(_ArrayEval(variables).eval(expr, previously_parsed=tree)), dtype=np.float64)
            value = np.array(np.broadcast_to(value, x.shape), dtype=np.float64)
    except _Refused as exc:
        raise SceneError(f"{field}: {exc}") from None
    except SyntaxError as exc:
        if re.match(r"\s*(import|from)\b", expr):
            raise SceneError(f"{field}: imports are not allowed; give an expression in x") from None
        where = f" at column {exc.offset}" if exc.offset else ""
        raise SceneError(f"{field}: invalid syntax{where} ({one_line(exc.msg)}) in {short}; {_ALLOWED_TEXT}") from None
    except RecursionError:
        raise SceneError(f"{field}: expression is nested too deeply; at most {MAX_DEPTH} levels are allowed") from None
    except Exception as exc:  # noqa: BLE001 - untrusted input: every failure must become a SceneError
        reason = f"{type(exc).__name__}: {one_line(exc)}"[:200]
        raise SceneError(f"{field}: cannot evaluate {short}: {reason}") from None
    bad = ~np.isfinite(value)
    if bad.any():
        first = np.flatnonzero(bad.ravel())[0]
        raise SceneError(f"{field}: {short} is not finite (nan or inf) at {int(bad.sum())} of {bad.size} points, "
                         f"first at x={x.ravel()[first]:.6g}; check divisions, sqrt/powers of negatives and overflow")
    return value


def uses_name(expr: str, name: str) -> bool:
    """Whether the (valid) expression ``expr`` reads the variable ``name`` (``t``: a moving obstacle)."""
    return any(isinstance(node, ast.Name) and node.id == name for node in ast.walk(ast.parse(expr.strip(), mode="eval")))
