"""stringcontact: dynamic inelastic contact of a viscoelastic string with a rigid obstacle (FEniCSx).

    import stringcontact as sc
    scene = sc.load_scene("example1").replace(nx=1000)
    res = sc.simulate(scene, penalty="explicit", mass="lumped")
"""

import lazy_loader as _lazy

from . import stack as _stack
from .errors import InstabilityError, InstabilityWarning, Interrupted, OutputError, SceneError, SolverError

_stack.load_mpi_first()  # the dolfinx wheel's MPI before anything imports dolfinx (nothing elsewhere)

__version__ = "0.1.0"

# Imported on first use (SPEC 1, PEP 562: lazy_loader), so that `import stringcontact.plot.run_pictures` (`stringcontact
# plot`) and the CLI's argument checks do not load dolfinx, PETSc and UFL (0.6 s).
__getattr__, _, _ = _lazy.attach(__name__, submod_attrs={
    "model.interface": ["Model", "ModelConstant", "OutputField", "SolverHints", "Parameters", "inelastic"],
    "io.result": ["Result"], "scene": ["Scene", "SceneWarning", "list_scenes", "load_scene"],
    "model.registry": ["load_model"], "timestepping": ["SCHEMES"], "run.driver": ["simulate"],
    "run.stepper": ["Stepper"], "run.restart": ["continued"], "core.problem": ["ContactProblem"],
    "core.stepper": ["TimeStepper"], "core.ledger": ["EnergyLedger"], "core.observers": ["Observer"],
    "run.rows": ["RowObserver"], "timestepping.base": ["SchemeOption"], "run.options": ["Storage", "Output"]})

__all__ = ["SCHEMES", "ContactProblem", "EnergyLedger", "Observer", "RowObserver", "SchemeOption", "TimeStepper",
           "InstabilityError", "InstabilityWarning", "Interrupted", "Model", "ModelConstant", "Output", "OutputError",
           "OutputField", "Parameters", "Result", "Scene", "SceneError", "SceneWarning", "SolverError", "SolverHints",
           "Stepper", "Storage", "continued", "inelastic", "list_scenes", "load_model", "load_scene", "simulate"]


def __dir__():
    """What a user should touch (tab completion): `__all__` and `__version__`."""
    return sorted([*__all__, "__version__"])
