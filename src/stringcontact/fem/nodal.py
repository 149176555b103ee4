"""Evaluate a pointwise UFL expression at the P1 nodes, vectorised with NumPy: `fem.Expression`'s kernel call per cell
costs ~0.6 ms per step at N = 5000 in 1D, more than the whole step (tests/fem/test_nodal.py checks the two agree)."""

from __future__ import annotations

import functools

import numpy as np
import ufl
from ufl.corealg.map_dag import map_expr_dag
from ufl.corealg.multifunction import MultiFunction

_UNARY = {"abs": np.abs, "sqrt": np.sqrt, "exp": np.exp, "ln": np.log, "sin": np.sin, "cos": np.cos, "tanh": np.tanh,
          "not_condition": np.logical_not}
_BINARY = {"division": np.divide, "power": np.power, "max_value": np.maximum, "min_value": np.minimum, "lt": np.less,
           "le": np.less_equal, "gt": np.greater, "ge": np.greater_equal, "eq": np.equal, "ne": np.not_equal,
           "and_condition": np.logical_and, "or_condition": np.logical_or}


def _is_number(o, value: float) -> bool:
    """Whether `o` is the UFL number `value` (UFL's `Zero` counts as 0)."""
    if isinstance(o, ufl.classes.Zero):
        return value == 0.0
    return isinstance(o, ufl.classes.RealValue) and float(o) == value


class _Compiler(MultiFunction):
    """Turns each UFL node into a closure `env -> array`, once; evaluation then only calls NumPy."""

    def coefficient(self, o):
        key = id(o)  # hashing a UFL coefficient walks its repr: far too slow for a per-step lookup

        def value(env):
            try:
                return env[key]
            except KeyError:
                raise ValueError(f"nodal evaluation: no nodal values given for coefficient {o}") from None

        return value

    def constant(self, o):
        value = o.value  # dolfinx: a view of the constant's storage, so later changes are seen
        if isinstance(value, np.ndarray) and value.shape == ():
            return lambda env: float(value)
        return lambda env: float(np.asarray(o.value))

    def constant_value(self, o):
        c = float(o)
        return lambda env: c

    def zero(self, o):
        return lambda env: 0.0

    def spatial_coordinate(self, o):
        return lambda env: env["x"]

    def indexed(self, o, operand, index):
        if not isinstance(o.ufl_operands[0], ufl.classes.SpatialCoordinate):
            raise ValueError(f"nodal evaluation: only x[i] may be indexed, not {o}")
        i = int(o.ufl_operands[1][0])

        def value(env):  # 1D: x is the (N,) coordinate array itself; 2D: (N, 2), x[i] is a column
            x = operand(env)
            return x if x.ndim == 1 else x[:, i]

        return value

    def multi_index(self, o):
        return None

    def conditional(self, o, c, a, b):
        return lambda env: np.where(c(env), a(env), b(env))

    def product(self, o, a, b):
        def value(env):
            return np.multiply(a(env), b(env))

        if _is_number(o.ufl_operands[0], -1.0):
            value.negated = b  # -1*b: a sum with it becomes a subtraction of b (see `sum`)
        return value

    def sum(self, o, a, b):
        # a - b is written Sum(a, Product(-1, b)) in UFL: one np.subtract, bit-identical to a + (-1*b)
        for kept, other in ((a, b), (b, a)):
            negated = getattr(other, "negated", None)
            if negated is not None:
                return lambda env: np.subtract(kept(env), negated(env))
        return lambda env: np.add(a(env), b(env))

    def operator(self, o, *ops):
        name = o._ufl_handler_name_
        if name in _UNARY:
            f, (a,) = _UNARY[name], ops
            return lambda env: f(a(env))
        if name in _BINARY:
            f, (a, b) = _BINARY[name], ops
            return lambda env: f(a(env), b(env))
        raise ValueError(f"nodal evaluation: UFL operator {type(o).__name__} is not supported in a pointwise law; use "
                         "arithmetic, conditional, max_value/min_value, abs, sqrt, exp, ln, sin, cos, tanh")

    def terminal(self, o):
        raise ValueError(f"nodal evaluation: UFL terminal {type(o).__name__} is not supported in a pointwise law")


def _compile(expr):
    return map_expr_dag(_Compiler(), expr, compress=False)


def _conjuncts(c) -> list:
    """c = c1 ∧ c2 ∧ ... as the list of its conjuncts (nested `ufl.And`s flattened)."""
    if isinstance(c, ufl.classes.AndCondition):
        return [part for operand in c.ufl_operands for part in _conjuncts(operand)]
    return [c]


class _Subset(dict):
    """An evaluation environment restricted to the nodes `idx` of `parent`, each array sliced on first use."""

    def __init__(self, parent: dict, idx: np.ndarray):
        super().__init__()
        self.parent, self.idx = parent, idx

    def __missing__(self, key):
        self[key] = self.parent[key][self.idx]
        return self[key]


class NodalExpression:
    """A UFL expression compiled once into NumPy calls; call it with the nodal arrays. A law conditional(c1 ∧ c2 ∧
    ..., a, 0) is evaluated only where c1 holds, bit for bit (18-22 µs against 24-26: bench_step.py --law)."""

    def __init__(self, expr):
        self.expr = expr
        self._f = _compile(expr)
        self._candidates = self._rest = None
        if isinstance(expr, ufl.classes.Conditional) and _is_number(expr.ufl_operands[2], 0.0):
            first, *rest = _conjuncts(expr.ufl_operands[0])
            self._candidates = _compile(first)
            value = expr.ufl_operands[1]
            self._rest = _compile(ufl.conditional(functools.reduce(ufl.And, rest), value, 0) if rest else value)

    def __call__(self, coefficients: dict, x: np.ndarray) -> np.ndarray:
        """Its values at the nodes `x`; `coefficients` maps each P1 Function in it to its nodal array."""
        with np.errstate(all="ignore"):
            return self.evaluate_env(environment(coefficients, x))

    def evaluate_env(self, env: dict) -> np.ndarray:
        """The hot-loop form on `environment`'s `env` (swap its arrays: ``env[id(f)] = array``); no np.errstate."""
        shape = env["x"].shape[:1]  # one value per node, in 1D and 2D
        if self._candidates is not None:
            return self._on_candidates(env, shape)
        value = np.asarray(self._f(env))
        return value if value.shape == shape else np.broadcast_to(value, shape)

    def _on_candidates(self, env: dict, shape: tuple) -> np.ndarray:
        """conditional(c1 ∧ rest, a, 0): c1 everywhere, `rest` and `a` on the span where c1 holds (views), or on its
        indices where they are sparse in it (a 2-D mesh's node order)."""
        c1 = np.asarray(self._candidates(env))
        c1 = c1 if c1.shape == shape else np.broadcast_to(c1, shape)
        out = np.zeros(shape)
        first, last = _span(c1)
        if first < 0:
            return out
        count = int(np.count_nonzero(c1[first:last]))
        if count * SPARSE < last - first:
            idx = np.flatnonzero(c1)
            out[idx] = self._rest(_Subset(env, idx))
        else:
            span = slice(first, last)
            np.copyto(out[span], self._rest(_Subset(env, span)), where=c1[span])
        return out


def _span(c1: np.ndarray) -> tuple[int, int]:
    """(first, last + 1) of the True entries of `c1`, or (-1, 0): memchr, 1.0 µs at 5001 nodes against argmax's 3.2."""
    raw = c1.view(np.uint8).tobytes()
    return raw.find(1), raw.rfind(1) + 1


#: Indices (copies) instead of a span (views) when fewer than 1/SPARSE of the span's nodes are candidates.
SPARSE = 4


def environment(coefficients: dict, x: np.ndarray) -> dict:
    """The evaluation environment: nodal arrays keyed by `id` of each coefficient, and "x"."""
    return {id(f): a for f, a in coefficients.items()} | {"x": x}


def evaluate(expr, coefficients: dict, x: np.ndarray) -> np.ndarray:
    """Nodal values of `expr`; `coefficients` maps each P1 `Function` in it to its dof array."""
    return NodalExpression(expr)(coefficients, x)
