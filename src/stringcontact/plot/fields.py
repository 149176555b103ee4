"""A model's output fields in the pictures, shown as their description says (label, unit, colours, scale), never by
their name: `FieldScale`, one field's colour scale over all rows (`io.paraview_view`'s), and ``NAME.png``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..io.paraview_view import field_range
from ..io.tables import field_info
from .charts import figure, literal, titled
from .style import SCREEN, Look
from .vtk_start import nice_ticks

#: the least distance of an inner tick from the bar's ends, in half-bars: their labels apart
TICK_GAP = 0.16


@dataclass(frozen=True)
class FieldScale:
    """An output field on one colour scale for every row: `low` … `high` onto −1 … 1 (`unit`) in its `colours`; linear,
    or ``"symlog"``, linear within ±`linear_share`·`high` (a landing's peak 1e3–1e4 times the rest)."""

    name: str
    low: float
    high: float
    colours: tuple
    scale: str = "linear"
    linear_share: float = 1e-3
    label: str = ""
    title: str = ""

    @classmethod
    def of(cls, values, info: dict) -> FieldScale:
        """The scale of the field's rows `values` as its description `info` says (`io.paraview_view.field_range`)."""
        low, high = field_range(values, info)
        label = info.get("label") or info["name"]
        title = f"{label} [{info['unit']}]" if info.get("unit") else label
        return cls(info["name"], low, high, tuple(tuple(c) for c in info["colours"]), info.get("scale", "linear"),
                   float(info.get("linear_share", 1e-3)), label, title)

    def unit(self, values) -> np.ndarray:
        """Where `values` lie on the scale (`norm`): −1 at `low`, 1 at `high` (clipped beyond); 0 at 0 on a symmetric one."""
        return np.clip(2.0 * np.asarray(self.norm()(np.asarray(values, dtype=float))) - 1.0, -1.0, 1.0)

    def colour_map(self):
        """The colours from −1 to 1 (`unit`), blended in between."""
        from matplotlib.colors import LinearSegmentedColormap

        return LinearSegmentedColormap.from_list(self.name, self.colours)

    def norm(self):
        """matplotlib's normalisation of the scale: `SymLogNorm` (base 10) or `Normalize` from `low` to `high`."""
        from matplotlib.colors import Normalize, SymLogNorm

        if self.scale == "symlog":
            return SymLogNorm(linthresh=self.linear_share * self.high, vmin=self.low, vmax=self.high, base=10)
        return Normalize(vmin=self.low, vmax=self.high)

    def colour_bar(self, fig, **options):
        """matplotlib's colour bar of the scale in `fig` (`Figure.colorbar`'s `options`), ticked at `ticks`."""
        from matplotlib.cm import ScalarMappable

        bar = fig.colorbar(ScalarMappable(self.norm(), self.colour_map()), **options)
        bar.set_ticks(self.ticks(), labels=[self.tick_label(v) for v in self.ticks()])
        return bar

    def ticks(self) -> np.ndarray:
        """The ends, and the round values (symlog: 0 and ± powers of ten) at least `TICK_GAP` inside them."""
        if self.scale == "symlog":
            powers = 10.0 ** np.arange(np.ceil(np.log10(self.linear_share * self.high)), np.floor(np.log10(self.high)) + 1)
            inner = np.concatenate([-powers[::-1], [0.0], powers])
        else:
            inner = nice_ticks(self.low, self.high)
        inner = inner[np.abs(self.unit(inner)) <= 1.0 - TICK_GAP]
        return np.concatenate([[self.low], inner, [self.high]])

    def tick_label(self, v: float) -> str:
        """A tick's label: the ends to 3 digits, the round values as they are; a true minus sign."""
        v = 0.0 if abs(v) < 1e-9 * (self.high - self.low) else float(v)  # a locator's round-off about 0
        text = f"{abs(v):.3g}" if np.isclose(v, self.low) or np.isclose(v, self.high) else f"{abs(v):g}"
        return ("−" if v < 0 else "") + text


def field_figure(result, look: Look = SCREEN, *, name: str):
    """The output field `name` on its scale: a string's over (x, t), contact outlined, a membrane's at its largest
    |value|; beside it its least and largest value at each time. Returns the figure and its two axes."""
    values = np.asarray(result.fields[name], dtype=float)
    scale = FieldScale.of(values, field_info(result)[name])
    narrow = look.width < 6.0  # a journal's column: the two panels one above the other
    fig = figure((look.width, 1.3 * look.width) if narrow else (look.width, 0.42 * look.width))
    ax, bx = fig.subplots(2, 1) if narrow else fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.4, 1]})
    colours = {"cmap": scale.colour_map(), "norm": scale.norm()}
    if result.dim == 1:
        mesh = ax.pcolormesh(result.x, result.t, values, shading="auto", **colours)
        if result.contact.any():
            ax.contour(result.x, result.t, result.contact.astype(float), levels=[0.5], colors="k", linewidths=0.8)
        ax.set(xlabel="x", ylabel="t", title="over (x, t); contact set outlined")
    else:
        k = int(np.argmax(np.fmax.reduce(np.abs(values), axis=1)))
        mesh = ax.tripcolor(result.x[:, 0], result.x[:, 1], result.cells, values[k], shading="gouraud", **colours)
        ax.set(aspect="equal", title=f"at t = {result.t[k]:.4g} (its largest |value|)")
    fig.colorbar(mesh, ax=ax, label=literal(scale.title))
    bx.plot(result.t, np.fmax.reduce(values, axis=1), label="largest")
    bx.plot(result.t, np.fmin.reduce(values, axis=1), label="least")
    if scale.scale == "symlog":
        bx.set_yscale("symlog", linthresh=scale.linear_share * scale.high)
    bx.set(xlabel="t", title="least and largest value")
    bx.legend()
    bx.grid(True, alpha=0.3)
    titled(fig, literal(scale.label[:1].upper() + scale.label[1:]), result, look)
    return fig, (ax, bx)

