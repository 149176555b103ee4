"""`stringcontact study work-precision|convergence|stability|film`: run a study, write its CSV and PNG files.
Under ``mpirun -n K`` the cases are dealt over the ranks (`analysis.problems.distribute`); rank 0 writes."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..analysis import study as studies
from .staged import staged_output

#: The most times one run is timed (`--repeat`): the best of 100 is as good as a timing gets.
MAX_REPEAT = 100


def add_arguments(parser):
    """`stringcontact study`'s subcommands and their arguments."""
    sub = parser.add_subparsers(dest="study", required=True, metavar="{work-precision,convergence,stability,film}")
    specs = {
        "work-precision": "error against wall-clock time per method (flat landing and Example 1)",
        "convergence": "observed orders in dt = dx and in eps; the --tol estimate against the true error",
        "stability": "outcome over r = dt/eps per penalty and law, over dt/dx per scheme, restitution, alpha -> 0",
        "film": "the fluid film over its viscosity mu against the inelastic landing (docs/explanation/film.md)",
    }
    for name, help_text in specs.items():
        p = sub.add_parser(name, help=help_text)
        p.add_argument("--out", metavar="DIR", default="out/study", help="folder for the CSV and PNG files")
        p.add_argument("--force", action="store_true", help="replace a folder that holds an earlier study")
        p.add_argument("--quick", action="store_true", help="a small version (seconds), for tests and demos")
        if name == "work-precision":
            p.add_argument("--problem", choices=("flat-landing", "example1", "all"), default="all")
            p.add_argument("--repeat", type=int, default=1, help="time each run this many times, keep the best")


def command(args) -> int:
    """Run the study (its folder taken first: a refusal costs no computing), print its times and the files written."""
    from mpi4py import MPI

    comm, out, busy = MPI.COMM_WORLD, Path(args.out), []
    if args.study == "work-precision" and not 1 <= args.repeat <= MAX_REPEAT:
        raise ValueError(f"--repeat: {args.repeat} is out of range; allowed: an integer in [1, {MAX_REPEAT}] (each run "
                         "is timed that many times)")
    t0 = time.perf_counter()
    with staged_output(out, args.force, "study", comm) as partial:
        sweep, written = _sweep_and_write(args, comm, partial, busy)
    if comm.rank == 0:
        per_rank = np.sum(np.reshape(busy, (-1, comm.size)), axis=0) if busy else []
        print(f"study {args.study}: {comm.size} rank(s), {time.perf_counter() - t0:.2f} s wall-clock, of which the "
              f"sweep {sweep:.2f} s; " + _cpu_text(per_rank))
        print("".join(f"wrote {out / p.name}\n" for p in written), end="")
    return 0


def _cpu_text(per_rank) -> str:
    """The report's CPU-time clause: the cases' time on each rank, or where they ran (`study film`: rank 0)."""
    if len(per_rank) == 0:
        return "the cases ran one after another on rank 0"
    return "CPU time of the cases per rank: " + ", ".join(f"{b:.2f} s" for b in per_rank)


def _sweep_and_write(args, comm, partial: Path | None, busy: list) -> tuple[float, list[Path]]:
    """The study's sweep (its seconds), then its files written into `partial` on rank 0."""
    t_sweep, quick = time.perf_counter(), args.quick
    if args.study == "work-precision":
        names = ("flat-landing", "example1") if args.problem == "all" else (args.problem,)
        result = studies.work_precision(quick=quick, problem_names=names, repeat=args.repeat, comm=comm, busy=busy)
    elif args.study == "convergence":
        result = studies.convergence(quick=quick, comm=comm, busy=busy)
    elif args.study == "film":  # serial: rank 0 runs the sweep
        from ..analysis.film import film_study

        result = film_study(quick=quick) if comm.rank == 0 else None
    else:
        result = (studies.stability_map(quick=quick, comm=comm, busy=busy), studies.alpha_sweep(quick=quick, comm=comm, busy=busy),
                  studies.step_size_map(quick=quick, comm=comm, busy=busy))
    sweep = time.perf_counter() - t_sweep
    if result is None or partial is None:  # ranks > 0: rank 0 has the results
        return sweep, []
    written = _write(args, partial, result)
    (partial / "study.json").write_text(json.dumps({"study": args.study, "quick": quick,
                                                    "files": [p.name for p in written]}, indent=1) + "\n")
    return sweep, written


def _write(args, out: Path, result) -> list[Path]:
    """The study's CSV files and charts, written into `out` (the hidden staged folder)."""
    csv = studies.write_csv
    if args.study == "work-precision":
        return [csv(out / "study_work_precision.csv", result, studies.WORK_PRECISION_COLUMNS),
                studies.plot_work_precision(result, out / "study_work_precision.png")]
    if args.study == "film":
        return _write_film(out, result)
    if args.study == "convergence":
        tracking = studies.tolerance_tracking((3e-2, 1e-2) if args.quick else (3e-2, 1e-2, 5e-3))
        _print_orders(result["orders"], args.quick)
        for t in tracking:
            print(f"tol {t['tol']:g}: {t['method']} nx={t['nx']} estimate {t['estimate']:.3g} true {t['true_error']:.3g}")
        return [csv(out / "study_convergence.csv", result["runs"], studies.CONVERGENCE_COLUMNS),
                csv(out / "study_orders.csv", result["orders"], studies.ORDER_COLUMNS),
                csv(out / "study_tolerance.csv", tracking, studies.TOLERANCE_COLUMNS),
                studies.plot_convergence(result, out / "study_convergence.png")]
    stability, alpha_rows, step_rows = result
    return [csv(out / "study_stability.csv", stability, studies.STABILITY_COLUMNS),
            csv(out / "study_alpha.csv", alpha_rows, studies.ALPHA_COLUMNS),
            csv(out / "study_step_size.csv", step_rows, studies.STEP_COLUMNS),
            studies.plot_stability(stability, alpha_rows, out / "study_stability.png"),
            studies.plot_step_size(step_rows, out / "study_step_size.png")]


def _print_orders(orders, quick: bool) -> None:
    """The observed orders, one line each; after --quick, a note first that its levels are pre-asymptotic."""
    if quick and orders:
        print("note: --quick runs three coarse levels, before the asymptotic range: the orders below (negative ones "
              "too) do not measure the schemes' convergence; run without --quick for those (docs/explanation/study.md)")
    for o in orders:
        print(f"order in {o['sweep']:3s} {o['method']:14s} {o['quantity']:12s} {o['order']:.3f}")


def _write_film(out: Path, rows: list[dict]) -> list[Path]:
    """`study film`'s rows, its fitted power laws in mu, and its chart; the laws printed."""
    from ..analysis.film import FILM_COLUMNS, RATE_COLUMNS, fit_rates, plot_film_study
    from ..model.film import H_MIN

    rates = fit_rates(rows)
    for r in rates:
        cavitation = "no cavitation" if np.isnan(r["p_cav"]) else f"p_cav = {r['p_cav']:g}"
        print(f"film {r['problem']:8s} {cavitation:14s} {r['quantity']:12s} ~ mu^{r['rate']:.3f} (mu = {r['mus']})")
    return [studies.write_csv(out / "study_film.csv", rows, FILM_COLUMNS),
            studies.write_csv(out / "study_film_rates.csv", rates, RATE_COLUMNS),
            plot_film_study(rows, out / "study_film.png", H_MIN)]
