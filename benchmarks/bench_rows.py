"""The size and writing time of rows.npz (the stored rows `stringcontact plot` redraws from) for the
built-in scenes at their own resolution, as written (`tables.write_rows`: contact and contact_force
compressed, eta and velocity stored), all stored (np.savez) and all zlib-compressed (np.savez_compressed).

    .venv/bin/python benchmarks/bench_rows.py [SCENE ...]     (default: example1 example2 drum bump)
    .venv/bin/python benchmarks/bench_rows.py --against-numpy 10 [--fresh] [SCENE]   (default: example1)

Prints, per scene: stored rows, nodes, the file's bytes and write time either way, and solution.h5's bytes.
With --against-numpy N: rows.npz written N times each, alternately, by `write_rows` and the way before it
(NumPy's `format.write_array` into each member, zlib level 6), and by write_npy at level 6 (the level apart);
median times and sizes. With --fresh as well, each write is the first of a fresh process, as in
`stringcontact run` (a warm process reuses the memory of its earlier writes' copies).
"""

from __future__ import annotations

import io
import statistics
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

import stringcontact as sc
from stringcontact.io.tables import FIELDS, write_npy, write_rows


def measure(name: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / name
        res = sc.simulate(sc.load_scene(name), output=sc.Output(out, pictures=False, progress=False))
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


def _members(path: Path, result, write, level: int) -> None:
    """write_rows' members, each written by `write` (f, array) at zlib `level`."""
    arrays = {"t": result.t, "steps": result.steps, "x": result.x, **{name: getattr(result, name) for name in FIELDS}}
    with zipfile.ZipFile(path, "w", compresslevel=level) as archive:
        for name, values in arrays.items():
            kind = zipfile.ZIP_STORED if name in ("eta", "velocity") else zipfile.ZIP_DEFLATED
            archive.compression = kind  # a name (not a ZipInfo) takes the archive's compression and level
            with archive.open(f"{name}.npy", "w", force_zip64=True) as f:
                write(f, np.asarray(values))


def _ways() -> dict:
    from numpy.lib import format as npy

    return {
        "write_rows (write_npy, level 1)": lambda p, r: write_rows(p, r),
        "write_npy, level 6": lambda p, r: _members(p, r, write_npy, 6),
        "NumPy's write_array, level 6 (before)": lambda p, r: _members(p, r, lambda f, a: npy.write_array(f, a, allow_pickle=False), 6),
    }


def _write_once(label: str, name: str, path: Path, res=None) -> tuple[float, float]:
    """(seconds, MB) of one write of `name`'s rows by the way `label`, checked against the run's arrays."""
    res = res if res is not None else sc.simulate(sc.load_scene(name), output=sc.Output(progress=False))
    t0 = time.perf_counter()
    _ways()[label](path, res)
    seconds = time.perf_counter() - t0
    with np.load(path) as npz:  # every way writes the same arrays
        assert all(np.array_equal(npz[f], getattr(res, f)) for f in FIELDS)
    size = path.stat().st_size / 1e6
    path.unlink()
    return seconds, size


def against_numpy(name: str, n: int, fresh: bool) -> None:
    import json
    import os
    import subprocess

    labels = list(_ways())
    times, sizes = {k: [] for k in labels}, {}
    with tempfile.TemporaryDirectory() as tmp:
        res = None if fresh else sc.simulate(sc.load_scene(name), output=sc.Output(progress=False))
        for k in range(n):
            for label in (labels if k % 2 == 0 else labels[::-1]):
                path = Path(tmp) / f"{k}.npz"
                if fresh:
                    out = subprocess.run([sys.executable, __file__, "--one", label, name, str(path)], check=True,
                                         capture_output=True, text=True).stdout
                    seconds, size = json.loads(out.strip().splitlines()[-1])
                else:
                    seconds, size = _write_once(label, name, path, res)
                times[label].append(seconds)
                sizes[label] = size
    print(f"{name}: {n} writes each, alternately{', each in a fresh process' if fresh else ''}; load average "
          f"{os.getloadavg()[0]:.2f}")
    for label, t in times.items():
        print(f"  {label}: median {statistics.median(t) * 1e3:.1f} ms (min {min(t) * 1e3:.1f}), {sizes[label]:.2f} MB")


if __name__ == "__main__":
    args = sys.argv[1:]
    fresh = "--fresh" in args
    args = [a for a in args if a != "--fresh"]
    if args[:1] == ["--one"]:
        print(__import__("json").dumps(_write_once(args[1], args[2], Path(args[3]))))
    elif args[:1] == ["--against-numpy"]:
        against_numpy(args[2] if len(args) > 2 else "example1", int(args[1]), fresh)
    else:
        for scene in args or ["example1", "example2", "drum", "bump"]:
            measure(scene)
