"""A run's output folder (`OutputWriter`): the stored rows streamed into `solution.xdmf` as whole time levels, then
the tables, `view.py` and the pictures (the caller's function), in a hidden folder renamed into place once the XDMF
is read back. A failing device removes the folder: one line (`OutputError`) on every MPI rank."""

from __future__ import annotations

import contextlib
import json
import shutil
import signal
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from ..errors import Interrupted, OutputError, one_line
from ..signals import signals_held
from .paraview_view import obstacle_at, write_view
from .publish import describe_os_error, disk_failure, open_partial, publish_partial, sync_soon
from .readback import read_xdmf
from .result import FIELDS, OBSTACLE_FIELD
from .tables import ROWS_FILE, clean_json, summary_dict, write_diagnostics, write_rows
from .xdmf import XdmfTimeSeries, mesh_arrays


def xdmf_frames(steps, keep_steps, max_frames: int) -> np.ndarray:
    """Which stored rows become XDMF frames (a mask), at most `max_frames` (at least 2): the first and the last, the
    rows at `keep_steps` (evenly thinned, with a warning, if they do not fit), then evenly spaced rows."""
    steps = np.asarray(steps)
    mask = np.zeros(steps.size, dtype=bool)
    if not steps.size:
        return mask
    budget = max(2, int(max_frames))
    mask[[0, -1]] = True
    keep = np.flatnonzero(np.isin(steps, np.asarray(sorted(keep_steps), dtype=steps.dtype)) & ~mask)
    _add_evenly(mask, keep, budget)
    if keep.size and not mask[keep].all():
        warnings.warn(f"the scene's {keep.size} output times do not fit in {budget} XDMF frames (--frames): solution.xdmf "
                      f"holds {int(mask[keep].sum())} of them; all are stored rows (diagnostics.csv, the pictures)",
                      stacklevel=2)
    _add_evenly(mask, np.flatnonzero(~mask), budget)
    return mask


def _add_evenly(mask: np.ndarray, candidates: np.ndarray, budget: int) -> None:
    """Set up to ``budget - mask.sum()`` of the rows `candidates` (sorted, unset) in `mask`, evenly spaced."""
    room = budget - int(mask.sum())
    if room > 0 and candidates.size:
        if candidates.size > room:
            candidates = candidates[((np.arange(room) + 0.5) * (candidates.size / room)).astype(int)]  # centred picks
        mask[candidates] = True


class OutputWriter:
    """``write(t, fields)`` at each stored time, then ``finish(result)``, or ``abort(status, message[, result])`` on
    InstabilityError or KeyboardInterrupt, ``discard()`` on an unexpected error. `frames`: which stored rows are XDMF
    frames; `pictures`: None or a function (result, folder). `path`: where the folder ended up."""

    def __init__(self, path, scene, V, comm, force: bool = False, pictures=None, frames=None):
        self.comm, self.scene, self.force, self.pictures = comm, scene, force, pictures
        self.frames = None if frames is None else np.asarray(frames, dtype=bool)
        self._row, self._kept = 0, None  # the last stored row if it is not a frame: (t, fields), written if the run stops
        self.write_time, self.times = 0.0, []
        self.lock = self.partial = self.xdmf = self.path = None
        self.target = Path(path).resolve()
        failure = None
        if comm.rank == 0:  # only rank 0 looks at the folder: another rank would find rank 0's own lock
            try:
                self.target, self.lock, self.partial = open_partial(path, force)
            except OutputError as exc:  # in the terms of `run.options.Output`, not the command line's
                failure = str(exc)
                for cli, python in (("pass --force to replace it", "pass Output(..., force=True) to replace it"),
                                    ("--force replaces only", "Output(force=True) replaces only"), ("--out ", "output folder ")):
                    failure = failure.replace(cli, python)
        if comm.size > 1:
            failure, self.partial = comm.bcast((failure, self.partial), root=0)
        if failure is not None:
            raise OutputError(failure)
        try:
            self.xdmf = XdmfTimeSeries(self.partial, mesh_arrays(V, comm), comm)
        except (RuntimeError, OSError) as exc:  # petsc4py's Error is a RuntimeError
            self._fail("cannot write solution.xdmf", exc)
        except BaseException:  # Ctrl-C while opening: leave nothing behind
            self.discard()
            raise

    def write(self, t: float, fields: dict) -> None:
        """One stored row as an XDMF frame, or, not among `frames`, kept: a run stopping there ends its XDMF with it."""
        row, self._row = self._row, self._row + 1
        if self.frames is not None and row < self.frames.size and not self.frames[row]:
            self._kept = (t, {name: np.array(values, dtype=float) for name, values in fields.items()})
            return
        self._kept = None
        self._write_frame(t, fields)

    def _write_frame(self, t: float, fields: dict) -> None:
        t0 = time.perf_counter()
        if getattr(self.scene, "obstacle_moves", False):  # ψ where it is at t: ParaView's view warps by it
            points = self.xdmf.mesh.points[:, 0] if self.scene.dim == 1 else self.xdmf.mesh.points[:, :2]
            fields = {**fields, OBSTACLE_FIELD: obstacle_at(self.scene, points, t)}
        try:
            with signals_held():
                self.xdmf.write(t, fields)
                self.times.append(float(t))
        except (RuntimeError, OSError) as exc:
            self._fail(f"cannot write solution.h5 at t = {t:.6g}", exc)
        self.write_time += time.perf_counter() - t0

    def finish(self, result) -> None:
        """Close the XDMF, write the tables, view.py, the pictures and summary.json, rename the folder into place; a
        failing device removes it (OutputError, every rank)."""
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
                self.discard()
                raise OutputError(f"--out {self.target}: cannot write the output files: {failure}; nothing was written there")
            self._publish(summary)
        except KeyboardInterrupt as exc:  # the data are whole: the folder says it was interrupted (or, published, stays complete)
            self.abort("interrupted", f"{str(exc) or 'interrupted'} while writing the output files", result=result)
            raise
        except OutputError:
            raise
        except (OSError, RuntimeError) as exc:
            self._fail("cannot write the output files", exc)

    def abort(self, status: str, message: str, result=None, error=None) -> None:
        """Keep what was written, marked `status`, with `result`'s rows so far and `error`'s (default: the exception
        being handled) step, time and r; never raises."""
        if self.partial is None and self.xdmf is None:
            return  # already finished, failed or aborted
        error = error if error is not None else sys.exc_info()[1]
        try:
            with signals_held():
                if self._kept is not None and self.xdmf is not None:  # end the XDMF with the last stored row
                    self._write_frame(*self._kept)
                self._close_xdmf()
                rows = result is not None and len(result.t)
                summary = summary_dict(result) if rows else self._bare_summary()
                summary.update(status=status, message=message or str(error or "") or status)
                if getattr(error, "step", None) is not None:
                    summary["instability"] = {"message": str(error), "step": error.step, "time": error.time, "r": error.r}
                if self.comm.rank == 0 and rows:
                    write_diagnostics(self.partial / "diagnostics.csv", result)
                    write_view(result, self.partial)
                self._publish(summary)
        except Exception as exc:  # noqa: BLE001 - never hide the run's own exception behind ours
            self.discard()
            warnings.warn(f"--out {self.target}: the partial output could not be kept: {describe_os_error(exc, self.target)}",
                          stacklevel=2)

    def _write_tables_and_pictures(self, result, summary: dict) -> None:
        """Rank 0: diagnostics.csv, rows.npz, view.py and the pictures (a failing picture warns)."""
        write_diagnostics(self.partial / "diagnostics.csv", result)
        write_rows(self.partial / ROWS_FILE, result)
        write_view(result, self.partial, target=self.target)
        sync_soon([self.partial / name for name in ("solution.h5", ROWS_FILE, "diagnostics.csv")])  # while drawing
        if self.pictures:
            t0 = time.perf_counter()
            try:
                self.pictures(result, self.partial)
            except Exception as exc:  # noqa: BLE001 - pictures are optional, unless the device fails
                if disk_failure(exc) is not None:
                    raise
                warnings.warn(f"pictures not written ({type(exc).__name__}: {one_line(exc, 300)})", stacklevel=3)
            summary.setdefault("timings", {})["pictures"] = time.perf_counter() - t0

    def _bare_summary(self) -> dict:
        import dolfinx

        return {"status": None, "message": "", "scene": self.scene.as_dict(), "r": self.scene.r,
                "dolfinx": dolfinx.__version__, "stored_rows": self._row, "xdmf_frames": len(self.times)}

    def _close_xdmf(self, discard: bool = False) -> None:
        if self.xdmf is not None:
            self.xdmf.close(discard=discard)  # kept if that fails: a discard closes it
            self.xdmf = None

    def _publish(self, summary: dict) -> None:
        """Check the XDMF's frames, write summary.json and publish the folder, the stop signals held."""
        status = summary.get("status") or "complete"
        failure = dest = None
        with signals_held():
            if self.comm.rank == 0:
                try:
                    _, series = read_xdmf(self.partial / "solution.xdmf")
                    counts = {name: len(series.get(name, ())) for name in FIELDS}
                    if any(c != len(self.times) for c in counts.values()):
                        raise OutputError(f"solution.xdmf holds {counts} time levels, expected {len(self.times)}")
                    summary.update(xdmf_frames=len(self.times), last_time=self.times[-1] if self.times else None)
                    (self.partial / "summary.json").write_text(json.dumps(clean_json(summary), indent=2, allow_nan=False))
                    dest = publish_partial(self.partial, self.target, self.force, status)
                except (OSError, OutputError) as exc:
                    failure = describe_os_error(exc, self.target) if isinstance(exc, OSError) else str(exc)
            if self.comm.size > 1:
                failure, dest = self.comm.bcast((failure, dest), root=0)
            if failure is not None:
                self.discard()
                raise OutputError(f"--out {self.target}: {failure}; nothing was written there")
            self.path, self.partial = dest, None
            self.discard()  # the folder is in place: this releases the lock
        if dest != self.target and self.comm.rank == 0:
            warnings.warn(f"--out {self.target} already holds a result; this run's {status} output is in {dest}", stacklevel=3)

    def _fail(self, what: str, exc: BaseException):
        reason = describe_os_error(exc, self.target.parent, probe=self.partial)  # before the partial folder frees the disk
        self.discard()
        raise OutputError(f"--out {self.target}: {what}: {reason}; nothing was written there") from None

    def discard(self) -> None:
        """Remove everything this run wrote (for a caller that stops on an unexpected error)."""
        if self.xdmf is not None:
            with contextlib.suppress(Exception):
                self._close_xdmf(discard=True)
        if self.comm.rank == 0 and self.partial is not None:
            shutil.rmtree(self.partial, ignore_errors=True)
        self.partial = None
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    def __del__(self):  # an unexpected error in the solver: no half-written folder, no stale lock
        with contextlib.suppress(Exception):
            if self.partial is not None:
                self.discard()
