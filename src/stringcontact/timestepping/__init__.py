"""Time schemes: one module and one class named after its scheme each (the contract: `base.Scheme`).

The core's `TimeStepper` knows none of them: it hands a scheme the model's operators and the step size, calls
``step()`` and books the energy terms the scheme reports. A scheme is registered under the entry-point group
``stringcontact.schemes`` (`scene.names.SCHEME_GROUP`), as models are, or handed over in Python as a class.
Importing this package does not load dolfinx.
"""

from __future__ import annotations

import contextlib
import warnings

from ..errors import SceneError
from ..scene.names import SCHEMES, scheme_class
from ..stack import load as _load_stack

_load_stack()  # the wheel's dolfinx_solver before a scheme module imports dolfinx, PETSc or MPI


def resolve_scheme(scheme) -> tuple[str, type]:
    """(its name, the class) of `scheme`: a registered name, or a `Scheme` class handed over in Python (named
    ``module:Class``, the form of an entry point, unless it is the class registered under a name)."""
    from .base import Scheme, SchemeOption

    if isinstance(scheme, type):
        if not issubclass(scheme, Scheme):
            raise TypeError(f"scheme: {scheme.__qualname__} is not a subclass of stringcontact.timestepping.base.Scheme")
        registered = [name for name, cls in _loadable().items() if cls is scheme]
        name = registered[0] if registered else f"{scheme.__module__}:{scheme.__qualname__}"
    else:
        name, scheme = scheme, scheme_class(scheme)
    if not (isinstance(scheme, type) and issubclass(scheme, Scheme)):
        raise SceneError(f"scheme: {name!r} is registered as a {type(scheme).__name__}, not a subclass of "
                         "stringcontact.timestepping.base.Scheme")
    options = getattr(scheme, "OPTIONS", None)
    if not isinstance(options, tuple) or not all(isinstance(o, SchemeOption) for o in options):
        raise SceneError(f"scheme {name!r}: OPTIONS must be a tuple of SchemeOptions, not {options!r:.80}")
    if not scheme.MASSES or any(not o.choices for o in options if o.name in ("penalty", "mass")):
        raise SceneError(f"scheme {name!r}: its penalty and mass options must list their choices (MASSES = "
                         f"{scheme.MASSES!r}); allowed: at least one, the default first")
    return name, scheme


def _loadable() -> dict[str, type]:
    """The registered schemes that load, by name: a stale entry point (its package gone) is refused where it is
    named, and breaks neither a Scheme class handed over nor the messages that list the others."""
    classes = {}
    for name in SCHEMES:
        with contextlib.suppress(SceneError):
            classes[name] = scheme_class(name)
    return classes


def _why_not(name: str, Scheme: type, model) -> str | None:
    """Why scheme `name` cannot run `model`: the scheme's reason, or the model's (`Model.schemes`)."""
    allowed = getattr(model, "schemes", ())
    if allowed and name not in allowed:
        return f"model '{model.name}' runs with scheme {' or '.join(allowed)} only: {model.scheme_note}"
    return Scheme.requires(model)


def check_model(name: str, model, Scheme: type | None = None) -> None:
    """ValueError (one line) if scheme `name` (class `Scheme`, the registered one by default) cannot run
    `model`, naming the registered schemes that can."""
    why = _why_not(name, Scheme or scheme_class(name), model)
    if why is not None:
        usable = [other for other, cls in _loadable().items() if _why_not(other, cls, model) is None]
        raise ValueError(f"scheme {name!r}: {why}; this model runs with scheme {' or '.join(usable) or 'none'}")


def check_restitution(name: str, restitution: float, Scheme: type | None = None) -> None:
    """ValueError (one line, naming the schemes that take one) if scheme `name` is given a restitution e > 0 it
    does not take (its class's ``RESTITUTION``)."""
    if restitution and not (Scheme or scheme_class(name)).RESTITUTION:
        takers = [other for other, cls in _loadable().items() if getattr(cls, "RESTITUTION", False)]
        raise ValueError(f"restitution: scheme {name!r} takes no restitution coefficient (e = {restitution:g} given); "
                         f"only scheme {' or '.join(repr(t) for t in takers)} does")


def resolve_options(name: str, Scheme: type, given: dict) -> dict:
    """The scheme's options (`Scheme.OPTIONS`) from `given` (None: not given), defaults filled in, each checked: a
    one-line ValueError/SceneError naming the option and what the scheme takes. An ``eps`` given to a scheme without
    a penalty is left unread (a scene written for both kinds of scheme); a restitution of 0 likewise."""
    given = {k: v for k, v in given.items() if v is not None}
    declared = {o.name: o for o in Scheme.OPTIONS}
    check_restitution(name, given.get("restitution") or 0.0, Scheme)
    penalty, mass = Scheme.check_options(name, given.get("penalty"), given.get("mass"))
    values = {o.name: o.default for o in Scheme.OPTIONS} | {"penalty": penalty, "mass": mass}
    for key, value in given.items():
        if key in ("penalty", "mass"):
            continue
        if key in declared:
            values[key] = declared[key].check(name, value)
        elif key not in ("eps", "restitution"):
            raise SceneError(f"scheme.{key}: scheme {name!r} takes no option {key!r}; allowed: "
                             f"{', '.join(sorted(declared))}")
    if Scheme.PENALTIES and values.get("eps") is None:
        raise SceneError(f"eps: scheme {name!r} needs the penalty's eps, and the scene gives none (a scheme without a "
                         "penalty, such as projection, does not read it); add eps to the scene's [scheme] table")
    values.setdefault("eps", None)
    values.setdefault("restitution", 0.0)
    values["petsc_options"] = dict(values.get("petsc_options") or {})
    return values


def check_scheme_run(scheme, model, dt: float, options: dict, ranks: int = 1) -> tuple[str, type, dict]:
    """(its name, the class, its options resolved) of `scheme` running `model` at the time step `dt` on `ranks`
    ranks, checked before anything is built: the scheme, its options, whether it runs the model, the model's
    penetration bound, the PETSc options and, for a penalty scheme, the contact law's stability at `dt`."""
    from ..model.interface import penetration_bound_of
    from .base import check_law_stability
    from .linear import check_option_values

    name, Scheme = resolve_scheme(scheme)
    resolved = resolve_options(name, Scheme, options)
    check_model(name, model, Scheme)
    penetration_bound_of(model)  # a bound the checks do not know is refused before the run, not after it
    check_option_values(resolved["petsc_options"], ranks=ranks)  # and Newton's tolerances, which could pass unsolved
    if Scheme.PENALTIES:
        with warnings.catch_warnings():  # refused here; the scheme warns once, when it is made
            warnings.simplefilter("ignore")
            check_law_stability(model, dt, resolved["eps"], resolved["penalty"])
    return name, Scheme, resolved


__all__ = ["SCHEMES", "check_model", "check_scheme_run", "check_restitution", "resolve_options", "resolve_scheme", "scheme_class"]
