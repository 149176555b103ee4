"""The physics in UFL: the model contract (`interface`), the paper's model (`inelastic`), the shipped variants
(`variants`, `nonlinear`, `film`, `stiff_string`), the model registry.

Importing this package loads nothing heavy: `registry` reads entry points and imports UFL (through `inelastic`)
only when a model is loaded. Layer: imports `scene` only.
"""
