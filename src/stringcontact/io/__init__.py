"""Output folders: the folder itself (lock, publish, signals), the writers (XDMF, CSV, JSON), read-back, `Result`.

Layer: imports `fem.compat` (no dolfinx at import), `model.registry` and `scene`; never the picture code.
"""
