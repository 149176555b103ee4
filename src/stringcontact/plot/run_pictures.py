"""A run's pictures (`pictures_of`: a string's, a membrane's, and one per output field of its model), each by the
library made for it: matplotlib (`charts`, `fields`), pyvista (`mesh_pictures`, imported only for them), Pillow
(`animation`); after a run's solve, or again from its stored rows."""

from __future__ import annotations

import json
from pathlib import Path

from ..io.tables import field_key
from ..signals import signals_held
from . import charts
from .charts import contact_components, snapshot_rows  # noqa: F401 - the demos' readings, as run_pictures.*
from .style import SCREEN_DPI, WINDOW_SIZE, Look

#: of a 1-D run (a string)
PICTURES = ("contact_set.png", "velocity_field.png", "snapshots.png", "energy.png", "space_time.png")
#: of a 2-D run (a membrane)
MEMBRANE_PICTURES = ("membrane.png", "contact_area.png", "energy.png", "membrane.gif")


def field_picture_names(result) -> dict[str, str]:
    """Picture -> output field: ``NAME.png``, or ``field_NAME.png`` where that is a core picture's name."""
    return {field_key(f"{name}.png", PICTURES + MEMBRANE_PICTURES): name for name in getattr(result, "fields", None) or {}}


def pictures_of(result) -> tuple[str, ...]:
    """`PICTURES` of a string, `MEMBRANE_PICTURES` of a membrane, then one per output field of its model."""
    names = PICTURES if result.dim == 1 else MEMBRANE_PICTURES
    return names + tuple(field_picture_names(result))


#: the matplotlib pictures' figure functions (`charts`), by name
CHARTS = {"contact_area.png": "contact_area_figure", "contact_set.png": "contact_set_figure",
          "velocity_field.png": "velocity_figure", "snapshots.png": "snapshots_figure", "energy.png": "energy_figure"}


def draw(name: str, result, folder, window_size=WINDOW_SIZE, look: Look | None = None) -> Path:
    """Draw the picture `name` (`pictures_of`) of `result` into `folder` in each format of `look` (default: a PNG
    `window_size` pixels large on a screen): the first file written."""
    look = look or Look.of_pixels(window_size)
    path = Path(folder) / name
    field = field_picture_names(result).get(name)
    if field is not None:
        from .fields import field_figure

        return charts.picture(field_figure, result, path, look, name=field)
    if name in CHARTS:
        return charts.picture(getattr(charts, CHARTS[name]), result, path, look)
    # VTK interrupted inside its import or a render can crash the process (SIGSEGV, "Failed to load vtkCommonMath"):
    # a Ctrl-C or SIGTERM takes effect when the picture is done (about a second)
    with signals_held():
        if name == "membrane.gif":
            from . import animation  # pyvista and Pillow

            return animation.membrane_animation(result, path, tuple(round(v * SCREEN_DPI) for v in look.inches))
        from . import mesh_pictures  # pyvista: 0.5-1 s to import, so only for these

        figure = mesh_pictures.space_time_figure if name == "space_time.png" else mesh_pictures.membrane_figure
        return charts.picture(figure, result, path, look)


def write_pictures(result, folder, window_size=WINDOW_SIZE, look: Look | None = None) -> list[Path]:
    """Write the pictures of `result` (`pictures_of`) into `folder` in each format of `look` (default: PNGs
    `window_size` pixels large), what `simulate(..., pictures=True)` calls: the files written (``membrane.gif`` with a
    raster format only)."""
    folder = Path(folder)
    look = look or Look.of_pixels(window_size)
    names = tuple(n for n in pictures_of(result) if n != "membrane.gif" or "png" in look.formats)
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        draw(name, result, folder, window_size, look)
    formats = {name: look.formats if name.endswith(".png") else ("gif",) for name in names}
    return [folder / Path(name).with_suffix(f".{f}").name for name, kinds in formats.items() for f in kinds]


def show_pictures(folder) -> list[Path]:
    """The pictures of a run folder: displayed inline in a Jupyter notebook, otherwise their paths printed."""
    import sys

    folder = Path(folder)
    membrane = any((folder / name).exists() for name in set(MEMBRANE_PICTURES) - set(PICTURES))
    names = (MEMBRANE_PICTURES if membrane else PICTURES) + tuple(field_picture_names(_named_fields(folder)))
    paths = [folder / name for name in names if (folder / name).exists()]
    if "ipykernel" in sys.modules:
        from IPython.display import Image, display

        for path in paths:
            display(Image(filename=str(path)))
    else:
        print("pictures:", ", ".join(str(p) for p in paths))
    return paths


def _named_fields(folder: Path):
    """A stand-in for a result with the output fields summary.json names (none if it cannot be read)."""
    from types import SimpleNamespace

    try:
        fields = json.loads((folder / "summary.json").read_text()).get("fields")
    except (OSError, ValueError, AttributeError):
        fields = None
    named = dict.fromkeys(n for n in fields if str(n).isidentifier()) if isinstance(fields, dict) else {}
    return SimpleNamespace(fields=named)
