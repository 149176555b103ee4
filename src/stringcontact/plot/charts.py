"""The matplotlib pictures of a run: the (x, t) plane as an image, and line charts.

* ``contact_set.png`` and ``velocity_field.png``: `pcolorfast` with one cell per stored sample (irregular
  stored times included), with a legend or a colour bar;
* ``snapshots.png`` and ``energy.png``: η(x) at the output times, and the energy balance (1.4);
* ``contact_area.png`` of a membrane (2D): its contact area and number of contact patches over time.

Also the small readings of a Result they share with `mesh_pictures`, the demos and `theorems`: the
contact intervals of a row, the rows at given times, the velocity colour range, the title line.
"""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

import numpy as np

from ..io.manifest import atomic_path
from .colours import CONTACT_COLOUR
from .picture_names import WINDOW_SIZE

#: |v| is clipped at this percentile for the colour range: v0 = −50 at t = 0 would otherwise wash out the rest.
VELOCITY_PERCENTILE = 99.0
DPI = 100
#: at most this many panels in snapshots.png and membrane.png, whatever the number of output times: a panel
#: costs a fixed time (Example 1's 200 output times took 50 s), so more output times are thinned evenly
#: (first and last kept); every output time is still a stored row (diagnostics.csv, rows.npz)
MAX_PANELS = 12
#: zlib level of the PNGs (Pillow's default is 6): the same pixels, 8-20 ms less a picture for 6-24 % more
#: bytes (Example 1's five pictures: 180 against 122 CPU-ms to encode; benchmarks/bench_png.py)
PNG_COMPRESSION = 3


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


def snapshot_rows(result, most: int = MAX_PANELS) -> list[int]:
    """The rows at the scene's output times, or six evenly spaced rows if it has none; at most `most` of
    them, evenly chosen, the first and the last always (`evenly`)."""
    rows = stored_rows_at(result, result.scene.output_times)
    if not rows:
        rows = sorted(set(np.linspace(0, len(result.t) - 1, 6).round().astype(int).tolist()))
    return [rows[k] for k in evenly(len(rows), most)]


def panels_note(result, rows) -> str:
    """'' or, when the output times were thinned to `rows`, a line saying how many of them are drawn."""
    n = len(stored_rows_at(result, result.scene.output_times))
    return f"{len(rows)} of the {n} output times, evenly chosen (all of them: rows.npz)" if n > len(rows) else ""


def evenly(n: int, most: int) -> list[int]:
    """At most `most` (≥ 2) of the indices 0..n-1, evenly spaced, with 0 and n-1: all of them if n ≤ most."""
    if n <= most:
        return list(range(n))
    return sorted(set(np.linspace(0, n - 1, max(2, most)).round().astype(int).tolist()))


def velocity_clip(result, percentile: float = VELOCITY_PERCENTILE) -> float:
    """Symmetric colour range ±c for v, with c the `percentile` of |v| over all stored samples."""
    c = float(np.percentile(np.abs(result.velocity), percentile))
    return c if c > 0 else max(float(np.max(np.abs(result.velocity))), 1.0)


# --- titles -----------------------------------------------------------------------------------------


def literal(text: str) -> str:
    """`text` shown as written in a matplotlib title: its ``$`` escaped, so a scene named ``$x^{$`` is not parsed
    as (broken) mathtext."""
    return str(text).replace("$", r"\$")


def parameter_line(result, sep: str = ", ") -> str:
    """The title's line of parameters: the mesh, Δt, α (and ε), the model, the scheme, its penalty and mass."""
    s = result.scene
    scheme = f"model {getattr(result, 'model', None) or 'inelastic'}, scheme {getattr(result, 'scheme', 'paper')}"
    mesh = f"nx = {s.nx}" if np.ndim(result.x) == 1 else f"{len(result.x)} nodes, {len(result.cells)} triangles"
    if result.penalty in (None, "none"):  # a scheme without ε (projection)
        return f"{mesh}, Δt = {s.dt:.3g}, α = {s.alpha:g}{sep}{scheme}, no penalty (no ε), {result.mass} mass"
    return (
        f"{mesh}, Δt = {s.dt:.3g}, α = {s.alpha:g}, ε = {s.eps:g}{sep}"
        f"{scheme}, penalty {result.penalty} (Δt/ε = {s.dt / s.eps:.3g}), {result.mass} mass"
    )


def obstacle_name(result) -> str:
    """'0' for the paper's flat obstacle y = 0, 'ψ' for a scene's profiled `obstacle`."""
    return "ψ" if getattr(result.scene, "obstacle", None) is not None else "0"


def obstacle_profile(result, t: float = 0.0) -> np.ndarray:
    """ψ at the nodes (x of shape (N,) or (N, 2)) at the time t: the scene's profiled obstacle, or 0."""
    x = np.asarray(result.x, dtype=float)
    return result.scene.obstacle_values(x, t) if obstacle_name(result) == "ψ" else np.zeros(x.shape[:1])


def obstacle_moves(result) -> bool:
    """Whether the run's obstacle moves (ψ(x, t), `Scene.obstacle_moves`): then each picture draws it at its time."""
    return bool(getattr(result.scene, "obstacle_moves", False))


def obstacle_history(result, rows, nodes=slice(None)) -> np.ndarray:
    """ψ at the `nodes` (indices, default all) at the times of the stored `rows`, one row each: (len(rows), nodes)."""
    x = np.asarray(result.x, dtype=float)[nodes]
    psi = [np.broadcast_to(result.scene.obstacle_values(x, float(result.t[i])), x.shape[:1]) for i in rows]
    return np.array(psi, dtype=float).reshape(-1, x.shape[0])


def obstacle_range(result) -> tuple[float, float]:
    """The least and the largest ψ at the nodes over every stored time (at t = 0 when it does not move)."""
    low, high = np.inf, -np.inf
    for t in result.t if obstacle_moves(result) else [0.0]:  # one time at a time: rows × nodes may not fit
        psi = obstacle_profile(result, float(t))
        low, high = min(low, float(np.min(psi))), max(high, float(np.max(psi)))
    return low, high


# --- matplotlib ---------------------------------------------------------------------------------------


@contextlib.contextmanager
def without_axes3d_warning():
    """Importing matplotlib's projections (pyplot, pyvista's colour maps) without the Axes3D warning: Debian's
    mpl_toolkits (python3-matplotlib) beside pip's matplotlib; no 3-D axes are drawn, so nothing is lost."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Unable to import Axes3D")
        yield


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    with without_axes3d_warning():
        import matplotlib.pyplot as plt

    return plt


def savefig(fig, path: Path, dpi: int = DPI) -> None:
    try:
        with atomic_path(path) as tmp:  # a picture is either complete or absent
            options = {"pil_kwargs": {"compress_level": PNG_COMPRESSION}} if path.suffix == ".png" else {}
            fig.savefig(tmp, dpi=dpi, **options)
    finally:
        pyplot().close(fig)


def _cell_edges(v: np.ndarray) -> np.ndarray:
    """Edges of cells centred on the samples `v`; the first and last cells end at the first and last sample."""
    if v.size == 1:
        return np.array([v[0], v[0] + 1.0])
    return np.concatenate([[v[0]], 0.5 * (v[1:] + v[:-1]), [v[-1]]])


def _space_time_image(result, values, title: str, window_size, note: str = "", **style):
    """A figure with `values` (one per stored sample) over the (x, t) plane, and its image.

    `pcolorfast` with the cell edges draws each pixel in the colour of the sample under it (nearest, no
    smoothing), keeps the irregular stored times as they are, and costs the same for 400 or 2 million samples.
    """
    plt = pyplot()
    fig = plt.figure(figsize=(window_size[0] / DPI, window_size[1] / DPI), dpi=DPI)
    # fixed margins in inches: room for the title above and the legend or colour bar on the right
    w, h = window_size[0] / DPI, window_size[1] / DPI
    ax = fig.add_axes((0.9 / w, 0.75 / h, 1 - 2.6 / w, 1 - 2.0 / h))
    image = ax.pcolorfast(_cell_edges(result.x), _cell_edges(result.t), values, **style)
    ax.set_xlabel("x (position along the string)")
    ax.set_ylabel("t (time)")
    fig.suptitle("\n".join(filter(None, (title, parameter_line(result), note))), fontsize=12, y=1 - 0.15 / h, va="top")
    return fig, ax, image


def contact_set_picture(result, path, window_size=WINDOW_SIZE) -> Path:
    """``contact_set.png``: `contact_set_figure`, written whole or not at all."""
    path = Path(path)
    savefig(contact_set_figure(result, window_size)[0], path)
    return path


def contact_set_figure(result, window_size=WINDOW_SIZE):
    """The space-time contact set {η ≤ ψ} (ψ = 0 by default): filled where in contact, blank where free; beside
    it the number of its components over time (`Result.contact_components`); below it, when the most
    components last a short while (Example 2's three before t = 0.02, Example 1's nine at its landing), the
    same picture zoomed in time onto them (`zoom_window`). Returns the figure and its axes {"set", "count",
    "zoom", "zoom_count"} (the last two absent without a zoom)."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    plt, psi = pyplot(), obstacle_name(result)
    counts = result.contact_components
    zoom = zoom_window(result.t, counts)
    fig = plt.figure(figsize=(window_size[0] / DPI, window_size[1] / DPI), dpi=DPI)
    boxes = _contact_set_boxes(window_size, zoom is not None)
    colours = ListedColormap(["white", CONTACT_COLOUR])
    axes = {}
    for key in ("set", "zoom")[: len(boxes)]:
        ax = axes[key] = fig.add_axes(boxes[key][0])
        ax.pcolorfast(_cell_edges(result.x), _cell_edges(result.t), result.contact.astype(np.uint8), cmap=colours, vmin=0, vmax=1)
        ax.set_ylabel("t (time)")
        strip = axes[f"{key}_count".replace("set_", "")] = fig.add_axes(boxes[key][1], sharey=ax)
        strip.stairs(counts, _cell_edges(result.t), orientation="horizontal", color="#2166ac", lw=1.5, baseline=None)
        strip.set_xlim(-0.3, max(2, int(counts.max())) + 0.5)
        strip.xaxis.get_major_locator().set_params(integer=True)
        strip.tick_params(labelleft=False)
        strip.grid(alpha=0.3)
    if result.t[-1] > result.t[0]:
        axes["set"].set_ylim(result.t[0], result.t[-1])
    axes["count"].set_xlabel("contact\ncomponents")
    bottom = axes.get("zoom", axes["set"])
    bottom.set_xlabel("x (position along the string)")
    if zoom is not None:
        lo, hi, most, first, last = zoom
        axes["zoom"].set_ylim(lo, hi)
        axes["zoom_count"].set_xlabel("contact\ncomponents")
        for t in (lo, hi):
            axes["set"].axhline(t, color="black", ls="--", lw=1.0)
        axes["zoom"].set_title(f"zoom: t = {lo:.3g} … {hi:.3g} (the dashed lines above); {most} components at "
                               f"t = {first:.3g} … {last:.3g}", fontsize=10, loc="left")
    patches = [Patch(facecolor=CONTACT_COLOUR, edgecolor="black", label=f"in contact\n(η ≤ {psi})"),
               Patch(facecolor="white", edgecolor="black", label=f"free\n(η > {psi})")]
    axes["count"].legend(handles=patches, loc="upper left", bbox_to_anchor=(1.1, 1.0), frameon=False, labelspacing=1.2)
    title = f"Contact set {{η ≤ {psi}}} in space-time: {literal(result.scene.name)}"
    most = f"at most {int(counts.max())} contact components (first at t = {result.t[int(np.argmax(counts))]:.3g})" if counts.max() > 1 else ""
    h = window_size[1] / DPI
    fig.suptitle("\n".join(filter(None, (title, parameter_line(result), most))), fontsize=12, y=1 - 0.15 / h, va="top")
    return fig, axes


def zoom_window(t: np.ndarray, counts: np.ndarray, share: float = 0.25):
    """(lo, hi, most, first, last): a time window around the first rows with the most contact components
    (from `first` to `last`), half as wide again on each side and at least 5 % of the run; None when there
    are never two components, or the window would span more than `share` of the run (no zoom needed)."""
    most = int(counts.max()) if counts.size else 0
    if most < 2:
        return None
    a = int(np.argmax(counts == most))
    b = a + (int(np.argmin(counts[a:] == most)) - 1 if not np.all(counts[a:] == most) else counts.size - a - 1)
    span, whole = float(t[b] - t[a]), float(t[-1] - t[0])
    half = max(span, 0.05 * whole) / 2 + 0.5 * span
    centre = 0.5 * float(t[a] + t[b])
    lo, hi = max(float(t[0]), centre - half), min(float(t[-1]), centre + half)
    return None if hi - lo > share * whole else (lo, hi, most, float(t[a]), float(t[b]))


def _contact_set_boxes(window_size, zoomed: bool) -> dict:
    """Figure boxes {"set": (image, strip)[, "zoom": (image, strip)]} at fixed margins in inches: the title
    above, the count strip right of each image, the legend right of the strips."""
    w, h = window_size[0] / DPI, window_size[1] / DPI
    left, strip, gap, right = 0.9, 0.75, 0.3, 1.55  # inches
    image = w - left - gap - strip - right
    bottom, top = 0.75, 1.2
    tall = h - bottom - top
    heights = [tall] if not zoomed else [0.56 * (tall - 0.8), 0.44 * (tall - 0.8)]
    boxes, y = {}, h - top
    for key, height in zip(("set", "zoom"), heights):
        y -= height
        boxes[key] = ((left / w, y / h, image / w, height / h), ((left + image + gap) / w, y / h, strip / w, height / h))
        y -= 0.8
    return boxes


def velocity_picture(result, path, window_size=WINDOW_SIZE, percentile: float = VELOCITY_PERCENTILE) -> Path:
    """The space-time velocity v(t, x), diverging colours centred on 0, range clipped at a percentile of |v|."""
    path = Path(path)
    c = velocity_clip(result, percentile)
    speed = float(np.max(np.abs(result.velocity)))
    title = f"Velocity field v(t, x) = η_t: {literal(result.scene.name)}"
    note = f"colours clipped at ±{c:.3g} ({percentile:g}th percentile of the speed; max {speed:.3g})"
    fig, ax, image = _space_time_image(result, result.velocity, title, window_size, note, cmap="RdBu_r", vmin=-c, vmax=c)
    box = ax.get_position()
    bar_axes = fig.add_axes((box.x1 + 0.03 * box.width, box.y0 + 0.1 * box.height, 0.03 * box.width, 0.8 * box.height))
    fig.colorbar(image, cax=bar_axes, extend="both" if speed > c else "neither").set_label("v (velocity)")
    savefig(fig, path)
    return path


def snapshots_picture(result, path) -> Path:
    """η(x) at the scene's output times, the obstacle (y = 0 or the scene's ψ), and the parts in contact."""
    plt = pyplot()
    path = Path(path)
    rows = snapshot_rows(result)
    ncols = 3 if len(rows) > 4 else min(len(rows), 2)
    nrows = int(np.ceil(len(rows) / ncols))
    fig, axs = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.2 * nrows + 0.8), sharex=True, sharey=True, squeeze=False)
    x = result.x
    name = obstacle_name(result)
    psis = {i: obstacle_profile(result, float(result.t[i])) for i in rows}  # a moving obstacle where it is at t
    lo = min(float(result.eta[rows].min()), min(float(p.min()) for p in psis.values()))
    hi = max(float(result.eta[rows].max()), max(float(p.max()) for p in psis.values()))
    pad = 0.08 * (hi - lo or 1.0)
    contact_length = result.contact_length  # a property over all rows: once, not per panel
    for ax, i in zip(axs.flat, rows):
        psi = psis[i]
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
    title = "\n".join(filter(None, (f"Snapshots of the string: {literal(result.scene.name)}", parameter_line(result), panels_note(result, rows))))
    fig.suptitle(title, fontsize=11)
    # fixed margins in inches: tight_layout would lay out every tick label once more (half the picture's time)
    w, h = fig.get_size_inches()
    top = 1 - (0.85 + 0.3 * (title.count("\n") - 1)) / h  # 0.85 in for the two usual lines, 0.3 in per more
    fig.subplots_adjust(left=0.75 / w, right=1 - 0.15 / w, bottom=0.95 / h, top=top, wspace=0.08, hspace=0.32 * 3.2 / (h / nrows))
    savefig(fig, path)
    return path


def energy_picture(result, path) -> Path:
    """``energy.png``: `energy_figure`, written whole or not at all."""
    path = Path(path)
    savefig(energy_figure(result)[0], path)
    return path


def stored_energy_label(result) -> str:
    """The legend of the stored energy: the model's own (`Model.energy_label`, kept in `Result.energy_label`),
    else the paper's elastic ½∫|∇η|²."""
    grad = r"\eta_x^2" if np.ndim(result.x) == 1 else r"|\nabla\eta|^2"
    return getattr(result, "energy_label", None) or rf"elastic $\frac{{1}}{{2}}\int {grad}\,dx$"


def energy_figure(result):
    """The discrete energy balance (1.4): E(t) plus what viscosity, contact and the scheme took, against E(0);
    beside it, when the energies settle early (`settle_time`: Example 2 within its first 5 %), the same
    curves zoomed onto the first times; below, |balance residual| on a log scale (`residual_panel`). The
    legend is under the panels, where it covers no curve. Returns the figure and its axes {"energy",
    "residual", and with a zoom "zoom", "zoom_residual"}."""
    plt = pyplot()
    e, t = result.energy, result.t
    E = result.total_energy
    spent = e["viscous_dissipation"] + e["contact_dissipation"] + e["numerical_dissipation"]
    grad_t = r"\eta_{tx}^2" if np.ndim(result.x) == 1 else r"|\nabla\eta_t|^2"
    curves = [(e["kinetic"], {"label": r"kinetic $\frac{1}{2}\int \eta_t^2\,dx$"}),
              (e["elastic"], {"label": stored_energy_label(result)}),
              (e["viscous_dissipation"], {"label": rf"viscous dissipation $\alpha\int_0^t\!\int {grad_t}$"}),
              (e["contact_dissipation"], {"label": r"contact dissipation $-\int_0^t\!\int F\,\eta_t$"}),
              (e["numerical_dissipation"], {"ls": "--", "label": "numerical dissipation of the scheme (cumulative)"})]
    if np.any(e["external_work"]):
        moving = getattr(result.scene, "obstacle_moves", False)  # the moving obstacle's work is booked there too
        what = "the moving obstacle and external loads" if moving else "external loads"
        curves.append((e["external_work"], {"ls": "-.", "label": f"work of {what} (cumulative)"}))
    curves.append((E + spent - e["external_work"], {"color": "black", "lw": 2.2, "alpha": 0.6, "label": "sum: E(t) + dissipations − work"}))
    settled = settle_time(t, [values for values, _ in curves])
    fig = plt.figure(figsize=(11, 8.5))
    grid = fig.add_gridspec(2, 2 if settled else 1, height_ratios=(3, 1), width_ratios=(3, 2) if settled else None,
                            left=0.08, right=0.98, bottom=0.17, top=0.9, hspace=0.08, wspace=0.06)
    axes = {}
    for column, key in enumerate(("energy", "zoom")[: 1 + bool(settled)]):
        ax = axes[key] = fig.add_subplot(grid[0, column], sharey=axes.get("energy"))
        ax.axhline(E[0], color="black", ls=":", lw=1.5, label=f"E(0) = {E[0]:.6g}")
        for values, style in curves:
            ax.plot(t, values, **style)
        ax.grid(alpha=0.3)
        ax.tick_params(labelbottom=False)
        below = axes[key.replace("energy", "residual").replace("zoom", "zoom_residual")] = fig.add_subplot(grid[1, column], sharex=ax)
        residual_panel(below, t, result.balance_residual, legend=column == 0)
    axes["energy"].set_ylabel("energy")
    if settled:
        axes["zoom"].set_xlim(t[0], settled)
        axes["zoom"].tick_params(labelleft=False)
        axes["zoom_residual"].set_ylabel("")
        axes["zoom"].set_title(f"zoom: t = {t[0]:.3g} … {settled:.3g} (shaded on the left)", fontsize=10)
        axes["energy"].axvspan(t[0], settled, color="0.5", alpha=0.12, lw=0)
    handles, labels = axes["energy"].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=9, frameon=False, bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(f"Energy balance: {literal(result.scene.name)}\n{parameter_line(result)}", fontsize=11)
    return fig, axes


def settle_time(t: np.ndarray, curves, share: float = 0.25, tolerance: float = 0.02):
    """The end of a zoomed panel onto the first times, or None: 1.5 times the time after which every curve
    stays within `tolerance` of the curves' largest range of its final value, when that is under `share`
    of the run (Example 2: its energy has moved to the dissipations by t ≈ 0.02 of 0.5)."""
    scale = max(float(np.ptp(values)) for values in curves) or 1.0
    moving = np.zeros(t.size, dtype=bool)
    for values in curves:
        moving |= np.abs(values - values[-1]) > tolerance * scale
    last = int(np.flatnonzero(moving)[-1]) + 1 if moving.any() else 0
    whole = float(t[-1] - t[0])
    end = float(t[0]) + 1.5 * float(t[min(last, t.size - 1)] - t[0])
    return end if 0 < end - float(t[0]) <= share * whole else None


def residual_panel(ax, t: np.ndarray, residual: np.ndarray, legend: bool = True) -> None:
    """|residual| on a log scale, honestly: the rows where it is exactly 0 (no point on a log scale) are left
    out of the line and marked by triangles at the panel's floor, named in the legend."""
    res = np.abs(residual)
    zero = res == 0
    floor = float(res[~zero].min()) / 10 if (~zero).any() else 1e-16
    ax.semilogy(t, np.where(zero, np.nan, res), color="black", lw=1.2, label="|balance residual|")
    if zero.any():
        ax.plot(t[zero], np.full(int(zero.sum()), floor), "v", color="#b2182b", ms=5, clip_on=False,
                label=f"exactly 0 ({int(zero.sum())} of {t.size} rows; drawn at the floor)")
        if legend:
            ax.legend(fontsize=8, loc="lower right", framealpha=0.9)
    top = float(res.max()) if res.max() > 0 else 1e-15
    ax.set_ylim(floor, top * 10)
    ax.set_ylabel("|balance residual|\nE(0) + W − [E(t) + D]", fontsize=9)
    ax.set_xlabel("t")
    ax.grid(alpha=0.3)


def contact_area_figure(result):
    """The figure of ``contact_area.png`` (2D): the contact area |{η ≤ ψ}|(t) above, the number of patches below.

    The area is `Result.contact_measure` (the lumped nodal areas of the nodes in contact), drawn against the
    domain's area; a patch is a connected set of contact nodes (`Result.contact_patches`). Dots mark the
    rows of the panels of ``membrane.png``.
    """
    plt = pyplot()
    t, area, patches = result.t, result.contact_measure, result.contact_patches()
    domain, psi = float(np.sum(result.weights)), obstacle_name(result)
    fig, (ax, axp) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True, gridspec_kw={"height_ratios": (2, 1)})
    ax.axhline(domain, color="black", ls=":", lw=1.5, label=f"area of the domain = {domain:.4g}")
    ax.plot(t, area, color=CONTACT_COLOUR, lw=2.0, label=f"contact area |{{η ≤ {psi}}}|")
    rows = snapshot_rows(result)
    ax.plot(t[rows], area[rows], "o", color="black", ms=5, label="the panels of membrane.png")
    ax.set_ylim(0, 1.08 * domain)
    ax.set_ylabel("contact area")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=9, loc="lower right")
    first = np.flatnonzero(area > 0)
    landed = f"first contact at t = {t[first[0]]:.3g}, largest area {area.max():.3g}" if first.size else "no contact"
    ax.set_title(f"Contact area and patches: {literal(result.scene.name)}\n{parameter_line(result)}\n{landed}", fontsize=11)
    axp.step(t, patches, where="mid", color="#2166ac", lw=1.5, label="contact patches (connected along mesh edges)")
    axp.set_ylim(-0.3, max(2, int(patches.max())) + 0.5)
    axp.yaxis.get_major_locator().set_params(integer=True)
    axp.set_ylabel("number of\npatches")
    axp.set_xlabel("t")
    axp.grid(alpha=0.3)
    axp.legend(fontsize=9, loc="upper right")
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.08, top=0.86, hspace=0.08)  # fixed: see snapshots_picture
    return fig


def contact_area_picture(result, path) -> Path:
    """``contact_area.png`` of a 2D run: `contact_area_figure`, written whole or not at all."""
    path = Path(path)
    savefig(contact_area_figure(result), path)
    return path


def warm_up() -> None:
    """A tiny picture with the elements the space-time pictures use: pyplot, fonts, an image, a colour bar."""
    import io

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(1, 1))
    fig.colorbar(ax.pcolorfast(np.array([0.0, 1.0, 3.0]), np.array([0.0, 1.0]), np.ones((1, 2)), cmap="RdBu_r"), ax=ax)
    ax.set_title("η ≤ ψ")
    fig.savefig(io.BytesIO(), format="png", dpi=20)
    plt.close(fig)
