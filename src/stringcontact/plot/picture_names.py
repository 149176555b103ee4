"""Which pictures a run has: their names and size, and nothing else.

This module imports nothing (no NumPy, no plotting library), so that `stringcontact run` can start its
picture process (`picture_process.PictureProcess`) before it imports anything heavy: importing NumPy and the
charts first delayed the start by 0.08 s, and the run's end with it (docs/explanation/performance.md).
"""

from __future__ import annotations

WINDOW_SIZE = (1100, 900)  # pixels of the space-time pictures
CHART_PICTURES = ("contact_set.png", "velocity_field.png", "snapshots.png", "energy.png")  # matplotlib
PICTURES = CHART_PICTURES + ("space_time.png",)  # of a 1-D run
#: of a 2-D run (a membrane): contact_area.png and energy.png by matplotlib, the others by pyvista
MEMBRANE_PICTURES = ("membrane.png", "contact_area.png", "energy.png", "membrane.gif")
MESH_PICTURES = ("space_time.png", "membrane.png", "membrane.gif")  # pyvista
#: what `stringcontact run` hands to its painter process, of the pictures the run has (`painted`): all of them.
#: The painter and its helper (`picture_process.main`) share them out over both cores, and the run, which would draw
#: one at a time, imports no plotting library at all (matplotlib alone: 0.2 s on its critical path)
PAINTED = tuple(dict.fromkeys(PICTURES + MEMBRANE_PICTURES))


#: every picture a run draws whatever its model; an output field's picture takes another name (`field_picture_names`)
CORE_PICTURES = PAINTED


def field_picture_names(result) -> dict[str, str]:
    """The picture of each of the model's output fields (`Result.fields`), drawn by the run itself, not the
    painter: picture -> field, ``NAME.png``, or ``field_NAME.png`` where that is a core picture's name."""
    names = {}
    for name in getattr(result, "fields", None) or {}:
        picture = f"{name}.png"
        while picture in CORE_PICTURES:
            picture = f"field_{picture}"
        names[picture] = name
    return names


def pictures_of(result) -> tuple[str, ...]:
    """The pictures of a run: `PICTURES` of a string (1D), `MEMBRANE_PICTURES` of a membrane (2D), then one per
    output field of its model (`field_picture_names`)."""
    names = PICTURES if result.dim == 1 else MEMBRANE_PICTURES
    return names + tuple(field_picture_names(result))


def painted(result, names=PAINTED) -> tuple[str, ...]:
    """Those of `names` that are pictures of `result`: what a painter started for `names` draws of it."""
    return tuple(name for name in names if name in pictures_of(result))
