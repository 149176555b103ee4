"""The size and writing time of rows.npz (the stored rows `stringcontact plot` redraws from) for the
built-in scenes at their own resolution, as written (`tables.write_rows`: contact and contact_force
compressed, eta and velocity stored), all stored (np.savez) and all zlib-compressed (np.savez_compressed).

    .venv/bin/python benchmarks/bench_rows.py [SCENE ...]     (default: example1 example2 drum bump)

Prints, per scene: stored rows, nodes, the file's bytes and write time either way, and solution.h5's bytes.
"""

from __future__ import annotations

import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import stringcontact as sc
from stringcontact.io.tables import write_rows


def measure(name: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / name
        res = sc.simulate(sc.load_scene(name), output_dir=out, pictures=False, progress=False)
        t0 = time.perf_counter()
        write_rows(Path(tmp) / "again.npz", res)
        plain = time.perf_counter() - t0
        with np.load(out / "rows.npz") as npz:
            arrays = {k: npz[k] for k in npz.files}
        sizes = {}
        for how, save in (("all stored", np.savez), ("all compressed", np.savez_compressed)):
            buffer = io.BytesIO()
            t0 = time.perf_counter()
            save(buffer, **arrays)
            sizes[how] = (buffer.tell() / 1e6, time.perf_counter() - t0)
        others = "; ".join(f"{how} {mb:.2f} MB in {s:.3f} s" for how, (mb, s) in sizes.items())
        print(f"{name}: {len(res.t)} rows x {len(res.x)} nodes; rows.npz {(out / 'rows.npz').stat().st_size / 1e6:.2f} MB "
              f"in {plain:.3f} s; {others}; solution.h5 {(out / 'solution.h5').stat().st_size / 1e6:.2f} MB")


if __name__ == "__main__":
    for scene in sys.argv[1:] or ["example1", "example2", "drum", "bump"]:
        measure(scene)
