"""Time schemes. Each is one module here with a class `Scheme` (see `base.Scheme` for the contract).

The driver (`solver.simulate`) knows none of them: it hands a scheme the model's assembled operators and
the step size, then calls ``step()`` and sums the energy terms the scheme reports. Adding a scheme is
a new module plus one line in `_REGISTRY`. Importing this package does not load dolfinx.
"""

from __future__ import annotations

import importlib

# name: (module, one-line description)
_REGISTRY = {
    "paper": ("paper", "the paper's Section 6: implicit elastic and viscous terms, penalty from the previous step"),
    "projection": ("projection", "explicit central difference, implicit viscosity, nodal projection onto gap >= 0 (no eps)"),
    "newmark": ("newmark", "trapezoidal rule (energy-conserving), semi-implicit penalty on the active set"),
}

#: {name: one-line description}
SCHEMES = {name: description for name, (_, description) in _REGISTRY.items()}


def scheme_class(name: str):
    """The `Scheme` class of the scheme called `name`; ValueError (one line) for an unknown name."""
    if name not in _REGISTRY:
        raise ValueError(f"scheme: unknown scheme {name!r}; allowed: {', '.join(SCHEMES)}")
    return importlib.import_module(f".{_REGISTRY[name][0]}", __name__).Scheme


def check_model(name: str, model) -> None:
    """ValueError (one line) if scheme `name` cannot run `model`, naming the schemes that can."""
    why = scheme_class(name).requires(model)
    if why is not None:
        usable = [other for other in SCHEMES if scheme_class(other).requires(model) is None]
        raise ValueError(f"scheme {name!r}: {why}; this model runs with scheme {' or '.join(usable) or 'none'}")


__all__ = ["SCHEMES", "check_model", "scheme_class"]
