"""Wall clock of `stringcontact run drum --out DIR` with its membrane pictures, and of each picture alone.

1. The command as a user runs it, in a fresh process, warm JIT cache: with its pictures and with
   `--no-pictures`, alternating so that a slower spell of the shared machine hits both; medians and ranges.
   The run draws its four pictures after its solve.
2. In one fresh process with dolfinx loaded (as in a run): the drum's Result, the first matplotlib and the first
   pyvista picture (each with its library's start-up), then each picture `--repeats` times (medians of CPU and
   wall time; CPU counts llvmpipe's threads).
   Also the GIF's size and frames, and the GIF written the way pyvista's `open_gif`/`write_frame` do it
   (imageio's Pillow writer quantising every frame by median cut), which `animation.write_gif` replaces.

    LP_NUM_THREADS=1 VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow \\
        .venv/bin/python benchmarks/bench_membrane_pictures.py [--repeats 5] [--scene drum]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run_cli(scene: str, out: Path, *extra: str) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "stringcontact", "run", scene, "--out", str(out), "--force", "--no-progress",
                    *extra], check=True, capture_output=True)
    return time.perf_counter() - t0


def timed(fn) -> tuple[float, float]:
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def end_to_end(scene: str, repeats: int, folder: Path) -> None:
    run_cli(scene, folder / "warm")  # the JIT cache and the OS's file cache
    times = {"with pictures": [], "--no-pictures": []}
    for _ in range(repeats):
        times["with pictures"].append(run_cli(scene, folder / "pictures"))
        times["--no-pictures"].append(run_cli(scene, folder / "bare", "--no-pictures"))
    print(f"`{Path(sys.executable).name} -m stringcontact run {scene} --out DIR --force --no-progress`, {repeats} runs\n")
    print("| command | median wall [s] | range [s] |\n|---|---:|---:|")
    for name, ts in times.items():
        print(f"| {name} | {statistics.median(ts):.2f} | {min(ts):.2f}-{max(ts):.2f} |")


def per_picture(scene: str, repeats: int, folder: Path) -> None:
    import stringcontact as sc

    res = sc.simulate(sc.load_scene(scene), output=sc.Output(progress=False))
    from stringcontact.plot import animation
    from stringcontact.plot import run_pictures as viz

    rows = [("energy.png, the first (pyplot's start-up included)", *timed(lambda: viz.draw("energy.png", res, folder))),
            ("membrane.png, the first (pyvista, EGL, shaders included)",
             *timed(lambda: viz.draw("membrane.png", res, folder)))]
    for name in viz.MEMBRANE_PICTURES:
        runs = [timed(lambda name=name: viz.draw(name, res, folder)) for _ in range(repeats)]
        rows.append((name, statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    runs = [timed(lambda: pyvista_gif(res, folder / "pyvista.gif")) for _ in range(repeats)]
    rows.append(("membrane.gif by open_gif/write_frame", statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)))
    print(f"\n{scene}: {len(res.t)} stored rows, {len(res.x)} nodes, {len(res.cells)} triangles; medians of {repeats}\n")
    print("| step | CPU [s] | wall [s] |\n|---|---:|---:|")
    for name, cpu, wall in rows:
        print(f"| {name} | {cpu:.2f} | {wall:.2f} |")
    import imageio.v3 as iio

    for name in ("membrane.gif", "pyvista.gif"):
        frames = iio.imread(folder / name, index=None)
        print(f"\n{name}: {frames.shape[0]} frames of {frames.shape[2]}x{frames.shape[1]}, "
              f"{os.path.getsize(folder / name) / 1e6:.2f} MB")
    print(f"frame rows: every {int(animation.frame_rows(res)[1])}th of {len(res.t)}")


def pyvista_gif(res, path: Path) -> None:
    """The same frames written by pyvista's own GIF writer (imageio, a median-cut palette per frame)."""
    from stringcontact.plot import animation, membrane, vtk_start
    from stringcontact.plot import run_pictures as viz

    view = membrane.membrane_view(res)
    p = vtk_start._plotter(animation.gif_size(viz.WINDOW_SIZE))
    surface = membrane.add_membrane(p, res, 0, view)
    text = p.add_text("", position=(0.02, 0.98), viewport=True, font_size=6, color="black")
    p.open_gif(str(path), fps=animation.FPS, palettesize=animation.PALETTE)
    for i in animation.frame_rows(res):
        surface.points[:, 2] = res.eta[i] * view.scale
        surface.point_data["contact"][:] = res.contact[i]
        surface.Modified()
        text.input = f"t = {res.t[i]:.3g}"
        p.write_frame()
    p.close()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--scene", default="drum")
    ap.add_argument("--only", choices=("cli", "pictures"), help="one of the two parts")
    args = ap.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="bench_membrane_"))
    if args.only != "pictures":
        end_to_end(args.scene, args.repeats, folder)
    if args.only != "cli":
        per_picture(args.scene, args.repeats, folder)
    return 0


if __name__ == "__main__":
    sys.exit(main())
