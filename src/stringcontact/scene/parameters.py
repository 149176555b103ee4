"""A model's constants: what a model declares (`ModelConstant`) and how a scene's ``[parameters]`` table is
checked against it (`resolve_parameters`). Data only: no UFL, no dolfinx.

A scene gives a model's constants in one table::

    model = "my_model"
    [parameters]
    k = 2000

The scene layer checks the table's form (`check_table`: names, finite numbers); the values are checked against the
constants the model declares (`resolve_parameters`: unknown names, ranges, required constants, the model's own
rules between them) when the scene names a registered model, and again against the model a run actually uses
(``--model module:name``, a `Model` handed to `simulate`), before anything is written.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import SceneError

__all__ = ["PARAMETERS_MAX", "ModelConstant", "check_table", "resolve_parameters"]

#: The most constants a ``[parameters]`` table may hold.
PARAMETERS_MAX = 64
#: The widest range a constant may declare (a scene's numbers are bounded like its other keys').
MAGNITUDE = 1e12


def _fmt(v: float) -> str:
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e16 else repr(float(v))


@dataclass(frozen=True)
class ModelConstant:
    """One constant a model declares: a scene sets it in its ``[parameters]`` table, the forms read it as a dolfinx
    ``Constant`` in ``Parameters.constants[name]`` (so a value can change between steps without recompiling).

    `default` is the value when the scene gives none; with ``required=True`` the scene must give it; with neither,
    an absent constant is absent from ``Parameters.constants`` too (an optional feature that is off unless
    given). The allowed range is [`low`, `high`], open at an end with `low_open`/`high_open`.
    `unit` and `description` (one line) are shown by ``stringcontact show``, the scene-key reference and
    ``stringcontact models``.
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
        if self.default is not None:
            self.check(self.default)

    @property
    def allowed(self) -> str:
        """The allowed range in words, as the error messages give it: ``a number in (0, 1e+06]``."""
        return (f"a number in {'(' if self.low_open else '['}{_fmt(self.low)}, "
                f"{_fmt(self.high)}{')' if self.high_open else ']'}")

    def check(self, value) -> float:
        """`value` as a float if it is a finite number in range, else a one-line `SceneError` naming the constant."""
        if not isinstance(value, numbers.Real) or isinstance(value, bool):
            raise SceneError(f"{self.name}: expected a number, got {type(value).__name__} {value!r:.40}; "
                             f"allowed: {self.allowed}")
        v = float(value)
        if not math.isfinite(v):
            raise SceneError(f"{self.name}: {value!r} is not finite; allowed: {self.allowed}")
        if v < self.low or v > self.high or (self.low_open and v == self.low) or (self.high_open and v == self.high):
            raise SceneError(f"{self.name}: {_fmt(v)} is out of range; allowed: {self.allowed}")
        return v

    @property
    def default_text(self) -> str:
        """The default in words (the reference page, ``stringcontact show``)."""
        if self.default is not None:
            return _fmt(self.default)
        return "required" if self.required else "none"


def check_table(value, key: str = "parameters", declared=()) -> tuple:
    """A ``[parameters]`` table's form: identifier names and finite numbers, as sorted-by-entry (name, value) pairs.
    A value of a constant in `declared` (the model's `ModelConstant`s, when the scene's model is known) is checked
    against that constant, so that its message gives the constant's own range; any other must be a number.
    Whether the model has these constants is `resolve_parameters`' question."""
    if isinstance(value, tuple):
        value = dict(value)
    if not isinstance(value, dict):
        raise SceneError(f"{key}: expected a table of model constants (name = number), got {type(value).__name__}")
    if len(value) > PARAMETERS_MAX:
        raise SceneError(f"{key}: {len(value)} constants; allowed: at most {PARAMETERS_MAX}")
    by_name = {c.name: c for c in declared}
    pairs = []
    for name, v in value.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise SceneError(f"{key}: {name!r:.40} is not a constant's name; allowed: an identifier such as k or gamma_0")
        pairs.append((name, by_name[name].check(v) if name in by_name else _number(name, v)))
    return tuple(pairs)


def _number(name: str, value) -> float:
    """`value` of a constant whose model is not known yet: a number (its range is checked when the run has the model,
    `resolve_parameters`)."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        raise SceneError(f"{name}: expected a number, got {type(value).__name__} {value!r:.40}; allowed: a number in "
                         "the range its model declares (`stringcontact models`)")
    if not math.isfinite(float(value)):
        raise SceneError(f"{name}: {value!r} is not finite; allowed: a number in the range its model declares "
                         "(`stringcontact models`)")
    return float(value)


def resolve_parameters(model: str, declared, given: dict, rule: Callable | None = None) -> dict[str, float]:
    """The model's constants for a run: `given` (name -> number) checked against `declared` (`ModelConstant`s),
    defaults filled in, then the model's own `rule` (values -> None, or a `SceneError` naming a constant).

    Refused in one line, naming the constant and what is allowed: a name the model does not declare, a value out
    of range, a required constant not given.
    """
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
