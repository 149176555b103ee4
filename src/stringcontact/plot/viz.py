"""Pictures of a run, and reading an output folder back.

Each picture is drawn by the library made for it: matplotlib (:mod:`stringcontact.plot.charts`) for
``contact_set.png`` and ``velocity_field.png`` (the (x, t) plane as an image) and the line charts
``snapshots.png`` and ``energy.png``; pyvista (:mod:`stringcontact.plot.mesh_pictures`, imported only for it)
for ``space_time.png``, the surface η(x, t) in 3-D coloured by contact.

A 2-D run (a membrane) has its own `MEMBRANE_PICTURES`: ``membrane.png`` (pyvista: the membrane at the
output times), ``contact_area.png`` and ``energy.png`` (matplotlib), and the animation ``membrane.gif``
(:mod:`stringcontact.plot.animation`). Each output field of the run's model (`Result.fields`) has its own
picture, ``NAME.png`` (:func:`stringcontact.plot.fields.field_picture`; ``field_NAME.png`` where ``NAME.png`` is
one of the pictures above). `pictures_of(result)` says which.

:func:`write_pictures` draws them all; given a started :class:`~stringcontact.plot.painter.PictureProcess`,
the pictures of `PAINTED` that the run has are drawn there, so that the libraries' start-up overlaps the
run. ``stringcontact plot DIR`` redraws them from an output folder alone, from the same stored rows
(``rows.npz``, :func:`stringcontact.io.readback.read_output`): the same pictures, pixel for pixel.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..io.signals import signals_held
from .catalogue import (  # noqa: F401 - the names are used as viz.* by the demos and tests
    CHART_PICTURES,
    MEMBRANE_PICTURES,
    MESH_PICTURES,
    PAINTED,
    PICTURES,
    WINDOW_SIZE,
    field_picture_names,
    painted,
    pictures_of,
)
from .charts import (  # noqa: F401 - the pictures and readings are used as viz.* by the demos and tests
    CONTACT_COLOUR,
    contact_area_picture,
    contact_components,
    contact_set_figure,
    contact_set_picture,
    energy_picture,
    obstacle_name,
    parameter_line,
    snapshot_rows,
    snapshots_picture,
    stored_rows_at,
    velocity_clip,
    velocity_picture,
)

# --- all pictures of a run ------------------------------------------------------------------------


def draw(name: str, result, folder, window_size=WINDOW_SIZE) -> Path:
    """Draw the picture `name` (one of PICTURES or MEMBRANE_PICTURES, or an output field's of `result`:
    `field_picture_names`) of `result` into `folder`."""
    path = Path(folder) / name
    field = field_picture_names(result).get(name)
    if field is not None:
        from .fields import field_picture

        return field_picture(result, field, path)
    if name == "membrane.gif" or name in MESH_PICTURES:
        # VTK interrupted inside its import or a render can crash the process (SIGSEGV, "Failed to load
        # vtkCommonMath"): a Ctrl-C or SIGTERM takes effect when the picture is done (about a second)
        with signals_held():
            return _draw_with_vtk(name, result, path, window_size)
    if name == "contact_area.png":
        return contact_area_picture(result, path)
    if name == "contact_set.png":
        return contact_set_picture(result, path, window_size)
    if name == "velocity_field.png":
        return velocity_picture(result, path, window_size)
    return snapshots_picture(result, path) if name == "snapshots.png" else energy_picture(result, path)


def _draw_with_vtk(name: str, result, path: Path, window_size) -> Path:
    if name == "membrane.gif":
        from . import animation  # pyvista and Pillow

        return animation.membrane_animation(result, path, window_size)
    from . import mesh_pictures  # pyvista: 0.5-1 s to import, so only for these

    draw_mesh = mesh_pictures.space_time_picture if name == "space_time.png" else mesh_pictures.membrane_picture
    return draw_mesh(result, path, window_size)


def write_pictures(result, folder, window_size=WINDOW_SIZE, painter=None) -> list[Path]:
    """Write the pictures of `result` (`pictures_of`: 1D or 2D) into `folder`; the function
    `simulate(..., pictures=True)` calls.

    With a started `painter.PictureProcess`, its pictures are drawn there while this process draws the
    others (none, for `stringcontact run`'s painter); whatever it fails to draw is then drawn here. The
    painter is stopped however this ends, so nothing writes into `folder` after it returns.
    """
    folder = Path(folder)
    names = pictures_of(result)
    folder.mkdir(parents=True, exist_ok=True)
    handed_out, drawn = set(), set()
    try:
        if painter is not None and painter.send(result, folder, window_size):
            handed_out = set(painter.names)  # `send` chose them: those of its names that the result has
        for name in names:
            if name not in handed_out:
                draw(name, result, folder, window_size)
        if handed_out:
            painter.wait()
            drawn = set(painter.drawn)  # all of them, unless a painting process failed
    finally:
        if painter is not None:
            painter.cancel()
            for name in handed_out - drawn:  # a picture the process was killed while writing
                for stray in folder.glob(f".{name}.tmp-*"):
                    stray.unlink(missing_ok=True)
    for name in handed_out - drawn:
        draw(name, result, folder, window_size)
    return [folder / name for name in names]


# --- reading an output folder back ---------------------------------------------------------------


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
    return SimpleNamespace(fields=dict.fromkeys(n for n in fields if str(n).isidentifier()) if isinstance(fields, dict) else {})


# --- the `plot` subcommand ----------------------------------------------------------------------


def add_arguments(parser) -> None:
    """`stringcontact plot`'s arguments: the folder, --out, --force and --size."""
    parser.description = (
        f"Redraw the pictures of an output folder ({', '.join(PICTURES)}; of a membrane {', '.join(MEMBRANE_PICTURES)}; "
        "and NAME.png of each output field NAME of the run's model) "
        "from its saved files alone: the stored rows the run drew them from (rows.npz; of an older folder the "
        "frames of solution.xdmf/.h5), diagnostics.csv and summary.json: the same pictures as the run's."
    )
    parser.add_argument("folder", metavar="DIR", help="an output folder written by `stringcontact run --out DIR`")
    parser.add_argument("--out", metavar="DIR", help="write the pictures here instead of into DIR (a new folder)")
    parser.add_argument("--force", action="store_true", help="replace an --out folder of earlier pictures")
    parser.add_argument(
        "--size",
        metavar="WxH",
        default=f"{WINDOW_SIZE[0]}x{WINDOW_SIZE[1]}",
        help=f"pixel size of the space-time and 3-D pictures (default {WINDOW_SIZE[0]}x{WINDOW_SIZE[1]}; membrane.gif: 0.6 of it)",
    )


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' -> (W, H), each in 200..4000."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size: expected WIDTHxHEIGHT such as 1100x900, got {text!r}") from None
    if not (200 <= w <= 4000 and 200 <= h <= 4000):
        raise ValueError(f"--size: width and height must be in 200..4000 pixels, got {text!r}")
    return w, h


def _check_not_the_data(folder: Path, out: Path) -> None:
    """Refuse an --out that is the folder being plotted or contains it: replacing it would delete the data."""
    data, target = folder.resolve(), out.resolve()
    if target.name and (target == data or target in data.parents):  # the root folder: check_target's refusal
        raise ValueError(f"--out {out}: is the folder being plotted ({folder}) or contains it, whose data replacing it "
                         "would delete; choose another folder (or leave out --out to redraw the pictures in place)")


def _launched_rank() -> int:
    """This process's rank when a launcher (mpirun) started several; 0 otherwise. Read from the launcher's
    environment: `plot` needs no MPI, and a picture process must not wait for it."""
    for name in ("OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"):
        value = os.environ.get(name, "").strip()
        if value.isdigit():
            return int(value)
    return 0


def command(args) -> int:
    """`stringcontact plot DIR`: every picture of the run in DIR (its output fields' too) drawn again from its
    files, into DIR or a new --out folder; 0 when done."""
    from ..io.readback import read_output

    size = parse_size(args.size)
    if _launched_rank() > 0:  # `mpirun -n 2 stringcontact plot`: one process draws, the others would race it
        return 0
    if args.out is None:  # into the run's own folder, each picture replaced whole (atomic_path)
        for path in write_pictures(read_output(args.folder), Path(args.folder), window_size=size):
            print(f"wrote {path}")
        return 0
    from ..io.publish import staged_folder
    from ..io.target import check_target

    out = Path(args.out)
    _check_not_the_data(Path(args.folder), out)
    check_target(out, args.force, command="plot")  # the rules of `run --out`: not /, not ., never a run's result
    result = read_output(args.folder)
    with staged_folder(out, args.force, command="plot") as partial:  # the whole folder or nothing
        names = [p.name for p in write_pictures(result, partial, window_size=size)]
        (partial / "pictures.json").write_text(json.dumps({"pictures": names, "of": str(args.folder)}, indent=1) + "\n")
    for name in names:
        print(f"wrote {out / name}")
    return 0
