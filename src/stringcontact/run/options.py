"""`simulate`'s options: which rows a run keeps (`Storage`) and what it writes (`Output`), as in
``simulate(scene, storage=Storage(max_rows=1000), output=Output("out/ex1", force=True))``."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..scene import MAX_STORED_BYTES, STORED_ROWS

#: The most bytes of stored rows on a rank that holds them, else fewer are kept (`budget_steps`): the scene loader's
#: limit for a 1D scene (2 GB: beside a 1e6-node LU factor, 3 GB, it fits a laptop; 400 rows of 1e6 nodes would not).
ROW_BUDGET = MAX_STORED_BYTES
#: The most XDMF frames (`Output.max_frames`): every stored row (`STORED_ROWS`, 400) and the most output times (1000).
MAX_FRAMES = 100_000


@dataclass(frozen=True)
class Storage:
    """The rows a run keeps (Result, diagnostics.csv, pictures): about `max_rows` time levels, always with 0, T and
    the output times, on rank 0 (`gather` "root") or every rank ("all"), at most `row_budget` bytes on a rank (else
    fewer, with a StorageWarning). A bad value: ValueError naming the option and its allowed values."""

    max_rows: int = STORED_ROWS
    gather: str = "root"
    row_budget: int = ROW_BUDGET

    def __post_init__(self) -> None:
        if not _whole(self.max_rows, 1):
            raise ValueError(f"max_rows: expected a whole number >= 1 (stored time levels), got {self.max_rows!r}")
        if self.gather not in ("root", "all"):
            raise ValueError(f"gather: expected 'root' (rows on rank 0) or 'all' (on every rank), got {self.gather!r}")
        if not _whole(self.row_budget, 1):
            raise ValueError(f"row_budget: expected a whole number of bytes >= 1, got {self.row_budget!r}")


def _whole(value, low: int, high: float = float("inf")) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and low <= value <= high


@dataclass(frozen=True)
class Output:
    """What a run writes: with a folder `dir`, solution.xdmf (about `max_frames` of the stored rows, always with
    0, T and the output times), CSV, JSON and PNGs; `force` replaces an existing output folder; `progress`: a
    progress bar on rank 0.

    `pictures`: True draws the default pictures (`plot.run_pictures`), False or None none, a function
    ``fn(result, folder)`` yours besides them (alone with ``default_pictures=False``). Their look
    (`plot.style.Look`): `formats` (``("png", "pdf")`` writes ``energy.pdf`` beside ``energy.png``; ``"svg"``),
    `style` (``"screen"``, or ``"paper"``: 8-point text for a figure 7 inches wide, PNG at 300 dots per inch) and
    `size` ((width, height) in inches; None: the style's)."""

    dir: str | os.PathLike | None = None
    max_frames: int = 100
    force: bool = False
    pictures: bool | Callable | None = True
    progress: bool = False
    default_pictures: bool = True
    formats: tuple = ("png",)
    style: str = "screen"
    size: tuple | None = None

    def __post_init__(self) -> None:
        from ..plot.style import Look

        object.__setattr__(self, "formats", Look(self.formats, self.style, self.size).formats)  # checked: ValueError
        if not (self.pictures in (True, False, None) or callable(self.pictures)):
            raise ValueError(f"pictures: expected True, False or a function (result, folder), got {self.pictures!r}")
        if not _whole(self.max_frames, 1, MAX_FRAMES):
            raise ValueError(f"max_frames: expected a whole number in [1, {MAX_FRAMES}] (XDMF frames), got "
                             f"{self.max_frames!r}")
        for name in ("force", "progress", "default_pictures"):  # force="no" is truthy: it would replace a result
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name}: expected True or False, got {getattr(self, name)!r}")  # noqa: TRY004 - exit 2


def picture_function(output: Output):
    """The function (result, folder) that draws `output`'s pictures, or None: the default ones, then the caller's."""
    own = output.pictures if callable(output.pictures) else None
    defaults = output.pictures is True or (own is not None and output.default_pictures)
    if not defaults:
        return own

    def draw(result, folder):
        from ..plot.run_pictures import write_pictures  # matplotlib and pyvista load when a picture is drawn
        from ..plot.style import Look

        written = write_pictures(result, folder, look=Look(output.formats, output.style, output.size))
        if own is not None:
            own(result, folder)
        return written

    return draw


__all__ = ["ROW_BUDGET", "Output", "Storage", "picture_function"]
