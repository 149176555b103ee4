"""Results on disk: a run's output folder, `solution.xdmf`/`.h5`, `diagnostics.csv` and `summary.json`.

`OutputWriter` streams the stored rows into the XDMF (`xdmf`) during the run and writes the tables
(`tables`) at the end, in a hidden folder that `publish` locks, checks and renames into place; each stored
time is written with SIGINT/SIGTERM held back (`signals`), so the XDMF holds whole time levels, and the XDMF
is closed (and read back) before the rename. A disk-full or permission error (in a picture too) removes the
partial folder and raises :class:`OutputError` with one line, on every MPI rank.

The run's numbers checks (energy balance, penetration) come with the `Result` (`result.checks`, made by
`run.checks`); this module writes them into summary.json and knows no physics. The pictures are drawn by
the function the caller passes (`pictures`); this module never imports the picture code.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import signal
import time
import warnings
from pathlib import Path

import numpy as np

from ..errors import (
    Interrupted,
    OutputError,  # noqa: F401 - re-exported: `from stringcontact.io.folder import OutputError`
    one_line,
)
from .disk import describe_os_error, disk_failure, sync_soon
from .hdf5 import Hdf5Quiet
from .paraview_view import write_view
from .publish import open_partial, publish_partial
from .readback import xdmf_series
from .result import FIELDS, OBSTACLE_FIELD  # the XDMF's attributes (also read as output.FIELDS)
from .signals import signals_held
from .tables import ROWS_FILE, clean_json, summary_dict, write_diagnostics, write_rows
from .xdmf import XdmfTimeSeries, mesh_arrays


def obstacle_at(scene, points, t: float) -> np.ndarray:
    """ψ(·, t) at the mesh `points` ((N, 3), as written to the XDMF); where the expression gives no finite
    value, its lowest finite value (a reader warps by it: no NaN)."""
    points = np.asarray(points, dtype=float)
    psi = np.asarray(scene.obstacle_values(points[:, 0] if scene.dim == 1 else points[:, :2], t), dtype=float).reshape(-1)
    psi = np.broadcast_to(psi, points.shape[:1]) if psi.size == 1 else psi
    finite = np.isfinite(psi)
    return np.where(finite, psi, psi[finite].min() if finite.any() else 0.0)

# --- the writer ------------------------------------------------------------------------------------------


def xdmf_frames(steps, keep_steps, max_frames: int) -> np.ndarray:
    """Which stored rows become XDMF frames: at most `max_frames` (at least 2) of them. The first and the last
    always; then the rows at `keep_steps` (the scene's output times), evenly thinned if they do not fit;
    then evenly spaced rows up to `max_frames`.

    dolfinx 0.5's XDMFFile rewrites its whole XML on every write, so writing costs O(frames²): 376 rows of
    Example 1 take 3.5 s, 100 take 0.4 s; 3000 output times took over 600 s. The bound is therefore on
    every frame, output times included. The Result and diagnostics.csv keep every stored row.
    """
    steps = np.asarray(steps)
    mask = np.zeros(steps.size, dtype=bool)
    if not steps.size:
        return mask
    budget = max(2, int(max_frames))
    mask[[0, -1]] = True
    keep = np.flatnonzero(np.isin(steps, np.asarray(sorted(keep_steps), dtype=steps.dtype)) & ~mask)
    _add_evenly(mask, keep, budget)
    if keep.size and not mask[keep].all():
        warnings.warn(
            f"the scene's {keep.size} output times do not fit in {budget} XDMF frames (--frames): solution.xdmf "
            f"holds {int(mask[keep].sum())} of them; all are stored rows (diagnostics.csv, the pictures)",
            stacklevel=2,
        )
    _add_evenly(mask, np.flatnonzero(~mask), budget)
    return mask


def _add_evenly(mask: np.ndarray, candidates: np.ndarray, budget: int) -> None:
    """Set up to ``budget - mask.sum()`` of the rows `candidates` (sorted, unset) in `mask`, evenly spaced."""
    room = budget - int(mask.sum())
    if room <= 0 or not candidates.size:
        return
    if candidates.size > room:
        candidates = candidates[((np.arange(room) + 0.5) * (candidates.size / room)).astype(int)]  # centred picks
    mask[candidates] = True


#: The command line's words in the output folder's messages (`publish.check_target`) and a Python caller's, who
#: gave the folder and the flag as `run.options.Output(dir, force=True)`.
_PYTHON_TERMS = (
    ("pass --force to replace it", "pass Output(..., force=True) to replace it"),
    ("--force replaces only", "Output(force=True) replaces only"),
    ("--out ", "output folder "),
)


def in_python_terms(message: str) -> str:
    """An output folder's refusal as a Python caller says it: ``Output(..., force=True)`` for ``--force``, "output
    folder X" for ``--out X``. The command line checks its --out itself first (`publish.check_target`), in its own
    words; what reaches `OutputWriter` comes from `simulate`/`Stepper`'s `Output`."""
    for cli, python in _PYTHON_TERMS:
        message = message.replace(cli, python)
    return message


class OutputWriter:
    """Streams the stored rows to XDMF during the run and writes the tables at the end.

    The solver calls ``write(t, fields)`` at each stored time, then ``finish(result)`` or, on
    InstabilityError or KeyboardInterrupt, ``abort(status, message[, result])``. `path` is where the
    folder ended up (the target, or ``NAME.interrupted``/``NAME.unstable`` beside an existing result).
    """

    def __init__(self, path, scene, V, comm, force: bool = False, pictures=None, frames=None):
        self.comm = comm
        self.frames = None if frames is None else np.asarray(frames, dtype=bool)  # which stored rows go to XDMF
        self._row = 0
        self._skipped = None  # the time of the last stored row not written to XDMF, if the latest row was one
        self._kept = None  # that row's fields: flushed if the run stops there
        self._spare = None  # the buffers the next skipped row is copied into before it replaces the kept one
        self.pictures = pictures  # None/False (no pictures) or a function (result, folder)
        self.scene = scene
        self.force = force
        self.write_time = 0.0
        self.times: list[float] = []
        self.lock = None
        self.partial = None
        self.xdmf = None
        self.path = None
        self._quiet = Hdf5Quiet()
        # Only rank 0 looks at the folder: another rank would find rank 0's own lock and refuse.
        self.target = Path(path).resolve()
        failure = None
        if comm.rank == 0:
            try:
                self.target, self.lock, self.partial = open_partial(path, force)
            except OutputError as exc:
                failure = in_python_terms(str(exc))
        failure, partial = comm.bcast((failure, self.partial), root=0) if comm.size > 1 else (failure, self.partial)
        if failure is not None:
            raise OutputError(failure)
        self.partial = partial
        try:
            self._quiet.__enter__()
            self.xdmf = XdmfTimeSeries(self.partial, mesh_arrays(V, comm), comm)
        except (RuntimeError, OSError) as exc:  # petsc4py's Error is a RuntimeError
            self._fail("cannot write solution.xdmf", exc)
        except BaseException:  # Ctrl-C while opening: leave nothing behind
            self._discard()
            raise

    # -- during the run

    def write(self, t: float, fields: dict) -> None:
        """One stored row: all four fields as one XDMF frame, or (interrupted) none of them.

        Rows that are not among `frames` are not written; the latest of them is kept, so that a run that
        stops there still ends its XDMF with its last stored row.
        """
        row, self._row = self._row, self._row + 1
        if self.frames is not None and row < self.frames.size and not self.frames[row]:
            if self._spare is None:
                self._spare = {name: np.empty(np.shape(values)) for name, values in fields.items()}
            for name, values in fields.items():  # into the spare buffers: a Ctrl-C here leaves the kept row whole
                np.copyto(self._spare[name], values)
            self._kept, self._spare = self._spare, self._kept
            self._skipped = t
            return
        self._skipped = None
        self._write_frame(t, fields)

    def _write_frame(self, t: float, fields: dict) -> None:
        t0 = time.perf_counter()
        if getattr(self.scene, "obstacle_moves", False):  # ψ where it is at t: ParaView's view warps by it
            fields = {**fields, OBSTACLE_FIELD: obstacle_at(self.scene, self.xdmf.mesh.points, t)}
        try:
            with signals_held():
                self.xdmf.write(t, fields)
                self.times.append(float(t))
        except (RuntimeError, OSError) as exc:
            self._fail(f"cannot write solution.h5 at t = {t:.6g}", exc)
        self.write_time += time.perf_counter() - t0

    # -- the end of a run

    def finish(self, result) -> None:
        """Close the XDMF, write diagnostics, pictures and summary, and rename the folder into place.

        The status is the result's (the driver marks a run whose energy balance does not close
        "unbalanced"; such a run is kept, never "complete"). A write that fails on the device (disk full, I/O error), pictures included, removes the
        folder and raises OutputError on every rank.
        """
        try:
            self._close_xdmf()
            summary = summary_dict(result)
            failure = stopped = None
            if self.comm.rank == 0:
                try:
                    self._write_tables_and_pictures(result, summary)
                except KeyboardInterrupt as exc:  # told to every rank below: they abort together
                    stopped = getattr(exc, "signum", signal.SIGINT)
                except Exception as exc:  # noqa: BLE001 - sorted below
                    if not isinstance(exc, (OSError, RuntimeError)) and disk_failure(exc) is None:
                        raise
                    failure = describe_os_error(disk_failure(exc) or exc, self.target.parent, probe=self.partial)
            if self.comm.size > 1:  # one outcome on every rank: rank 0's pictures may fail or be interrupted
                failure, stopped = self.comm.bcast((failure, stopped), root=0)
            if stopped is not None:
                raise Interrupted(stopped)
            if failure is not None:
                self._discard()
                raise OutputError(f"--out {self.target}: cannot write the output files: {failure}; nothing was written there")
            self._publish(summary)
        except KeyboardInterrupt as exc:
            # Ctrl-C while drawing: the data are whole, and the folder says it was interrupted. If it came
            # after the folder was published (held back until then), the folder is complete and stays so.
            self.abort("interrupted", f"{str(exc) or 'interrupted'} while writing the output files", result=result)
            raise
        except OutputError:
            raise
        except (OSError, RuntimeError) as exc:
            self._fail("cannot write the output files", exc)

    def abort(self, status: str, message: str, result=None, error=None) -> None:
        """Keep what was written so far, marked `status` ("interrupted" or "unstable").

        `result` (optional) holds the rows stored so far, for diagnostics.csv and the energy balance.
        `error` (default: the exception being handled) gives the step, time and r of an InstabilityError.
        Never raises an I/O error: the caller is already handling the run's own exception.
        """
        if self.partial is None and self.xdmf is None:
            return  # already finished, failed or aborted
        if error is None:
            import sys

            error = sys.exc_info()[1]
        try:
            with signals_held():
                if self._skipped is not None and self.xdmf is not None:  # end the XDMF with the last stored row
                    self._write_frame(self._skipped, self._kept)
                    self._skipped = None
                self._close_xdmf()
                summary = summary_dict(result) if result is not None and len(result.t) else self._bare_summary()
                summary["status"] = status
                summary["message"] = message or str(error or "") or status
                if error is not None and getattr(error, "step", None) is not None:
                    summary["instability"] = {"message": str(error), "step": error.step, "time": error.time, "r": error.r}
                if self.comm.rank == 0 and result is not None and len(result.t):
                    write_diagnostics(self.partial / "diagnostics.csv", result)
                    write_view(result, self.partial)
                self._publish(summary)
        except Exception as exc:  # noqa: BLE001 - never hide the run's own exception behind ours
            self._discard()
            warnings.warn(f"--out {self.target}: the partial output could not be kept: {describe_os_error(exc, self.target)}", stacklevel=2)

    def discard(self) -> None:
        """Remove everything this run wrote (for a caller that stops on an unexpected error)."""
        self._discard()

    # -- internals

    def _write_tables_and_pictures(self, result, summary: dict) -> None:
        """Rank 0: diagnostics.csv, view.py (the ParaView view) and the pictures. A picture that fails on the device raises (`disk_failure`)."""
        write_diagnostics(self.partial / "diagnostics.csv", result)
        write_rows(self.partial / ROWS_FILE, result)  # what the pictures are drawn from, for `plot` (readback)
        write_view(result, self.partial, target=self.target)
        sync_soon([self.partial / name for name in ("solution.h5", ROWS_FILE, "diagnostics.csv")])  # while drawing
        if self.pictures:
            t0 = time.perf_counter()
            self._pictures(result)
            summary.setdefault("timings", {})["pictures"] = time.perf_counter() - t0

    def _pictures(self, result) -> None:
        try:  # on rank 0 only
            self.pictures(result, self.partial)
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # noqa: BLE001 - pictures are optional; the data must still be kept
            if disk_failure(exc) is not None:  # ...but not on a device that fails: then nothing is kept (finish)
                raise
            warnings.warn(f"pictures not written ({type(exc).__name__}: {one_line(exc, 300)})", stacklevel=3)

    def _bare_summary(self) -> dict:
        import dolfinx

        scene = self.scene
        return {
            "status": None,
            "message": "",
            "scene": scene.as_dict(),
            "r": scene.r,  # nan without eps (scheme projection)
            "dolfinx": dolfinx.__version__,
            "stored_rows": self._row,
            "xdmf_frames": len(self.times),
        }

    def _close_xdmf(self, discard: bool = False) -> None:
        if self.xdmf is not None:
            xdmf, self.xdmf = self.xdmf, None
            try:
                xdmf.close(discard=discard)
            except BaseException:
                self.xdmf = xdmf  # still open: a discard closes it (XdmfTimeSeries.close)
                raise
            finally:
                self._quiet.__exit__()

    def _publish(self, summary: dict) -> None:
        """Check the XDMF, write summary.json, fsync, and rename the partial folder into place.

        SIGINT/SIGTERM are held back throughout, so the folder is either still partial or fully in place.
        """
        status = summary.get("status") or "complete"
        failure, dest = None, None
        with signals_held():
            if self.comm.rank == 0:
                try:
                    series = xdmf_series(self.partial / "solution.xdmf")
                    counts = {name: len(series.get(name, ())) for name in FIELDS}
                    if any(c != len(self.times) for c in counts.values()):
                        raise OutputError(f"solution.xdmf holds {counts} time levels, expected {len(self.times)}")
                    summary["xdmf_frames"] = len(self.times)
                    summary["last_time"] = self.times[-1] if self.times else None
                    with open(self.partial / "summary.json", "w") as f:
                        f.write(json.dumps(clean_json(summary), indent=2, allow_nan=False))
                    dest = publish_partial(self.partial, self.target, self.force, status)
                except (OSError, OutputError) as exc:
                    failure = describe_os_error(exc, self.target) if isinstance(exc, OSError) else str(exc)
            if self.comm.size > 1:
                failure, dest = self.comm.bcast((failure, dest), root=0)
            if failure is not None:
                self._discard()
                raise OutputError(f"--out {self.target}: {failure}; nothing was written there")
            self.path, self.partial = dest, None
            self._release()
        if dest != self.target and self.comm.rank == 0:
            warnings.warn(f"--out {self.target} already holds a result; this run's {status} output is in {dest}", stacklevel=3)

    def _fail(self, what: str, exc: BaseException):
        reason = describe_os_error(exc, self.target.parent, probe=self.partial)  # before the partial folder frees the disk
        self._discard()
        raise OutputError(f"--out {self.target}: {what}: {reason}; nothing was written there") from None

    def _discard(self) -> None:
        if self.xdmf is not None:
            with contextlib.suppress(Exception):
                self._close_xdmf(discard=True)
        self._quiet.__exit__()
        if self.comm.rank == 0 and self.partial is not None:
            shutil.rmtree(self.partial, ignore_errors=True)
        self.partial = None
        self._release()

    def _release(self) -> None:
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    def __del__(self):  # an unexpected error in the solver: no half-written folder, no stale lock
        with contextlib.suppress(Exception):
            if self.partial is not None:
                self._discard()


