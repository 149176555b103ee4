"""Test oracles and peers: an independent NumPy reference scheme, exact solutions, GetFEM's impacting rod, and the
schemes as NumPy/SciPy and C peers (`peers`, what the benchmarks time `simulate` against).

Layer: imports `scene` only (they must stay independent of the solver they check).
"""
