"""Time schemes. Each is one module here with a class `Scheme` (see `base.Scheme` for the contract).

The driver (`run.driver.simulate`) knows none of them: it hands a scheme the model's assembled operators and
the step size, then calls ``step()`` and sums the energy terms the scheme reports. Adding a scheme is
a new module here plus one line in `scene.names.SCHEMES` (the names a scene may use). Importing this
package does not load dolfinx.
"""

from __future__ import annotations

import importlib

from ..scene.names import SCHEMES


def scheme_class(name: str):
    """The `Scheme` class of the scheme called `name`; ValueError (one line) for an unknown name."""
    if name not in SCHEMES:
        raise ValueError(f"scheme: unknown scheme {name!r}; allowed: {', '.join(SCHEMES)}")
    return importlib.import_module(f".{name}", __name__).Scheme


def _why_not(name: str, model) -> str | None:
    """Why scheme `name` cannot run `model`: the scheme's reason, or the model's (`Model.schemes`)."""
    allowed = getattr(model, "schemes", ())
    if allowed and name not in allowed:
        return f"model '{model.name}' runs with scheme {' or '.join(allowed)} only: {model.scheme_note}"
    return scheme_class(name).requires(model)


def check_model(name: str, model) -> None:
    """ValueError (one line) if scheme `name` cannot run `model`, naming the schemes that can."""
    why = _why_not(name, model)
    if why is not None:
        usable = [other for other in SCHEMES if _why_not(other, model) is None]
        raise ValueError(f"scheme {name!r}: {why}; this model runs with scheme {' or '.join(usable) or 'none'}")


def check_restitution(name: str, restitution: float) -> None:
    """ValueError (one line, naming `projection`) if scheme `name` is given a restitution e > 0 it does not take."""
    if restitution and not scheme_class(name).RESTITUTION:
        raise ValueError(f"restitution: scheme {name!r} takes no restitution coefficient (e = {restitution:g} given); "
                         "only scheme 'projection' does")


__all__ = ["SCHEMES", "check_model", "check_restitution", "scheme_class"]
