"""CPU time and size of each picture's PNG at several zlib levels, the pixels unchanged (Pillow).

Reads the pictures of an output folder (default: a fresh `stringcontact run example1`), decodes each, and
writes it again at each level, `--repeats` times (the fastest kept); prints a table. The pixels are the
same at every level: each encoding is decoded again and compared with the original.

    .venv/bin/python benchmarks/bench_png.py [FOLDER]
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

LEVELS = (6, 3, 1)


def encode(image: Image.Image, level: int, repeats: int) -> tuple[float, int]:
    """(fastest CPU seconds, bytes) of writing `image` as PNG at zlib `level`; checks the pixels survive."""
    best, data = float("inf"), b""
    for _ in range(repeats):
        buffer = io.BytesIO()
        c0 = time.process_time()
        image.save(buffer, format="PNG", compress_level=level)
        best = min(best, time.process_time() - c0)
        data = buffer.getvalue()
    again = np.asarray(Image.open(io.BytesIO(data)))
    if not np.array_equal(again, np.asarray(image)):
        raise SystemExit(f"level {level}: the pixels changed")
    return best, len(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", type=Path)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.folder
        if folder is None:
            folder = Path(tmp) / "example1"
            subprocess.run([sys.executable, "-m", "stringcontact", "run", "example1", "--out", str(folder)], check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        print("| picture | " + " | ".join(f"level {lv}: ms, KB" for lv in LEVELS) + " |")
        print("|---|" + "---:|" * len(LEVELS))
        totals = dict.fromkeys(LEVELS, 0.0)
        for path in sorted(folder.glob("*.png")):
            image = Image.open(path)
            image.load()
            cells = []
            for level in LEVELS:
                cpu, size = encode(image, level, args.repeats)
                totals[level] += cpu
                cells.append(f"{1e3 * cpu:.1f}, {size / 1024:.0f}")
            print(f"| {path.name} | " + " | ".join(cells) + " |")
        print("| all | " + " | ".join(f"{1e3 * totals[lv]:.0f} ms" for lv in LEVELS) + " |")


if __name__ == "__main__":
    main()
