"""The FEniCS stack this package runs on: dolfinx from Debian (0.5, 0.9), from conda or from the PyPI wheel
``dolfinx-solver-real`` (0.11).

The wheel carries its own PETSc and MPI and needs ``import dolfinx_solver`` (its ``libmpi.so.12``) before dolfinx,
petsc4py, slepc4py or mpi4py. Where it is installed, ``import stringcontact`` puts `WheelFirst` on ``sys.meta_path``:
the first import of one of those (the package's, or the user's own after ``import stringcontact``) brings
``dolfinx_solver`` first. So MPI starts when the stack is first needed, not at ``import stringcontact``, and the
command line has its standard streams, signal handlers and MPI settings in place before. The packages that import
the stack call `load` first, which also refuses a dolfinx outside `SUPPORTED` in one line (`StackError`: exit 2).
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import sys

from .errors import StackError

#: The dolfinx releases this package runs on (oldest, newest), as (major, minor). Tested: 0.5.2 (Debian
#: bookworm), 0.9.0 (Debian trixie, the Docker image) and 0.11.0 (the wheel ``dolfinx-solver-real``).
SUPPORTED = ((0, 5), (0, 11))

#: The PyPI wheel of dolfinx this package installs with ``pip install "stringcontact[dolfinx]"``.
WHEEL = "dolfinx-solver-real"

@functools.cache  # a refused version is not cached: the next call raises again
def load() -> None:
    """Import the stack in its order (the wheel's ``dolfinx_solver`` first) and check dolfinx's version, once."""
    load_mpi_first()
    import dolfinx

    check_version(dolfinx.__version__)


def load_mpi_first() -> None:
    """The import-order half of `load`: where the wheel is installed, `WheelFirst` on ``sys.meta_path`` (once), so
    that ``dolfinx_solver`` comes before the first import of the stack. Imports nothing itself."""
    if "dolfinx_solver" in sys.modules or any(isinstance(f, WheelFirst) for f in sys.meta_path):
        return
    if importlib.util.find_spec("dolfinx_solver") is not None:
        sys.meta_path.insert(0, WheelFirst())


#: The packages that need the wheel's MPI loaded before them.
STACK = frozenset({"dolfinx", "petsc4py", "slepc4py", "mpi4py"})


class WheelFirst:
    """A meta-path finder that imports ``dolfinx_solver`` before the first module of `STACK`, and nothing after
    (it stays on ``sys.meta_path``: removed while the import system walks the list, it would hide the next finder
    from that import); it finds nothing itself."""

    def __init__(self):
        self.done = False

    def find_spec(self, name, path=None, target=None):
        """``dolfinx_solver`` first when `name` is in `STACK`; always None (the usual finders find `name`)."""
        if not self.done and name.partition(".")[0] in STACK:
            self.done = True  # before the import: dolfinx_solver imports mpi4py and petsc4py itself
            try:
                importlib.import_module("dolfinx_solver")
            except BaseException:
                self.done = False  # interrupted while it loads: the next import of the stack tries again
                raise
        return None


def check_version(found: str) -> None:
    """`StackError` (one line) unless dolfinx version `found` is within `SUPPORTED`."""
    try:
        major_minor = tuple(int(part) for part in found.split(".")[:2])
    except ValueError:
        major_minor = None
    low, high = SUPPORTED
    if major_minor is None or not low <= major_minor <= high:
        raise StackError(f"dolfinx {found} is not supported; allowed: dolfinx {low[0]}.{low[1]} to "
                         f"{high[0]}.{high[1]} (Debian's python3-dolfinx, conda's fenics-dolfinx, or pip install "
                         f"'stringcontact[dolfinx]' for the wheel {WHEEL})")


__all__ = ["STACK", "SUPPORTED", "WHEEL", "WheelFirst", "check_version", "load", "load_mpi_first"]
