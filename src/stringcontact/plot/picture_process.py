"""Pictures drawn in two processes started before a run, so that the libraries' start-up overlaps it and the
pictures use both cores while the run waits.

Importing pyvista and VTK, creating the EGL context and compiling llvmpipe's shaders take 0.5-0.8 s of CPU
before the first picture, importing matplotlib and drawing its first figure 0.3-0.4 s
(benchmarks/bench_pictures.py). `stringcontact run --out` starts a `PictureProcess` first thing, before the
scene (1D or 2D) is known. The process (the *painter*) warms matplotlib up, forks a *helper* that inherits
that warm matplotlib (no second start-up), then warms pyvista up; both wait for the run's rows. The run then
hands them every picture it has (`picture_names.painted`) and imports no plotting library at all: the painter draws
the pyvista pictures (only it has pyvista), and both take the matplotlib pictures one at a time, the
costliest first, so that the two cores finish together. Neither process imports dolfinx.
"""

from __future__ import annotations

import contextlib
import gc
import json
import os
import pickle
import selectors
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from .picture_names import MESH_PICTURES, PAINTED, WINDOW_SIZE, painted

#: the order in which the processes take the pictures: costliest first (benchmarks/bench_pictures.py), so that
#: the last picture taken is a short one and both cores finish at about the same time
BY_COST = ("membrane.gif", "space_time.png", "membrane.png", "energy.png", "snapshots.png", "contact_set.png",
           "contact_area.png", "velocity_field.png")


class PictureProcess:
    """Some pictures (`names`) drawn in a second Python process and its helper.

    `start(names)` launches it; it warms up, then waits. `send(result, folder)` hands it those of `names`
    that the result has (`picture_names.painted`), the Result written into a private temporary folder (files, not a
    pipe: writing to a pipe whose reader died raises SIGPIPE, which PETSc turns into an abort), and sets
    `names` to them; `wait()` returns True once they are all written, and sets `drawn` to those that were.
    `cancel()` stops both processes. Any failure makes `send`/`wait` return False, and `error` says why if it can.
    """

    TIMEOUT = 300.0  # seconds to draw; a picture takes 0.1-2 s

    def __init__(self, proc: subprocess.Popen, folder: str, names: tuple[str, ...]):
        self.proc = proc
        self.folder = folder  # the private temporary folder that receives the payload
        self.names = names
        self.drawn: tuple[str, ...] = ()
        self.error = ""

    @classmethod
    def start(cls, names=PAINTED) -> PictureProcess | None:
        env = dict(os.environ)
        env.setdefault("LP_NUM_THREADS", "1")  # Mesa's software renderer: one thread, the helper has the other core
        env.setdefault("OPENBLAS_NUM_THREADS", "1")  # no BLAS threads: nothing to draw needs them, and the fork copies none
        # pyvista's own switch: its first Plotter then skips its check for a display (`xset -q`, else an extra
        # render window), which an off-screen EGL picture does not need: the warm-up's first picture 0.254 against
        # 0.283 CPU-s (medians of 10)
        env.setdefault("ALLOW_PLOTTING", "true")
        folder = tempfile.mkdtemp(prefix="stringcontact-pictures-")
        code = "from stringcontact.plot.picture_process import main; main()"
        try:
            proc = subprocess.Popen(
                # -P: no current folder on sys.path (`-c` would put it first, and a pyvista.py or stringcontact.py
                # there would be imported); PYTHONPATH, which may be how the package is found, still holds
                [sys.executable, "-P", "-c", code, folder, ",".join(names), str(os.getpid())],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,  # VTK's own warnings; failures come back on stdout
                env=env,
                start_new_session=True,  # Ctrl-C reaches the run, which then stops this process; its own process group
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
        from .handover import write_payload  # NumPy: loaded by the run long before it sends

        try:
            write_payload(Path(self.folder), result, (str(folder), tuple(window_size), names))
            self.names = names
            return True
        except (OSError, pickle.PicklingError, TypeError, AttributeError, ValueError):
            self.cancel()
            return False

    def wait(self) -> bool:
        """True once the processes report all their pictures written (their own exit is not waited for)."""
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
        self.drawn = tuple(name for name in reply.get("drawn", ()) if name in self.names)
        ok = bool(reply.get("ok")) and set(self.drawn) == set(self.names)
        self.error = "" if ok else str(reply.get("error") or "no reply")
        return ok

    def cancel(self) -> None:
        """Stop the painter and its helper; once this returns, neither writes anything any more."""
        if self.proc.returncode is None:  # not reaped: its pid is still its process group's, no one else's
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        if self.proc.stdout is not None and not self.proc.stdout.closed:
            _until_closed(self.proc.stdout, self.TIMEOUT)  # the helper holds it open until it is gone too
            self.proc.stdout.close()
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)
            self.folder = None


def _until_closed(pipe, timeout: float) -> None:
    """Read `pipe` until every process holding its other end has exited (end of file)."""
    with contextlib.suppress(OSError, ValueError), selectors.DefaultSelector() as sel:
        sel.register(pipe, selectors.EVENT_READ)
        while sel.select(timeout=timeout) and os.read(pipe.fileno(), 65536):
            pass


# --- the painter process and its helper -----------------------------------------------------------


def draw_claimed(result, job: tuple, folder: Path, can_draw) -> list[str]:
    """Draw, costliest first, each picture of `job` that `can_draw` and that no other process took first
    (a claim is a file created with O_EXCL: exactly one process gets it). Returns the names drawn."""
    from . import run_pictures

    out, window_size, names = job
    drawn = []
    for name in sorted(names, key=lambda n: BY_COST.index(n) if n in BY_COST else len(BY_COST)):
        if not can_draw(name):
            continue
        try:
            os.close(os.open(folder / f"{name}.claim", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            continue
        run_pictures.draw(name, result, out, window_size)
        drawn.append(name)
    return drawn


def _fork_helper(folder: Path) -> tuple[int, int]:
    """Fork the helper: it inherits this process's warm matplotlib, draws matplotlib pictures only, and
    writes the names it drew as one JSON line to the pipe whose read end is returned (with its pid)."""
    from .handover import await_payload

    read, write = os.pipe()
    painter = os.getpid()
    pid = os.fork()
    if pid:
        os.close(write)
        return pid, read
    os.close(read)
    reply = {"drawn": []}
    try:
        job = await_payload(folder, painter)
        if job is not None:
            reply["drawn"] = draw_claimed(*job, folder, lambda name: name not in MESH_PICTURES)
    except Exception as exc:  # noqa: BLE001 - reported through the painter; the run draws what is missing
        reply["error"] = f"{type(exc).__name__}: {exc}"
    finally:
        with contextlib.suppress(OSError):
            os.write(write, (json.dumps(reply) + "\n").encode())
        os._exit(0)


def _helper_reply(helper) -> dict:
    """The helper's reply (empty if it died), once it has exited."""
    if helper is None:
        return {}
    pid, read = helper
    with os.fdopen(read, "rb") as pipe:
        text = pipe.read().decode()
    os.waitpid(pid, 0)
    try:
        return json.loads(text or "{}")
    except ValueError:
        return {}


def _watch(folder: Path, parent: int) -> None:
    """A thread of the painter: once the run is gone, remove the payload and stop drawing (painter and helper)."""
    while os.getppid() == parent:
        time.sleep(0.05)
    shutil.rmtree(folder, ignore_errors=True)
    if os.getpgid(0) == os.getpid():  # our own process group (PictureProcess.start): the painter and its helper
        os.killpg(0, signal.SIGKILL)
    os._exit(1)


def main() -> None:
    """The body of `PictureProcess`: warm up (for the names it was started with), fork the helper, wait for
    the payload, draw with the helper the names the payload gives, report on stdout."""
    from . import charts, mesh_pictures
    from .handover import await_payload

    # No cyclic collector in these two short-lived processes: importing the libraries sets off 372 collections,
    # drawing more. CPU medians, on against off (benchmarks/bench_pictures.py --gc --repeats 12): the warm-ups
    # 0.730 against 0.655 s (fresh processes), Example 1's five pictures 0.940 against 0.915 s; no growth of
    # the resident memory. Nor does a collection in the forked helper write to the pages it shares.
    gc.disable()
    folder, names, parent = Path(sys.argv[1]), tuple(sys.argv[2].split(",")), int(sys.argv[3])
    answer = os.fdopen(os.dup(1), "w")  # the reply's own channel: anything VTK prints goes to stderr instead
    os.dup2(2, 1)
    reply, helper, drawn = {"ok": False}, None, []
    try:
        if set(names) - set(MESH_PICTURES):
            charts.warm_up()
            if len(names) > 1:  # before pyvista: the helper gets no EGL context and no llvmpipe threads
                helper = _fork_helper(folder)
        threading.Thread(target=_watch, args=(folder, parent), daemon=True).start()
        if set(names) & set(MESH_PICTURES):
            mesh_pictures.warm_up()
        if "membrane.gif" in names:
            from . import animation  # noqa: F401 - imports Pillow before the payload comes
        job = await_payload(folder, parent)
        if job is None:  # the run ended (even before we started) or cancelled us
            shutil.rmtree(folder, ignore_errors=True)
            return
        result, (out, window_size, handed) = job
        drawn = draw_claimed(result, (out, window_size, handed), folder, lambda name: True)
        theirs = _helper_reply(helper)
        helper = None
        drawn += theirs.get("drawn", [])
        reply = {"ok": set(drawn) == set(handed), "drawn": drawn, "error": theirs.get("error", "")}
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which then draws the pictures itself
        drawn += _helper_reply(helper).get("drawn", [])
        reply = {"ok": False, "drawn": drawn, "error": f"{type(exc).__name__}: {exc}"}
    finally:
        with contextlib.suppress(OSError):
            answer.write(json.dumps(reply) + "\n")
            answer.flush()
    os._exit(0)  # the pictures are on disk; tearing down VTK and the EGL context would only cost time
