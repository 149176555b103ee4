"""Pictures drawn in a second process, started before a run so that the libraries' start-up overlaps it.

Importing pyvista and VTK, creating the EGL context and compiling llvmpipe's shaders take about 1.2 s
of CPU before the first picture, importing matplotlib about 0.4 s (benchmarks/bench_pictures.py). `stringcontact run
--out` starts a `PictureProcess` first thing, before the scene (1D or 2D) is known; it does that start-up
while the run imports dolfinx and solves, then draws those of `viz.PAINTED` that the run has (`viz.painted`:
the space-time pictures of a string, ``membrane.png`` and ``membrane.gif`` of a membrane) while the run
draws the line charts. The process never imports dolfinx.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import pickle
import selectors
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from .viz import MESH_PICTURES, PAINTED, WINDOW_SIZE, painted


class PictureProcess:
    """Some pictures (`names`) drawn in a second Python process.

    `start(names)` launches it; it draws a tiny warm-up picture, then waits. `send(result, folder)` hands it
    the Result and the names it is to draw, those of `names` that the result has (`viz.painted`), as a
    pickle in a private temporary folder (a file, not a pipe: writing to a pipe whose reader died raises
    SIGPIPE, which PETSc turns into an abort), and sets `names` to them; `wait()` returns True once those
    pictures are written. `cancel()` stops it. Any failure makes `send`/`wait` return False, and `error`
    says why if it can.
    """

    TIMEOUT = 300.0  # seconds to draw; a picture takes 0.2-2 s

    def __init__(self, proc: subprocess.Popen, folder: str, names: tuple[str, ...]):
        self.proc = proc
        self.folder = folder  # the private temporary folder that receives the payload
        self.names = names
        self.error = ""

    @classmethod
    def start(cls, names=PAINTED) -> PictureProcess | None:
        env = dict(os.environ)
        env.setdefault("LP_NUM_THREADS", "1")  # Mesa's software renderer: leave the other core to the run
        folder = tempfile.mkdtemp(prefix="stringcontact-pictures-")
        code = "from stringcontact.plot.painter import main; main()"
        try:
            proc = subprocess.Popen(
                [sys.executable, "-c", code, folder, ",".join(names), str(os.getpid())],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,  # VTK's own warnings; failures come back on stdout
                env=env,
                start_new_session=True,  # Ctrl-C reaches the run, which then stops this process
            )
        except OSError:
            os.rmdir(folder)
            return None
        return cls(proc, folder, tuple(names))

    def send(self, result, folder, window_size=WINDOW_SIZE) -> bool:
        if self.folder is None or self.proc.poll() is not None:
            self.cancel()
            return False
        names = painted(result, self.names)
        if not names:  # none of its pictures is a picture of this run
            self.cancel()
            return False
        payload = Path(self.folder) / "payload.pickle"
        result = dataclasses.replace(result, contact_force=np.empty((0, 0)))  # no picture shows it: less to pickle
        try:
            with open(payload.with_suffix(".part"), "wb") as f:
                pickle.dump((result, str(folder), tuple(window_size), names), f, protocol=pickle.HIGHEST_PROTOCOL)
            self.names = names
            os.replace(payload.with_suffix(".part"), payload)  # the process only ever sees a whole file
            return True
        except (OSError, pickle.PicklingError, TypeError, AttributeError):
            self.cancel()
            return False

    def wait(self) -> bool:
        """True once the process reports its pictures written (its own exit is not waited for)."""
        reply = {}
        try:
            with selectors.DefaultSelector() as sel:
                sel.register(self.proc.stdout, selectors.EVENT_READ)
                if sel.select(timeout=self.TIMEOUT):
                    reply = json.loads(self.proc.stdout.readline().decode() or "{}")
        except (ValueError, OSError):
            reply = {}
        finally:
            self.cancel()
        self.error = "" if reply.get("ok") else str(reply.get("error", "no reply"))
        return bool(reply.get("ok"))

    def cancel(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout is not None and not self.proc.stdout.closed:
            self.proc.stdout.close()
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)
            self.folder = None


def main() -> None:
    """The body of `PictureProcess`: warm up (for the names it was started with), wait for the payload, draw
    the names the payload gives, report on stdout."""
    import time

    from . import charts, mesh_pictures, viz

    folder, names, parent = Path(sys.argv[1]), tuple(sys.argv[2].split(",")), int(sys.argv[3])
    answer = os.fdopen(os.dup(1), "w")  # the reply's own channel: anything VTK prints goes to stderr instead
    os.dup2(2, 1)
    reply = {"ok": False}
    try:
        if set(names) & set(MESH_PICTURES):
            mesh_pictures.warm_up()
        if set(names) - set(MESH_PICTURES):
            charts.warm_up()
        if "membrane.gif" in names:
            from . import animation  # noqa: F401 - imports Pillow before the payload comes
        payload = folder / "payload.pickle"
        while not payload.exists():
            if os.getppid() != parent or not folder.is_dir():  # the run ended (even before we started) or cancelled us
                shutil.rmtree(folder, ignore_errors=True)
                return
            time.sleep(0.005)
        with open(payload, "rb") as f:
            result, out, window_size, names = pickle.load(f)
        payload.unlink()  # read: no large file left behind even if the run is killed now
        for name in names:
            viz.draw(name, result, out, window_size)
        reply = {"ok": True}
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which then draws the pictures itself
        reply = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
    finally:
        with contextlib.suppress(OSError):
            answer.write(json.dumps(reply) + "\n")
            answer.flush()
    os._exit(0)  # the pictures are on disk; tearing down VTK and the EGL context would only cost time
