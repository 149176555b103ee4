"""The FEniCS stack this package runs on: dolfinx from Debian (0.5, 0.9), from conda or from the PyPI wheel
``dolfinx-solver-real`` (0.11).

The wheel carries its own PETSc and MPI and needs ``import dolfinx_solver`` (its ``libmpi.so.12``) before dolfinx,
petsc4py or mpi4py. The packages that import the stack call `load` first, which also refuses a dolfinx outside
`SUPPORTED` in one line (`StackError`: exit code 2).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys

from .errors import StackError

#: The dolfinx releases this package runs on (oldest, newest), as (major, minor). Tested: 0.5.2 (Debian
#: bookworm), 0.9.0 (Debian trixie, the Docker image) and 0.11.0 (the wheel ``dolfinx-solver-real``).
SUPPORTED = ((0, 5), (0, 11))

#: The PyPI wheel of dolfinx this package installs with ``pip install "stringcontact[dolfinx]"``.
WHEEL = "dolfinx-solver-real"

_state = {"checked": False}


def load() -> None:
    """Import the stack in its order (the wheel's ``dolfinx_solver`` first) and check dolfinx's version, once."""
    if _state["checked"]:
        return
    load_mpi_first()
    import dolfinx

    check_version(dolfinx.__version__)
    _state["checked"] = True


def load_mpi_first() -> None:
    """The import-order half of `load`: the wheel's ``dolfinx_solver`` (its MPI) where installed, not dolfinx."""
    if "dolfinx_solver" not in sys.modules and importlib.util.find_spec("dolfinx_solver") is not None:
        importlib.import_module("dolfinx_solver")


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


__all__ = ["SUPPORTED", "WHEEL", "check_version", "load", "load_mpi_first"]
