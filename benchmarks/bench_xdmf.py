"""Writing solution.xdmf/.h5: `XdmfTimeSeries` against the bytes alone and dolfinx 0.5's `XDMFFile.write_function`.

Each writer writes F frames of the four P1 fields of Example 1's mesh (N = 5000 cells, 5001 nodes: 160 kB
a frame) into a fresh folder under --dir (so the file system can be chosen: ext4 under /tmp, tmpfs under
/dev/shm). The writers alternate, so that a slower spell of a shared machine hits all of them; medians and
ranges of the wall clock over --repeats rounds.

* `XdmfTimeSeries`: this package's writer (the mesh, one dataset per field and frame, the XML per frame).
* bytes: the same arrays written with `file.write` into one file and flushed to the OS per frame (no fsync),
  the floor for any writer of these bytes.
* dolfinx `XDMFFile` (--dolfinx): rewrites its whole XML on every call, O(frames²); slow, so off by default.

The number of fsync calls while writing is counted with
``strace -f -y -e trace=fsync,fdatasync .venv/bin/python benchmarks/bench_xdmf.py --repeats 1 --frames 100``.

    .venv/bin/python benchmarks/bench_xdmf.py [--repeats 5] [--frames 100 400] [--dir /tmp] [--dolfinx]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from dolfinx import fem, mesh
from dolfinx.io import XDMFFile
from mpi4py import MPI

from stringcontact.fem import compat
from stringcontact.io.result import FIELDS
from stringcontact.io.xdmf import XdmfTimeSeries, mesh_arrays


def ours(V, folder: Path, frames: int, values) -> float:
    t0 = time.perf_counter()
    series = XdmfTimeSeries(folder, mesh_arrays(V, MPI.COMM_WORLD), MPI.COMM_WORLD)
    for k in range(frames):
        series.write(k * 1e-3, {name: values for name in FIELDS})
    series.close()
    return time.perf_counter() - t0


def raw_bytes(V, folder: Path, frames: int, values) -> float:
    t0 = time.perf_counter()
    with open(folder / "bytes", "wb") as f:
        for _ in range(frames):
            f.writelines(values for _name in FIELDS)
            f.flush()
    return time.perf_counter() - t0


def dolfinx_xdmf(V, folder: Path, frames: int, values) -> float:
    t0 = time.perf_counter()
    functions = {name: fem.Function(V, name=name) for name in FIELDS}
    with XDMFFile(MPI.COMM_WORLD, str(folder / "solution.xdmf"), "w") as xdmf:
        xdmf.write_mesh(V.mesh)
        for k in range(frames):
            for u in functions.values():
                u.x.array[:] = values
                xdmf.write_function(u, k * 1e-3)
    return time.perf_counter() - t0


LABELS = {ours: "XdmfTimeSeries", raw_bytes: "bytes", dolfinx_xdmf: "dolfinx XDMFFile"}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--frames", type=int, nargs="+", default=[100, 400])
    parser.add_argument("--dir", default=None, help="the folder to write under (default: the system's temporary folder)")
    parser.add_argument("--dolfinx", action="store_true", help="also time dolfinx's XDMFFile")
    args = parser.parse_args()
    V = compat.function_space(mesh.create_interval(MPI.COMM_WORLD, 5000, [0.0, 1.0]))
    values = np.random.default_rng(0).random(V.dofmap.index_map.size_local)
    writers = [ours, raw_bytes, *([dolfinx_xdmf] if args.dolfinx else [])]
    tmp = Path(tempfile.mkdtemp(prefix="bench-xdmf-", dir=args.dir))
    print(f"writing under {tmp.parent}")
    print("| frames | " + " | ".join(f"{LABELS[w]} [s] median (min-max)" for w in writers) + " |")
    print("|---:|" + "---:|" * len(writers))
    try:
        for frames in args.frames:
            times = {writer: [] for writer in writers}
            for i in range(args.repeats):
                for writer, spent in times.items():
                    folder = tmp / f"{writer.__name__}-{frames}-{i}"
                    folder.mkdir()
                    spent.append(writer(V, folder, frames, values))
                    shutil.rmtree(folder)
            cells = [f"{statistics.median(t):.3f} ({min(t):.3f}-{max(t):.3f})" for t in times.values()]
            print(f"| {frames} | " + " | ".join(cells) + " |", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
