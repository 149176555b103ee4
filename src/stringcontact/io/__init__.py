"""Output folders: the folder itself (target, lock, publish, manifest, disk), the writers (XDMF and HDF5,
CSV, JSON), read-back, `Result`.

Layer: imports `fem.compat` (no dolfinx at import), `model.registry` and `scene`; never the picture code.
"""
