"""The command line: `stringcontact run|list|show|models|plot|study|check` (also `python -m stringcontact`).

Exit codes:

* 0 success;
* 1 an internal error (a bug: one line; STRINGCONTACT_TRACEBACK=1 shows the traceback);
* 2 bad input: scene, options, output folder (not empty, locked by another run, read-only, disk full),
  a scheme that would be unstable before it starts, a model or scheme plugin that breaks its contract or calls
  sys.exit (named), MPI ranks given different input;
* 3 a run that became unstable (its partial output is kept, marked "unstable"), or whose energy balance does
  not close (its output is kept, marked "unbalanced");
* 130 interrupted by SIGINT (Ctrl-C), 143 by SIGTERM, 129 by SIGHUP (partial output kept, marked "interrupted").

Every error is one line on stderr; no traceback.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import os
import sys

from ..jitlog import quiet_compiler
from ..scene import parameters
from ..signals import stop_signals
from . import process
from .parser import SUBCOMMANDS, build_parser, scene_with_flags
from .process import EXIT_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_UNSTABLE, error


def _run(args) -> int:
    """`run`: the scene simulated, its output and pictures written (pictures after the run, in this process)."""
    import time

    import stringcontact as sc

    started = time.perf_counter()
    if args.profile:  # dolfinx, UFL and the solver, timed as a section (else loaded when first needed)
        importlib.import_module("stringcontact.run.driver")
    imports = time.perf_counter() - started
    model = spec = None
    if args.model:  # before the scene: its [parameters] values are told this model's ranges
        from ..model.forms import check_declarations
        from ..model.registry import load_model

        spec = args.model
        with _current_folder_importable(args.model):
            model = load_model(spec)
        check_declarations(model)
    ranges = parameters.RUN_CONSTANTS.set(model.constants if model is not None else ())
    try:
        scene = sc.load_scene(args.scene)
    finally:
        parameters.RUN_CONSTANTS.reset(ranges)
    # --petsc-option into the scene, so that summary.json records the options the run used
    petsc = {"petsc_options": dict(scene.petsc_options) | _petsc_options(args.petsc_option)} if args.petsc_option else {}
    scene = scene_with_flags(args, scene, "it accepts --mass lumped only", **petsc)
    options = {"scheme": args.scheme, "penalty": args.penalty, "mass": args.mass}
    if model is None and scene.model:  # the scene's key is a registered name, checked when it was loaded
        from ..model.registry import load_model

        spec, model = scene.model, load_model(scene.model)
    from ..run.options import MAX_FRAMES, Output

    if not 1 <= args.frames <= MAX_FRAMES:  # named as the flag, not as the API's max_frames
        raise ValueError(f"--frames: {args.frames} is out of range; allowed: a whole number in [1, {MAX_FRAMES}] (XDMF frames)")
    if args.out is not None:
        from ..io.publish import check_target

        check_target(args.out, args.force)  # before --tol's pilots and the set-up: a refused folder costs nothing
    if args.tol is not None:
        from ..analysis.study import choose_for_tolerance

        scene, options, text = choose_for_tolerance(scene, args.tol, model=model)  # the pilots use the run's model
        print(text)
    output = Output(args.out, max_frames=args.frames, force=args.force, pictures=not args.no_pictures,
                    progress=not args.no_progress)
    res = sc.simulate(scene, **options, model=spec, output=output)  # the name: summary.json says where it came from
    if res.has_rows:  # rank 0 under MPI (the other ranks hold the series, not the rows): one report
        from .report import report

        report(res)
        print(f"wrote {args.out}" if args.out is not None else
              "nothing written (no --out): add --out DIR to write XDMF, CSV, JSON and pictures")
        if args.profile:
            from ..run import profile

            print("where the time went:\n" + profile.table(profile.sections(res.timings, imports, started)))
    if res.status == "unbalanced":  # its output (if any) is marked so, never "complete" (`Stepper.result`)
        error(res.message)
        return EXIT_UNSTABLE
    return EXIT_OK


@contextlib.contextmanager
def _current_folder_importable(spec):
    """--model package.module:name finds a module in the current folder (first on sys.path while it loads)."""
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
    """--petsc-option NAME=VALUE, ...: a dict with TOML's value types (true/false, numbers, else a word), checked."""
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
        with contextlib.suppress(ValueError):
            return kind(text)
    return text


def _partial_report(exc) -> None:
    """After an interrupted or unstable run: the closing lines of the rows stored so far, if any."""
    res = getattr(exc, "result", None)
    if res is not None and len(getattr(res, "t", ())) and res.has_rows:
        from .report import report

        with contextlib.suppress(Exception):
            report(res)


def main(argv=None) -> int:
    """The command line (`argv`, default: the process's own; only then are Open MPI's singleton settings made and
    the last garbage collection skipped). Returns the exit code."""
    own = argv is None
    if own and "mpi4py.MPI" not in sys.modules:  # before MPI starts
        process.quick_singleton(os.environ)
    process.standard_streams()
    quiet_compiler()  # before any form is compiled; a library import leaves the user's logging alone
    with stop_signals():  # first thing: a Ctrl-C while Python, PETSc or dolfinx start up is one line too
        try:
            code = _main(argv)
        except KeyboardInterrupt as exc:
            error(str(exc) or "interrupted")
            code = getattr(exc, "exit_code", EXIT_INTERRUPTED)
    if own:
        process.end_together(code)
        gc.freeze()  # no last collection of dolfinx's objects: 3.56, not 3.77 CPU-s a run (bench_run.py --against-src)
    return code


def _main(argv) -> int:
    args = build_parser(argv).parse_args(argv)
    if getattr(args, "_unavailable", None):
        error(f"the '{args.command}' command is unavailable ({args._unavailable})")
        return EXIT_INTERNAL
    problem = process.environment_problem(os.environ)
    if problem is not None:  # before PETSc and MPI start: each would print a page of its own and exit 1
        error(problem)
        return EXIT_INPUT
    return _command(args)


def _command(args) -> int:
    from ..errors import InstabilityError, Interrupted, OutputError, SceneError, SolverError, StackError

    petsc = args.command not in ("list", "show", "models", "plot")
    if petsc:
        from ..stack import load

        try:
            with process.argv_as_text():
                load()  # the FEniCS stack before PETSc installs its signal handlers: one line if it is not supported
        except StackError as exc:
            error(exc)
            return EXIT_INPUT
    with process.one_line_warnings(), process.signals_interrupt(petsc=petsc):
        try:
            if args.command == "run":
                return _run(args)
            from ..scene import toml as scenes

            if args.command == "list":
                listed = scenes.list_scenes()
                width = max((len(name) for name, _ in listed), default=0)
                print("".join(f"{name:{width}s}  {description}\n" for name, description in listed), end="")
            elif args.command in ("show", "models"):
                from .report import show_models, show_scene

                print(show_scene(scenes.load_scene(args.scene)) if args.command == "show" else show_models(), end="")
            else:
                return importlib.import_module(SUBCOMMANDS[args.command][0]).command(args)
            return EXIT_OK
        except (SceneError, OutputError, ValueError) as exc:
            error(exc)
            return EXIT_INPUT
        except (SolverError, InstabilityError, KeyboardInterrupt) as exc:  # a run stopped: its rows so far, then why
            _partial_report(exc)
            error(str(exc) or "interrupted")
            if isinstance(exc, SolverError):  # a numerical failure after the input was accepted (reliability.md)
                return EXIT_INTERNAL
            if isinstance(exc, InstabilityError):
                return EXIT_INPUT if exc.step == 0 else EXIT_UNSTABLE
            return exc.exit_code if isinstance(exc, Interrupted) else EXIT_INTERRUPTED
        except OSError as exc:  # a file a subcommand reads or writes
            error(f"{exc.strerror or exc}" + (f" ({exc.filename})" if getattr(exc, "filename", None) else ""))
            return EXIT_INPUT
        except RecursionError:  # crafted input nested too deeply (JSON, a .npy header): not a size problem
            error("RecursionError: an input file is nested too deeply to read; allowed: the files stringcontact writes")
            return EXIT_INPUT
        except MemoryError:
            error("MemoryError: out of memory: the problem, or an input file, is too large for this machine; "
                  "reduce nx or nt, or check the files read")
            return EXIT_INPUT
        except Exception as exc:  # noqa: BLE001 - a bug: one line, and the traceback on request
            if os.environ.get("STRINGCONTACT_TRACEBACK"):
                raise
            error(f"internal error {type(exc).__name__}: {exc} (set STRINGCONTACT_TRACEBACK=1 to see the traceback)")
            return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
