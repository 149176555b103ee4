"""Which pictures a run has (`pictures_of`): a string's, a membrane's, and one per output field of its model."""

from __future__ import annotations

WINDOW_SIZE = (1100, 900)  # pixels of the space-time pictures
CHART_PICTURES = ("contact_set.png", "velocity_field.png", "snapshots.png", "energy.png")  # matplotlib
PICTURES = CHART_PICTURES + ("space_time.png",)  # of a 1-D run
#: of a 2-D run (a membrane): contact_area.png and energy.png by matplotlib, the others by pyvista
MEMBRANE_PICTURES = ("membrane.png", "contact_area.png", "energy.png", "membrane.gif")
MESH_PICTURES = ("space_time.png", "membrane.png", "membrane.gif")  # pyvista
#: every picture a run draws whatever its model; an output field's picture takes another name (`field_picture_names`)
CORE_PICTURES = tuple(dict.fromkeys(PICTURES + MEMBRANE_PICTURES))


def field_picture_names(result) -> dict[str, str]:
    """The picture of each of the model's output fields (`Result.fields`): picture -> field, ``NAME.png``, or
    ``field_NAME.png`` where that is a core picture's name."""
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
