"""The process around a command: how it ends (the exit codes; under MPI every rank together, `_end_together`,
or the job aborted), the stop signals (SIGINT, SIGTERM, SIGHUP raise `Interrupted`; PETSc's own handlers
replaced), its standard streams (closed ones reopened on /dev/null, every message and warning one line on
stderr), and what in the environment would stop PETSc or MPI at start-up (`_environment_problem`)."""

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

#: The exit codes (what each means: the command line's docstring, `cli.main`; a signal's: 128 + its number).
EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_UNSTABLE, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


class _OneLineWarningHandler(logging.Handler):
    """Warnings that reach the logger "py.warnings" (once ffcx has called ``logging.captureWarnings``)."""

    def emit(self, record):
        _stderr_line(f"stringcontact: warning: {one_line(record.getMessage())}")


@contextlib.contextmanager
def _one_line_warnings():
    """Every warning as one line ``stringcontact: warning: MESSAGE``, however Python shows it.

    ffcx calls ``logging.captureWarnings(True)`` when it is imported (mid-run): from then on warnings go, through
    ``warnings.formatwarning``, to the logger "py.warnings" as ``WARNING:py.warnings:FILE:LINE: ...`` plus a
    source line. So the format and that logger are set too, not only ``warnings.showwarning``.
    """

    def show(message, category, filename, lineno, file=None, line=None):
        _stderr_line(f"stringcontact: warning: {one_line(message)}")

    def format_warning(message, category, filename, lineno, line=None):
        return one_line(message)

    logger = logging.getLogger("py.warnings")
    handler = _OneLineWarningHandler()
    saved = warnings.showwarning, warnings.formatwarning, logger.propagate
    warnings.showwarning, warnings.formatwarning = show, format_warning
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(handler)
        warnings.showwarning, warnings.formatwarning, logger.propagate = saved


#: Signals that stop a run cleanly (its output kept, marked "interrupted"); exit code 128 + the signal number.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@contextlib.contextmanager
def _signals_interrupt(petsc: bool = True):
    """SIGINT, SIGTERM and SIGHUP raise `Interrupted`, a KeyboardInterrupt: the run stops and keeps its output.

    PETSc installs C handlers for SIGHUP, SIGTERM and SIGPIPE that abort MPI with a page of text when it is
    first imported; with `petsc` it is imported here, and the Python handlers are installed again over its
    own while the command runs. SIGPIPE gets its default back (`stringcontact list | head` ends quietly, as
    Unix tools do).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if petsc:
        from ..stack import load

        load()  # the wheel's MPI before PETSc's (`stack.load`)
        from petsc4py import PETSc  # noqa: F401 - initialises PETSc, which installs its signal handlers

        _mpi_exit_comm()
    saved_pipe = signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    try:
        with _stop_signals():
            yield
    finally:
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()  # while SIGPIPE is still the default: a closed pipe ends the process quietly
        signal.signal(signal.SIGPIPE, saved_pipe if saved_pipe is not None else signal.SIG_DFL)


def _single_process() -> bool:
    """Not one rank of an MPI job (checked without importing mpi4py, which the picture process must not wait for)."""
    sizes = (os.environ.get(v, "1").strip() for v in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"))
    return all(not size.isdigit() or int(size) <= 1 for size in sizes)


def _error(message) -> None:
    _stderr_line(f"stringcontact: error: {one_line(message)}")


def _stderr_line(text: str) -> None:
    # One write for text and newline: stderr is unbuffered, and print() writes them apart, so the lines of
    # two MPI ranks could interleave into "msg1msg2\n\n".
    sys.stderr.write(text + "\n")
    sys.stderr.flush()


def _utf8_text(arg: str) -> str:
    """`arg` as text that encodes to UTF-8: bytes that are not UTF-8 (a file name such as ``o9/\\xff\\xfe``, held
    by Python as surrogate escapes) shown as U+FFFD.

    dolfinx passes ``sys.argv`` to its C++ ``init_logging(List[str])`` when it is imported, and pybind11
    cannot encode a surrogate escape (TypeError). The parsed arguments keep the real bytes; only this copy,
    which dolfinx reads, is changed.
    """
    return os.fsencode(arg).decode("utf-8", "replace") if isinstance(arg, str) else arg


def _standard_streams() -> None:
    """Started with stdin, stdout or stderr closed (``stringcontact run ... >&-``): /dev/null takes its place.

    Python then has ``sys.stdout = None`` (print() drops the text, ``.flush()`` fails), and the next file the
    run opens would get descriptor 1 or 2, where PETSc, HDF5 and MPI write their messages. With /dev/null
    there, the run works, its output folder is whole, and the exit code tells how it went; the messages of a
    closed stream are lost, as with any Unix tool.
    """
    for fd, name, mode in ((0, "stdin", "r"), (1, "stdout", "w"), (2, "stderr", "w")):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)  # the lowest free descriptor: `fd` itself, as 0..fd-1 are open
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
        if getattr(sys, name) is None:
            setattr(sys, name, open(fd, mode, closefd=False, errors="backslashreplace"))


#: How long a rank of an MPI job that fails or is signalled waits for the others to end with it before it
#: aborts the whole job (MPI_Abort, with its exit code). Ranks that fail alike (a bad input: every rank checks
#: it) end within moments of each other; a rank left alone would wait in a collective call for ever.
END_GRACE = 10.0
_exit = {"comm": None, "timer": None}


def _mpi_exit_comm() -> None:
    """Under MPI, a communicator of its own for the ranks' last handshake (`_end_together`): collective, so
    called on every rank at the same point, right after MPI starts; nothing else uses it."""
    from mpi4py import MPI

    if MPI.COMM_WORLD.size > 1 and _exit["comm"] is None:
        _exit["comm"] = MPI.COMM_WORLD.Dup()


def _end_together(code: int) -> None:
    """The ranks of an MPI job end together: each waits at a non-blocking barrier; a rank that failed (`code`
    not 0) waits at most END_GRACE seconds, then aborts the job with its code. Without MPI, nothing."""
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
    timer = _exit["timer"]
    if timer is not None:
        timer.cancel()


def _abort(code: int) -> None:
    sys.stderr.flush()
    _exit["comm"].Abort(code)


def _abort_later(code: int) -> None:
    """After a stop signal under MPI: abort the job with `code` unless this rank has ended by END_GRACE seconds
    (a thread: the main one may be waiting in a collective call for a rank that will never join it)."""
    if _exit["comm"] is None or _exit["timer"] is not None:
        return
    _exit["timer"] = threading.Timer(END_GRACE, _abort, args=(code,))
    _exit["timer"].daemon = True
    _exit["timer"].start()


@contextlib.contextmanager
def _stop_signals():
    """SIGINT, SIGTERM and SIGHUP raise `Interrupted` from here on; the previous handlers come back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from ..errors import Interrupted

    def handler(signum, frame):
        _abort_later(128 + signum)  # under MPI: if this rank cannot end with the others, it ends them all
        raise Interrupted(signum)

    saved = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, h in saved.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


def _environment_problem(environ) -> str | None:
    """What in the environment would stop PETSc or MPI at start-up with a page of text: an options file in
    ``PETSC_OPTIONS`` that is not a readable regular file (a FIFO would block), a ``TMPDIR`` folder where no
    folder can be made (Open MPI's session folder; ``/proc``). None if nothing."""
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

