"""`simulate`'s grouped options: which rows a run keeps (`Storage`) and what it writes (`Output`).

`simulate(scene, storage=Storage(max_rows=1000), output=Output("out/ex1", force=True))`. The old flat keywords
(`max_rows`, `gather`, `row_budget`; `output_dir`, `max_frames`, `force`, `pictures`, `progress`) are still
accepted and mapped onto these objects (`grouped`); a keyword together with its object is refused.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..scene import MAX_STORED_BYTES, STORED_ROWS

#: The stored rows may take at most this many bytes on a rank that holds them (rank 0; every rank with
#: gather="all"), else fewer are kept (`budget_steps`). It is the scene loader's limit for a 1D scene's
#: rows (scene.MAX_STORED_BYTES, 2 GB), so that no 1D scene it accepts is thinned; a 2D scene's node
#: count is known only once meshed, so the solver applies it. 2 GB beside a 1e6-node LU factor (3 GB)
#: fits a laptop; 400 rows of 1e6 nodes (10 GB) would not.
ROW_BUDGET = MAX_STORED_BYTES
#: The most XDMF frames (`Output.max_frames`): every stored row (`STORED_ROWS`, 400) and the most output times (1000).
MAX_FRAMES = 100_000


@dataclass(frozen=True)
class Storage:
    """The rows a run keeps (Result, diagnostics.csv, pictures): about `max_rows` time levels, always with 0, T
    and the output times; on rank 0 (`gather` "root") or on every rank ("all"); at most `row_budget` bytes on a
    rank that holds them (above it fewer are kept, with a StorageWarning). Checked when made: a ValueError
    names the option and its allowed values."""

    max_rows: int = STORED_ROWS
    gather: str = "root"
    row_budget: int = ROW_BUDGET

    def __post_init__(self) -> None:
        max_rows, gather, row_budget = self.max_rows, self.gather, self.row_budget
        if isinstance(max_rows, bool) or not isinstance(max_rows, (int, np.integer)) or max_rows < 1:
            raise ValueError(f"max_rows: expected a whole number >= 1 (stored time levels), got {max_rows!r}")
        if gather not in ("root", "all"):
            raise ValueError(f"gather: expected 'root' (rows on rank 0) or 'all' (on every rank), got {gather!r}")
        if isinstance(row_budget, bool) or not isinstance(row_budget, (int, np.integer)) or row_budget < 1:
            raise ValueError(f"row_budget: expected a whole number of bytes >= 1, got {row_budget!r}")


@dataclass(frozen=True)
class Output:
    """What a run writes: with a folder `dir`, solution.xdmf (about `max_frames` of the stored rows, always with
    0, T and the output times), CSV, JSON and PNGs; `force` replaces an existing output folder. `progress`: a
    progress bar on rank 0.

    `pictures`: True draws the default pictures (`plot.picture_names`), False or None none. A function
    ``fn(result, folder)`` draws a picture of your own into the folder *besides* the default ones:
    ``Output("out/run", pictures=my_picture)``. To draw only your own, say so with ``default_pictures=False``:
    ``Output("out/run", pictures=my_picture, default_pictures=False)``.

    How the default pictures are written (`plot.style.Look`): `formats` (``("png",)``; ``("png", "pdf")`` writes
    ``energy.pdf`` beside ``energy.png``, ``"svg"`` too), `style` (``"screen"``, or ``"paper"``: 8-point text for a
    figure 7 inches wide, PNG at 300 dots per inch) and `size` ((width, height) in inches; None: the style's)."""

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
        frames = self.max_frames
        if not (self.pictures in (True, False, None) or callable(self.pictures)):
            raise ValueError(f"pictures: expected True, False or a function (result, folder), got {self.pictures!r}")
        if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or not 1 <= frames <= MAX_FRAMES:
            raise ValueError(f"max_frames: expected a whole number in [1, {MAX_FRAMES}] (XDMF frames), got {frames!r}")
        for name in ("force", "progress", "default_pictures"):  # force="no" is truthy: it would replace a result
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name}: expected True or False, got {getattr(self, name)!r}")  # noqa: TRY004 - exit 2


#: The old keywords of `simulate`, each with its group and its field there.
KEYWORDS = {
    "max_rows": ("storage", "max_rows"),
    "gather": ("storage", "gather"),
    "row_budget": ("storage", "row_budget"),
    "output_dir": ("output", "dir"),
    "max_frames": ("output", "max_frames"),
    "force": ("output", "force"),
    "pictures": ("output", "pictures"),
    "progress": ("output", "progress"),
}


def grouped(storage: Storage | None, output: Output | None, keywords: dict) -> tuple[Storage, Output]:
    """The `Storage` and `Output` of a `simulate` call: the objects given, or the old keywords mapped onto the
    defaults. An unknown keyword is a TypeError, as for any function; a keyword beside its object a ValueError."""
    unknown = [k for k in keywords if k not in KEYWORDS]
    if unknown:
        raise TypeError(f"simulate() got an unexpected keyword argument {unknown[0]!r}")
    given = {"storage": storage, "output": output}
    for key in keywords:
        group, _ = KEYWORDS[key]
        if given[group] is not None:
            raise ValueError(f"{key}: give it in {group}={group.capitalize()}(...) or as a keyword, not both")
    fields = {"storage": {}, "output": {}}
    for key, value in keywords.items():
        group, field = KEYWORDS[key]
        fields[group][field] = value
    storage = storage if storage is not None else Storage(**fields["storage"])
    output = output if output is not None else Output(**fields["output"])
    return storage, output


def picture_function(output: Output):
    """The function that draws `output`'s pictures into a run's folder, or None: the default pictures
    (`plot.run_pictures.write_pictures`, imported when a picture is drawn), the caller's function after them, or the
    caller's alone (``default_pictures=False``)."""
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


__all__ = ["KEYWORDS", "ROW_BUDGET", "Output", "Storage", "grouped", "picture_function"]
