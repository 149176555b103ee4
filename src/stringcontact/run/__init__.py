"""The driver (`simulate`): discretise, choose the scheme, march, store the rows, keep the energy ledger.

Layer: imports `plot`, `io`, `timestepping`, `fem`, `model`, `scene`; nothing imports it but `analysis`,
`cli` and the package's lazy top level. Importing it loads the FEniCS stack first (`stack.load`).
"""

from ..stack import load as _load_stack

_load_stack()
