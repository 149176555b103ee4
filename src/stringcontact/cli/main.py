"""The command line: `stringcontact run|list|show|plot|study|check|models` (also `python -m stringcontact`).

Exit codes:

* 0 success;
* 1 an internal error (a bug: one line; STRINGCONTACT_TRACEBACK=1 shows the traceback);
* 2 bad input: scene, options, output folder (not empty, locked by another run, read-only, disk full),
  a scheme that would be unstable before it starts;
* 3 a run that became unstable (its partial output is kept, marked "unstable"), or whose energy balance does
  not close (its output is kept, marked "unbalanced");
* 130 interrupted by SIGINT (Ctrl-C), 143 by SIGTERM, 129 by SIGHUP (partial output kept, marked "interrupted").

Every error is one line on stderr; no traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import gc
import importlib
import itertools
import logging
import os
import signal
import sys
import threading
import warnings

from ..errors import one_line
from ..scene.names import DEFAULT_SCHEME
from ..timestepping import SCHEMES
from .mpi_start import quick_singleton

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_UNSTABLE, EXIT_INTERRUPTED = 0, 1, 2, 3, 130

# Subcommands that live with their concern; each module has add_arguments(parser) and command(args) -> int,
# and keeps heavy imports (dolfinx, pyvista) inside its functions so that `--help` stays fast.
SUBCOMMANDS = {
    "plot": ("stringcontact.plot.viz", "redraw the pictures of an output folder from its saved files"),
    "study": ("stringcontact.cli.study", "work-precision, convergence and stability studies"),
    "check": ("stringcontact.cli.check", "check the paper's (A1)-(A4) and Theorems 2.2-2.3 on a computed solution"),
    "models": ("stringcontact.model.registry", "list the models a scene may name (registered under stringcontact.models)"),
}


class _Version(argparse.Action):
    """--version: the installed distribution's version, read only when asked (importlib.metadata)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        import importlib.metadata

        try:
            version = importlib.metadata.version("stringcontact")
        except importlib.metadata.PackageNotFoundError:
            version = "unknown (not installed: run scripts/setup)"
        sys.stdout.write(f"stringcontact {version}\n")
        parser.exit(EXIT_OK)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, like every other input error; "stringcontact: error:" first
        root, _, sub = self.prog.partition(" ")  # a subcommand's parser is "stringcontact run"
        self.exit(EXIT_INPUT, f"{root}: error: {sub + ': ' if sub else ''}{one_line(message)}\n")


def build_parser(argv=None) -> argparse.ArgumentParser:
    """The command line's parser. The subcommands of `SUBCOMMANDS` get their arguments only when `argv` (default:
    the process's own) names them: their modules import NumPy and more, 0.08 s that `stringcontact run` would
    spend before it starts its picture process (docs/explanation/performance.md)."""
    named = set(sys.argv[1:] if argv is None else argv)
    parser = _Parser(prog="stringcontact", description="Inelastic contact of a viscoelastic string with an obstacle.")
    parser.add_argument("--version", action=_Version, help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="simulate a scene and write XDMF, CSV and JSON")
    run.add_argument("scene", help="built-in scene name (see `stringcontact list`) or path to a .toml file")
    run.add_argument("--nx", type=int, help="number of cells")
    run.add_argument("--nt", type=int, help="number of time steps")
    run.add_argument("--eps", type=float, help="penalty parameter ε > 0")
    run.add_argument("--alpha", type=float, help="viscosity α ≥ 0")
    run.add_argument("--restitution", type=float, metavar="E",
                     help="restitution coefficient e in [0, 1] of scheme projection (default: the scene's, else 0: inelastic)")
    run.add_argument("--scheme", choices=tuple(SCHEMES), help="time scheme (default: the scene's, else paper): "
                     + "; ".join(f"{k}: {v}" for k, v in SCHEMES.items()))
    run.add_argument("--penalty", choices=("explicit", "semi-implicit"), help="default: the scheme's (paper: explicit)")
    run.add_argument("--mass", choices=("lumped", "consistent"), help="default: lumped")
    run.add_argument("--out", metavar="DIR", help="output folder (refused if not empty, unless --force)")
    run.add_argument("--force", action="store_true", help="replace an output folder holding a stringcontact result (only by a complete run)")
    run.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    run.add_argument("--model", metavar="NAME",
                     help="model: a name from `stringcontact models`, or package.module:name of a Model object "
                          "(default: the scene's, else the paper's)")
    run.add_argument("--tol", type=float, help="choose the cheapest method and resolution with estimated error below TOL")
    run.add_argument("--no-pictures", action="store_true", help="write only XDMF, CSV and JSON")
    run.add_argument("--petsc-option", action="append", default=[], metavar="NAME=VALUE",
                     help="a PETSc option for the linear solver, e.g. ksp_type=cg or pc_type=hypre (repeatable; over "
                          "the scene's petsc_options; names ksp_*, pc_*, mat_mumps_*: see docs/explanation/linear_solvers.md)")
    run.add_argument("--profile", action="store_true",
                     help="print where the run's time went: start-up, imports, set-up, solve, output, pictures")
    run.add_argument("--frames", type=int, default=100, metavar="N",
                     help="XDMF frames: at most N of the ~400 stored rows: 0, T, the output times, then evenly "
                          "spaced rows (default 100; dolfinx 0.5 writes N frames in time ~N²)")

    sub.add_parser("list", help="list the built-in scenes")
    show = sub.add_parser("show", help="print a scene as TOML: every key it sets, the scheme and model it runs with")
    show.add_argument("scene", help="built-in scene name (see `stringcontact list`) or path to a .toml file")
    for name, (module, help_text) in SUBCOMMANDS.items():
        sub_parser = sub.add_parser(name, help=help_text)
        if name not in named:
            continue
        try:
            importlib.import_module(module).add_arguments(sub_parser)
        except Exception as exc:  # noqa: BLE001 - one broken subcommand must not take `run` down with it
            sub_parser.set_defaults(_unavailable=f"{type(exc).__name__}: {one_line(exc)}"[:200])
            sub_parser.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    return parser


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


def _run(args, painter=None) -> int:
    """`run`; `painter` (a `painter.PictureProcess`) was started by `main` before PETSc and dolfinx were imported."""
    import time

    import stringcontact as sc

    started = time.perf_counter()
    if args.profile:  # dolfinx, UFL and the solver, timed as a section (else loaded when first needed)
        importlib.import_module("stringcontact.run.driver")
    imports = time.perf_counter() - started

    scene = sc.load_scene(args.scene)
    changes = {k: getattr(args, k) for k in ("nx", "nt", "eps", "alpha", "restitution") if getattr(args, k) is not None}
    if args.petsc_option:  # into the scene, so that summary.json records the options the run used
        changes["petsc_options"] = dict(scene.petsc_options) | _petsc_options(args.petsc_option)
    if changes:
        scene = scene.replace(**changes)
    options = {"scheme": args.scheme, "penalty": args.penalty, "mass": args.mass}
    _check_scheme_options(args, scene)
    model = spec = None
    if args.model or scene.model:  # the scene's key is a registered name, checked when it was loaded
        from ..model.registry import load_model

        spec = args.model or scene.model
        with _current_folder_importable(args.model):
            model = load_model(spec)
    from ..run.options import MAX_FRAMES

    if not 1 <= args.frames <= MAX_FRAMES:  # named as the flag, not as the API's max_frames
        raise ValueError(f"--frames: {args.frames} is out of range; allowed: a whole number in [1, {MAX_FRAMES}] (XDMF frames)")
    if args.out is not None:
        from ..io.publish import check_target

        check_target(args.out, args.force)  # before --tol's pilots and the set-up: a refused folder costs nothing
    if args.tol is not None:
        from ..analysis.study import choose_for_tolerance

        scene, options, text = choose_for_tolerance(scene, args.tol, model=model)  # the pilots use the run's model
        print(text)
    from ..run.options import Output

    output = Output(args.out, max_frames=args.frames, force=args.force, pictures=_pictures(args, painter),
                    progress=not args.no_progress)
    res = sc.simulate(scene, **options, model=spec, output=output)  # the name: summary.json says where it came from
    if res.has_rows:  # rank 0 under MPI (the other ranks hold the series, not the rows): one report
        from .report import report

        report(res)
        if args.out is not None:
            print(f"wrote {args.out}")
        else:
            print("nothing written (no --out): add --out DIR to write XDMF, CSV, JSON and pictures")
        if args.profile:
            from ..run import profile

            print("where the time went:\n" + profile.table(profile.sections(res.timings, imports, started)))
    from ..run.checks import unbalanced_message

    unbalanced = unbalanced_message(res)
    if unbalanced is not None:  # the output (if any) is marked "unbalanced", never "complete"
        _error(unbalanced)
        return EXIT_UNSTABLE
    return EXIT_OK


@contextlib.contextmanager
def _current_folder_importable(spec):
    """--model package.module:name finds a module in the current folder, as under `python -m stringcontact`
    (whose sys.path starts with it): the folder is first on sys.path while the model is loaded."""
    folder = os.getcwd()
    added = bool(spec) and ":" in spec and folder not in sys.path and "" not in sys.path
    if added:
        sys.path.insert(0, folder)
    try:
        yield
    finally:
        if added and folder in sys.path:
            sys.path.remove(folder)


def _petsc_options(items: list[str]) -> dict:
    """--petsc-option NAME=VALUE, ...: a dict with TOML's value types (true/false, numbers, words), checked."""
    from ..scene import check_petsc_options

    options = {}
    for item in items:
        name, eq, text = item.partition("=")
        if not eq or not name or not text:
            raise ValueError(f"petsc_options (--petsc-option): expected NAME=VALUE (e.g. ksp_type=cg), got {item!r}")
        options[name.strip()] = _option_value(text.strip())
    return dict(check_petsc_options(options, key="petsc_options (--petsc-option)"))


def _option_value(text: str):
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _check_scheme_options(args, scene) -> None:
    """--eps or --penalty with a scheme that has no penalty, a restitution e > 0 with a scheme other than
    projection: refused before anything runs."""
    from ..timestepping import check_restitution, scheme_class

    name = args.scheme or scene.scheme or DEFAULT_SCHEME
    check_restitution(name, scene.restitution or 0.0)
    if not scheme_class(name).PENALTIES and (args.eps is not None or args.penalty is not None):
        given = "--eps" if args.eps is not None else "--penalty"
        raise ValueError(f"{given}: scheme {name!r} uses no penalty (no eps); it accepts --mass lumped only")


def _pictures(args, painter):
    """`simulate`'s `pictures`: the picture function, with the started painter, or whether to draw them."""
    if painter is None:
        return not args.no_pictures
    from ..plot.viz import write_pictures

    return functools.partial(write_pictures, painter=painter)


def _single_process() -> bool:
    """Not one rank of an MPI job (checked without importing mpi4py, which the picture process must not wait for)."""
    sizes = (os.environ.get(v, "1").strip() for v in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"))
    return all(not size.isdigit() or int(size) <= 1 for size in sizes)


def _partial_report(exc) -> None:
    """After an interrupted or unstable run: the closing lines for the rows stored so far, if the solver gave them."""
    res = getattr(exc, "result", None)
    if res is not None and len(getattr(res, "t", ())) and res.has_rows:
        from .report import report

        with contextlib.suppress(Exception):
            report(res)


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


def main(argv=None) -> int:
    own = argv is None  # the process's own command line (the console script), not a call from Python
    if own and "mpi4py.MPI" not in sys.modules:  # before MPI starts
        quick_singleton(os.environ)
    _standard_streams()
    with _stop_signals():  # first thing: a Ctrl-C while Python, PETSc or dolfinx start up is one line too
        try:
            code = _main(argv)
        except KeyboardInterrupt as exc:
            _error(str(exc) or "interrupted")
            code = exc.exit_code if hasattr(exc, "exit_code") else EXIT_INTERRUPTED
    if own:
        _end_together(code)
        # The process ends now, its files closed and its folder published. Python's last garbage collection
        # would visit every object of dolfinx, UFL and matplotlib: 0.15-0.2 s of the exit (docs/explanation/performance.md).
        gc.freeze()
    return code


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


def _main(argv) -> int:
    args = build_parser(argv).parse_args(argv)
    sys.argv = [_utf8_text(a) for a in sys.argv]  # after parsing: the args keep the bytes the user gave
    if getattr(args, "_unavailable", None):
        _error(f"the '{args.command}' command is unavailable ({args._unavailable})")
        return EXIT_INTERNAL
    problem = _environment_problem(os.environ)
    if problem is not None:  # before PETSc and MPI start: each would print a page of its own and exit 1
        _error(problem)
        return EXIT_INPUT
    painter = None
    if args.command == "run" and args.out is not None and not args.no_pictures and _single_process():
        from ..plot.painter import PictureProcess

        painter = PictureProcess.start()  # first: its start-up then overlaps the whole run, imports included
    try:
        return _command(args, painter)
    finally:
        if painter is not None:
            painter.cancel()  # already finished after a complete run; stops it after an error


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


def _command(args, painter) -> int:
    from ..errors import InstabilityError, Interrupted, OutputError, SceneError, SolverError

    with _one_line_warnings(), _signals_interrupt(petsc=args.command not in ("list", "show", "plot", "models")):
        try:
            if args.command == "run":
                return _run(args, painter)
            from ..scene import toml as scenes

            if args.command == "list":
                listed = scenes.list_scenes()
                width = max((len(name) for name, _ in listed), default=0)
                for name, description in listed:
                    print(f"{name:{width}s}  {description}")
                return EXIT_OK
            if args.command == "show":
                from .report import show_scene

                print(show_scene(scenes.load_scene(args.scene)), end="")
                return EXIT_OK
            if args.command in SUBCOMMANDS:
                return importlib.import_module(SUBCOMMANDS[args.command][0]).command(args)
        except SolverError as exc:  # a numerical failure after the input was accepted (docs/explanation/reliability.md)
            _partial_report(exc)
            _error(exc)
            return EXIT_INTERNAL
        except (SceneError, OutputError, ValueError) as exc:
            _error(exc)
            return EXIT_INPUT
        except InstabilityError as exc:
            _partial_report(exc)
            _error(exc)
            return EXIT_INPUT if exc.step == 0 else EXIT_UNSTABLE
        except KeyboardInterrupt as exc:
            _partial_report(exc)
            _error(str(exc) or "interrupted")
            return exc.exit_code if isinstance(exc, Interrupted) else EXIT_INTERRUPTED
        except OSError as exc:  # a file a subcommand reads or writes
            where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
            _error(f"{exc.strerror or exc}{where}")
            return EXIT_INPUT
        except RecursionError:  # crafted input nested too deeply (JSON, a .npy header): not a size problem
            _error("RecursionError: an input file is nested too deeply to read; allowed: the files stringcontact writes")
            return EXIT_INPUT
        except MemoryError:
            _error("MemoryError: out of memory: the problem, or an input file, is too large for this machine; "
                   "reduce nx or nt, or check the files read")
            return EXIT_INPUT
        except Exception as exc:  # noqa: BLE001 - a bug: one line, and the traceback on request
            if os.environ.get("STRINGCONTACT_TRACEBACK"):
                raise
            _error(f"internal error {type(exc).__name__}: {exc} (set STRINGCONTACT_TRACEBACK=1 to see the traceback)")
            return EXIT_INTERNAL
    return EXIT_INPUT


if __name__ == "__main__":
    sys.exit(main())
