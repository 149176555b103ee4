"""The matplotlib pictures of a run (``contact_set.png``, ``velocity_field.png``, ``snapshots.png``, ``energy.png``,
a membrane's ``contact_area.png``), each in its `style.Look`'s style sheet and constrained layout, a one-line title
and a caption of the run's details; and the readings of a Result they share with `mesh_pictures` and `theorems`."""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

import numpy as np

from ..io.publish import atomic_path
from .style import CONTACT_COLOUR, SCREEN, Look

#: |v| is clipped at this percentile for the colour range: v0 = −50 at t = 0 would otherwise wash out the rest.
VELOCITY_PERCENTILE = 99.0
#: at most this many panels in snapshots.png and membrane.png: a panel costs a fixed time (Example 1's 200 output
#: times took 50 s), so more output times are thinned evenly; every one is still a stored row (rows.npz)
MAX_PANELS = 12
#: zlib level of the PNGs (Pillow's default is 6): the same pixels, Example 1's five encoded in 122 against 180
#: CPU-ms for 6-24 % more bytes (benchmarks/bench_png.py)
PNG_COMPRESSION = 3


def contact_components(x: np.ndarray, contact_row: np.ndarray, min_nodes: int = 2) -> list[tuple[float, float]]:
    """The intervals [a, b] of one contact row's runs of at least `min_nodes` contact nodes (2: not a single node of
    zero length, Example 2's left end pinned at η = 0)."""
    edges = np.diff(np.concatenate([[0], np.asarray(contact_row, dtype=bool).astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # runs [start, stop)
    return [(float(x[a]), float(x[b - 1])) for a, b in zip(starts, stops) if b - a >= min_nodes]


def stored_rows_at(result, times) -> list[int]:
    """Indices of the stored rows at `times` (nearest stored time within half a step; others skipped)."""
    nearest = [int(np.argmin(np.abs(result.t - t))) for t in times]
    return [i for i, t in zip(nearest, times) if abs(result.t[i] - t) <= 0.5 * result.scene.dt]


def snapshot_rows(result, most: int = MAX_PANELS) -> list[int]:
    """The rows at the scene's output times (else six evenly spaced), at most `most` of them (`evenly`)."""
    rows = stored_rows_at(result, result.scene.output_times) or evenly(len(result.t), 6)
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


def literal(text: str) -> str:
    """`text` as written in a matplotlib text: its ``$`` escaped, so a scene named ``$x^{$`` is not mathtext."""
    return str(text).replace("$", r"\$")


def parameter_line(result, sep: str = ", ") -> str:
    """The run's details: scene, mesh, Δt, α (ε where the law reads it), `sep`, model, scheme, penalty and mass."""
    s = result.scene
    scheme = f"model {getattr(result, 'model', None) or 'inelastic'}, scheme {getattr(result, 'scheme', 'paper')}"
    mesh = f"nx = {s.nx}" if np.ndim(result.x) == 1 else f"{len(result.x)} nodes, {len(result.cells)} triangles"
    grid = f"{literal(s.name)}: {mesh}, Δt = {s.dt:.3g}, α = {s.alpha:g}"
    if result.penalty in (None, "none"):  # a scheme without ε (projection)
        return f"{grid}{sep}{scheme}, no penalty (no ε), {result.mass} mass"
    if not getattr(result, "law_reads_eps", True):  # a contact law of the model's own constants (a spring)
        return f"{grid}{sep}{scheme}, penalty {result.penalty} (its contact law reads no ε), {result.mass} mass"
    return f"{grid}, ε = {s.eps:g}{sep}{scheme}, penalty {result.penalty} (Δt/ε = {s.dt / s.eps:.3g}), {result.mass} mass"


def contact_times(t: np.ndarray, counts: np.ndarray) -> str:
    """'first contact at t = A; at most K contact components at once (first at t = B)', or '' when never two."""
    if not counts.size or counts.max() < 2:
        return ""
    began, most = float(t[int(np.argmax(counts > 0))]), int(np.argmax(counts))
    return (f"first contact at t = {began:.3g}; at most {int(counts[most])} contact components at once "
            f"(first at t = {float(t[most]):.3g})")


def obstacle_name(result) -> str:
    """'0' for the paper's flat obstacle y = 0, 'ψ' for a scene's profiled `obstacle`."""
    return "ψ" if getattr(result.scene, "obstacle", None) is not None else "0"


def obstacle_range(result) -> tuple[float, float]:
    """The least and the largest ψ at the nodes over every stored time (at t = 0 when it does not move)."""
    times = result.t if result.scene.obstacle_moves else [0.0]
    psi = (result.scene.obstacle_values(result.x, float(t)) for t in times)  # one at a time
    lows, highs = zip(*((float(np.min(p)), float(np.max(p))) for p in psi))
    return min(lows), max(highs)


# --- matplotlib ---------------------------------------------------------------------------------------


@contextlib.contextmanager
def without_axes3d_warning():
    """Without the "Unable to import Axes3D" warning of a pip matplotlib beside Debian's mpl_toolkits (no 3-D axes)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Unable to import Axes3D")
        yield


def figure(inches, **options):
    """A figure `inches` large in constrained layout on its own Agg canvas (no pyplot: its state is the caller's)."""
    with without_axes3d_warning():
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

    fig = Figure(figsize=inches, **{"layout": "constrained", **options})
    FigureCanvasAgg(fig)
    return fig


def with_key(fig, rows: int = 1, columns: int = 1, key: float = 0.06, **grid):
    """A grid of `rows` × `columns` panels over a key row (`key` of the height) and that row's frameless axes for
    `add_key`: constrained layout makes room for an axes' legend, not for a `Figure.legend` (3.6)."""
    heights = grid.pop("height_ratios", None) or (1,) * rows
    spec = fig.add_gridspec(2, 1, height_ratios=(sum(heights) * (1 - key), sum(heights) * key))
    panels = spec[0].subgridspec(rows, columns, height_ratios=heights, **grid)
    below = fig.add_subplot(spec[1])
    below.set_axis_off()
    return panels, below


def add_key(ax, handles, labels=None) -> None:
    """The legend of `handles` centred in `ax`, in as many columns (≤ 3) as the figure's width holds, measured: a
    legend wider than the figure makes constrained layout give up."""
    fig = ax.figure
    labels = labels if labels is not None else [h.get_label() for h in handles]
    for columns in range(min(3, len(handles)), 0, -1):
        legend = ax.legend(handles, labels, loc="center", ncol=columns, frameon=False)
        if legend.get_window_extent(fig.canvas.get_renderer()).width <= 0.95 * fig.bbox.width:
            return


def savefig(fig, path: Path, look: Look = SCREEN) -> list[Path]:
    """`fig` written as `path` in each format of `look`, each file whole or not at all: the paths written."""
    written = []
    for target in look.paths(path):
        with atomic_path(target) as tmp:  # a picture is either complete or absent
            options = {"pil_kwargs": {"compress_level": PNG_COMPRESSION}} if target.suffix == ".png" else {}
            fig.savefig(tmp, dpi=look.dpi, format=target.suffix[1:], **options)
        written.append(target)
    return written


def titled(fig, title: str, result, look: Look, *notes: str) -> None:
    """`fig` titled `title`, with the run's details (`parameter_line`) and `notes` as a caption under it when `look`
    has one."""
    fig.suptitle(title)
    if look.caption:
        fig.supxlabel("\n".join(filter(None, (parameter_line(result, sep="\n"), *notes))), fontsize="small",
                      color="0.25")


def picture(draw, result, path, look: Look = SCREEN, **options) -> Path:
    """The figure of `draw` ``(result, look, **options) -> figure or (figure, axes)`` in `look`'s style sheet, written
    to `path` in each format of `look`: the first file written."""
    with look.drawn():
        made = draw(result, look, **options)
        return savefig(made[0] if isinstance(made, tuple) else made, Path(path), look)[0]


def panel_grid(panels: int, width: float) -> tuple[int, int]:
    """(rows, columns) of `panels` panels `width` inches wide: three columns from five on, two below 6 inches."""
    columns = 3 if panels > 4 and width >= 6.0 else min(panels, 2)
    return -(-panels // columns), columns


def _cell_edges(v: np.ndarray) -> np.ndarray:
    """Edges of cells centred on the samples `v`; the first and last cells end at the first and last sample."""
    if v.size == 1:
        return np.array([v[0], v[0] + 1.0])
    return np.concatenate([[v[0]], 0.5 * (v[1:] + v[:-1]), [v[-1]]])


def contact_set_figure(result, look: Look = SCREEN):
    """The space-time contact set {η ≤ ψ} and its number of components over time, and zoomed in time when the most
    components last a short while (`zoom_window`): the figure and its axes {"set", "count", ["zoom", "zoom_count"]}."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    psi, counts = obstacle_name(result), result.contact_components
    zoom = zoom_window(result.t, counts)
    fig = figure(look.inches)
    grid = fig.add_gridspec(1 + (zoom is not None), 2, width_ratios=(5, 1), height_ratios=(0.56, 0.44) if zoom else None)
    colours = ListedColormap(["white", CONTACT_COLOUR])
    axes = {}
    for row, key in enumerate(("set", "zoom")[: 1 + (zoom is not None)]):
        ax = axes[key] = fig.add_subplot(grid[row, 0])
        ax.pcolorfast(_cell_edges(result.x), _cell_edges(result.t), result.contact.astype(np.uint8), cmap=colours, vmin=0, vmax=1)
        ax.set_ylabel("time t")
        strip = axes[f"{key}_count".replace("set_", "")] = fig.add_subplot(grid[row, 1], sharey=ax)
        strip.stairs(counts, _cell_edges(result.t), orientation="horizontal", color="#2166ac", lw=1.5, baseline=None)
        strip.set(xlim=(-0.3, max(2, int(counts.max())) + 0.5), xlabel="contact\ncomponents")
        strip.xaxis.get_major_locator().set_params(integer=True)
        strip.tick_params(labelleft=False)
        strip.grid(alpha=0.3)
    if result.t[-1] > result.t[0]:
        axes["set"].set_ylim(result.t[0], result.t[-1])
    axes.get("zoom", axes["set"]).set_xlabel("position x")
    if zoom is not None:
        lo, hi = zoom[:2]
        axes["zoom"].set_ylim(lo, hi)
        for t in (lo, hi):
            axes["set"].axhline(t, color="black", ls="--", lw=1.0)
        axes["zoom"].set_title(f"zoom: t = {lo:.3g} … {hi:.3g} (dashed above)", loc="left")
    patches = [Patch(facecolor=CONTACT_COLOUR, edgecolor="black", label=f"in contact (η ≤ {psi})"),
               Patch(facecolor="white", edgecolor="black", label=f"free (η > {psi})")]
    axes["count"].legend(handles=patches, loc="upper left", bbox_to_anchor=(1.15, 1.0), frameon=False)
    titled(fig, f"Contact set {{η ≤ {psi}}} over (x, t)", result, look, contact_times(result.t, counts))
    return fig, axes



def zoom_window(t: np.ndarray, counts: np.ndarray, share: float = 0.25):
    """(lo, hi, most, first, last): a window half as wide again each side of the first rows with the most components
    (≥ 5 % of the run); None without two components or when wider than `share` of the run."""
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


def velocity_figure(result, look: Look = SCREEN, percentile: float = VELOCITY_PERCENTILE):
    """The space-time velocity v(t, x), diverging colours centred on 0, range clipped at a percentile of |v|."""
    c = velocity_clip(result, percentile)
    speed = float(np.max(np.abs(result.velocity)))
    fig = figure(look.inches)
    ax = fig.add_subplot()
    image = ax.pcolorfast(_cell_edges(result.x), _cell_edges(result.t), result.velocity, cmap="RdBu_r", vmin=-c, vmax=c)
    ax.set(xlabel="position x", ylabel="time t")
    fig.colorbar(image, ax=ax, extend="both" if speed > c else "neither", shrink=0.8).set_label("v (velocity)")
    titled(fig, "Velocity v = η_t over (x, t)", result, look,
           f"colours clipped at ±{c:.3g} ({percentile:g}th percentile of the speed; max {speed:.3g})")
    return fig, ax



def snapshots_figure(result, look: Look = SCREEN):
    """η(x) at the scene's output times, the obstacle (y = 0 or the scene's ψ), and the parts in contact."""
    from matplotlib.patches import Patch

    rows = snapshot_rows(result)
    nrows, ncols = panel_grid(len(rows), look.width)
    height = nrows * 0.76 * look.width / ncols + 1.0  # panels 0.76 as high as wide, and the key
    fig = figure((look.width, height))
    panels, below = with_key(fig, nrows, ncols, key=0.3 / height)
    axs = panels.subplots(sharex=True, sharey=True, squeeze=False)
    x, name = result.x, obstacle_name(result)
    psis = {i: result.scene.obstacle_values(x, float(result.t[i])) for i in rows}  # a moving obstacle where it is at t
    lo = min(float(result.eta[rows].min()), min(float(p.min()) for p in psis.values()))
    hi = max(float(result.eta[rows].max()), max(float(p.max()) for p in psis.values()))
    pad = 0.08 * (hi - lo or 1.0)
    contact_length = result.contact_length  # a property over all rows: once, not per panel
    sep = "\n" if look.width / ncols < 2.5 else " "  # a title of 33 characters is wider than a panel 1.7 in wide
    for ax, i in zip(axs.flat, rows):
        psi = psis[i]
        ax.fill_between(x, lo - pad, psi, color="0.85", lw=0, zorder=0)
        ax.plot(x, psi, color="0.3", lw=1.0, zorder=1)
        ax.plot(x, result.eta[i], color="#2166ac", label="η(t, x)", zorder=2)
        ax.plot(x, np.where(result.contact[i], result.eta[i], np.nan), color=CONTACT_COLOUR, lw=3.0,
                label=f"in contact (η ≤ {name})", zorder=3)
        parts = len(contact_components(x, result.contact[i]))
        frac = float(contact_length[i]) / float(x[-1] - x[0])
        ax.set_title(f"t = {result.t[i]:.3g}:{sep}{100 * frac:.0f}% in contact, {parts} part{'s' * (parts != 1)}",
                     fontsize="small")
        ax.set(ylim=(lo - pad, hi + pad), xlabel="x", ylabel="η (displacement)")
        ax.label_outer()  # the labels of the bottom row and the left column
        ax.grid(alpha=0.3)
    for ax in axs.flat[len(rows):]:
        ax.set_visible(False)
    handles, labels = axs.flat[0].get_legend_handles_labels()
    handles.append(Patch(color="0.85", label=f"obstacle (y ≤ {name})"))
    add_key(below, handles, [*labels, handles[-1].get_label()])
    titled(fig, "The string at the output times", result, look, panels_note(result, rows))
    return fig, axs



def energy_figure(result, look: Look = SCREEN):
    """The balance (1.4): E(t) plus what viscosity, contact and the scheme took against E(0), zoomed onto the first
    times when it settles early (`settle_time`), |residual| below: the figure and its axes {"energy", "residual",
    ["zoom", "zoom_residual"]}."""
    e, t = result.energy, result.t
    E = result.total_energy
    spent = e["viscous_dissipation"] + e["contact_dissipation"] + e["numerical_dissipation"]
    internal = e.get("internal_dissipation", np.zeros_like(t))
    grad, grad_t = (r"\eta_x^2", r"\eta_{tx}^2") if np.ndim(result.x) == 1 else (r"|\nabla\eta|^2", r"|\nabla\eta_t|^2")
    stored = getattr(result, "energy_label", None) or rf"elastic $\frac{{1}}{{2}}\int {grad}\,dx$"  # the model's own, or ½∫|∇η|²
    curves = [(e["kinetic"], {"label": r"kinetic $\frac{1}{2}\int \eta_t^2\,dx$"}),
              (e["elastic"], {"label": stored}),
              (e["viscous_dissipation"], {"label": rf"viscous dissipation $\alpha\int_0^t\!\int {grad_t}$"}),
              (e["contact_dissipation"], {"label": r"contact dissipation $-\int_0^t\!\int F\,\eta_t$"}),
              (e["numerical_dissipation"], {"ls": "--", "label": "numerical dissipation (cumulative)"})]
    if np.any(internal):  # a dashpot's: the model's internal variables, by name (`fem.dissipation`)
        names = ", ".join(n for n, info in (getattr(result, "field_info", None) or {}).items() if info.get("internal"))
        curves.insert(3, (internal, {"label": f"dissipation of the internal variables {names}".rstrip()}))
        spent = spent + internal
    if np.any(e["external_work"]):
        moving = getattr(result.scene, "obstacle_moves", False)  # the moving obstacle's work is booked there too
        what = "the moving obstacle and external loads" if moving else "external loads"
        curves.append((e["external_work"], {"ls": "-.", "label": f"work of {what} (cumulative)"}))
    curves.append((E + spent - e["external_work"], {"color": "black", "lw": 2.2, "alpha": 0.6, "label": "sum: E(t) + dissipations − work"}))
    settled = settle_time(t, [values for values, _ in curves])
    fig = figure((look.width, 0.78 * look.width if look.width >= 6.0 else 1.35 * look.width))  # a column: the legend's rows
    grid, legend_row = with_key(fig, 2, 2 if settled else 1, key=0.12, height_ratios=(3, 1), width_ratios=(3, 2) if settled else None)
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
        axes["zoom"].set(xlim=(t[0], settled), title=f"zoom: t = {t[0]:.3g} … {settled:.3g} (shaded left)")
        axes["zoom"].tick_params(labelleft=False)
        axes["zoom_residual"].set_ylabel("")
        axes["energy"].axvspan(t[0], settled, color="0.5", alpha=0.12, lw=0)
    add_key(legend_row, *axes["energy"].get_legend_handles_labels())
    titled(fig, "Energy balance (1.4)", result, look)
    return fig, axes



def settle_time(t: np.ndarray, curves, share: float = 0.25, tolerance: float = 0.02):
    """1.5 times the time after which every curve stays within `tolerance` of the largest range of its final value,
    when under `share` of the run (a zoomed panel's end), else None."""
    scale = max(float(np.ptp(values)) for values in curves) or 1.0
    moving = np.zeros(t.size, dtype=bool)
    for values in curves:
        moving |= np.abs(values - values[-1]) > tolerance * scale
    last = int(np.flatnonzero(moving)[-1]) + 1 if moving.any() else 0
    whole = float(t[-1] - t[0])
    end = float(t[0]) + 1.5 * float(t[min(last, t.size - 1)] - t[0])
    return end if 0 < end - float(t[0]) <= share * whole else None


def residual_panel(ax, t: np.ndarray, residual: np.ndarray, legend: bool = True) -> None:
    """|residual| on a log scale, rows where it is exactly 0 marked by triangles at the panel's floor."""
    res = np.abs(residual)
    zero = res == 0
    floor = float(res[~zero].min()) / 10 if (~zero).any() else 1e-16
    ax.semilogy(t, np.where(zero, np.nan, res), color="black", lw=1.2, label="|balance residual|")
    if zero.any():
        ax.plot(t[zero], np.full(int(zero.sum()), floor), "v", color="#b2182b", ms=5, clip_on=False,
                label=f"exactly 0 ({int(zero.sum())} of {t.size} rows; drawn at the floor)")
        if legend:
            ax.legend(fontsize="x-small", loc="lower right", framealpha=0.9)
    top = float(res.max()) if res.max() > 0 else 1e-15
    ax.set(ylim=(floor, top * 10), xlabel="t")
    ax.set_ylabel("|residual|", fontsize="small")
    ax.grid(alpha=0.3)


def contact_area_figure(result, look: Look = SCREEN):
    """``contact_area.png`` (2D): the contact area against the domain's (dots: membrane.png's panels) and patches."""
    t, area, patches = result.t, result.contact_measure, result.contact_patches()
    domain, psi = float(np.sum(result.weights)), obstacle_name(result)
    fig = figure((look.width, 0.72 * look.width))
    ax, axp = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (2, 1)})
    ax.axhline(domain, color="black", ls=":", lw=1.5, label=f"area of the domain = {domain:.4g}")
    ax.plot(t, area, color=CONTACT_COLOUR, lw=2.0, label=f"contact area |{{η ≤ {psi}}}|")
    rows = snapshot_rows(result)
    ax.plot(t[rows], area[rows], "o", color="black", ms=5, label="the panels of membrane.png")
    ax.set(ylim=(0, 1.08 * domain), ylabel="contact area")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    first = np.flatnonzero(area > 0)
    landed = f"first contact at t = {t[first[0]]:.3g}, largest area {area.max():.3g}" if first.size else "no contact"
    axp.step(t, patches, where="mid", color="#2166ac", lw=1.5, label="contact patches (connected along mesh edges)")
    axp.set(ylim=(-0.3, max(2, int(patches.max())) + 0.5), ylabel="number of\npatches", xlabel="t")
    axp.yaxis.get_major_locator().set_params(integer=True)
    axp.grid(alpha=0.3)
    axp.legend(loc="upper right")
    titled(fig, "Contact area and contact patches over time", result, look, landed)
    return fig

