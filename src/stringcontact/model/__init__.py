"""The physics in UFL: the paper's model (`paper`), the shipped variants (`variants`), the model registry.

Importing this package loads nothing heavy: `registry` reads entry points and imports UFL (through `paper`)
only when a model is loaded. Layer: imports `scene` only.
"""
