"""The command line: `stringcontact run|list|show` (also `python -m stringcontact`).

Exit codes: 0 success, 2 bad input (scene, options, output folder, a scheme that would be unstable
before it starts), 3 a run that became unstable, 130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings

EXIT_OK, EXIT_INPUT, EXIT_UNSTABLE, EXIT_INTERRUPTED = 0, 2, 3, 130

# Subcommands that live with their concern; each module has add_arguments(parser) and command(args) -> int,
# and keeps heavy imports (dolfinx, pyvista) inside its functions so that `--help` stays fast.
SUBCOMMANDS = {
    "plot": ("stringcontact.viz", "redraw the pictures of an output folder from its saved files"),
    "study": ("stringcontact.study", "work-precision, convergence and stability studies"),
    "check": ("stringcontact.theorems", "check the paper's (A1)-(A4) and Theorems 2.2-2.3 on a computed solution"),
}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, like every other input error
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="stringcontact", description="Inelastic contact of a viscoelastic string with an obstacle.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="simulate a scene and write XDMF, CSV and JSON")
    run.add_argument("scene", help="built-in scene name (see `stringcontact list`) or path to a .toml file")
    run.add_argument("--nx", type=int, help="number of cells")
    run.add_argument("--nt", type=int, help="number of time steps")
    run.add_argument("--eps", type=float, help="penalty parameter ε > 0")
    run.add_argument("--alpha", type=float, help="viscosity α ≥ 0")
    run.add_argument("--penalty", choices=("explicit", "semi-implicit"), default="explicit")
    run.add_argument("--mass", choices=("lumped", "consistent"), default="lumped")
    run.add_argument("--out", metavar="DIR", help="output folder (refused if not empty, unless --force)")
    run.add_argument("--force", action="store_true", help="replace a non-empty output folder")
    run.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    run.add_argument("--model", metavar="MODULE:FUNCTION", help="model variant (default: the scene's, else the paper's)")
    run.add_argument("--tol", type=float, help="choose the cheapest method and resolution with estimated error below TOL")
    run.add_argument("--no-pictures", action="store_true", help="write only XDMF, CSV and JSON")

    sub.add_parser("list", help="list the built-in scenes")
    show = sub.add_parser("show", help="print a scene as TOML")
    show.add_argument("scene")
    for name, (module, help_text) in SUBCOMMANDS.items():
        importlib.import_module(module).add_arguments(sub.add_parser(name, help=help_text))
    return parser


def _one_line_warnings():
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"stringcontact: warning: {message}", file=sys.stderr)

    warnings.showwarning = show


def _run(args) -> int:
    import stringcontact as sc

    scene = sc.load_scene(args.scene)
    changes = {k: getattr(args, k) for k in ("nx", "nt", "eps", "alpha") if getattr(args, k) is not None}
    if changes:
        scene = scene.replace(**changes)
    options = {"penalty": args.penalty, "mass": args.mass}
    if args.tol is not None:
        from .study import choose_for_tolerance

        scene, options, report = choose_for_tolerance(scene, args.tol)
        print(report)
    model = None
    if args.model or scene.model:
        from .variants import load_model

        model = load_model(args.model or scene.model)
    if args.out is not None:
        from .output import check_target

        check_target(args.out, args.force)
    res = sc.simulate(
        scene,
        **options,
        model=model,
        output_dir=args.out,
        progress=not args.no_progress,
        force=args.force,
        pictures=not args.no_pictures,
    )
    e = res.energy
    print(f"scene {scene.name}: nx={scene.nx} nt={scene.nt} dt={scene.dt:.4g} eps={scene.eps:.4g} r={scene.dt / scene.eps:.3g} "
          f"penalty={res.penalty} mass={res.mass}")
    print(f"min eta = {res.min_eta:.6g}; final contact length = {res.contact_length[-1]:.4g}")
    print(
        "energy balance: E0 = {:.6g} = E(T) {:.6g} + viscous {:.6g} + contact {:.6g} + numerical {:.6g}; residual {:.2e}".format(
            res.total_energy[0],
            res.total_energy[-1],
            e["viscous_dissipation"][-1],
            e["contact_dissipation"][-1],
            e["numerical_dissipation"][-1],
            abs(res.balance_residual[-1]),
        )
    )
    print("time: " + ", ".join(f"{k} {v:.3g} s" for k, v in res.timings.items()))
    if args.out is not None:
        print(f"wrote {args.out}")
    return EXIT_OK


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    _one_line_warnings()
    from .errors import InstabilityError, SceneError
    from .output import OutputError

    try:
        if args.command == "run":
            return _run(args)
        from . import scene as scenes

        if args.command == "list":
            for name, description in scenes.list_scenes():
                print(f"{name:12s} {description}")
            return EXIT_OK
        if args.command == "show":
            print(scenes.scene_to_toml(scenes.load_scene(args.scene)), end="")
            return EXIT_OK
        if args.command in SUBCOMMANDS:
            return importlib.import_module(SUBCOMMANDS[args.command][0]).command(args)
    except (SceneError, OutputError, ValueError) as exc:
        print(f"stringcontact: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except InstabilityError as exc:
        print(f"stringcontact: error: {exc}", file=sys.stderr)
        return EXIT_INPUT if exc.step == 0 else EXIT_UNSTABLE
    except KeyboardInterrupt:
        print("stringcontact: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_INPUT


if __name__ == "__main__":
    sys.exit(main())
