"""Test oracles: an independent NumPy reference scheme, exact solutions, GetFEM's impacting rod.

Layer: imports `scene` only (they must stay independent of the solver they check).
"""
