"""Evaluate a pointwise UFL expression at the P1 nodes, vectorised with NumPy.

This is P1 interpolation of the expression (what `Function.interpolate(fem.Expression(...))`
computes), but without a compiled kernel call per cell: in 1D that call costs ~0.6 ms per step
at N=5000, more than the whole time step. The UFL expression stays the single definition of the
contact law; this module only walks its graph.
"""

from __future__ import annotations

import numpy as np
import ufl
from ufl.corealg.map_dag import map_expr_dag
from ufl.corealg.multifunction import MultiFunction

_UNARY = {
    "abs": np.abs,
    "sqrt": np.sqrt,
    "exp": np.exp,
    "ln": np.log,
    "sin": np.sin,
    "cos": np.cos,
    "tanh": np.tanh,
    "not_condition": np.logical_not,
}
_BINARY = {
    "division": np.divide,
    "power": np.power,
    "max_value": np.maximum,
    "min_value": np.minimum,
    "lt": np.less,
    "le": np.less_equal,
    "gt": np.greater,
    "ge": np.greater_equal,
    "eq": np.equal,
    "ne": np.not_equal,
    "and_condition": np.logical_and,
    "or_condition": np.logical_or,
}


def _is_minus_one(o) -> bool:
    return isinstance(o, (ufl.classes.IntValue, ufl.classes.RealValue)) and float(o) == -1.0


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

        if _is_minus_one(o.ufl_operands[0]):
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
        raise ValueError(
            f"nodal evaluation: UFL operator {type(o).__name__} is not supported in a pointwise "
            "law; use arithmetic, conditional, max_value/min_value, abs, sqrt, exp, ln, sin, cos, tanh"
        )

    def terminal(self, o):
        raise ValueError(f"nodal evaluation: UFL terminal {type(o).__name__} is not supported in a pointwise law")


class NodalExpression:
    """A UFL expression compiled once into NumPy calls; call it with the nodal arrays."""

    def __init__(self, expr):
        self.expr = expr
        self._f = map_expr_dag(_Compiler(), expr, compress=False)

    def __call__(self, coefficients: dict, x: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            return self.evaluate_env(environment(coefficients, x))

    def evaluate_env(self, env: dict) -> np.ndarray:
        """The hot-loop form: `env` is made by `environment`; the caller owns np.errstate.

        A time loop keeps one `env` and only swaps its arrays (`env[id(f)] = array`), so no dict and
        no error-state context is built per step.
        """
        value = np.asarray(self._f(env))
        shape = env["x"].shape[:1]  # one value per node, in 1D and 2D
        return value if value.shape == shape else np.broadcast_to(value, shape)


def environment(coefficients: dict, x: np.ndarray) -> dict:
    """The evaluation environment: nodal arrays keyed by `id` of each coefficient, and "x"."""
    env = {id(f): a for f, a in coefficients.items()}
    env["x"] = x
    return env


def evaluate(expr, coefficients: dict, x: np.ndarray) -> np.ndarray:
    """Nodal values of `expr`; `coefficients` maps each P1 `Function` in it to its dof array."""
    return NodalExpression(expr)(coefficients, x)
