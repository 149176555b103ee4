"""The command line's parser: `build_parser`, with the arguments of `run`, `list`, `show` and `models`, and those of a
subcommand of `SUBCOMMANDS` (its module's `add_arguments`) only when the command line names it."""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import sys

from ..errors import one_line
from ..scene.names import DEFAULT_SCHEME, SCHEMES
from .process import EXIT_INPUT

#: Subcommands that live with their concern: each module has add_arguments(parser) and command(args) -> int.
SUBCOMMANDS = {
    "plot": ("stringcontact.cli.plot", "redraw the pictures of an output folder from its saved files"),
    "study": ("stringcontact.cli.study", "work-precision, convergence and stability studies"),
    "check": ("stringcontact.cli.check", "check the paper's (A1)-(A4) and Theorems 2.2-2.3 on a computed solution"),
}


def _version() -> str:
    """The installed distribution's version (importlib.metadata)."""
    try:
        return importlib.metadata.version("stringcontact")
    except importlib.metadata.PackageNotFoundError:
        return "unknown (not installed: run scripts/setup)"


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, like every other input error; "stringcontact: error:" first
        root, _, sub = self.prog.partition(" ")  # a subcommand's parser is "stringcontact run"
        self.exit(EXIT_INPUT, f"{root}: error: {sub + ': ' if sub else ''}{one_line(message)}\n")


def add_scene_flags(parser, level: str) -> None:
    """The flags that change the scene `run` and `check` compute: --nx, --nt, --eps (those of the `level` of a
    refinement), --alpha, --restitution, --scheme and --penalty."""
    add = parser.add_argument
    add("--nx", type=int, help="number of cells" + level)
    add("--nt", type=int, help="number of time steps" + level)
    add("--eps", type=float, help="penalty parameter ε > 0" + level)
    add("--alpha", type=float, help="viscosity α ≥ 0")
    add("--restitution", type=float, metavar="E",
        help="restitution coefficient e in [0, 1] of scheme projection (default: the scene's, else 0: inelastic)")
    # the names only: a description is read from the scheme's class, which would load dolfinx before the run starts
    add("--scheme", choices=tuple(SCHEMES), help="time scheme (default: the scene's, else paper); "
        "stringcontact.SCHEMES describes each")
    add("--penalty", choices=("explicit", "semi-implicit"), help="default: the scheme's (paper: explicit)")


def scene_with_flags(args, scene, takes: str, keys=("nx", "nt", "eps", "alpha", "restitution"), **more):
    """`scene` with the values of `add_scene_flags`' `keys` given and `more` (a new, checked scene); --eps or
    --penalty refused with a scheme that has no penalty (saying what it `takes` instead), a restitution e > 0 but
    with projection."""
    from ..timestepping import check_restitution, scheme_class

    changes = {k: getattr(args, k) for k in keys if getattr(args, k) is not None} | more
    scene = scene.replace(**changes) if changes else scene
    name = args.scheme or scene.scheme or DEFAULT_SCHEME
    check_restitution(name, scene.restitution or 0.0)
    if not scheme_class(name).PENALTIES and (args.eps is not None or args.penalty is not None):
        given = "--eps" if args.eps is not None else "--penalty"
        raise ValueError(f"{given}: scheme {name!r} uses no penalty (no eps); {takes}")
    return scene


def build_parser(argv=None) -> argparse.ArgumentParser:
    """The command line's parser. The subcommands of `SUBCOMMANDS` get their arguments only when `argv` (default:
    the process's own) names them: their modules import dolfinx and more, 1.1 s that `--help`, `list` and `show` do
    not need (`python -X importtime -c "import stringcontact.cli.check"`)."""
    named = set(sys.argv[1:] if argv is None else argv)
    parser = _Parser(prog="stringcontact", description="Inelastic contact of a viscoelastic string with an obstacle.")
    parser.add_argument("--version", action="version", version=f"stringcontact {_version()}",
                        help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="simulate a scene and write XDMF, CSV and JSON")
    run.add_argument("scene", help="built-in scene name (see `stringcontact list`) or path to a .toml file")
    add_scene_flags(run, "")
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
    sub.add_parser("models", help="list the models a scene may name (registered under stringcontact.models)",
                   description="The models a scene's `model` key may name: those registered under stringcontact.models.")
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
