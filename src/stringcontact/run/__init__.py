"""The application: a scene adapted to the core (`adapter`), stepped with the standard observers (`Stepper`: the
stored rows, the output folder) and looped over by `simulate`; the run's checks and its options.

Layer: imports `plot`, `io`, `timestepping`, `fem`, `model`, `scene`; nothing imports it but `analysis`,
`cli` and the package's lazy top level. Importing it loads the FEniCS stack first (`stack.load`).
"""

from ..stack import load as _load_stack

_load_stack()
