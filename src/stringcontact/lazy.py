"""Names a package imports from its modules on first use (PEP 562), for `stringcontact` and `stringcontact.scene`.

    __getattr__, __dir__ = lazy_names(__name__, {"Scene": "scene", ...}, globals())

A name is looked up in its module when first read, then kept in the package's namespace.
"""

from __future__ import annotations

import importlib


def lazy_names(package: str, table: dict[str, str], namespace: dict):
    """The module-level `__getattr__` and `__dir__` of `package` (namespace `namespace`, its globals()) for the
    names of `table` (name -> module relative to `package`)."""

    def __getattr__(name):
        if name in table:
            value = getattr(importlib.import_module(f".{table[name]}", package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(set(namespace) | set(table))

    return __getattr__, __dir__
