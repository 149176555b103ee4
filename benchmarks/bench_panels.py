"""The time to draw snapshots.png for a scene with many output times (issue 27, item 4): Example 1 at nx = 200
with N evenly spaced output times, N = 12, 100, 1000 (the most a scene may give). The picture draws at most
`charts.MAX_PANELS` of them, so its time no longer grows with N.

    .venv/bin/python benchmarks/bench_panels.py [N ...]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import stringcontact as sc
from stringcontact.plot import charts


def measure(n: int) -> None:
    scene = sc.load_scene("example1")
    times = np.round(np.linspace(0.0, scene.T, n), 12).tolist()
    res = sc.simulate(scene.replace(nx=200, output_times=times), progress=False)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        charts.snapshots_picture(res, Path(tmp) / "snapshots.png")
        took = time.perf_counter() - t0
    print(f"{n} output times ({len(res.t)} stored rows): snapshots.png {len(charts.snapshot_rows(res))} panels in {took:.2f} s")


if __name__ == "__main__":
    for n in [int(v) for v in sys.argv[1:]] or [12, 100, 1000]:
        measure(n)
