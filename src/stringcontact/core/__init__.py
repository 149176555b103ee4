"""The core as a library: a model on the caller's own mesh and Functions (`ContactProblem`), advanced by a time
scheme one step per call (`TimeStepper`), with its energy ledger (`EnergyLedger`) and the observers that watch the
steps (`Observer`). docs/explanation/design.md.

Layer: imports `timestepping`, `fem`, `model` and `scene` (the model's constants); importing it loads the FEniCS
stack (`stack.load`).
"""

from ..stack import load as _load_stack

_load_stack()
