"""stringcontact: dynamic inelastic contact of a viscoelastic string with a rigid obstacle (FEniCSx).

    import stringcontact as sc
    scene = sc.load_scene("example1").replace(nx=1000, nt=300)
    res = sc.simulate(scene, penalty="explicit", mass="lumped")
"""

from .errors import InstabilityError, InstabilityWarning, SceneError
from .fenics_versions import read_without_pkg_resources
from .jitlog import quiet_compiler
from .lazy import lazy_names

quiet_compiler()  # before any form is compiled: the JIT's compiler log stays at WARNING
read_without_pkg_resources()  # before UFL is imported: 55-60 ms of start-up on bookworm

__version__ = "0.1.0"

# Imported on first use (PEP 562), so that `import stringcontact.plot.viz` in the picture process and the CLI's
# argument checks do not load dolfinx, PETSc and UFL (0.6 s).
_LAZY = {
    "Model": "model.paper",
    "Parameters": "model.paper",
    "inelastic": "model.paper",
    "Result": "io.result",
    "Scene": "scene",
    "SceneWarning": "scene",
    "list_scenes": "scene",
    "load_scene": "scene",
    "load_model": "model.registry",
    "SCHEMES": "timestepping",
    "simulate": "run.driver",
    "Storage": "run.options",
    "Output": "run.options",
}
__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())


__all__ = [
    "SCHEMES",
    "InstabilityError",
    "InstabilityWarning",
    "Model",
    "Output",
    "Parameters",
    "Result",
    "Scene",
    "SceneError",
    "SceneWarning",
    "Storage",
    "inelastic",
    "list_scenes",
    "load_model",
    "load_scene",
    "simulate",
]
