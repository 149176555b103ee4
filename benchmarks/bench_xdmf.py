"""Writing solution.xdmf/.h5: this package's `XdmfTimeSeries` against dolfinx 0.5's `XDMFFile.write_function`.

Both write F frames of the four P1 fields of Example 1's mesh (N = 5000 cells, 5001 nodes) into a fresh
folder; the two alternate, so that a slower spell of a shared machine hits both; medians and ranges of the
wall clock over --repeats pairs. dolfinx's writer rewrites its whole XML file on every call (O(frames²));
`XdmfTimeSeries` appends one grid per frame (O(frames)).

    .venv/bin/python benchmarks/bench_xdmf.py [--repeats 5] [--frames 100 400]
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--frames", type=int, nargs="+", default=[100, 400])
    args = parser.parse_args()
    V = compat.function_space(mesh.create_interval(MPI.COMM_WORLD, 5000, [0.0, 1.0]))
    values = np.random.default_rng(0).random(V.dofmap.index_map.size_local)
    tmp = Path(tempfile.mkdtemp(prefix="bench-xdmf-"))
    print("| frames | XdmfTimeSeries [s] median (min-max) | dolfinx XDMFFile [s] median (min-max) |")
    print("|---:|---:|---:|")
    try:
        for frames in args.frames:
            times = {ours: [], dolfinx_xdmf: []}
            for i in range(args.repeats):
                for writer, spent in times.items():
                    folder = tmp / f"{writer.__name__}-{frames}-{i}"
                    folder.mkdir()
                    spent.append(writer(V, folder, frames, values))
                    shutil.rmtree(folder)
            cells = [f"{statistics.median(t):.3f} ({min(t):.3f}-{max(t):.3f})" for t in times.values()]
            print(f"| {frames} | {cells[0]} | {cells[1]} |", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
