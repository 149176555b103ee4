"""UFL's and FFCx's versions without importing `pkg_resources` (Debian bookworm's FEniCS).

UFL 2022.2 and FFCx 0.5 set ``__version__`` with ``pkg_resources.get_distribution(name).version``. Importing
`pkg_resources` builds setuptools' working set of every installed distribution: 55-60 ms of a run's start-up
(`python -X importtime`: pkg_resources 59.6 ms of dolfinx's 117), on the critical path of `stringcontact run`.
`importlib.metadata` gives the same version strings without it. Newer FEniCS (Debian trixie) reads its
versions with importlib.metadata itself, and nothing here changes what it does.

`pkg_resources` is stood in for, not replaced: anything else asked of the stand-in (another distribution, any
other name) imports the real `pkg_resources`, which from then on is the one `import pkg_resources` gives.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types

#: the distributions whose version the stand-in answers itself
FENICS = ("fenics-ufl", "fenics-ffcx")


class _Versions(types.ModuleType):
    """`pkg_resources` as far as UFL and FFCx use it (`get_distribution(name).version`); the real one for the rest."""

    def get_distribution(self, name):
        if name in FENICS:
            from importlib.metadata import version  # here: the picture process imports this package, not UFL

            return types.SimpleNamespace(project_name=name, version=version(name))
        return self._real().get_distribution(name)

    def __getattr__(self, name):
        return getattr(self._real(), name)

    def _real(self):
        if sys.modules.get("pkg_resources") is self:
            del sys.modules["pkg_resources"]
        return importlib.import_module("pkg_resources")


def read_without_pkg_resources() -> None:
    """Stand in for `pkg_resources` until something other than UFL's and FFCx's versions is asked of it. Does
    nothing once pkg_resources or UFL is imported, or where pkg_resources is not installed."""
    if "pkg_resources" in sys.modules or "ufl" in sys.modules:
        return
    spec = importlib.util.find_spec("pkg_resources")
    if spec is None:
        return
    stand_in = _Versions("pkg_resources")
    stand_in.__spec__ = spec  # what find_spec("pkg_resources") answers while it stands in
    sys.modules["pkg_resources"] = stand_in
