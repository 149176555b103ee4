"""`stringcontact plot DIR`: a run's pictures drawn again from its output folder alone, into DIR under its lock (a
run writing there and this refuse each other) or into a new `--out` folder."""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

from ..plot.run_pictures import MEMBRANE_PICTURES, PICTURES, write_pictures
from ..plot.style import FORMATS, LARGEST, SMALLEST, STYLES, Look


def add_arguments(parser) -> None:
    """`stringcontact plot`'s arguments: the folder, --out, --force, --format, --style and --size."""
    parser.description = (
        f"Redraw the pictures of an output folder ({', '.join(PICTURES)}; of a membrane {', '.join(MEMBRANE_PICTURES)}; "
        "and NAME.png of each output field NAME of the run's model) from its saved files alone: the stored rows the "
        "run drew them from (rows.npz), diagnostics.csv and summary.json: the same pictures as the run's; as PDF or "
        "SVG for a paper (--format pdf --style paper).")
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


def command(args) -> int:
    """`stringcontact plot DIR`: the pictures drawn into DIR (each replaced whole) or a new --out folder (whole or
    nothing, by the rules of `run --out`); 0 when done."""
    from ..errors import OutputError
    from ..io.publish import TargetLock, check_target, describe_os_error, staged_folder
    from ..io.readback import read_output

    look, folder = look_of(args), Path(args.folder)
    launched = (os.environ.get(v, "").strip() for v in ("OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"))
    if any(rank.isdigit() and int(rank) > 0 for rank in launched):  # `mpirun -n 2 stringcontact plot`: one draws
        return 0
    if args.out is None:
        with contextlib.ExitStack() as held:  # its lock, released however the drawing ends
            if folder.is_dir():  # (not a folder: read_output says what it is)
                try:
                    held.callback(TargetLock(folder, "plot", label=str(folder)).release)
                except OSError as exc:
                    raise OutputError(f"{folder}: cannot take its lock to draw in it: "
                                      f"{describe_os_error(exc, folder.resolve().parent)}") from None
            for path in write_pictures(read_output(folder), folder, look=look):
                print(f"wrote {path}")
        return 0
    out = Path(args.out)
    if out.resolve().name and (out.resolve() == folder.resolve() or out.resolve() in folder.resolve().parents):
        raise ValueError(f"--out {out}: is the folder being plotted ({folder}) or contains it, whose data replacing it "
                         "would delete; choose another folder (or leave out --out to redraw the pictures in place)")
    check_target(out, args.force, command="plot")  # the rules of `run --out`: not /, not ., never a run's result
    result = read_output(folder)
    with staged_folder(out, args.force, command="plot") as partial:
        names = [p.name for p in write_pictures(result, partial, look=look)]
        (partial / "pictures.json").write_text(json.dumps({"pictures": names, "of": str(args.folder)}, indent=1) + "\n")
    print("".join(f"wrote {out / name}\n" for name in names), end="")
    return 0
