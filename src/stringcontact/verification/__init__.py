"""Oracles: an independent NumPy reference scheme and exact solutions (the benchmarks' peers and GetFEM's rod are in
benchmarks/).

Layer: imports `scene` only (they must stay independent of the solver they check).
"""
