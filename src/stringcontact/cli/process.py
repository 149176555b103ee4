"""The process around a command: exit codes, the stop signals over PETSc's handlers (`stringcontact.signals`), MPI
ranks ending together, the standard streams (every message and warning one line on stderr), and the environment PETSc
and MPI start in (Open MPI's settings for a process started without `mpirun`)."""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import signal
import sys
import threading
import warnings

from ..errors import one_line
from ..signals import stop_signals

#: The exit codes (`cli.main`'s docstring says what each means; a signal's: 128 + its number).
EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_UNSTABLE, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
#: Seconds a failed or signalled MPI rank waits for the others to end with it before it aborts the job (MPI_Abort):
#: a rank left alone would wait in a collective call for ever.
END_GRACE = 10.0
_exit = {"comm": None, "timer": None}
#: Open MPI's MCA parameters for a command run without `mpirun`, set before MPI loads: no ``orted`` daemon and no UCX
#: probe, `from petsc4py import PETSc` 0.216 s with them, 0.548 s without (`benchmarks/bench_mpi_start.py`).
SINGLETON = {"OMPI_MCA_ess_singleton_isolated": "1", "OMPI_MCA_pml": "ob1"}
#: Set by a launcher (mpirun, mpiexec, srun with PMIx) in each process it starts.
LAUNCHED = ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK")


def error(message) -> None:
    """``stringcontact: error: MESSAGE`` on stderr, one line."""
    _stderr_line(f"stringcontact: error: {one_line(message)}")


def _stderr_line(text: str) -> None:
    sys.stderr.write(text + "\n")  # one write: print() writes text and newline apart, and two ranks' lines interleave
    sys.stderr.flush()


@contextlib.contextmanager
def one_line_warnings():
    """Every warning as one line ``stringcontact: warning: MESSAGE``, also through the logger "py.warnings" once ffcx
    has called ``logging.captureWarnings(True)``."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("stringcontact: warning: %(message)s"))
    logger = logging.getLogger("py.warnings")
    saved = warnings.showwarning, warnings.formatwarning, logger.propagate
    warnings.showwarning = lambda message, *args, **kwargs: _stderr_line(f"stringcontact: warning: {one_line(message)}")
    warnings.formatwarning = lambda message, *args, **kwargs: one_line(message)
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(handler)
        warnings.showwarning, warnings.formatwarning, logger.propagate = saved


@contextlib.contextmanager
def signals_interrupt(petsc: bool = True):
    """The stop signals raise `Interrupted` (`stop_signals`), over PETSc's own handlers (imported first with `petsc`);
    SIGPIPE gets its default back: `stringcontact list | head` ends quietly."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if petsc:  # the caller has loaded the stack (`stack.load`: the wheel's MPI before PETSc's)
        from mpi4py import MPI
        from petsc4py import PETSc  # noqa: F401 - initialises PETSc, which installs its signal handlers

        if MPI.COMM_WORLD.size > 1 and _exit["comm"] is None:  # collective, on every rank: `end_together`'s own
            _exit["comm"] = MPI.COMM_WORLD.Dup()
    saved_pipe = signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    try:
        with stop_signals(on_signal=_end_others_later):
            yield
    finally:
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()  # while SIGPIPE is still the default: a closed pipe ends the process quietly
        signal.signal(signal.SIGPIPE, saved_pipe if saved_pipe is not None else signal.SIG_DFL)


def _end_others_later(signum: int) -> None:
    if _exit["comm"] is not None and _exit["timer"] is None:  # if this rank cannot end with the others, it ends them all
        _exit["timer"] = threading.Timer(END_GRACE, _abort, args=(128 + signum,))
        _exit["timer"].daemon = True
        _exit["timer"].start()


def end_together(code: int) -> None:
    """Under MPI the ranks end together: each waits at a non-blocking barrier; a rank that failed (`code` not 0)
    waits at most END_GRACE seconds, then aborts the job with its code."""
    comm = _exit["comm"]
    if comm is None:
        return
    import time

    request = comm.Ibarrier()
    deadline = time.monotonic() + END_GRACE
    while not request.Test():
        if code != 0 and time.monotonic() > deadline:
            _abort(code)
        time.sleep(0.01)
    if _exit["timer"] is not None:
        _exit["timer"].cancel()


def _abort(code: int) -> None:
    sys.stderr.flush()
    _exit["comm"].Abort(code)


@contextlib.contextmanager
def argv_as_text():
    """``sys.argv`` encodable as UTF-8 while dolfinx loads (its C++ logging fails on a non-UTF-8 file name's surrogate
    escapes); the parsed arguments keep the real bytes."""
    saved = sys.argv
    sys.argv = [os.fsencode(a).decode("utf-8", "replace") if isinstance(a, str) else a for a in saved]
    try:
        yield
    finally:
        sys.argv = saved


def standard_streams() -> None:
    """A standard stream closed at start (``run ... >&-``) reopened on /dev/null, so that no file opened later gets
    descriptor 1 or 2, where PETSc, HDF5 and MPI write."""
    for fd, name, mode in ((0, "stdin", "r"), (1, "stdout", "w"), (2, "stderr", "w")):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)  # the lowest free descriptor: `fd` itself, as 0..fd-1 are open
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
        if getattr(sys, name) is None:
            setattr(sys, name, open(fd, mode, closefd=False, errors="backslashreplace"))  # noqa: SIM115


def quick_singleton(environ) -> dict[str, str]:
    """Add `SINGLETON` to `environ` (``os.environ`` before MPI is imported), but nothing under a launcher and no
    setting the user made; returns the settings added."""
    added = {} if any(name in environ for name in LAUNCHED) else {k: v for k, v in SINGLETON.items() if k not in environ}
    environ.update(added)
    return added


def environment_problem(environ) -> str | None:
    """What in the environment would stop PETSc or MPI at start-up with a page of text (an options file in
    ``PETSC_OPTIONS`` that is not a readable regular file, a ``TMPDIR`` where no folder can be made), or None."""
    import shlex
    import stat
    import tempfile

    try:
        words = shlex.split(environ.get("PETSC_OPTIONS", ""))
    except ValueError as exc:
        return f"PETSC_OPTIONS: {exc}; allowed: PETSc options such as '-ksp_type cg'"
    for flag, path in itertools.pairwise(words):
        if flag in ("-options_file", "-options_file_yaml", "-options_file_noerror"):
            try:
                regular = stat.S_ISREG(os.stat(path).st_mode) and os.access(path, os.R_OK)
            except OSError as exc:
                return f"PETSC_OPTIONS: {flag} {path}: {exc.strerror}; allowed: a readable options file"
            if not regular:
                return f"PETSC_OPTIONS: {flag} {path}: not a readable regular file; allowed: a readable options file"
    folder = environ.get("TMPDIR")
    if folder and os.path.isdir(folder):
        try:
            os.rmdir(tempfile.mkdtemp(prefix="stringcontact-", dir=folder))
        except OSError as exc:
            return (f"TMPDIR={folder}: cannot make a folder there ({exc.strerror}), where MPI keeps its session; "
                    "allowed: a writable folder (or leave TMPDIR unset)")
    return None
