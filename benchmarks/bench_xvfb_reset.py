"""How often pvpython under xvfb-run aborts with "bad X server connection", with and without Xvfb's -noreset.

pvpython starts MPI, and hwloc's GL probe (in pvpython and in its orted) opens and closes every X display it
finds. When that was the server's last client, Xvfb resets; a connection arriving during the reset is
dropped, and VTK aborts. The test harness (tests/system/test_paraview.py) and the README's recipe pass
-noreset. This counts the aborts of a minimal render, `--together` runs at once, `--rounds` times, for each
server setting; `--load N` keeps N busy loops running (a busy CI machine).

    .venv/bin/python benchmarks/bench_xvfb_reset.py --together 8 --rounds 3
    .venv/bin/python benchmarks/bench_xvfb_reset.py --together 1 --rounds 12 --load 2
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

RENDER = "from paraview.simple import *\nCreateRenderView()\nRender()\n"
SETTINGS = {"default": "-screen 0 1280x1024x24", "-noreset": "-screen 0 1280x1024x24 -noreset"}


def aborts(script: Path, server_args: str, together: int) -> int:
    """How many of `together` simultaneous `xvfb-run -a pvpython script` runs end with VTK's abort."""
    runs = [subprocess.Popen(["xvfb-run", "-a", "-s", server_args, "pvpython", str(script)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True) for _ in range(together)]
    return sum("bad X server connection" in run.communicate()[1] for run in runs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--together", type=int, default=8, help="runs started at once (default 8)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds per setting (default 3)")
    parser.add_argument("--load", type=int, default=0, help="busy loops beside the runs (default 0)")
    args = parser.parse_args(argv)
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.load)]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            script = Path(tmp) / "render.py"
            script.write_text(RENDER)
            total = args.together * args.rounds
            for name, server_args in SETTINGS.items():
                failed = sum(aborts(script, server_args, args.together) for _ in range(args.rounds))
                print(f"{name:>9}: {failed} of {total} runs aborted ({args.together} at once, load {args.load})")
    finally:
        for loop in busy:
            loop.kill()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
