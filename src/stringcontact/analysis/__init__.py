"""Studies (work-precision, convergence, stability, `run --tol`) and the paper's theorem checks.

Layer: imports `run` and everything below it, and `verification`.
"""
