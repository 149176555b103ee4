"""Space discretisation: domains and meshes, the semi-discrete operators, nodal laws, dolfinx compat.

The package itself imports nothing: dolfinx loads with the module that needs it. Layer: imports `model`
and `scene` only.
"""
