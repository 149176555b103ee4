"""stringcontact: dynamic inelastic contact of a viscoelastic string with a rigid obstacle (FEniCSx).

    import stringcontact as sc
    scene = sc.load_scene("example1").replace(nx=1000)
    res = sc.simulate(scene, penalty="explicit", mass="lumped")
"""

from . import stack as _stack
from .errors import InstabilityError, InstabilityWarning, Interrupted, OutputError, SceneError, SolverError
from .lazy import lazy_names as _lazy_names

_stack.load_mpi_first()  # the dolfinx wheel's MPI before anything imports dolfinx (nothing elsewhere)

__version__ = "0.1.0"

# Imported on first use (PEP 562), so that `import stringcontact.plot.run_pictures` (`stringcontact plot`) and the CLI's
# argument checks do not load dolfinx, PETSc and UFL (0.6 s).
_LAZY = {
    **dict.fromkeys(("Model", "ModelConstant", "OutputField", "SolverHints", "Parameters", "inelastic"),
                    "model.interface"),
    "Result": "io.result",
    **dict.fromkeys(("Scene", "SceneWarning", "list_scenes", "load_scene"), "scene"),
    "load_model": "model.registry",
    "SCHEMES": "timestepping",
    "simulate": "run.driver",
    "Stepper": "run.stepper",
    "continued": "run.restart",
    "ContactProblem": "core.problem",
    "TimeStepper": "core.stepper",
    "EnergyLedger": "core.ledger",
    "Observer": "core.observers",
    "RowObserver": "run.rows",
    "SchemeOption": "timestepping.base",
    **dict.fromkeys(("Storage", "Output"), "run.options"),
}
__getattr__, _ = _lazy_names(__name__, _LAZY, globals())

__all__ = ["SCHEMES", "ContactProblem", "EnergyLedger", "Observer", "RowObserver", "SchemeOption", "TimeStepper",
           "InstabilityError", "InstabilityWarning", "Interrupted", "Model", "ModelConstant", "Output", "OutputError",
           "OutputField", "Parameters", "Result", "Scene", "SceneError", "SceneWarning", "SolverError", "SolverHints",
           "Stepper", "Storage", "continued", "inelastic", "list_scenes", "load_model", "load_scene", "simulate"]


def __dir__():
    """What a user should touch (tab completion): `__all__` and `__version__`."""
    return sorted([*__all__, "__version__"])
