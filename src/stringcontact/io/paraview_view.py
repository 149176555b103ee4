"""`view.py`, a ready ParaView view of an output folder: the package's `paraview/view.py` with the run's numbers
filled in as literals (`view_script`), computed over all stored rows: the fixed colour ranges, the obstacle at rest,
the title and the box one camera frames at every time (docs/howto/view_in_paraview.md)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np

from .publish import atomic_path
from .tables import field_info

#: control points of a symmetric-log field's colours per decade of its |value|
POINTS_PER_DECADE = 4
#: at most this many samples of the obstacle per direction (its profile; a flat one needs 2)
OBSTACLE_SAMPLES = 200
#: a membrane's obstacle is drawn this share of the height range below ψ (a patch on ψ would flicker with it)
_MEMBRANE_DROP = 0.01


def symlog_unit(values, peak: float, share: float) -> np.ndarray:
    """`values` from −peak … peak onto −1 … 1 (clipped) by matplotlib's SymLogNorm (base 10, linthresh share·peak)."""
    from matplotlib.colors import SymLogNorm

    norm = SymLogNorm(linthresh=share * peak, vmin=-peak, vmax=peak, base=10, clip=True)
    return 2.0 * np.asarray(norm(np.asarray(values, dtype=float))) - 1.0


def field_range(values, info: dict) -> tuple[float, float]:
    """An output field's fixed colour range over its rows: ±max |value| for a symmetric or ``"symlog"`` one (`info`:
    `OutputField.metadata`), else its finite least … largest, never empty."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if info.get("symmetric") or info.get("scale") == "symlog":
        peak = float(np.max(np.abs(v))) if v.size else 0.0
        return (-(peak or 1.0), peak or 1.0)
    low, high = (float(v.min()), float(v.max())) if v.size else (0.0, 0.0)
    pad = 0.0 if high > low else 0.5 * (abs(low) or 1.0)
    return low - pad, high + pad


def field_points(low: float, high: float, info: dict) -> list:
    """ParaView's control points (value, r, g, b) of an output field's colours on `low` … `high` (a ``"symlog"`` one's
    at 0, ±linthresh and `POINTS_PER_DECADE` per decade up to ±high, blended as `LinearSegmentedColormap` does)."""
    colours = np.asarray(info["colours"], dtype=float)
    if info.get("scale") == "symlog":
        share = float(info.get("linear_share", 1e-3))
        decades = -float(np.log10(share))
        above = high * 10.0 ** -np.linspace(decades, 0.0, round(decades * POINTS_PER_DECADE) + 1)
        values = np.concatenate([-above[::-1], [0.0], above])
        unit, stops = symlog_unit(values, high, share), np.linspace(-1.0, 1.0, len(colours))
        colours = np.column_stack([np.interp(unit, stops, colours[:, k]) for k in range(3)])
    else:
        values = np.linspace(low, high, len(colours))
    return [(float(v), *(float(x) for x in c)) for v, c in zip(values, colours)]


def symlog_view(high: float, info: dict) -> list:
    """A symmetric-log field's scale in view.py: ``[linthresh, [[unit, r, g, b], ...], [[unit, label], ...]]``, its
    colour bar's ticks at 0, ±linthresh, a decade apart up to ±high."""
    share = float(info.get("linear_share", 1e-3))
    points = field_points(-1.0, 1.0, {"colours": info["colours"]})
    above = high * 10.0 ** -np.arange(0, int(np.floor(-np.log10(share) + 1e-9)) + 1)
    if above[-1] > share * high * (1 + 1e-9):
        above = np.append(above, share * high)
    values = np.concatenate([-above, [0.0], above[::-1]])
    ticks = [[float(u), f"{v:.3g}" if v else "0"] for u, v in zip(symlog_unit(values, high, share), values)]
    return [share * high, points, ticks]


def view_numbers(result) -> dict:
    """view.py's numbers by the names of its lines, from the stored rows."""
    scene, x, eta = result.scene, np.asarray(result.x, dtype=float), np.asarray(result.eta, dtype=float)
    speed = float(np.nanmax(np.abs(result.velocity))) if np.size(result.velocity) else 0.0
    lo, hi = (float(np.nanmin(eta)), float(np.nanmax(eta))) if eta.size else (0.0, 0.0)
    string, moves = x.ndim == 1 or x.shape[1] == 1, bool(getattr(scene, "obstacle_moves", False))
    if moves:  # the box holds the obstacle at every stored time, not only at t = 0
        grid = _obstacle_grid(scene, x) if string else x[:: max(1, len(x) * 16 // OBSTACLE_SAMPLES**2), :2]
        for t in np.unique(np.asarray(result.t, dtype=float)):
            psi = obstacle_at(scene, grid, float(t))
            lo, hi = min(lo, float(psi.min())), max(hi, float(psi.max()))
    grid = _obstacle_grid(scene, x)
    psi = obstacle_at(scene, grid)
    lo, hi = min(lo, float(psi.min())), max(hi, float(psi.max()))
    points, quads, bounds, shift = (_string_obstacle if string else _membrane_obstacle)(x, grid, psi, lo, hi)
    maps, symlog = {}, {}
    for name, info in field_info(result).items():
        low, high = field_range(result.fields[name], info)
        maps[name] = [[low, high], field_points(low, high, info)]
        if info.get("scale") == "symlog":
            symlog[name] = symlog_view(high, info)
    return {"KIND": "string" if string else "membrane", "NORMAL": (0.0, 1.0, 0.0) if string else (0.0, 0.0, 1.0),
            "VELOCITY_RANGE": (-(speed or 1.0), speed or 1.0), "BOUNDS": bounds,
            "OBSTACLE_POINTS": [] if moves else points, "OBSTACLE_QUADS": [] if moves else quads,
            "OBSTACLE_MOVES": moves, "OBSTACLE_SHIFT": shift, "FIELD_MAPS": maps, "SYMLOG": symlog,
            "TITLE": f"{scene.name}: model {result.model}, scheme {getattr(result, 'scheme', 'paper')}"}


def obstacle_at(scene, points, t: float = 0.0) -> np.ndarray:
    """ψ at `points` (x, or rows of x, y) at the time t; ψ's lowest finite value where it has none (no NaN)."""
    points = np.asarray(points, dtype=float)
    psi = np.asarray(scene.obstacle_values(points, t), dtype=float).reshape(-1)
    finite = np.isfinite(psi)
    return np.where(finite, psi, psi[finite].min() if finite.any() else 0.0)


def _obstacle_grid(scene, x) -> np.ndarray:
    """Where the obstacle is drawn: `OBSTACLE_SAMPLES` x (a string's) or an n × n grid's rows of x, y (a membrane's)
    over the mesh's box; a flat one's ends or corners."""
    flat = getattr(scene, "obstacle", None) is None
    if x.ndim == 1 or x.shape[1] == 1:
        xs = x.reshape(-1)
        return np.linspace(xs.min(), xs.max(), 2 if flat else min(OBSTACLE_SAMPLES, len(xs)))
    n = 2 if flat else min(OBSTACLE_SAMPLES // 4, int(np.sqrt(len(x))) + 1)
    gx, gy = np.meshgrid(np.linspace(x[:, 0].min(), x[:, 0].max(), n), np.linspace(x[:, 1].min(), x[:, 1].max(), n))
    return np.column_stack([gx.ravel(), gy.ravel()])


def _string_obstacle(x, grid, psi, lo, hi):
    """The region below y = ψ(x) down to a floor under everything, slightly behind the string: its points and quads,
    the box over everything, the shift of a moving obstacle (as this one)."""
    xs, n = x.reshape(-1), len(grid)
    floor = lo - 0.08 * max(hi - lo, 1e-12)
    z = -1e-3 * max(xs.max() - xs.min(), 1e-12)
    points = [(float(g), float(p), z) for g, p in zip(grid, psi)] + [(float(g), floor, z) for g in grid]
    quads = [(i, i + 1, n + i + 1, n + i) for i in range(n - 1)]
    return points, quads, (float(xs.min()), float(xs.max()), floor, hi, 0.0, 0.0), (0.0, 0.0, z)


def _membrane_obstacle(x, grid, psi, lo, hi):
    """z = ψ(x, y) on the n × n `grid`, `_MEMBRANE_DROP` of the height range lower; returns as `_string_obstacle`."""
    n = round(np.sqrt(len(grid)))
    psi = psi - _MEMBRANE_DROP * max(hi - lo, 1e-12)
    points = [(float(a), float(b), float(c)) for (a, b), c in zip(grid, psi)]
    quads = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i)
             for j in range(n - 1) for i in range(n - 1)]
    lo = min(lo, float(psi.min()))
    box = (float(x[:, 0].min()), float(x[:, 0].max()), float(x[:, 1].min()), float(x[:, 1].max()), lo, hi)
    return points, quads, box, (0.0, 0.0, -_MEMBRANE_DROP * max(hi - lo, 1e-12))


def _literal(value) -> str:
    """A Python literal of `value` (tuples as lists, NumPy scalars as Python's) whose floats read back exactly."""
    return repr(json.loads(json.dumps(value, default=lambda v: v.item())))


def view_script(numbers: dict) -> str:
    """The package's view.py with each line ``NAME = value  # comment`` between its markers set to `numbers[NAME]`."""
    program = resources.files(__package__).joinpath("paraview", "view.py").read_text(encoding="utf-8")
    start = program.index("\n", program.index("# --- the run's numbers")) + 1
    end = program.index("# --- end of the run's numbers ---")
    values, lines = dict(numbers), []
    for line in program[start:end].splitlines():
        name, equals, rest = line.partition(" = ")
        if equals and name in values:
            comment = rest.partition("  #")[2]
            line = f"{name} = {_literal(values.pop(name))}" + (f"  #{comment}" if comment else "")
        lines.append(line)
    if values:  # the program and this module out of step: a packaging error, not the user's
        raise RuntimeError(f"paraview/view.py has no line for {sorted(values)}")
    return program[:start] + "\n".join(lines) + "\n" + program[end:]


def write_view(result, folder, target=None) -> Path:
    """Write `folder`/view.py for `result`; `target`: where the folder will be once published (view.py's fallback)."""
    path = Path(folder) / "view.py"
    numbers = view_numbers(result) | {"FOLDER": str(Path(target).resolve()) if target is not None else ""}
    with atomic_path(path) as tmp:
        Path(tmp).write_text(view_script(numbers), encoding="utf-8")
    return path
