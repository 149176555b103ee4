"""The time loop of `simulate`: a `Stepper` (the scene's problem, its `TimeStepper` and the standard observers)
advanced from 0 to T, with a progress bar and signals that stop every rank together. It knows no scheme and no
model."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..io.result import Result
from ..model.interface import Model
from ..signals import StopTogether
from .options import Output, Storage
from .stepper import Stepper, one_thread

__all__ = ["simulate"]


def _march(st: Stepper, progress: bool, comm=None) -> None:
    """Advance `st` to T. Under MPI (`comm`), a stop signal on any rank stops every rank at the same step
    (`StopTogether`): polled at every step of a membrane, every 64th of a string (its steps take microseconds)."""
    from tqdm import tqdm

    # disable=None: tqdm's own test, no bar when stderr is not a terminal (a log file, a pipe, CI)
    bar = tqdm(total=st.nt, disable=None if progress else True, unit="step", mininterval=0.5, leave=False)
    mask = 0 if st.scene.dim == 2 else 63
    # NaN, overflow: the energy guard names the step; the bar closes last, however the loop ends
    with bar, st._guarded(), np.errstate(all="ignore"), StopTogether(comm) as stop, one_thread(st.vector_length):
        for n in range(st.step, st.nt):  # computes step n + 1
            st._advance()
            if (n & mask) == 0:
                stop.poll()
            if progress and (n & 63) == 0:
                bar.update(min(64, st.nt - bar.n))


def simulate(
    scene,
    scheme: str | type | None = None,
    penalty: str | None = None,
    mass: str | None = None,
    *,
    model: Model | str | None = None,
    storage: Storage | None = None,
    output: Output | None = None,
    comm=MPI.COMM_WORLD,
    petsc_options: dict | None = None,
    restitution: float | None = None,
) -> Result:
    """Run `scene` with a time scheme (`stringcontact.SCHEMES`; default: the scene's, else "paper").

    `scheme` is a registered name or a scheme class itself (a subclass of `timestepping.base.Scheme`, e.g. of
    `timestepping.implicit.ImplicitScheme`); an unregistered class is named "module:Class" in the result.

    `model` is a `Model`, a registered name (`stringcontact models`) or "package.module:name"; default:
    the scene's `model`, else the paper's.

    `penalty` and `mass` default to the scheme's own (for "paper": explicit, lumped); an option the scheme
    does not take is refused.

    `storage` (`Storage`): the rows kept (Result, diagnostics.csv, pictures), by default on rank 0 under MPI, the
    other ranks' Result holding the per-time series only. `output` (`Output`): what is written, and where.

    `petsc_options` (checked like the scene's key, which it overrides name by name) set the PETSc options of the
    step's linear solver (`timestepping.linear.solver_options`: LU or CG), e.g. ``{"ksp_type": "cg"}``.

    It is a loop over a `Stepper` (the same arguments): step one yourself for control of the time loop.

    `restitution` (e in [0, 1], checked like the scene's key, which it replaces; the Result's scene records it):
    scheme "projection"'s restitution coefficient (Paoli-Schatzman); every other scheme refuses e > 0.
    """
    st = Stepper(scene, scheme, penalty, mass, model=model, storage=storage, output=output, comm=comm,
                 petsc_options=petsc_options, restitution=restitution)
    _march(st, st.output.progress and comm.rank == 0, comm)
    return st.result()
