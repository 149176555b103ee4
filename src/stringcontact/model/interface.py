"""What a model declares besides its UFL: its constants, its output fields and how they are shown, its solver hints.

These are data. The core (scene, fem, time schemes, output, pictures, the run) reads them through the `Model`
and never names a particular model: a plugin's constant is checked, recorded and handed to its forms, and its
output field is written, read back and drawn, exactly as the built-in film's pressure or the stiff string's
curvature.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..scene.parameters import ModelConstant

__all__ = ["DIVERGING", "SEQUENTIAL", "ModelConstant", "OutputField", "SolverHints", "output_fields"]

#: A diverging field's colours at −P, 0 and P (RGB in 0 … 1): blue, a middle grey, red. The grey middle stays seen on
#: a white background and on the light grey obstacle, and black labels on it are read.
DIVERGING = ((0.085, 0.40, 0.85), (0.55, 0.55, 0.55), (0.85, 0.10, 0.08))
#: A one-signed field's colours from its least to its largest value: viridis' ends and middle.
SEQUENTIAL = ((0.267, 0.005, 0.329), (0.128, 0.567, 0.551), (0.993, 0.906, 0.144))
#: The scales a field may be drawn on.
SCALES = ("linear", "symlog")
#: Names an output field may not take: the fields every run stores beside it (`io.result.FIELDS`, the coordinates,
#: a moving obstacle) share its row, and one of these names would overwrite them.
RESERVED = ("eta", "velocity", "contact", "contact_force", "obstacle", "x", "t")


@dataclass(frozen=True)
class OutputField:
    """A field a model writes at every stored time: to `Result.fields[name]`, ``rows.npz``, ``solution.xdmf``, the
    pictures (``NAME.png``) and ParaView's view.

    `expression` is ``(U, p) -> UFL``, a scalar expression of the unknowns ``U = (η, *fields)`` and the
    `Parameters` `p`, interpolated into P1 at each stored time (a reaction, a flux); ``None``: the model's unknown
    of this `name` itself. How it is shown is metadata here, not code in the pictures: its `label` and `unit`;
    its `colours` (RGB triples in 0 … 1 from the least value through the middle to the largest); its `scale`,
    ``"linear"`` or ``"symlog"`` (symmetric about 0, linear within ``linear_share`` of its largest absolute value,
    logarithmic beyond: a landing's pressure peak is 1e3-1e4 times the pressure around it); `symmetric`, a range
    −P … P about 0 (a diverging field; ``"symlog"`` always is); `surface`, that it colours a membrane in the
    pictures and ParaView's view instead of the contact set (one field of a model at most).
    """

    name: str
    expression: Callable | None = None
    label: str = ""
    unit: str = ""
    colours: tuple = SEQUENTIAL
    scale: str = "linear"
    linear_share: float = 1e-3
    symmetric: bool = False
    surface: bool = False

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"OutputField: name must be an identifier, not {self.name!r}")
        if self.name in RESERVED:
            raise ValueError(f"OutputField {self.name!r}: a name every run stores already; choose another")
        if self.scale not in SCALES:
            raise ValueError(f"OutputField {self.name!r}: scale must be one of {', '.join(SCALES)}, not {self.scale!r}")
        if len(self.colours) < 2 or any(len(c) != 3 or not all(0 <= v <= 1 for v in c) for c in self.colours):
            raise ValueError(f"OutputField {self.name!r}: colours must be two or more RGB triples in 0 ... 1")
        if not 0 < self.linear_share < 1:
            raise ValueError(f"OutputField {self.name!r}: linear_share must be in (0, 1)")

    @property
    def title(self) -> str:
        """The label with its unit, for a colour bar or an axis: ``"curvature κ [1/x]"``."""
        label = self.label or self.name
        return f"{label} [{self.unit}]" if self.unit else label

    def metadata(self) -> dict:
        """What the output folder records of it (summary.json's ``fields``): everything but the expression."""
        return {"name": self.name, "label": self.label, "unit": self.unit, "colours": [list(c) for c in self.colours],
                "scale": self.scale, "linear_share": self.linear_share, "symmetric": self.symmetric or
                self.scale == "symlog", "surface": self.surface, "derived": self.expression is not None}


@dataclass(frozen=True)
class SolverHints:
    """How a model's Newton step is best solved: defaults, never physics; the user's PETSc options win.

    `newton_options`: (name, value) pairs of the PETSc options a scene may give (``(("snes_linesearch_type",
    "l2"),)``), above the schemes' defaults. `linear_options`: ``(dim, ranks, constants) -> pairs`` for the Newton
    step's linear solver on a mesh of dimension `dim` on `ranks` ranks with the model's constants (a dict of
    floats); naming ``ksp_type`` or ``pc_type`` replaces the size rule's choice
    (`timestepping.linear.solver_options`). `setup_bytes_per_node`: the memory a membrane's set-up takes per node
    with this model (mesh, operators, the Newton step's factor), measured; None: the core's estimate for one unknown
    per node (`scene.limits.SETUP_BYTES_PER_NODE`). A run's size is checked against it before the mesh is built.
    """

    newton_options: tuple = ()
    linear_options: Callable | None = None
    setup_bytes_per_node: float | None = None

    def options(self, dim: int, ranks: int, constants: dict) -> dict:
        """The model's defaults for a run: `newton_options`, then `linear_options` on top."""
        options = dict(self.newton_options)
        if self.linear_options is not None:
            options |= dict(self.linear_options(dim, ranks, constants))
        return options


def output_fields(model) -> tuple[OutputField, ...]:
    """The fields a model writes: its declared `outputs`, and for each of its unknowns (`Model.fields`) that none
    of them names, a plain `OutputField` of that name."""
    declared = tuple(getattr(model, "outputs", ()))
    named = {f.name for f in declared}
    plain = tuple(OutputField(name) for name in getattr(model, "fields", ()) if name not in named)
    return plain + declared
