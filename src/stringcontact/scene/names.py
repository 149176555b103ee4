"""The names installed packages register that a scene may use: models (`GROUP`) and time schemes (`SCHEME_GROUP`).
Checking a name reads metadata only; what it stands for loads its entry point (the user's ``pip install`` is the
trust boundary)."""

from __future__ import annotations

import functools
import importlib.metadata
from collections.abc import Mapping

from ..errors import SceneError, one_line, plugin_code

#: The scheme and the model of a scene that names none (`stringcontact show` writes them out).
DEFAULT_SCHEME, DEFAULT_MODEL = "paper", "inelastic"

#: The entry-point group of the time schemes: name = "package.module:Class", a `timestepping.base.Scheme` subclass.
SCHEME_GROUP = "stringcontact.schemes"


def _entry_points(group: str) -> dict[str, list[importlib.metadata.EntryPoint]]:
    """name -> the entry points registered under `group` (one per distinct target; two mean a conflict)."""
    found = {}
    for ep in importlib.metadata.entry_points(group=group):
        targets = found.setdefault(ep.name, [])
        if all(other.value != ep.value for other in targets):  # the same package seen twice is one entry
            targets.append(ep)
    return found


class SchemeNames(Mapping):
    """The registered time schemes (`stringcontact.SCHEMES`): name -> one-line description, the default first, the
    rest in alphabetical order. Iterating and ``in`` import nothing; a description imports the scheme's module."""

    def __iter__(self):
        return iter(sorted(_entry_points(SCHEME_GROUP), key=lambda name: (name != DEFAULT_SCHEME, name)))

    def __len__(self) -> int:
        return len(_entry_points(SCHEME_GROUP))

    def __contains__(self, name) -> bool:
        return isinstance(name, str) and name in _entry_points(SCHEME_GROUP)

    def __getitem__(self, name: str) -> str:
        if name not in self:
            raise KeyError(name)
        return scheme_class(name).DESCRIPTION

    def __repr__(self) -> str:
        return f"SchemeNames({', '.join(self)})"


#: The registered time schemes: name -> one-line description (`SchemeNames`).
SCHEMES = SchemeNames()


@functools.cache
def scheme_class(name: str):
    """The class registered as time scheme `name`; a one-line `SceneError` naming ``scheme`` if it cannot be."""
    ep = _one_entry_point("scheme", name, _entry_points(SCHEME_GROUP), f"allowed: {', '.join(SCHEMES)}")
    return _load("scheme", name, ep)


def _one_entry_point(kind: str, value, found: dict, allowed: str):
    """The one entry point registered as `value` in `found`, else a `SceneError` naming `kind` (unknown, or twice)."""
    if not isinstance(value, str) or value not in found:
        shown = repr(value) if isinstance(value, str) else f"{type(value).__name__} {value!r}"
        raise SceneError(f"{kind}: unknown {kind} {one_line(shown)[:80]}; {allowed}")
    if len(found[value]) > 1:
        targets = ", ".join(f"{ep.value} ({package_of(ep)})" for ep in found[value])
        raise SceneError(f"{kind}: {value!r} is registered twice, as {targets}; uninstall one of the packages")
    return found[value][0]


def _load(kind: str, name: str, ep):
    """The object entry point `ep` names; a `SceneError` naming `kind` if it cannot be loaded or its code exits."""
    with plugin_code(f"{kind}: loading {name!r} ({ep.value}, from {package_of(ep)})"):  # its sys.exit too
        try:
            return ep.load()
        except Exception as exc:  # noqa: BLE001 - an ImportError, or any error raised by the plugin itself
            raise SceneError(f"{kind}: cannot load {name!r} ({ep.value}, from {package_of(ep)}): "
                             f"{type(exc).__name__}: {one_line(exc)}") from None


#: The entry-point group a package registers its models under (``[project.entry-points."stringcontact.models"]``).
GROUP = "stringcontact.models"


def registered() -> dict[str, list[importlib.metadata.EntryPoint]]:
    """The registered models: name -> its entry points (one per distinct target; two mean a conflict)."""
    return dict(sorted(_entry_points(GROUP).items()))


def check_name(value) -> str:
    """`value` if it is a registered model name, else a one-line `SceneError` naming ``model``. Imports nothing."""
    models = registered()
    names = ", ".join(models) or "none (is stringcontact installed? run scripts/setup)"
    _one_entry_point("model", value, models, f"allowed: {names} (the names installed packages register under the "
                     f"entry-point group {GROUP}; see `stringcontact models`)")
    return value


def package_of(ep) -> str:
    dist = getattr(ep, "dist", None)
    return dist.name if dist is not None else "unknown package"


def load_registered(name: str):
    """The object registered as model `name`; a one-line `SceneError` naming ``model`` if it cannot be loaded."""
    return _load("model", name, registered()[check_name(name)][0])


def declared(name: str) -> tuple:
    """(`Model.constants`, `Model.check_constants`) of registered model `name`, for ``[parameters]``."""
    obj = load_registered(name)
    return tuple(getattr(obj, "constants", ())), getattr(obj, "check_constants", None)
