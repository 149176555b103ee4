"""Space discretisation: domains and meshes, the semi-discrete operators, nodal laws, dolfinx compat.

Importing it loads the FEniCS stack in the order it needs (`stack.load`: the wheel's ``dolfinx_solver``
first) and checks dolfinx's version. Layer: imports `model` and `scene` only.
"""

from ..stack import load as _load_stack

_load_stack()
