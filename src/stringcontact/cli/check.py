"""`stringcontact check SCENE`: the paper's (A1)–(A4), Theorems 2.2/2.3 and (1.4) on a computed solution, as a
table of numbers with verdicts (`stringcontact.analysis.theorems`); ``--out`` also writes checks.json, checks.txt
and figure1.png."""

from __future__ import annotations

import json
from pathlib import Path

from ..analysis import theorems
from ..analysis.problems import FLAT_V, flat_landing_scene
from ..analysis.theorems import FLAT_LANDING, STRESS_JUMP, penalised, run_checks
from .staged import staged_output


def add_arguments(parser):
    """`stringcontact check`'s arguments."""
    from .parser import add_scene_flags

    parser.description = ("The paper's (A1)-(A4) and Theorems 2.2-2.3 on a computed solution at --levels resolutions "
                          "(scheme projection refines nx and nt only, no eps); (A4) is the paper's restitution e = 0.")
    add = parser.add_argument
    add("scene", help=f"built-in scene, a .toml file, or '{FLAT_LANDING}' (the exact alpha=0 case)")
    add_scene_flags(parser, " of the finest level")
    add("--levels", type=int, default=3, help="refinement levels for the trends (nx, nt, 1/eps halved per level; default 3)")
    add("--delay", type=float, help="(A4) delay after first contact (default 8 eps; 2 dt for an eps-free scheme)")
    add("--delta", type=float, default=0.02, help="Thm 2.3(1) band half-width around fronts")
    add("--out", metavar="DIR", help="write checks.json, checks.txt and figure1.png here")
    add("--force", action="store_true", help="replace a non-empty output folder")


def _scene_from_args(args):
    """The finest level's scene (1D only): --nx and --nt checked as flags; --eps, --penalty and --restitution
    refused as by `run`."""
    from ..errors import SceneError
    from ..scene import load_scene
    from ..scene.limits import INT_BOUNDS
    from .parser import scene_with_flags

    for key in ("nx", "nt"):
        value, (low, high) = getattr(args, key), INT_BOUNDS[key]
        if value is not None and not low <= value <= high:
            raise ValueError(f"--{key}: {value} is out of range; allowed: an integer in [{low}, {high}]")
    keys = ("eps", "alpha", "restitution")
    if args.scene == FLAT_LANDING:  # keep r = dt/eps = 0.4 when only the grid is changed
        scene = flat_landing_scene(args.nx if args.nx is not None else 1000, args.nt if args.nt is not None else 1200, r=0.4)
    else:
        scene, keys = load_scene(args.scene), ("nx", "nt", *keys)
        if scene.dim != 1:
            raise SceneError(f"scene {scene.name!r}: domain {scene.domain!r}: `stringcontact check` is 1D-only (the "
                             "paper's theorems are about the string); allowed: a scene with domain 'interval'")
    return scene_with_flags(args, scene, "it refines nx and nt only", keys)


def _compute(args, scene):
    """The levels' runs and their checks, the table and the trends printed: ``(finest, results, checks)``."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", category=UserWarning)  # scene warnings were shown by `show`/`run`
        checks, finest, results = run_checks(scene, args.levels, args.penalty, args.delay, args.delta,
                                             FLAT_V if scene.name == FLAT_LANDING else None, scheme=args.scheme)
    levels = [f"nx={r.scene.nx} nt={r.scene.nt}" + (f" eps={r.scene.eps:.3g}" if penalised(finest) else "") for r in results]
    rule = f" (r = dt/eps = {scene.r:.3g})" if penalised(finest) else " (no eps)"
    print(f"scene {scene.name}, scheme {finest.scheme}, restitution e = {scene.restitution or 0:g}: levels "
          f"{', '.join(levels)}{rule}\n{theorems.format_table(checks)}\n\n{theorems.format_trends(checks)}")
    return finest, results, checks


def command(args) -> int:
    """Check the flags, take the --out folder (a refusal costs no computing), compute, print and write."""
    from mpi4py import MPI

    if not 1 <= args.levels <= 6:
        raise ValueError(f"--levels must be between 1 and 6, got {args.levels}")
    if args.delay is not None and not args.delay > 0:
        raise ValueError(f"--delay must be > 0, got {args.delay}")
    scene = _scene_from_args(args)
    if not 0 < args.delta <= scene.length:  # a band half-width in x: 1e308 overflowed (and nan is refused)
        raise ValueError(f"--delta: {args.delta:g} is out of range; allowed: a number in (0, length = {scene.length:g}] "
                         "(the half-width of the band around the fronts)")
    if args.delay is not None and args.delay >= scene.T:
        raise ValueError(f"--delay must be below T = {scene.T:g}, got {args.delay}")
    with staged_output(args.out, args.force, "check", MPI.COMM_WORLD) as partial:
        finest, results, checks = _compute(args, scene)
        if partial is not None:
            (partial / "checks.json").write_text(json.dumps(
                {"scene": scene.name, "levels": [r.scene.as_dict() for r in results],
                 "checks": [c.as_dict() for c in checks]}, indent=1, default=float))
            (partial / "checks.txt").write_text(theorems.format_table(checks) + "\n\n" + theorems.format_trends(checks) + "\n")
            balance = next(c.data for c in checks if c.name == STRESS_JUMP)  # computed by run_checks
            theorems.draw_figure1(finest, partial / "figure1.png", args.delta, balance=balance)
    if args.out is not None and MPI.COMM_WORLD.rank == 0:
        print(f"wrote {Path(args.out)}")
    return 0
