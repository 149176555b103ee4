"""stringcontact: dynamic inelastic contact of a viscoelastic string with a rigid obstacle (FEniCSx).

    import stringcontact as sc
    scene = sc.load_scene("example1").replace(nx=1000, nt=300)
    res = sc.simulate(scene, penalty="explicit", mass="lumped")
"""

from .errors import InstabilityError, SceneError
from .model import Model, Parameters, inelastic
from .result import Result
from .scene import Scene, SceneWarning, list_scenes, load_scene
from .solver import InstabilityWarning, simulate

__version__ = "0.1.0"

__all__ = [
    "InstabilityError",
    "InstabilityWarning",
    "Model",
    "Parameters",
    "Result",
    "Scene",
    "SceneError",
    "SceneWarning",
    "inelastic",
    "list_scenes",
    "load_scene",
    "simulate",
]
