"""CPU and wall time of each picture of Example 1 (N = 5000, about 400 stored rows), and of the libraries' start-up.

In one fresh process with dolfinx loaded (as in a run): the first matplotlib picture (energy.png) and the first
pyvista picture (space_time.png), each with its library's start-up (pyplot; pyvista, the EGL context, llvmpipe's
shaders); then each picture `--repeats` times (medians), the surface once more with pyvista's default 8x
multisampling, which `vtk_start` turns off, and every picture as a run draws them after its solve
(`write_pictures`). CPU time counts llvmpipe's threads; on a shared machine it is steadier than the wall clock.

    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow LP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_pictures.py

With `--paper`, each picture of Example 1 `--repeats` times in the screen style as a PNG, and in the paper style
(`plot.style.Look(style="paper")`) as a PNG (300 dots per inch), a PDF and an SVG: CPU and wall medians.

With `--panels N ...`, only `snapshots.png` of Example 1 at nx = 200 with N evenly spaced output times (default
12, 100, 1000: the most a scene may give): the picture draws at most `charts.MAX_PANELS` of them, so its time does
not grow with N.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path


def timed(fn) -> tuple[float, float]:
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def paper_costs(res, out: Path, repeats: int) -> list[tuple[str, float, float]]:
    """(picture and look, CPU, wall) medians of each picture in the screen style (PNG) and the paper style (PNG, PDF,
    SVG: the figure drawn once, saved three times)."""
    from stringcontact.plot import run_pictures as viz
    from stringcontact.plot.style import Look

    for name in viz.PICTURES:  # each library's start-up out of the medians
        viz.draw(name, res, out)
    rows = []
    for name in viz.PICTURES:
        for label, look in (("screen, png", Look()), ("paper, png + pdf + svg", Look(("png", "pdf", "svg"), "paper"))):
            runs = [timed(lambda name=name, look=look: viz.draw(name, res, out, look=look)) for _ in range(repeats)]
            rows.append((f"{name} ({label})", statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    return rows


def panel_costs(counts) -> int:
    """`snapshots.png` of Example 1 at nx = 200 with each count of evenly spaced output times: its panels and
    wall time."""
    import numpy as np

    import stringcontact as sc
    from stringcontact.plot import charts

    scene = sc.load_scene("example1")
    for n in counts:
        times = np.round(np.linspace(0.0, scene.T, n), 12).tolist()
        res = sc.simulate(scene.replace(nx=200, output_times=times), output=sc.Output(progress=False))
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            charts.picture(charts.snapshots_figure, res, Path(tmp) / "snapshots.png")
            took = time.perf_counter() - t0
        panels = len(charts.snapshot_rows(res))
        print(f"{n} output times ({len(res.t)} stored rows): snapshots.png {panels} panels in {took:.2f} s")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--paper", action="store_true", help="only the pictures, in the screen and the paper style")
    ap.add_argument("--panels", type=int, nargs="*", metavar="N",
                    help="only snapshots.png with N output times (default 12 100 1000)")
    args = ap.parse_args(argv)
    if args.panels is not None:
        return panel_costs(args.panels or [12, 100, 1000])
    import stringcontact as sc

    res = sc.simulate(sc.load_scene("example1"), output=sc.Output(progress=False))
    from stringcontact.plot import mesh_pictures
    from stringcontact.plot import run_pictures as viz

    out = Path(tempfile.mkdtemp(prefix="bench_pictures_"))
    if args.paper:
        return _table(res, paper_costs(res, out, args.repeats), args.repeats)
    rows = [
        ("energy.png, the first (pyplot's start-up included)", *timed(lambda: viz.draw("energy.png", res, out))),
        ("space_time.png, the first (pyvista, EGL, shaders included)", *timed(lambda: viz.draw("space_time.png", res, out))),
    ]
    for name in viz.PICTURES:
        runs = [timed(lambda name=name: viz.draw(name, res, out)) for _ in range(args.repeats)]
        rows.append((name, statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    runs = [timed(lambda: viz.write_pictures(res, out)) for _ in range(args.repeats)]
    rows.append(("all five: write_pictures", statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    plain = mesh_pictures._plotter

    def with_msaa(window_size):
        p = plain(window_size)
        p.enable_anti_aliasing("msaa", multi_samples=8)
        return p

    mesh_pictures._plotter = with_msaa
    runs = [timed(lambda: viz.draw("space_time.png", res, out)) for _ in range(args.repeats)]
    rows.append(("space_time.png with 8x MSAA", statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    return _table(res, rows, args.repeats)


def _table(res, rows, repeats: int, third: str = "wall [s]") -> int:
    print(f"Example 1, {len(res.t)} stored rows, {len(res.x)} nodes; " if res is not None else "", end="")
    print(f"medians of {repeats}\n")
    print(f"| step | CPU [s] | {third} |\n|---|---:|---:|")
    for name, cpu, wall in rows:
        print(f"| {name} | {cpu:.3f} | {wall:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
