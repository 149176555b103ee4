"""CPU and wall time of each picture of Example 1 (N = 5000, about 400 stored rows), of the start-up, and of
the painter and its helper drawing them all.

In one fresh process with dolfinx loaded (as in a run): importing pyplot and pyvista, the warm-ups the
painter process does, then each picture `--repeats` times (medians), and the surface once more with
pyvista's default 8x multisampling, which `mesh_pictures` turns off. CPU time counts llvmpipe's threads;
on a shared machine it is steadier than the wall clock.

Then what `stringcontact run` does after its solve, `--repeats` times: a `picture_process.PictureProcess` started
`--settle` seconds before (time to warm up, as it does during a run) is sent the Result and draws every
picture with its helper; the wall clock from `send` to the reply, and the CPU seconds of both processes in
that span (from /proc before `send`, and from `getrusage` once they are gone).

    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow LP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_pictures.py

With `--paper`, each picture of Example 1 `--repeats` times in the screen style as a PNG, and in the paper style
(`plot.style.Look(style="paper")`) as a PNG (300 dots per inch), a PDF and an SVG: CPU and wall medians.

With `--gc`, the painter's two costs with Python's cyclic collector on and off (the painter runs without it):
the warm-ups (charts and pyvista) in `--repeats` fresh processes each way, alternating, and Example 1's
five pictures drawn `--repeats` times each way in one warm process (the collector on: Python's default),
with the growth of the resident memory.

With `--panels N ...`, only `snapshots.png` of Example 1 at nx = 200 with N evenly spaced output times (default
12, 100, 1000: the most a scene may give): the picture draws at most `charts.MAX_PANELS` of them, so its time does
not grow with N.

With `--vtk-search`, only pyvista's import and warm-up picture, after matplotlib's warm-up as in the painter,
in `--repeats` fresh processes each way, alternating: VTK's own module search (a glob of its folder per module
and extension) and `vtk_modules.search_once` (each folder listed once); CPU medians and minima.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path


def timed(fn) -> tuple[float, float]:
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def group_cpu(pgid: int) -> float:
    """CPU seconds (user + system) so far of the live processes of the process group `pgid`."""
    ticks = os.sysconf("SC_CLK_TCK")
    total = 0.0
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid:
            total += (int(fields[11]) + int(fields[12])) / ticks  # utime, stime
    return total


def painted(res, out: Path, settle: float) -> tuple[float, float]:
    """(CPU, wall) of the painter and its helper drawing every picture of `res`, from `send` to the reply."""
    from stringcontact.plot import run_pictures as viz
    from stringcontact.plot.picture_process import PictureProcess

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    process = PictureProcess.start(viz.PICTURES)
    time.sleep(settle)
    warm = group_cpu(process.proc.pid)
    w0 = time.perf_counter()
    assert process.send(res, out) and process.wait(), process.error
    wall = time.perf_counter() - w0
    after = resource.getrusage(
        resource.RUSAGE_CHILDREN
    )  # the painter, reaped by cancel(), and its helper, reaped by it
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime) - warm
    return cpu, wall


def paper_costs(res, out: Path, repeats: int) -> list[tuple[str, float, float]]:
    """(picture and look, CPU, wall) medians of each picture in the screen style (PNG) and the paper style (PNG, PDF,
    SVG: the figure drawn once, saved three times)."""
    from stringcontact.plot import charts, mesh_pictures
    from stringcontact.plot import run_pictures as viz
    from stringcontact.plot.style import Look

    charts.warm_up()
    mesh_pictures.warm_up()
    rows = []
    for name in viz.PICTURES:
        for label, look in (("screen, png", Look()), ("paper, png + pdf + svg", Look(("png", "pdf", "svg"), "paper"))):
            runs = [timed(lambda name=name, look=look: viz.draw(name, res, out, look=look)) for _ in range(repeats)]
            rows.append((f"{name} ({label})", statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    return rows


WARM_UP = """
import gc, sys, time
if sys.argv[1] == "off":
    gc.disable()
c0 = time.process_time()
from stringcontact.plot import charts, mesh_pictures
charts.warm_up()
mesh_pictures.warm_up()
print(time.process_time() - c0)
"""


VTK_SEARCH = """
import sys, time
from stringcontact.plot import charts, mesh_pictures, vtk_start
charts.warm_up()  # as the painter: matplotlib first, then pyvista
if sys.argv[1] == "vtk":
    vtk_start.search_once = lambda: False  # VTK's own search
c0 = time.process_time()
mesh_pictures.warm_up()
print(time.process_time() - c0)
"""


def fresh_cpu(code: str, ways: tuple[str, ...], repeats: int) -> dict[str, list[float]]:
    """The CPU seconds that `code` prints, run `repeats` times in a fresh process per way (its argv[1]),
    the ways alternating."""
    import subprocess

    runs = {way: [] for way in ways}
    for _ in range(repeats):
        for way, times in runs.items():
            text = subprocess.run([sys.executable, "-c", code, way], capture_output=True, text=True, check=True).stdout
            times.append(float(text.split()[-1]))
    return runs


def vtk_search_costs(repeats: int) -> list[tuple[str, float, float]]:
    """(what, CPU median, min): pyvista's import and warm-up picture with VTK's module search and with
    `vtk_start.search_once`, alternating fresh processes."""
    runs = fresh_cpu(VTK_SEARCH, ("vtk", "once"), repeats)
    names = {"vtk": "VTK's search (a glob per module and extension)", "once": "vtk_start.search_once"}
    return [(f"import pyvista + warm-up, {names[way]}", statistics.median(t), min(t)) for way, t in runs.items()]


def _rss_mb() -> int:
    with open("/proc/self/status") as status:
        return next(int(line.split()[1]) // 1024 for line in status if line.startswith("VmRSS"))


def gc_costs(res, out: Path, repeats: int) -> list[tuple[str, float, float]]:
    """(what, CPU median, memory growth median [MB] or nan) with the collector on and off, alternating."""
    import gc

    from stringcontact.plot import charts, mesh_pictures
    from stringcontact.plot import run_pictures as viz

    warm = fresh_cpu(WARM_UP, ("on", "off"), repeats)
    charts.warm_up()
    mesh_pictures.warm_up()
    gc.freeze()
    draw = {"on": [], "off": []}
    for _ in range(repeats):
        for mode, runs in draw.items():
            (gc.enable if mode == "on" else gc.disable)()
            before, c0 = _rss_mb(), time.process_time()
            for name in viz.PICTURES:
                viz.draw(name, res, out)
            runs.append((time.process_time() - c0, _rss_mb() - before))
            gc.enable()
            gc.collect()
    rows = [
        (f"warm-ups, collector {mode} (fresh processes)", statistics.median(t), float("nan"))
        for mode, t in warm.items()
    ]
    return rows + [
        (
            f"the five pictures, collector {mode} (one process)",
            statistics.median(r[0] for r in runs),
            statistics.median(r[1] for r in runs),
        )
        for mode, runs in draw.items()
    ]


def panel_costs(counts) -> int:
    """`snapshots.png` of Example 1 at nx = 200 with each count of evenly spaced output times: its panels and
    wall time."""
    import numpy as np

    import stringcontact as sc
    from stringcontact.plot import charts

    scene = sc.load_scene("example1")
    for n in counts:
        times = np.round(np.linspace(0.0, scene.T, n), 12).tolist()
        res = sc.simulate(scene.replace(nx=200, output_times=times), progress=False)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            charts.snapshots_picture(res, Path(tmp) / "snapshots.png")
            took = time.perf_counter() - t0
        panels = len(charts.snapshot_rows(res))
        print(f"{n} output times ({len(res.t)} stored rows): snapshots.png {panels} panels in {took:.2f} s")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--settle", type=float, default=5.0, help="seconds the painter has to warm up before `send`")
    ap.add_argument("--paper", action="store_true", help="only the pictures, in the screen and the paper style")
    ap.add_argument("--gc", action="store_true", help="only the warm-ups and the pictures, collector on and off")
    ap.add_argument("--vtk-search", action="store_true", help="only pyvista's warm-up, VTK's module search two ways")
    ap.add_argument(
        "--panels",
        type=int,
        nargs="*",
        metavar="N",
        help="only snapshots.png with N output times (default 12 100 1000)",
    )
    args = ap.parse_args(argv)
    if args.panels is not None:
        return panel_costs(args.panels or [12, 100, 1000])
    if args.vtk_search:
        return _table(None, vtk_search_costs(args.repeats), args.repeats, third="min [s]")
    import stringcontact as sc

    res = sc.simulate(sc.load_scene("example1"), progress=False)
    from stringcontact.plot import charts, mesh_pictures
    from stringcontact.plot import run_pictures as viz

    out = Path(tempfile.mkdtemp(prefix="bench_pictures_"))
    if args.paper:
        return _table(res, paper_costs(res, out, args.repeats), args.repeats)
    if args.gc:
        return _table(res, gc_costs(res, out, args.repeats), args.repeats, third="RSS growth [MB]")
    rows = [
        ("import matplotlib.pyplot + warm-up", *timed(charts.warm_up)),
        ("import pyvista + warm-up (EGL, shaders)", *timed(mesh_pictures.warm_up)),
    ]
    for name in viz.PICTURES:
        runs = [timed(lambda name=name: viz.draw(name, res, out)) for _ in range(args.repeats)]
        rows.append((name, statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    plain = mesh_pictures._plotter

    def with_msaa(window_size):
        p = plain(window_size)
        p.enable_anti_aliasing("msaa", multi_samples=8)
        return p

    mesh_pictures._plotter = with_msaa
    runs = [timed(lambda: viz.draw("space_time.png", res, out)) for _ in range(args.repeats)]
    rows.append(
        ("space_time.png with 8x MSAA", statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs))
    )
    runs = [painted(res, out, args.settle) for _ in range(args.repeats)]
    rows.append(
        (
            "all pictures: painter + helper, send to reply",
            statistics.median(r[0] for r in runs),
            statistics.median(r[1] for r in runs),
        )
    )
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
