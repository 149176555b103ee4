"""Which models a scene may name, and `load_model` (`stringcontact models` lists them).

A scene's ``model`` is a *name* an installed package registers under the entry-point group ``stringcontact.models``
(docs/howto/models.md): checking it reads metadata only; a run loads the one entry point it names (the trust
boundary is the user's ``pip install``). ``"package.module:name"`` is accepted only where the user types it
(``--model``, `load_model`), and the object must already be a `Model`: nothing is called.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.metadata
import os
import sys

from ..errors import SceneError, one_line, plugin_code
from ..scene.names import GROUP, check_name, load_registered, registered  # noqa: F401 - GROUP re-exported
from ..scene.names import package_of as _package


def load_model(spec):
    """The `Model` for `spec`: a `Model` itself, a registered name, or ``"package.module:name"`` (typed by the user;
    imported, never called). Raises `SceneError` with a one-line message naming ``model``."""
    from .interface import Model

    if isinstance(spec, Model):
        return spec
    if isinstance(spec, str) and ":" in spec and spec not in registered():
        return _load_path(spec, Model)
    return _load_registered(check_name(spec), Model)


def _load_registered(name: str, Model):
    obj = load_registered(name)  # imports the installed package's module
    if not isinstance(obj, Model):
        (ep,) = registered()[name]
        raise SceneError(f"model: {name!r} is registered as {ep.value} (from {_package(ep)}), "
                         f"a {type(obj).__name__}, not a stringcontact.Model")
    return obj


def _load_path(spec: str, Model):
    module_name, _, attr = spec.partition(":")
    if not module_name or not all(part.isidentifier() for part in module_name.split(".")) or not attr.isidentifier():
        raise SceneError(f"model: invalid value {spec!r}; allowed: a registered name or 'package.module:name'")
    with plugin_code(f"model: importing module {module_name!r} for {spec!r}"):  # its sys.exit too
        try:
            module = importlib.import_module(module_name)
        except Exception as exc:  # noqa: BLE001 - an ImportError, or any error raised by the user's module itself
            reason = one_line(exc) or type(exc).__name__
            raise SceneError(f"model: cannot import module {module_name!r} for {spec!r} ({reason})") from None
    obj = getattr(module, attr, None)
    if obj is None:
        raise SceneError(f"model: module {module_name!r} has no {attr!r} (for {spec!r})")
    if not isinstance(obj, Model):  # never called: a function here would run whatever it does
        raise SceneError(f"model: {spec!r} is a {type(obj).__name__}, not a stringcontact.Model (nothing is called "
                         "to make one: name a Model object)")
    return obj


def model_origin(spec, model) -> dict:
    """Where the `model` that `spec` named came from, for summary.json: ``{"name", "source", ...}``. ``source`` is
    ``"built-in"``, ``"entry point"`` (with ``package``, ``version``, ``entry_point``), ``"module"`` (a typed
    ``package.module:name``: its ``file`` and ``sha256``) or ``"object"`` (a `Model` no imported entry point holds)."""
    name = getattr(model, "name", str(spec))
    if isinstance(spec, str) and ":" in spec and spec not in _entry_points():
        module = sys.modules.get(spec.partition(":")[0])
        path = getattr(module, "__file__", None)
        origin = {"name": name, "source": "module", "spec": spec, "file": str(path) if path else None}
        if path and os.path.isfile(path):
            with open(path, "rb") as f:
                origin["sha256"] = hashlib.sha256(f.read()).hexdigest()
        return origin
    for registered_name, entry in _entry_points().items():
        module, attr = entry["target"]
        held = module in sys.modules and getattr(sys.modules[module], attr, None) is model  # imported only
        if spec == registered_name or (not isinstance(spec, str) and held):
            return {"name": name, **{k: v for k, v in entry.items() if k != "target"}}
    return {"name": name, "source": "object"}


@functools.lru_cache(maxsize=1)
def _entry_points() -> dict:
    """The registered models' provenance, read once per process (the metadata scan costs 6-9 ms, once per run)."""
    found = {}
    for registered_name, eps in registered().items():
        ep = eps[0]
        package = _package(ep)
        module, _, attr = ep.value.partition(":")
        found[registered_name] = {
            "source": "built-in" if package == "stringcontact" else "entry point",
            "entry_point": f"{registered_name} = {ep.value}", "package": package,
            "version": getattr(getattr(ep, "dist", None), "version", None), "target": (module.strip(), attr.strip())}
    return found
