"""Which pictures a run has (`pictures_of`): a string's, a membrane's, and one per output field of its model."""

from __future__ import annotations

from ..io.tables import field_key

WINDOW_SIZE = (1100, 900)  # pixels of the space-time pictures
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
