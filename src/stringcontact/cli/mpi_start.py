"""Open MPI's settings for a command run without `mpirun`, made before MPI loads: no ``orted`` daemon and no UCX
probe, `from petsc4py import PETSc` 0.216 s with them, 0.548 s without (`benchmarks/bench_mpi_start.py`)."""

from __future__ import annotations

#: Open MPI's MCA parameters (as environment variables) for a singleton
SINGLETON = {"OMPI_MCA_ess_singleton_isolated": "1", "OMPI_MCA_pml": "ob1"}
#: set by a launcher (mpirun, mpiexec, srun with PMIx) in each process it starts
LAUNCHED = ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK")


def singleton_settings(environ) -> dict[str, str]:
    """The settings of `SINGLETON` to add to `environ`: none under a launcher, none the user set already."""
    if any(name in environ for name in LAUNCHED):
        return {}
    return {name: value for name, value in SINGLETON.items() if name not in environ}


def quick_singleton(environ) -> dict[str, str]:
    """Add `singleton_settings(environ)` to `environ` (``os.environ`` before MPI is imported); returns them."""
    added = singleton_settings(environ)
    environ.update(added)
    return added
