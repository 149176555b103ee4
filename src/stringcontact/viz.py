"""Pictures of a run, and `stringcontact plot`.

* :func:`write_pictures` draws ``contact_set.png`` and ``velocity_field.png`` (space-time pictures, pyvista
  off-screen) and ``snapshots.png`` and ``energy.png`` (line charts, matplotlib) from a :class:`Result`.
* ``stringcontact plot DIR`` redraws everything from an output folder alone (read back by
  :func:`stringcontact.readback.read_output`), without re-running.
* :func:`contact_components` splits one row of the contact set into its intervals (used by the
  snapshot titles and by the demos).

* :class:`Painters` draws the two pyvista pictures in another process that starts with the run, so that
  its start-up (loading VTK, creating the EGL context, compiling llvmpipe's shaders, the font: about
  1.2 s) overlaps the time loop; the run draws the matplotlib charts meanwhile.

Why two libraries: the space-time fields are a rectilinear (x, t) grid of up to millions of cells, which
VTK shows as one texture with a texel per screen pixel; the snapshots and the energy balance are small line charts with shared axes, a
log-scale panel, filled regions and mathtext labels, which matplotlib draws better than pyvista's charts.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import pickle
import selectors
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from .output import atomic_path

PICTURES = ("contact_set.png", "velocity_field.png", "snapshots.png", "energy.png")
#: |v| is clipped at this percentile for the colour range: v0 = −50 at t = 0 would otherwise wash out the rest.
VELOCITY_PERCENTILE = 99.0
CONTACT_COLOUR = "#b2182b"
WINDOW_SIZE = (1100, 900)


# --- reading the contact set ------------------------------------------------------------------------


def contact_components(x: np.ndarray, contact_row: np.ndarray, min_nodes: int = 2) -> list[tuple[float, float]]:
    """The intervals [a, b] of one contact row: maximal runs of at least `min_nodes` contact nodes.

    The default drops isolated nodes, i.e. components of zero length (Example 2's left end is pinned at
    η = 0 and so is always "in contact" at one node).
    """
    c = np.asarray(contact_row, dtype=bool).astype(np.int8)
    edges = np.diff(np.concatenate([[0], c, [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # runs [start, stop)
    return [(float(x[a]), float(x[b - 1])) for a, b in zip(starts, stops) if b - a >= min_nodes]


def stored_rows_at(result, times) -> list[int]:
    """Indices of the stored rows at `times` (nearest stored time within half a step; others skipped)."""
    half_step = 0.5 * result.scene.dt
    rows = []
    for t in times:
        i = int(np.argmin(np.abs(result.t - t)))
        if abs(result.t[i] - t) <= half_step:
            rows.append(i)
    return rows


def snapshot_rows(result) -> list[int]:
    """The rows at the scene's output times, or six evenly spaced rows if it has none."""
    rows = stored_rows_at(result, result.scene.output_times)
    if not rows:
        rows = sorted(set(np.linspace(0, len(result.t) - 1, 6).round().astype(int).tolist()))
    return rows


def velocity_clip(result, percentile: float = VELOCITY_PERCENTILE) -> float:
    """Symmetric colour range ±c for v, with c the `percentile` of |v| over all stored samples."""
    c = float(np.percentile(np.abs(result.velocity), percentile))
    return c if c > 0 else max(float(np.max(np.abs(result.velocity))), 1.0)


# --- titles -----------------------------------------------------------------------------------------


def parameter_line(result, sep: str = ", ") -> str:
    s = result.scene
    return (
        f"nx = {s.nx}, Δt = {s.dt:.3g}, α = {s.alpha:g}, ε = {s.eps:g}{sep}"
        f"penalty {result.penalty} (Δt/ε = {s.dt / s.eps:.3g}), {result.mass} mass"
    )


# --- pyvista: space-time pictures ---------------------------------------------------------------------


def _font_file() -> str | None:
    """A TrueType font with Greek letters (VTK's built-in fonts have none): matplotlib's DejaVu Sans."""
    try:
        from matplotlib import font_manager

        return font_manager.findfont("DejaVu Sans", fallback_to_default=False)
    except Exception:  # no font: VTK's own font, Greek letters missing
        return None


def _use_font(prop, font: str | None) -> None:
    if font:
        prop.SetFontFamilyAsString("File")  # VTK_FONT_FILE
        prop.SetFontFile(font)


def _offscreen():
    # EGL needs no display; on a desktop with a display VTK's default window works too.
    if "DISPLAY" not in os.environ:
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def space_time_grid(result, aspect: float = 0.75, max_columns: int = 1200):
    """A rectilinear grid with one cell per stored sample (x_i, t_k), cells centred on the samples.

    Time is scaled by `aspect`·l/T so that the picture is `aspect` times as high as it is wide; the axes
    are labelled with the true t. With more than `max_columns` nodes, neighbouring nodes are merged into
    blocks (velocity averaged, contact where at least half the block is in contact): a picture has under
    a thousand pixels across (the pictures draw the grid as a texture, see `_add_raster`).
    """
    pv = _offscreen()
    x, t = result.x, result.t
    L, T = float(x[-1] - x[0]), float(t[-1] - t[0]) or 1.0
    xe = np.concatenate([[x[0]], 0.5 * (x[1:] + x[:-1]), [x[-1]]])
    te = np.concatenate([[t[0]], 0.5 * (t[1:] + t[:-1]), [t[-1]]]) if len(t) > 1 else np.array([t[0], t[0] + 1.0])
    velocity = np.asarray(result.velocity, dtype=float)
    contact = np.asarray(result.contact, dtype=float)
    n = x.size
    if n > max_columns:
        starts = np.arange(0, n, int(np.ceil(n / max_columns)))
        counts = np.diff(np.append(starts, n))
        xe = np.append(xe[starts], xe[-1])
        velocity, contact = (np.add.reduceat(a, starts, axis=1) / counts for a in (velocity, contact))
    scale = aspect * L / T
    grid = pv.RectilinearGrid(xe, te * scale, np.array([0.0]))
    # cell order: x fastest, then t, i.e. a (k, n) array raveled in C order
    grid.cell_data["velocity"] = velocity.ravel()
    grid.cell_data["contact"] = (contact >= 0.5).astype(np.uint8).ravel()
    return grid, (float(x[0]), float(x[-1]), float(t[0]), float(t[-1]))


def _tick_values(lo: float, hi: float, n: int) -> np.ndarray:
    from matplotlib.ticker import MaxNLocator

    ticks = MaxNLocator(nbins=n, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)
    span = hi - lo
    return ticks[(ticks >= lo - 1e-9 * span) & (ticks <= hi + 1e-9 * span)]


def _world_text(p, text: str, xy, font, size: int, halign: str, valign: str):
    from vtkmodules.vtkRenderingCore import vtkTextActor  # not `import vtk`: that loads all ~170 VTK modules (0.4 s)

    actor = vtkTextActor()
    actor.SetInput(text)
    actor.GetPositionCoordinate().SetCoordinateSystemToWorld()
    actor.GetPositionCoordinate().SetValue(float(xy[0]), float(xy[1]), 0.0)
    prop = actor.GetTextProperty()
    prop.SetFontSize(size)
    prop.SetColor(0.0, 0.0, 0.0)
    getattr(prop, f"SetJustificationTo{halign}")()
    getattr(prop, f"SetVerticalJustificationTo{valign}")()
    _use_font(prop, font)
    p.add_actor(actor)
    return actor


def _draw_axes(p, bounds, ranges, font, xlabel: str, ylabel: str) -> None:
    """Frame, ticks and labels drawn from plain lines and text actors.

    Not pyvista's show_bounds: its vtkCubeAxesActor formats labels with std::regex, which crashes
    (std::bad_alloc) once dolfinx's C++ module has been loaded with global symbols.
    """
    pv = _offscreen()
    x0, x1, y0, y1 = bounds[:4]
    r = ranges
    tick = 0.012 * max(x1 - x0, y1 - y0)
    segments = [[x0, y0, 0], [x1, y0, 0], [x1, y0, 0], [x1, y1, 0], [x1, y1, 0], [x0, y1, 0], [x0, y1, 0], [x0, y0, 0]]
    for v in _tick_values(r[0], r[1], 5):
        X = x0 + (v - r[0]) / (r[1] - r[0]) * (x1 - x0)
        segments += [[X, y0, 0], [X, y0 - tick, 0]]
        _world_text(p, np.format_float_positional(round(v, 10), trim="-"), (X, y0 - 1.6 * tick), font, 18, "Centered", "Top")
    for v in _tick_values(r[2], r[3], 6):
        Y = y0 + (v - r[2]) / (r[3] - r[2]) * (y1 - y0)
        segments += [[x0, Y, 0], [x0 - tick, Y, 0]]
        _world_text(p, np.format_float_positional(round(v, 10), trim="-"), (x0 - 1.6 * tick, Y), font, 18, "Right", "Centered")
    p.add_mesh(pv.line_segments_from_points(np.array(segments, dtype=float)), color="black", line_width=1.5)
    _world_text(p, xlabel, (0.5 * (x0 + x1), y0 - 6 * tick), font, 19, "Centered", "Top")
    _world_text(p, ylabel, (x0 - 9 * tick, 0.5 * (y0 + y1)), font, 19, "Right", "Centered")


def _legend_patch(p, xy, size: float, colour, text: str, font) -> None:
    """A filled square with a black edge and its label, in world coordinates."""
    pv = _offscreen()
    square = pv.Rectangle([[xy[0], xy[1], 0.0], [xy[0] + size, xy[1], 0.0], [xy[0] + size, xy[1] + size, 0.0]])
    p.add_mesh(square, color=colour, lighting=False)
    p.add_mesh(square.extract_feature_edges(), color="black", line_width=1)
    _world_text(p, text, (xy[0] + 1.5 * size, xy[1] + 0.5 * size), font, 16, "Left", "Centered")


def _colour_bar(p, bounds, clim, cmap: str, label: str, font) -> None:
    """A vertical colour bar right of the picture, drawn as a grid strip (VTK's scalar bar also uses std::regex)."""
    pv = _offscreen()
    x0, x1, y0, y1 = bounds[:4]
    width = x1 - x0
    bx0, bx1 = x1 + 0.05 * width, x1 + 0.09 * width
    by0, by1 = y0 + 0.1 * (y1 - y0), y1 - 0.1 * (y1 - y0)
    levels = np.linspace(clim[0], clim[1], 257)
    strip = pv.RectilinearGrid(np.array([bx0, bx1]), np.linspace(by0, by1, len(levels) + 1), np.array([0.0]))
    strip.cell_data[label] = levels
    p.add_mesh(strip, scalars=label, cmap=cmap, clim=list(clim), show_scalar_bar=False, lighting=False)
    p.add_mesh(strip.outline(), color="black", line_width=1)
    tick = 0.012 * width
    segments = []
    for v in _tick_values(clim[0], clim[1], 6):
        Y = by0 + (v - clim[0]) / (clim[1] - clim[0]) * (by1 - by0)
        segments += [[bx1, Y, 0], [bx1 + tick, Y, 0]]
        _world_text(p, f"{v:.3g}", (bx1 + 1.6 * tick, Y), font, 15, "Left", "Centered")
    if segments:
        p.add_mesh(pv.line_segments_from_points(np.array(segments, dtype=float)), color="black", line_width=1.5)
    _world_text(p, label, (0.5 * (bx0 + bx1), by1 + 1.5 * tick), font, 19, "Centered", "Bottom")


def _add_raster(p, grid, rgb_of_cells, margins=(0.16, 0.16, 0.14, 0.2)) -> None:
    """Draw `grid`'s cells as one textured rectangle instead of one quad per cell.

    `rgb_of_cells(cell_index_array)` gives the (…, 3) uint8 colours of the cells at those flat indices.
    Software OpenGL (llvmpipe) takes ~0.4 s to draw the half-million cells of a space-time grid and ~0.01 s
    for one texture; the texture has about one texel per screen pixel, each the colour of the grid cell
    under its centre (nearest, as the cells themselves would be drawn), so nothing is smoothed away.
    """
    pv = _offscreen()
    x0, x1, y0, y1 = grid.bounds[:4]
    left, right, bottom, top = margins
    w, h = p.window_size
    nx, ny = max(2, round(w * (1 - left - right))), max(2, round(h * (1 - bottom - top)))
    xe, ye = np.asarray(grid.x), np.asarray(grid.y)
    i = np.searchsorted(xe, x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx).clip(1, xe.size - 1) - 1
    j = np.searchsorted(ye, y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny).clip(1, ye.size - 1) - 1
    rgb = rgb_of_cells(j[::-1, None] * (xe.size - 1) + i[None, :])  # an image's first row is its top: the last t
    texture = pv.Texture(np.ascontiguousarray(rgb, dtype=np.uint8))
    texture.interpolate = False
    behind = -1e-3 * (y1 - y0)  # just behind the frame and tick lines at z = 0, which would otherwise flicker
    plane = pv.Plane(center=(0.5 * (x0 + x1), 0.5 * (y0 + y1), behind), direction=(0, 0, 1),
                     i_size=x1 - x0, j_size=y1 - y0, i_resolution=1, j_resolution=1)
    p.add_mesh(plane, texture=texture, lighting=False)


def _rgb(colour) -> np.ndarray:
    from matplotlib.colors import to_rgb

    return np.round(255 * np.array(to_rgb(colour))).astype(np.uint8)


def _space_time_plotter(result, grid, ranges, title: str, subtitle: str, window_size=WINDOW_SIZE):
    pv = _offscreen()
    font = _font_file()
    p = pv.Plotter(window_size=list(window_size), off_screen=True)
    p.set_background("white")
    _draw_axes(p, grid.bounds, ranges, font, "x (position along the string)", "t\n(time)")
    for text, pos, size in ((title, (0.5, 0.97), 17), (subtitle, (0.5, 0.915), 12)):
        actor = p.add_text(text, position=pos, viewport=True, font_size=size, color="black")
        prop = actor.GetTextProperty()
        prop.SetJustificationToCentered()
        prop.SetVerticalJustificationToTop()
        _use_font(prop, font)
    p.view_xy()
    p.enable_parallel_projection()
    return p, font


def _frame(p, grid, left=0.16, right=0.16, bottom=0.14, top=0.2) -> None:
    """Place the camera so that the grid fills the window less the given margins (fractions)."""
    x0, x1, y0, y1 = grid.bounds[:4]
    w, h = p.window_size
    # parallel scale = half the visible world height; solve for the tighter of width and height
    world_w = (x1 - x0) / (1 - left - right)
    world_h = (y1 - y0) / (1 - bottom - top)
    scale = max(world_h, world_w * h / w) / 2
    cx = 0.5 * (x0 + x1) - (left - right) / 2 * (2 * scale * w / h)
    cy = 0.5 * (y0 + y1) - (bottom - top) / 2 * (2 * scale)
    cam = p.camera
    cam.focal_point = (cx, cy, 0.0)
    cam.position = (cx, cy, 10.0)
    cam.up = (0.0, 1.0, 0.0)
    cam.parallel_projection = True
    cam.parallel_scale = scale
    p.renderer.ResetCameraClippingRange()


def _screenshot(p, path: Path) -> None:
    with atomic_path(path) as tmp:  # a picture is either complete or absent
        p.screenshot(str(tmp))
        p.close()


def obstacle_name(result) -> str:
    """'0' for the paper's flat obstacle y = 0, 'ψ' for a scene's profiled `obstacle`."""
    return "ψ" if getattr(result.scene, "obstacle", None) is not None else "0"


def contact_set_picture(result, path, window_size=WINDOW_SIZE) -> Path:
    """The space-time contact set {η ≤ ψ} (ψ = 0 by default): filled where in contact, blank where free."""
    path = Path(path)
    grid, ranges = space_time_grid(result)
    psi = obstacle_name(result)
    title = f"Contact set {{η ≤ {psi}}} in space-time: {result.scene.name}"
    p, font = _space_time_plotter(result, grid, ranges, title, parameter_line(result, "\n"), window_size)
    contact = np.asarray(grid.cell_data["contact"]) > 0
    colours = np.stack([_rgb("white"), _rgb(CONTACT_COLOUR)])
    _add_raster(p, grid, lambda cells: colours[contact[cells].astype(int)])
    x0, x1, y0, y1 = grid.bounds[:4]
    _legend_patch(p, (x1 + 0.03 * (x1 - x0), y1 - 0.06 * (y1 - y0)), 0.03 * (x1 - x0), CONTACT_COLOUR, f"in contact\n(η ≤ {psi})", font)
    _legend_patch(p, (x1 + 0.03 * (x1 - x0), y1 - 0.2 * (y1 - y0)), 0.03 * (x1 - x0), "white", f"free\n(η > {psi})", font)
    _frame(p, grid)
    _screenshot(p, path)
    return path


def velocity_picture(result, path, window_size=WINDOW_SIZE, percentile: float = VELOCITY_PERCENTILE) -> Path:
    """The space-time velocity v(t, x), diverging colours centred on 0, range clipped at a percentile of |v|."""
    path = Path(path)
    grid, ranges = space_time_grid(result)
    c = velocity_clip(result, percentile)
    title = f"Velocity field v(t, x) = η_t: {result.scene.name}"
    # no "|" in VTK text: it is the column separator of VTK's text renderer
    speed = float(np.max(np.abs(result.velocity)))
    subtitle = parameter_line(result, "\n") + (
        f"\ncolours clipped at ±{c:.3g} ({percentile:g}th percentile of the speed; max {speed:.3g})"
    )
    p, font = _space_time_plotter(result, grid, ranges, title, subtitle, window_size)
    import matplotlib

    lut = (255 * matplotlib.colormaps["RdBu_r"].resampled(256)(np.arange(256))[:, :3]).round().astype(np.uint8)
    level = np.clip((np.asarray(grid.cell_data["velocity"]) + c) / (2 * c) * 256, 0, 255).astype(int)  # as VTK's 256-colour table
    _add_raster(p, grid, lambda cells: lut[level[cells]])
    _colour_bar(p, grid.bounds, (-c, c), "RdBu_r", "v", font)
    _frame(p, grid)
    _screenshot(p, path)
    return path


# --- matplotlib: line charts -------------------------------------------------------------------------


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _savefig(fig, path: Path, dpi: int = 100) -> None:
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi)
    finally:
        _pyplot().close(fig)


def snapshots_picture(result, path) -> Path:
    """η(x) at the scene's output times, the obstacle (y = 0 or the scene's ψ), and the parts in contact."""
    plt = _pyplot()
    path = Path(path)
    rows = snapshot_rows(result)
    ncols = 3 if len(rows) > 4 else min(len(rows), 2)
    nrows = int(np.ceil(len(rows) / ncols))
    fig, axs = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.2 * nrows + 0.8), sharex=True, sharey=True, squeeze=False)
    x = result.x
    name = obstacle_name(result)
    psi = result.scene.obstacle_values(x) if name == "ψ" else np.zeros_like(x)
    lo = min(float(result.eta[rows].min()), float(psi.min()))
    hi = max(float(result.eta[rows].max()), float(psi.max()))
    pad = 0.08 * (hi - lo or 1.0)
    contact_length = result.contact_length  # a property over all rows: once, not per panel
    for ax, i in zip(axs.flat, rows):
        ax.fill_between(x, lo - pad, psi, color="0.85", lw=0, zorder=0)
        ax.plot(x, psi, color="0.3", lw=1.0, zorder=1)
        ax.plot(x, result.eta[i], color="#2166ac", lw=1.2, label="η(t, x)", zorder=2)
        on = np.where(result.contact[i], result.eta[i], np.nan)
        ax.plot(x, on, color=CONTACT_COLOUR, lw=3.0, label=f"in contact (η ≤ {name})", zorder=3)
        parts = contact_components(x, result.contact[i])
        frac = float(contact_length[i]) / float(x[-1] - x[0])
        ax.set_title(f"t = {result.t[i]:.3g}: contact {100 * frac:.0f}% of l, {len(parts)} part{'s' * (len(parts) != 1)}", fontsize=10)
        ax.set_ylim(lo - pad, hi + pad)
        ax.grid(alpha=0.3)
    for ax in axs.flat[len(rows):]:
        ax.set_visible(False)
    for ax in axs[-1]:
        ax.set_xlabel("x")
    for ax in axs[:, 0]:
        ax.set_ylabel("η (displacement)")
    axs.flat[0].text(0.02, 0.04, "obstacle (y ≤ 0)" if name == "0" else "obstacle (y ≤ ψ(x))", transform=axs.flat[0].transAxes, fontsize=8, color="0.3")
    handles, labels = axs.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, frameon=False)
    fig.suptitle(f"Snapshots of the string: {result.scene.name}\n{parameter_line(result)}", fontsize=11)
    # fixed margins in inches: tight_layout would lay out every tick label once more (half the picture's time)
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=0.75 / w, right=1 - 0.15 / w, bottom=0.95 / h, top=1 - 0.85 / h, wspace=0.08, hspace=0.32 * 3.2 / (h / nrows))
    _savefig(fig, path)
    return path


def energy_picture(result, path) -> Path:
    """The discrete energy balance (1.4): E(t) plus what viscosity, contact and the scheme took, against E(0)."""
    plt = _pyplot()
    path = Path(path)
    e, t = result.energy, result.t
    E = result.total_energy
    spent = e["viscous_dissipation"] + e["contact_dissipation"] + e["numerical_dissipation"]
    fig, (ax, axr) = plt.subplots(2, 1, figsize=(9, 7), sharex=True, gridspec_kw=dict(height_ratios=(3, 1)))
    ax.axhline(E[0], color="black", ls=":", lw=1.5, label=f"E(0) = {E[0]:.6g}")
    ax.plot(t, e["kinetic"], label=r"kinetic $\frac{1}{2}\int \eta_t^2\,dx$")
    ax.plot(t, e["elastic"], label=r"elastic $\frac{1}{2}\int \eta_x^2\,dx$")
    ax.plot(t, e["viscous_dissipation"], label=r"viscous dissipation $\alpha\int_0^t\!\int \eta_{tx}^2$")
    ax.plot(t, e["contact_dissipation"], label=r"contact dissipation $-\int_0^t\!\int F\,\eta_t$")
    ax.plot(t, e["numerical_dissipation"], ls="--", label="numerical dissipation of the scheme (cumulative)")
    if np.any(e["external_work"]):
        ax.plot(t, e["external_work"], ls="-.", label="work of external loads (cumulative)")
    ax.plot(t, E + spent - e["external_work"], color="black", lw=2.2, alpha=0.6, label="sum: E(t) + dissipations − work")
    ax.set_ylabel("energy")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="center right")
    ax.set_title(f"Energy balance: {result.scene.name}\n{parameter_line(result)}", fontsize=11)
    res = np.abs(result.balance_residual)
    axr.semilogy(t, np.maximum(res, 1e-300), color="black")
    axr.set_ylim(max(res.max(), 1e-300) * 1e-6 if res.max() > 0 else 1e-20, max(res.max(), 1e-300) * 10)
    axr.set_ylabel("|balance residual|\nE(0) + W − [E(t) + D]", fontsize=9)
    axr.set_xlabel("t")
    axr.grid(alpha=0.3, which="both")
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.08, top=0.9, hspace=0.08)  # fixed: see snapshots_picture
    _savefig(fig, path)
    return path


SPACE_TIME_PICTURES = PICTURES[:2]  # pyvista
CHART_PICTURES = PICTURES[2:]  # matplotlib


def _draw(name: str, result, folder: Path, window_size) -> Path:
    if name == "contact_set.png":
        return contact_set_picture(result, folder / name, window_size)
    if name == "velocity_field.png":
        return velocity_picture(result, folder / name, window_size)
    if name == "snapshots.png":
        return snapshots_picture(result, folder / name)
    return energy_picture(result, folder / name)


def write_pictures(result, folder, window_size=WINDOW_SIZE, painter: Painters | None = None) -> list[Path]:
    """Write contact_set.png, velocity_field.png, snapshots.png and energy.png into `folder`.

    With started `Painters`, their pictures are drawn there while this process draws the others; whatever
    they fail to draw is then drawn here.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        handed_out = painter.send(result, folder, window_size) if painter is not None else set()
        for name in PICTURES:
            if name not in handed_out:
                _draw(name, result, folder, window_size)
        drawn = painter.wait() if painter is not None else set()
    finally:
        if painter is not None:
            painter.cancel()  # however this ends: nothing may write into `folder` after it returns
    for name in PICTURES:
        if name in handed_out and name not in drawn:
            for stray in folder.glob(f".{name}.tmp-*"):  # a picture the process was killed while writing
                stray.unlink(missing_ok=True)
            _draw(name, result, folder, window_size)
    return [folder / name for name in PICTURES]


class PictureProcess:
    """Some of the pictures (`names`) drawn in a second Python process, which has no dolfinx in it.

    `start(names)` launches it; it imports pyvista or matplotlib and draws a small warm-up picture (EGL
    context, shaders, fonts, mathtext) while the caller runs the simulation. `send(result, folder)` hands
    it the Result as a pickle in a private temporary folder (a file, not a pipe: writing to a pipe whose
    reader died raises SIGPIPE, which PETSc or the CLI turn into an abort); `wait()` returns True once
    its PNGs are written. `cancel()` stops it. Any failure makes `send`/`wait` return False.
    """

    TIMEOUT = 300.0  # seconds to draw; each picture takes 0.2-0.4 s

    def __init__(self, proc: subprocess.Popen, folder: str, names: tuple[str, ...]):
        self.proc = proc
        self.folder = folder  # the private temporary folder that receives the payload
        self.names = names
        self.error = ""  # why it did not draw, if it said so (the caller then draws the pictures itself)

    @classmethod
    def start(cls, names=PICTURES) -> PictureProcess | None:
        env = dict(os.environ)
        env.setdefault("LP_NUM_THREADS", "1")  # Mesa's software renderer: leave the other cores to the run
        folder = tempfile.mkdtemp(prefix="stringcontact-pictures-")
        code = "from stringcontact.viz import _picture_process; _picture_process()"
        try:
            proc = subprocess.Popen(
                [sys.executable, "-c", code, folder, ",".join(names), str(os.getpid())],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,  # VTK's own warnings; failures come back on stdout
                env=env,
                start_new_session=True,  # Ctrl-C reaches the run, which then stops this process
            )
        except OSError:
            os.rmdir(folder)
            return None
        return cls(proc, folder, tuple(names))

    def send(self, result, folder, window_size=WINDOW_SIZE) -> bool:
        if self.folder is None or self.proc.poll() is not None:
            self.cancel()
            return False
        payload = Path(self.folder) / "payload.pickle"
        if set(self.names) <= set(SPACE_TIME_PICTURES):  # they read x, t, velocity and contact: 1/3 less to pickle
            result = dataclasses.replace(result, eta=np.empty((0, 0)), contact_force=np.empty((0, 0)))
        try:
            with open(payload.with_suffix(".part"), "wb") as f:
                pickle.dump((result, str(folder), tuple(window_size)), f, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(payload.with_suffix(".part"), payload)  # the process only ever sees a whole file
            return True
        except (OSError, pickle.PicklingError, TypeError, AttributeError):
            self.cancel()
            return False

    def wait(self) -> bool:
        """True once the process reports its pictures written (its own exit is not waited for)."""
        reply = {}
        try:
            with selectors.DefaultSelector() as sel:
                sel.register(self.proc.stdout, selectors.EVENT_READ)
                if sel.select(timeout=self.TIMEOUT):
                    reply = json.loads(self.proc.stdout.readline().decode() or "{}")
        except (ValueError, OSError):
            reply = {}
        finally:
            self.cancel()
        self.error = "" if reply.get("ok") else str(reply.get("error", "no reply"))
        return bool(reply.get("ok"))

    def cancel(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout is not None and not self.proc.stdout.closed:
            self.proc.stdout.close()
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)
            self.folder = None


class Painters:
    """`PictureProcess`es started before a run, so that their start-up overlaps it.

    `start()` starts one, for the two pyvista pictures: its start-up (importing VTK, the EGL context,
    llvmpipe's shaders, the font: about 1.2 s) happens during the run, and the run draws the two matplotlib
    charts itself while the process draws. Giving the process the snapshots too, or the charts a second
    process, measured no faster on 2 cores (docs/performance.md).
    """

    def __init__(self, processes):
        self.processes = [p for p in processes if p is not None]
        self._sent: list[PictureProcess] = []

    @classmethod
    def start(cls, groups=(SPACE_TIME_PICTURES,)) -> Painters:
        return cls([PictureProcess.start(names) for names in groups])

    def send(self, result, folder, window_size=WINDOW_SIZE) -> set[str]:
        """Hand the Result to every process; the names of the pictures they were given."""
        self._sent = [p for p in self.processes if p.send(result, folder, window_size)]
        return {name for p in self._sent for name in p.names}

    def wait(self) -> set[str]:
        """Wait for the processes; the names of the pictures they drew. Stops them all."""
        drawn = {name for p in self._sent if p.wait() for name in p.names}
        self.cancel()
        return drawn

    def cancel(self) -> None:
        for p in self.processes:
            p.cancel()


def _warm_up(names) -> None:
    """Draw tiny pictures with every kind of element the real ones use (shaders, fonts, mathtext)."""
    if set(names) & set(SPACE_TIME_PICTURES):
        pv = _offscreen()
        p = pv.Plotter(window_size=[64, 48], off_screen=True)
        _world_text(p, "tη", (0.0, 0.0), _font_file(), 12, "Left", "Bottom")
        _colour_bar(p, (0.0, 1.0, 0.0, 1.0, 0.0, 0.0), (-1.0, 1.0), "RdBu_r", "v", None)
        plane = pv.Plane(i_resolution=1, j_resolution=1)
        p.add_mesh(plane, texture=pv.Texture(np.zeros((2, 2, 3), np.uint8)), lighting=False)
        p.screenshot(None, return_img=True)
        p.close()
    if set(names) & set(CHART_PICTURES):
        import io

        plt = _pyplot()
        fig, (ax, axr) = plt.subplots(2, 1, figsize=(2, 2))
        ax.fill_between([0, 1], [0, 1], color="0.85")
        ax.plot([0, 1], [1, 0], label=r"$\frac{1}{2}\int \eta_t^2\,dx$ η")
        ax.legend(fontsize=8)
        axr.semilogy([0, 1], [1e-9, 1e-3])
        fig.suptitle("η ≤ ψ")
        fig.savefig(io.BytesIO(), format="png", dpi=20)
        plt.close(fig)


def _picture_process() -> None:
    """The body of `PictureProcess`: warm up, wait for the payload, draw, report on stdout."""
    import time

    folder, names, parent = Path(sys.argv[1]), tuple(sys.argv[2].split(",")), int(sys.argv[3])
    answer = os.fdopen(os.dup(1), "w")  # the reply's own channel: anything VTK prints goes to stderr instead
    os.dup2(2, 1)
    reply = {"ok": False}
    try:
        _warm_up(names)
        payload = folder / "payload.pickle"
        while not payload.exists():
            if os.getppid() != parent or not folder.is_dir():  # the run ended (even before we started) or cancelled us
                shutil.rmtree(folder, ignore_errors=True)
                return
            time.sleep(0.005)
        with open(payload, "rb") as f:
            result, out, window_size = pickle.load(f)
        payload.unlink()  # read: no 50 MB file left behind even if the run is killed now
        for name in names:
            _draw(name, result, Path(out), window_size)
        reply = {"ok": True}
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which then draws the pictures itself
        reply = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
    finally:
        with contextlib.suppress(OSError):
            answer.write(json.dumps(reply) + "\n")
            answer.flush()
    os._exit(0)  # the pictures are on disk; tearing down VTK and the EGL context would only cost time


# --- reading an output folder back ---------------------------------------------------------------


def show_pictures(folder) -> list[Path]:
    """The pictures of a run folder: displayed inline in a Jupyter notebook, otherwise their paths printed."""
    import sys

    paths = [Path(folder) / name for name in PICTURES if (Path(folder) / name).exists()]
    if "ipykernel" in sys.modules:
        from IPython.display import Image, display

        for path in paths:
            display(Image(filename=str(path)))
    else:
        print("pictures:", ", ".join(str(p) for p in paths))
    return paths


# --- the `plot` subcommand ----------------------------------------------------------------------


def add_arguments(parser) -> None:
    parser.description = (
        "Redraw contact_set.png, velocity_field.png, snapshots.png and energy.png of an output folder "
        "from its saved files (solution.xdmf/.h5, diagnostics.csv, summary.json) alone."
    )
    parser.add_argument("folder", metavar="DIR", help="an output folder written by `stringcontact run --out DIR`")
    parser.add_argument("--out", metavar="DIR", help="write the pictures here instead of into DIR")
    parser.add_argument(
        "--size",
        metavar="WxH",
        default=f"{WINDOW_SIZE[0]}x{WINDOW_SIZE[1]}",
        help=f"pixel size of the space-time pictures (default {WINDOW_SIZE[0]}x{WINDOW_SIZE[1]})",
    )


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' -> (W, H), each in 200..4000."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size: expected WIDTHxHEIGHT such as 1100x900, got {text!r}") from None
    if not (200 <= w <= 4000 and 200 <= h <= 4000):
        raise ValueError(f"--size: width and height must be in 200..4000 pixels, got {text!r}")
    return w, h


def command(args) -> int:
    from .readback import read_output

    size = parse_size(args.size)
    result = read_output(args.folder)
    out = Path(args.out) if args.out else Path(args.folder)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a folder")
    for path in write_pictures(result, out, window_size=size):
        print(f"wrote {path}")
    return 0
