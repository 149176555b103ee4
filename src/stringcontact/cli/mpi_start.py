"""Open MPI's start-up for a command run without `mpirun` (a singleton), set before MPI is loaded.

`from petsc4py import PETSc` initialises MPI. Run as a singleton, Open MPI 4.1 then starts an `orted`
daemon for the process and probes the UCX network layer, although one process talks to nobody:
`python3 -c "from mpi4py import MPI"` takes 0.34-0.37 s on this project's machine, 0.04-0.05 s with the
two settings below (`benchmarks/bench_mpi_start.py`; docs/explanation/performance.md). They are Open MPI's own MCA
parameters, read from the environment when MPI starts:

- ``ess_singleton_isolated=1``: no daemon for a singleton (it then cannot spawn processes; nothing here does);
- ``pml=ob1``: the point-to-point layer that needs no UCX probe (a singleton only talks to itself).

A value the user set is kept, and under `mpirun` (which sets ``OMPI_COMM_WORLD_SIZE``, or PMIx's
``PMIX_RANK``) nothing is changed: a parallel run's transport stays the user's and Open MPI's choice.
Other MPI implementations ignore the ``OMPI_MCA_`` names.
"""

from __future__ import annotations

#: Open MPI's MCA parameters (as environment variables) for a singleton
SINGLETON = {"OMPI_MCA_ess_singleton_isolated": "1", "OMPI_MCA_pml": "ob1"}
#: set by a launcher (mpirun, mpiexec, srun with PMIx) in each process it starts
LAUNCHED = ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK")


def singleton_settings(environ) -> dict[str, str]:
    """The settings of `SINGLETON` to add to `environ` (a mapping, e.g. ``os.environ``): none under a launcher,
    none the user set already."""
    if any(name in environ for name in LAUNCHED):
        return {}
    return {name: value for name, value in SINGLETON.items() if name not in environ}


def quick_singleton(environ) -> dict[str, str]:
    """Add `singleton_settings(environ)` to `environ`; call before MPI is imported. Returns what was added."""
    added = singleton_settings(environ)
    environ.update(added)
    return added
