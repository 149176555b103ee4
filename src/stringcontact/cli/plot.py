"""`stringcontact plot DIR`: every picture of a run drawn again from its output folder alone
(`plot.run_pictures.write_pictures` on `io.readback.read_output`), into DIR under DIR's lock (the one a run writing
there holds: each refuses the other, naming it), or into a new `--out` folder."""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..plot.picture_names import MEMBRANE_PICTURES, PICTURES, WINDOW_SIZE
from ..plot.run_pictures import write_pictures


def add_arguments(parser) -> None:
    """`stringcontact plot`'s arguments: the folder, --out, --force and --size."""
    parser.description = (
        f"Redraw the pictures of an output folder ({', '.join(PICTURES)}; of a membrane {', '.join(MEMBRANE_PICTURES)}; "
        "and NAME.png of each output field NAME of the run's model) from its saved files alone: the stored rows the "
        "run drew them from (rows.npz), diagnostics.csv and summary.json: the same pictures as the run's."
    )
    parser.add_argument("folder", metavar="DIR", help="an output folder written by `stringcontact run --out DIR`")
    parser.add_argument("--out", metavar="DIR", help="write the pictures here instead of into DIR (a new folder)")
    parser.add_argument("--force", action="store_true", help="replace an --out folder of earlier pictures")
    parser.add_argument("--size", metavar="WxH", default=f"{WINDOW_SIZE[0]}x{WINDOW_SIZE[1]}",
                        help=f"pixel size of the space-time and 3-D pictures (default {WINDOW_SIZE[0]}x{WINDOW_SIZE[1]}; "
                             "membrane.gif: 0.6 of it)")


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' -> (W, H), each in 200..4000."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size: expected WIDTHxHEIGHT such as 1100x900, got {text!r}") from None
    if not (200 <= w <= 4000 and 200 <= h <= 4000):
        raise ValueError(f"--size: width and height must be in 200..4000 pixels, got {text!r}")
    return w, h


def command(args) -> int:
    """`stringcontact plot DIR`: the pictures drawn into DIR (each replaced whole, `atomic_path`) or a new --out
    folder (the whole folder or nothing, by the rules of `run --out`); 0 when done."""
    from ..errors import OutputError
    from ..io.disk import describe_os_error
    from ..io.lock import TargetLock
    from ..io.publish import staged_folder
    from ..io.readback import read_output
    from ..io.target import check_target

    size, folder = parse_size(args.size), Path(args.folder)
    launched = (os.environ.get(v, "").strip() for v in ("OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"))
    if any(rank.isdigit() and int(rank) > 0 for rank in launched):  # `mpirun -n 2 stringcontact plot`: one draws
        return 0
    if args.out is None:
        lock = None
        if folder.is_dir():  # (not a folder: read_output says what it is)
            try:
                lock = TargetLock(folder, "plot", label=str(folder))
            except OSError as exc:
                raise OutputError(f"{folder}: cannot take its lock to draw in it: "
                                  f"{describe_os_error(exc, folder.resolve().parent)}") from None
        try:
            for path in write_pictures(read_output(folder), folder, window_size=size):
                print(f"wrote {path}")
        finally:
            if lock is not None:
                lock.release()
        return 0
    out = Path(args.out)
    if out.resolve().name and (out.resolve() == folder.resolve() or out.resolve() in folder.resolve().parents):
        raise ValueError(f"--out {out}: is the folder being plotted ({folder}) or contains it, whose data replacing it "
                         "would delete; choose another folder (or leave out --out to redraw the pictures in place)")
    check_target(out, args.force, command="plot")  # the rules of `run --out`: not /, not ., never a run's result
    result = read_output(folder)
    with staged_folder(out, args.force, command="plot") as partial:
        names = [p.name for p in write_pictures(result, partial, window_size=size)]
        (partial / "pictures.json").write_text(json.dumps({"pictures": names, "of": str(args.folder)}, indent=1) + "\n")
    print("".join(f"wrote {out / name}\n" for name in names), end="")
    return 0
