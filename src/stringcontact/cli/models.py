"""`stringcontact models`: the models a scene's `model` key may name (registered under the entry-point group
`scene.names.GROUP`), each with where it comes from, its description, constants and output fields."""

from __future__ import annotations

from ..errors import SceneError
from ..model.registry import load_model
from ..scene.names import GROUP, package_of, registered


def add_arguments(parser) -> None:
    """`stringcontact models` takes no arguments."""
    parser.description = f"The models a scene's `model` key may name: those registered under {GROUP}."


def command(args) -> int:
    """Each registered model: name, description, where it comes from, its constants and output fields."""
    from ..model.interface import output_fields

    for name, eps in registered().items():
        try:
            model = load_model(name)
        except SceneError as exc:
            model, lines = None, [f"(unavailable: {exc})"]
        else:
            lines = [model.description]
        lines.append(", ".join(f"{ep.value} [{package_of(ep)}]" for ep in eps))
        if model is not None:
            lines += [f"[parameters] {c.name} = {c.default_text}: {c.allowed}" + (f" [{c.unit}]" if c.unit else "")
                      + (f", {c.description}" if c.description else "") for c in model.constants]
            lines += [f"field {f.name}: {f.title}" for f in output_fields(model)]
        print("".join(f"{name if i == 0 else '':16s} {line}\n" for i, line in enumerate(lines)), end="")
    return 0
