"""The application: a scene adapted to the core (`adapter`), stepped with the stored rows and the output folder
(`Stepper`), looped over by `simulate`; the run's checks and options. Layer: above `plot`, `io` and the core;
importing it loads the FEniCS stack first (`stack.load`)."""

from ..stack import load as _load_stack

_load_stack()
