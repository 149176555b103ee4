"""`stringcontact plot DIR`: every picture of a run drawn again from its output folder alone
(`plot.run_pictures.write_pictures` on `io.readback.read_output`), into DIR or a new `--out` folder.

Into DIR, it holds DIR's lock (`io.lock.TargetLock`, the one a run writing there holds) while it reads and draws:
a `run --out DIR --force` meanwhile is refused naming `plot` and its pid, and `plot` refuses a folder a run is
writing."""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

from ..plot.picture_names import MEMBRANE_PICTURES, PICTURES
from ..plot.run_pictures import write_pictures
from ..plot.style import FORMATS, LARGEST, SMALLEST, STYLES, Look


def add_arguments(parser) -> None:
    """`stringcontact plot`'s arguments: the folder, --out, --force, --format, --style and --size."""
    parser.description = (
        f"Redraw the pictures of an output folder ({', '.join(PICTURES)}; of a membrane {', '.join(MEMBRANE_PICTURES)}; "
        "and NAME.png of each output field NAME of the run's model) "
        "from its saved files alone: the stored rows the run drew them from (rows.npz; of an older folder the "
        "frames of solution.xdmf/.h5), diagnostics.csv and summary.json: the same pictures as the run's; "
        "as PDF or SVG for a paper (--format pdf --style paper)."
    )
    parser.add_argument("folder", metavar="DIR", help="an output folder written by `stringcontact run --out DIR`")
    parser.add_argument("--out", metavar="DIR", help="write the pictures here instead of into DIR (a new folder)")
    parser.add_argument("--force", action="store_true", help="replace an --out folder of earlier pictures")
    parser.add_argument("--format", metavar="FORMATS", default="png",
                        help=f"the files each picture is written as: {', '.join(FORMATS)}, or several joined by commas "
                             "(png,pdf); membrane.gif only with png (default png)")
    parser.add_argument("--style", choices=tuple(STYLES), default="screen",
                        help="the pictures' style sheet: screen (the run's pictures), or paper (8-point text for a "
                             "figure 7 inches wide, PNG at 300 dots per inch; no caption line)")
    parser.add_argument("--size", metavar="WxH",
                        help="the size of the space-time and 3-D pictures, and the width of the others: pixels at the "
                             "style's resolution (1100x900 on a screen, the default), or inches (3.4x2.8in) or "
                             "centimetres (17x12cm); membrane.gif: 0.6 of it on a screen")


def parse_formats(text: str) -> tuple[str, ...]:
    """'png,pdf' -> ("png", "pdf"): each one of `style.FORMATS`."""
    formats = tuple(f.strip().lower() for f in text.split(","))
    if not all(f in FORMATS for f in formats):
        raise ValueError(f"--format: expected {', '.join(FORMATS)} or several joined by commas, got {text!r}")
    return formats


def parse_size(text: str, dpi: float = 100.0) -> tuple[float, float]:
    """'WxH' (pixels at `dpi` per inch, each in 200..4000), 'WxHin' (inches) or 'WxHcm' -> (width, height) in inches,
    each in the range `style.Look` takes."""
    unit = next((u for u in ("in", "cm") if text.lower().endswith(u)), "")
    try:
        w, h = (float(v) if unit else int(v) for v in text.lower().removesuffix(unit).split("x"))
    except ValueError:
        raise ValueError(f"--size: expected WIDTHxHEIGHT such as 1100x900 (pixels), 3.4x2.8in or 17x12cm, got {text!r}") from None
    if not unit and not (200 <= w <= 4000 and 200 <= h <= 4000):
        raise ValueError(f"--size: width and height must be in 200..4000 pixels, got {text!r}")
    inches = (w / dpi, h / dpi) if not unit else (w, h) if unit == "in" else (w / 2.54, h / 2.54)
    if not all(SMALLEST <= v <= LARGEST for v in inches):
        raise ValueError(f"--size: width and height must be in {SMALLEST:g}..{LARGEST:g} inches, got {text!r}")
    return inches


def look_of(args) -> Look | None:
    """The `style.Look` of `stringcontact plot`'s --format, --style and --size; None for the run's own pictures."""
    if args.format == "png" and args.style == "screen" and args.size is None:
        return None
    look = Look(parse_formats(args.format), args.style)
    return look if args.size is None else Look(look.formats, look.style, parse_size(args.size, look.dpi))


def _check_not_the_data(folder: Path, out: Path) -> None:
    """Refuse an --out that is the folder being plotted or contains it: replacing it would delete the data."""
    data, target = folder.resolve(), out.resolve()
    if target.name and (target == data or target in data.parents):  # the root folder: check_target's refusal
        raise ValueError(f"--out {out}: is the folder being plotted ({folder}) or contains it, whose data replacing it "
                         "would delete; choose another folder (or leave out --out to redraw the pictures in place)")


@contextlib.contextmanager
def _redrawing(folder: Path):
    """Hold the lock of the run folder `folder` while its pictures are drawn in place (nothing to hold if it is no
    folder: `read_output` then says what it is)."""
    if not folder.is_dir():
        yield
        return
    from ..errors import OutputError
    from ..io.disk import describe_os_error
    from ..io.lock import TargetLock

    try:
        lock = TargetLock(folder, "plot", label=str(folder))
    except OSError as exc:
        raise OutputError(f"{folder}: cannot take its lock to draw in it: "
                          f"{describe_os_error(exc, folder.resolve().parent)}") from None
    try:
        yield
    finally:
        lock.release()


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

    look = look_of(args)
    if _launched_rank() > 0:  # `mpirun -n 2 stringcontact plot`: one process draws, the others would race it
        return 0
    if args.out is None:  # into the run's own folder, under its lock, each picture replaced whole (atomic_path)
        with _redrawing(Path(args.folder)):
            for path in write_pictures(read_output(args.folder), Path(args.folder), look=look):
                print(f"wrote {path}")
        return 0
    from ..io.publish import staged_folder
    from ..io.target import check_target

    out = Path(args.out)
    _check_not_the_data(Path(args.folder), out)
    check_target(out, args.force, command="plot")  # the rules of `run --out`: not /, not ., never a run's result
    result = read_output(args.folder)
    with staged_folder(out, args.force, command="plot") as partial:  # the whole folder or nothing
        names = [p.name for p in write_pictures(result, partial, look=look)]
        (partial / "pictures.json").write_text(json.dumps({"pictures": names, "of": str(args.folder)}, indent=1) + "\n")
    for name in names:
        print(f"wrote {out / name}")
    return 0
