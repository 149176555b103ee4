"""Pictures: matplotlib charts, pyvista mesh pictures, the membrane animation, the picture process.

Layer: imports `io` (atomic writes, read-back) and below; the writer in `io` never imports this package.
"""
