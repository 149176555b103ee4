"""Safe, vectorised evaluation of user expressions in ``x`` (initial data of a scene).

The text of a scene file is untrusted, so it is never given to ``eval``/``exec``.
It is parsed with :mod:`ast`, checked against a whitelist, and evaluated by a
restricted :class:`simpleeval.SimpleEval` whose operators are numpy ufuncs.

Allowed:

* names ``x`` (node coordinates), ``l`` (string length), ``pi``, and ``h``
  (the boundary height, only when the scene gives a single ``h``); on a 2D domain also ``y``
  (in 1D ``y`` is an unknown name, so that a 1D scene cannot silently read ``y = 0``);
* numbers (int or float literals; an int may have at most 30 digits);
* ``+ - * / **``, unary ``-`` and ``+``, comparisons ``< <= > >= == !=``
  (chained comparisons such as ``0.2 <= x < 0.8`` act elementwise);
* functions ``sin cos exp sqrt abs`` (one argument), ``min max`` (elementwise,
  two or more arguments), ``where(cond, a, b)`` and
  ``piecewise(c1, v1, c2, v2, ..., default)`` (the first true condition wins).

Everything else (attributes, subscripts, strings, lambdas, comprehensions,
keyword arguments, ...) is refused with a :class:`SceneError` whose one-line
message names the field and what is allowed.

Example
-------
>>> import numpy as np
>>> evaluate("where(x < 0.6, -50, -0.5)", np.array([0.0, 1.0]), field="v0", names={"l": 1.0})
array([-50. ,  -0.5])
"""

from __future__ import annotations

import ast
import math
import re
import warnings

import numpy as np
from simpleeval import SimpleEval

from ..errors import SceneError, one_line

__all__ = ["ALLOWED_FUNCTIONS", "ALLOWED_NAMES", "MAX_DEPTH", "MAX_LENGTH", "check", "evaluate", "uses_name"]

MAX_LENGTH = 500  # characters in one expression
MAX_DEPTH = 50  # nesting of operators/calls; also keeps the recursive evaluator far from Python's recursion limit
MAX_EXPONENT = 100.0  # |b| in a**b; beyond this the result is inf/0 for any sensible base
MAX_INT_DIGITS = 30  # integer literals; longer ones are almost surely a mistake (or an attack)
PROBE_POINTS = 101  # grid used by check()

ALLOWED_NAMES = ("x", "y", "l", "h", "t", "pi")
ALLOWED_FUNCTIONS = ("sin", "cos", "exp", "sqrt", "abs", "min", "max", "where", "piecewise")

_OPERATORS_TEXT = "+ - * / **, unary -, comparisons < <= > >= == !="
_FUNCTIONS_TEXT = ", ".join(ALLOWED_FUNCTIONS)
_NAMES_TEXT = ", ".join(ALLOWED_NAMES)
_ALLOWED_TEXT = f"allowed are numbers, names {_NAMES_TEXT}, operators {_OPERATORS_TEXT} and functions {_FUNCTIONS_TEXT}"


# --- numpy operators -------------------------------------------------------------------


def _num(a):
    """Booleans (from comparisons) take part in arithmetic as 0.0/1.0; numpy refuses e.g. -bool."""
    a = np.asarray(a)
    return a.astype(np.float64) if a.dtype == np.bool_ else a


def _arith(ufunc):
    def op(*args):
        return ufunc(*(_num(a) for a in args))

    op.__name__ = ufunc.__name__
    return op


def _power(base, exponent):
    exponent = _num(exponent)
    # Check before np.power: a huge exponent is the classic way to make an evaluator hang or overflow.
    with np.errstate(invalid="ignore"):
        too_big = np.abs(exponent) > MAX_EXPONENT
    if np.any(too_big):
        bad = float(np.asarray(exponent)[too_big].flat[0]) if np.ndim(exponent) else float(exponent)
        raise _Refused(f"exponent {bad:g} is too large; allowed |exponent| <= {MAX_EXPONENT:g}")
    return np.power(_num(base), exponent)


_BINARY = {
    ast.Add: _arith(np.add),
    ast.Sub: _arith(np.subtract),
    ast.Mult: _arith(np.multiply),
    ast.Div: _arith(np.true_divide),
    ast.Pow: _power,
}
_UNARY = {ast.USub: _arith(np.negative), ast.UAdd: _arith(np.positive)}
# Comparisons act on floats; the results stay boolean so they can feed where/piecewise.
_COMPARE = {
    ast.Lt: _arith(np.less),
    ast.LtE: _arith(np.less_equal),
    ast.Gt: _arith(np.greater),
    ast.GtE: _arith(np.greater_equal),
    ast.Eq: _arith(np.equal),
    ast.NotEq: _arith(np.not_equal),
}


# --- whitelisted functions, with their arity ---------------------------------------------


def _minimum(*args):
    return _reduce(np.minimum, args)


def _maximum(*args):
    return _reduce(np.maximum, args)


def _reduce(ufunc, args):
    result = _num(args[0])
    for a in args[1:]:
        result = ufunc(result, _num(a))
    return result


def _where(cond, a, b):
    return np.where(_num(cond) != 0, _num(a), _num(b))


def _piecewise(*args):
    # Build from the last pair backwards so that the FIRST true condition wins.
    result = _num(args[-1])
    for i in range(len(args) - 3, -1, -2):
        result = np.where(_num(args[i]) != 0, _num(args[i + 1]), result)
    return result


# name -> (function, minimum number of args, maximum (None: unbounded), usage)
_FUNCTIONS = {
    "sin": (_arith(np.sin), 1, 1, "sin(a)"),
    "cos": (_arith(np.cos), 1, 1, "cos(a)"),
    "exp": (_arith(np.exp), 1, 1, "exp(a)"),
    "sqrt": (_arith(np.sqrt), 1, 1, "sqrt(a)"),
    "abs": (_arith(np.abs), 1, 1, "abs(a)"),
    "min": (_minimum, 2, None, "min(a, b, ...)"),
    "max": (_maximum, 2, None, "max(a, b, ...)"),
    "where": (_where, 3, 3, "where(cond, a, b)"),
    "piecewise": (_piecewise, 3, None, "piecewise(c1, v1, c2, v2, ..., default)"),
}


# --- whitelist check on the syntax tree ------------------------------------------------------


class _Refused(Exception):
    """Raised inside evaluation with a user-facing reason; turned into SceneError with the field."""


_NODE_REASONS = {
    ast.Attribute: "attribute access (a.b) is not allowed",
    ast.Subscript: "subscripts/indexing (a[i]) are not allowed",
    ast.Lambda: "lambda is not allowed",
    ast.ListComp: "comprehensions are not allowed",
    ast.SetComp: "comprehensions are not allowed",
    ast.DictComp: "comprehensions are not allowed",
    ast.GeneratorExp: "comprehensions are not allowed",
    ast.List: "lists are not allowed",
    ast.Tuple: "tuples are not allowed",
    ast.Set: "sets are not allowed",
    ast.Dict: "dicts are not allowed",
    ast.JoinedStr: "f-strings are not allowed",
    ast.FormattedValue: "f-strings are not allowed",
    ast.IfExp: "'a if c else b' is not allowed; use where(c, a, b)",
    ast.BoolOp: "'and'/'or' are not allowed; use where/piecewise or chained comparisons",
    ast.NamedExpr: "assignment (:=) is not allowed",
    ast.Starred: "* unpacking is not allowed",
    ast.Await: "await is not allowed",
    ast.Yield: "yield is not allowed",
    ast.YieldFrom: "yield is not allowed",
    ast.Slice: "slices are not allowed",
}


def _validate_tree(tree: ast.Expression, names: dict) -> None:
    """Refuse every node outside the whitelist, with a reason a user can act on."""
    stack = [(tree.body, 1)]  # iterative: the tree may be deep and we check depth ourselves
    while stack:
        node, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise _Refused(f"expression is nested too deeply (more than {MAX_DEPTH} levels)")
        children = []
        if isinstance(node, ast.Constant):
            _check_constant(node.value)
        elif isinstance(node, ast.Name):
            _check_name(node.id, names)
        elif isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARY:
                raise _Refused(f"operator {_op_text(node.op)} is not allowed; allowed operators are {_OPERATORS_TEXT}")
            children = [node.operand]
        elif isinstance(node, ast.BinOp):
            if type(node.op) not in _BINARY:
                raise _Refused(f"operator {_op_text(node.op)} is not allowed; allowed operators are {_OPERATORS_TEXT}")
            children = [node.left, node.right]
        elif isinstance(node, ast.Compare):
            for op in node.ops:
                if type(op) not in _COMPARE:
                    raise _Refused(f"operator {_op_text(op)} is not allowed; allowed operators are {_OPERATORS_TEXT}")
            children = [node.left, *node.comparators]
        elif isinstance(node, ast.Call):
            _check_call(node)
            children = list(node.args)
        else:
            reason = _NODE_REASONS.get(type(node), f"{type(node).__name__} is not allowed")
            raise _Refused(f"{reason}; {_ALLOWED_TEXT}")
        stack.extend((child, depth + 1) for child in children)


def _op_text(op) -> str:
    symbols = {
        ast.Mod: "%", ast.FloorDiv: "//", ast.MatMult: "@", ast.LShift: "<<", ast.RShift: ">>",
        ast.BitAnd: "&", ast.BitOr: "|", ast.BitXor: "^", ast.Invert: "~", ast.Not: "not",
        ast.Is: "is", ast.IsNot: "is not", ast.In: "in", ast.NotIn: "not in",
    }
    return repr(symbols.get(type(op), type(op).__name__))


def _check_constant(value) -> None:
    if isinstance(value, bool) or value is None or value is Ellipsis:
        raise _Refused(f"literal {value!r} is not allowed; only numbers are")
    if isinstance(value, (str, bytes)):
        raise _Refused("strings are not allowed; only numbers, names and functions are")
    if isinstance(value, complex):
        raise _Refused("complex numbers are not allowed")
    if isinstance(value, int):
        # bit_length first: str() of a huge int is slow (and limited to 4300 digits since 3.11).
        if value.bit_length() > 4 * MAX_INT_DIGITS or len(str(abs(value))) > MAX_INT_DIGITS:
            raise _Refused(f"integer literal has more than {MAX_INT_DIGITS} digits")
    elif isinstance(value, float):
        if not math.isfinite(value):
            raise _Refused("number literal is too large (it overflows to inf)")
    else:  # pragma: no cover - ast produces no other constants today
        raise _Refused(f"literal of type {type(value).__name__} is not allowed")


def _check_name(name: str, names: dict) -> None:
    if name.startswith("__") or name.endswith("__"):
        raise _Refused(
            f"double-underscore name {name!r} is not allowed; allowed names are {_allowed_names_text(names)}"
        )
    if name in names:
        return
    if name == "h":
        raise _Refused(
            "name 'h' is only available when the scene gives a single boundary height h "
            "(not h_left/h_right); allowed names are " + _allowed_names_text(names)
        )
    if name in _FUNCTIONS:
        raise _Refused(f"{name!r} is a function; call it as {_FUNCTIONS[name][3]}")
    raise _Refused(f"unknown name {name!r}; allowed names are {_allowed_names_text(names)}")


def _allowed_names_text(names: dict) -> str:
    return ", ".join(n for n in ALLOWED_NAMES if n in names or n == "h")


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


# --- the evaluator ------------------------------------------------------------------------


class _ArrayEval(SimpleEval):
    """SimpleEval restricted to the whitelist, with numpy semantics.

    simpleeval's default operators guard against huge Python ints/strings with checks
    that do not work on arrays (``abs(a) > MAX_POWER`` is ambiguous for an array), so
    the operators are replaced by ufuncs and the guards are done in _validate_tree and
    _power instead.  Unsupported node types are dropped from the dispatch table, so
    even a tree that slipped past _validate_tree could not reach attributes or subscripts.
    """

    def __init__(self, names: dict):
        operators = {**_BINARY, **_UNARY, **_COMPARE}
        functions = {name: spec[0] for name, spec in _FUNCTIONS.items()}
        super().__init__(operators=operators, functions=functions, names=names)
        self.nodes = {
            ast.Expression: lambda node: self._eval(node.body),
            ast.Constant: self._eval_constant,
            ast.Name: self._eval_name,
            ast.UnaryOp: self._eval_unaryop,
            ast.BinOp: self._eval_binop,
            ast.Compare: self._eval_compare,
            ast.Call: self._eval_call,
        }

    @staticmethod
    def _eval_constant(node):
        _check_constant(node.value)
        # Floats throughout: numpy int arithmetic would wrap around silently, and 2**-1 would fail.
        return np.float64(node.value)

    def _eval_name(self, node):
        try:
            return self.names[node.id]
        except KeyError:
            raise _Refused(f"unknown name {node.id!r}") from None

    def _eval_compare(self, node):
        # Elementwise chain: a < b < c means (a < b) & (b < c), each operand evaluated once;
        # no short-circuit, since "false" differs from point to point.
        left = self._eval(node.left)
        result = None
        for op, comparator in zip(node.ops, node.comparators):
            right = self._eval(comparator)
            value = self.operators[type(op)](left, right)
            result = value if result is None else np.logical_and(result, value)
            left = right
        return result

    def _eval_call(self, node):
        _check_call(node)
        func = self.functions[node.func.id]
        return func(*[self._eval(a) for a in node.args])


# --- public API ------------------------------------------------------------------------


def evaluate(expr: str, x: np.ndarray, *, field: str, names: dict[str, float], y: np.ndarray | None = None) -> np.ndarray:
    """Evaluate ``expr`` at the points ``x`` (and ``y`` on a 2D domain); returns a float64 array of ``x``'s shape.

    ``names`` gives the scalar variables besides ``x`` and ``pi``: ``l``, ``t`` (the time, for a moving
    obstacle only) and, if the scene has a single boundary height, ``h``. Any problem with the
    expression raises :class:`SceneError` with a one-line message naming ``field``.
    """
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

    variables = {"x": x, "pi": np.float64(np.pi)}
    if y is not None:
        variables["y"] = np.asarray(y, dtype=np.float64)
    variables.update({k: np.float64(v) for k, v in names.items() if v is not None})
    try:
        with np.errstate(all="ignore"):  # non-finite results are reported below, not warned about
            with warnings.catch_warnings():
                # The parser warns about things like "9if"; the user gets an error or a result instead.
                warnings.simplefilter("ignore", SyntaxWarning)
                tree = ast.parse(expr.strip(), mode="eval")
            _validate_tree(tree, variables)
            value = _ArrayEval(variables).eval(expr, previously_parsed=tree)
            value = np.asarray(_num(value), dtype=np.float64)
            value = np.array(np.broadcast_to(value, x.shape), dtype=np.float64)
    except SceneError:
        raise
    except _Refused as exc:
        raise SceneError(f"{field}: {exc}") from None
    except SyntaxError as exc:
        if re.match(r"\s*(import|from)\b", expr):
            raise SceneError(f"{field}: imports are not allowed; give an expression in x") from None
        where = f" at column {exc.offset}" if exc.offset else ""
        raise SceneError(
            f"{field}: invalid syntax{where} ({one_line(exc.msg)}) in {_short(expr)}; {_ALLOWED_TEXT}"
        ) from None
    except RecursionError:
        raise SceneError(f"{field}: expression is nested too deeply; at most {MAX_DEPTH} levels are allowed") from None
    except Exception as exc:  # noqa: BLE001 - untrusted input: every failure must become a SceneError
        reason = f"{type(exc).__name__}: {one_line(exc)}"[:200]
        raise SceneError(f"{field}: cannot evaluate {_short(expr)}: {reason}") from None

    bad = ~np.isfinite(value)
    if bad.any():
        first = np.flatnonzero(bad.ravel())[0]
        raise SceneError(
            f"{field}: {_short(expr)} is not finite (nan or inf) at {int(bad.sum())} of {bad.size} points, "
            f"first at x={x.ravel()[first]:.6g}; check divisions, sqrt/powers of negatives and overflow"
        )
    return value


def check(expr: str, *, field: str, names: dict[str, float]) -> None:
    """Validate ``expr`` by evaluating it on a small grid over [0, l]; raises SceneError if invalid.

    (A 2D scene evaluates its expressions at its own probe points: `Scene.probe_points`.)"""
    length = float(names.get("l", 1.0))
    evaluate(expr, np.linspace(0.0, length, PROBE_POINTS), field=field, names=names)


def uses_name(expr: str, name: str) -> bool:
    """Whether the (valid) expression ``expr`` reads the variable ``name`` (``t``: a moving obstacle)."""
    return any(isinstance(node, ast.Name) and node.id == name for node in ast.walk(ast.parse(expr.strip(), mode="eval")))


def _short(expr: str, limit: int = 60) -> str:
    text = expr if len(expr) <= limit else expr[:limit] + "..."
    return repr(text)
