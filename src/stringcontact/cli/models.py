"""`stringcontact models`: the models a scene's `model` key may name (those registered under the entry-point
group `scene.names.GROUP`), each with where it comes from, its description, constants and output fields."""

from __future__ import annotations

from ..errors import SceneError
from ..model.registry import load_model
from ..scene.names import GROUP, registered
from ..scene.names import package_of as _package


def add_arguments(parser) -> None:
    parser.description = f"The models a scene's `model` key may name: those registered under {GROUP}."


def describe() -> list[tuple[str, str, str]]:
    """(name, where it comes from, description) of every registered model; loading each imports its package."""
    rows = []
    for name, eps in registered().items():
        where = ", ".join(f"{ep.value} [{_package(ep)}]" for ep in eps)
        try:
            description = load_model(name).description
        except SceneError as exc:
            description = f"(unavailable: {exc})"
        rows.append((name, where, description))
    return rows


def declared_text(model) -> list[str]:
    """One line per constant (name = default, range, unit, meaning) and per output field (name: label [unit]) that
    `model` declares: what `stringcontact models` shows under its name."""
    from ..model.interface import output_fields

    lines = [f"[parameters] {c.name} = {c.default_text}: {c.allowed}" + (f" [{c.unit}]" if c.unit else "")
             + (f", {c.description}" if c.description else "") for c in model.constants]
    return lines + [f"field {f.name}: {f.title}" for f in output_fields(model)]


def command(args) -> int:
    for name, where, description in describe():
        print(f"{name:16s} {description}\n{'':16s} {where}")
        try:
            extra = declared_text(load_model(name))
        except SceneError:
            extra = []
        for line in extra:
            print(f"{'':16s} {line}")
    return 0
