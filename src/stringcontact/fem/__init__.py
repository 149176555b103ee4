"""Space discretisation: domains and meshes, the semi-discrete operators, nodal laws, dolfinx compat. Importing it
loads the FEniCS stack in its order (`stack.load`) and checks dolfinx's version. Layer: imports `model`, `scene`."""

from ..stack import load as _load_stack

_load_stack()
