"""The names a scene may use that are registered elsewhere: models (entry points) and time schemes.

Checking a name imports nothing: a model's name is checked against the installed packages' metadata (the
entry-point group `GROUP`), a scheme's against `SCHEMES`. A model's declared constants (`declared`) are read from
the registered object itself, which loads its entry point (the user's ``pip install`` is the trust boundary), the time-scheme registry (the class `Scheme` of
scheme NAME is in `stringcontact.timestepping.NAME`; `timestepping.scheme_class` loads it). Adding a
scheme: its module plus one line here.
"""

from __future__ import annotations

import importlib.metadata

from ..errors import SceneError, one_line, plugin_code

#: The scheme and the model of a scene that names none (`stringcontact show` writes them out).
DEFAULT_SCHEME, DEFAULT_MODEL = "paper", "inelastic"

#: The time schemes: name -> one-line description (`stringcontact.SCHEMES`); the code is timestepping/NAME.py.
SCHEMES = {
    "paper": "the paper's Section 6: implicit elastic and viscous terms, penalty from the previous step",
    "projection": "explicit central difference, implicit viscosity, contact as a complementarity problem (no eps)",
    "newmark": "trapezoidal rule (energy-conserving), semi-implicit penalty on the active set",
}

#: The schemes without a penalty (no ε): the ones whose class has no PENALTIES (tests/scene/test_show.py checks it).
EPS_FREE = frozenset({"projection"})

#: The entry-point group a package registers its models under (``[project.entry-points."stringcontact.models"]``).
GROUP = "stringcontact.models"


def registered() -> dict[str, list[importlib.metadata.EntryPoint]]:
    """The registered models: name -> its entry points (one per distinct target; two mean a conflict)."""
    found: dict[str, list[importlib.metadata.EntryPoint]] = {}
    for ep in importlib.metadata.entry_points(group=GROUP):
        targets = found.setdefault(ep.name, [])
        if all(other.value != ep.value for other in targets):  # the same package seen twice is one entry
            targets.append(ep)
    return dict(sorted(found.items()))


def _allowed(names) -> str:
    return (f"allowed: {', '.join(names) or 'none (is stringcontact installed? run scripts/setup)'} "
            f"(the names installed packages register under the entry-point group {GROUP}; see `stringcontact models`)")


def check_name(value) -> str:
    """`value` if it is a registered model name, else a one-line `SceneError` naming ``model``. Imports nothing."""
    models = registered()
    if not isinstance(value, str) or value not in models:
        shown = repr(value) if isinstance(value, str) else f"{type(value).__name__} {value!r}"
        raise SceneError(f"model: unknown model {one_line(shown)[:80]}; {_allowed(models)}")
    if len(models[value]) > 1:
        targets = ", ".join(f"{ep.value} ({package_of(ep)})" for ep in models[value])
        raise SceneError(f"model: {value!r} is registered twice, as {targets}; uninstall one of the packages")
    return value


def package_of(ep) -> str:
    dist = getattr(ep, "dist", None)
    return dist.name if dist is not None else "unknown package"


def load_registered(name: str):
    """The object registered as model `name` (its entry point loaded: the installed package's module imported);
    a one-line `SceneError` naming ``model`` if it cannot be loaded."""
    (ep,) = registered()[check_name(name)]
    with plugin_code(f"model: loading {name!r} ({ep.value}, from {package_of(ep)})"):  # its sys.exit too
        try:
            return ep.load()
        except Exception as exc:  # noqa: BLE001 - an ImportError, or any error raised by the plugin itself
            raise SceneError(f"model: cannot load {name!r} ({ep.value}, from {package_of(ep)}): "
                             f"{type(exc).__name__}: {one_line(exc)}") from None


def declared(name: str) -> tuple:
    """(the constants, the rule between them) that registered model `name` declares (`Model.constants`,
    `Model.check_constants`): what a scene's ``[parameters]`` table is checked against."""
    obj = load_registered(name)
    return tuple(getattr(obj, "constants", ())), getattr(obj, "check_constants", None)
