"""A model's constants: what a model declares (`ModelConstant`) and a scene's ``[parameters]`` table (``k = 2000``)
checked against it: its form by `check_table`, its values by `resolve_parameters` (for the scene's model, and again
for the model a run uses, before anything is written)."""

from __future__ import annotations

import contextvars
import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError

__all__ = ["PARAMETERS_MAX", "ModelConstant", "check_table", "resolve_parameters"]

#: The most constants a ``[parameters]`` table may hold.
PARAMETERS_MAX = 64
#: The widest range a constant may declare (a scene's numbers are bounded like its other keys').
MAGNITUDE = 1e12
#: A constant's range before its model is known (the run checks it against the model's).
_UNKNOWN_RANGE = "a number in the range its model declares (`stringcontact models`)"
#: The constants of the model a run will use, known before its scene is read (the command line's ``--model``): a
#: ``[parameters]`` value the scene's own model does not declare is told its range there (`check_table`).
RUN_CONSTANTS: contextvars.ContextVar = contextvars.ContextVar("RUN_CONSTANTS", default=())


def fmt(v) -> str:
    """A number as a scene writes it: 3 for 3.0, repr otherwise."""
    v = float(v)
    return str(int(v)) if v.is_integer() and abs(v) < 1e16 else repr(v)


def describe(value) -> str:
    """A value's type and its repr (at most 40 characters): what a message says it got."""
    text = repr(value)
    return f"{type(value).__name__} {text[:40] + '...' if len(text) > 40 else text}"


def is_number(value) -> bool:
    """A real number, not a bool (`nx = true` is surely a mistake)."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def check_number(name: str, value, allowed: str, inside=lambda v: True) -> float:
    """`value` as a float if a finite number (not a bool) for which `inside` holds, else a one-line `SceneError`."""
    if not is_number(value):
        raise SceneError(f"{name}: expected a number, got {describe(value)}; allowed: {allowed}")
    try:
        v = float(value)
    except OverflowError:  # an int beyond float's range
        v = math.inf
    if not math.isfinite(v):
        raise SceneError(f"{name}: {value!r} is not finite; allowed: {allowed}")
    if not inside(v):
        raise SceneError(f"{name}: {fmt(v)} is out of range; allowed: {allowed}")
    return v


@dataclass(frozen=True)
class ModelConstant:
    """One constant a model declares: a scene sets it in ``[parameters]``, the forms read it as a dolfinx
    ``Constant`` in ``Parameters.constants[name]`` (a value can change between steps without recompiling).

    `default` is the value when the scene gives none; with ``required=True`` the scene must give it; with neither,
    an absent constant is absent from ``Parameters.constants`` too. The allowed range is [`low`, `high`], open at
    an end with `low_open`/`high_open`. `unit` and `description` (one line) are shown by ``stringcontact show``.
    """

    name: str
    default: float | None = None
    low: float = -MAGNITUDE
    high: float = MAGNITUDE
    low_open: bool = False
    high_open: bool = False
    unit: str = ""
    description: str = ""
    required: bool = False

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"ModelConstant: name must be an identifier, not {self.name!r}")
        if not -MAGNITUDE <= self.low <= self.high <= MAGNITUDE:
            raise ValueError(f"ModelConstant {self.name!r}: need -1e12 <= low <= high <= 1e12")
        if self.low == self.high and (self.low_open or self.high_open):
            raise ValueError(f"ModelConstant {self.name!r}: {self.allowed} holds no number")
        if self.default is not None:
            self.check(self.default)

    @property
    def allowed(self) -> str:
        """The allowed range in words, as the error messages give it: ``a number in (0, 1e+06]``."""
        return (f"a number in {'(' if self.low_open else '['}{fmt(self.low)}, "
                f"{fmt(self.high)}{')' if self.high_open else ']'}")

    def check(self, value) -> float:
        """`value` as a float if it is a finite number in range, else a one-line `SceneError` naming the constant."""
        lo, hi = self.low, self.high
        return check_number(self.name, value, self.allowed, lambda v: (lo < v if self.low_open else lo <= v)
                            and (v < hi if self.high_open else v <= hi))

    @property
    def default_text(self) -> str:
        """The default in words (the reference page, ``stringcontact show``)."""
        if self.default is not None:
            return fmt(self.default)
        return "required" if self.required else "none"


def check_table(value, key: str = "parameters", declared=()) -> tuple:
    """A ``[parameters]`` table's form as (name, value) pairs: identifiers, finite numbers (in range for `declared`,
    else for `RUN_CONSTANTS`)."""
    if isinstance(value, tuple):
        value = dict(value)
    if not isinstance(value, dict):
        raise SceneError(f"{key}: expected a table of model constants (name = number), got {type(value).__name__}")
    if len(value) > PARAMETERS_MAX:
        raise SceneError(f"{key}: {len(value)} constants; allowed: at most {PARAMETERS_MAX}")
    by_name = {c.name: c for c in (*RUN_CONSTANTS.get(), *declared)}  # the scene's own model's ranges first
    pairs = []
    for name, v in value.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise SceneError(f"{key}: {name!r:.40} is not a constant's name; allowed: an identifier such as k or gamma_0")
        pairs.append((name, by_name[name].check(v) if name in by_name else check_number(name, v, _UNKNOWN_RANGE)))
    return tuple(pairs)


def resolve_parameters(model: str, declared, given: dict, rule: Callable | None = None) -> dict[str, float]:
    """The model's constants for a run: `given` (name -> number) checked against `declared` (unknown names, out of
    range, required ones missing refused in one line), defaults filled in, then the model's own `rule`."""
    by_name = {c.name: c for c in declared}
    for name in given:
        if name not in by_name:
            known = ", ".join(by_name) or "none"
            raise SceneError(f"{name}: model {model!r} has no constant {name!r} (its constants: {known}); "
                             "remove it from [parameters] or choose the model that declares it")
    values = {}
    for c in declared:
        if c.name in given:
            values[c.name] = c.check(given[c.name])
        elif c.required:
            raise SceneError(f"{c.name}: model {model!r} needs it in [parameters]; allowed: {c.allowed}"
                             + (f" ({c.description})" if c.description else ""))
        elif c.default is not None:
            values[c.name] = float(c.default)
    if rule is not None:
        rule(values)
    return values
