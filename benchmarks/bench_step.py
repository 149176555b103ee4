"""Per step of every scheme at the paper's resolution, against the NumPy peer and (optionally) another checkout.

    .venv/bin/python benchmarks/bench_step.py                          # this checkout, 3 rounds
    .venv/bin/python benchmarks/bench_step.py --against /tmp/before    # and a checkout's src/ alternately
    .venv/bin/python benchmarks/bench_step.py --loop /tmp/before --repeats 6   # the step and the march loop alone
    .venv/bin/python benchmarks/bench_step.py --refactor lapack        # the peers' changed matrices by LAPACK's dgtsv
    .venv/bin/python benchmarks/bench_step.py --check-peers            # each peer's rows against simulate's
    .venv/bin/python benchmarks/bench_step.py --compiled               # the C loop alone (--cflags=-O2: other flags)
    .venv/bin/python benchmarks/bench_step.py --law                    # the contact law alone: all nodes or candidates
    PYTHONPATH=/tmp/before/src .venv/bin/python benchmarks/bench_step.py --save before.npz   # every stored array,
    .venv/bin/python benchmarks/bench_step.py --save after.npz                               # then: bit for bit?
    .venv/bin/python benchmarks/bench_step.py --same before.npz after.npz
    ... --save FILE.npz --scenes example2,bump,loaded_string,single_impact,drum             # the other built-in scenes

Example 1 (nx = 5000, Δt = 2e-4, 1500 steps). Each round starts one fresh process per checkout, alternately; in it
each scheme (paper explicit, paper semi-implicit, projection, newmark), each followed by its own NumPy peer
(`peers.py`: splu, vectorised right-hand side, the scheme's own contact step, the same
stored rows), run `--repeats` times, alternately. `--check-peers` first: every peer's η
against `simulate`'s at every stored row. "µs/step" is `simulate`'s time loop (`timings["solve"]`: the steps and
the stored rows, no output) over the steps; the peer's is its whole loop. Medians over all runs; "ratio to its
peer" is the median of the ratios of runs made next to each other. The compiled limit is measured in the same
process, beside each run of the paper's scheme (`peers.compiled_peer`: a C loop of the same scheme with the
system's compiler, -O3 -march=native): the solve alone (the issue's "Thomas loop") and the same with the energy identity
that every scheme books per step; the last two columns are the ratios to them. Prints a Markdown table, with
`uptime`'s load before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

try:  # a checkout timed by --against from before the peers moved to benchmarks/ runs its own, as it did then
    from stringcontact.verification import peers
except ImportError:
    import peers

RUNS = (("paper", {}), ("paper semi-implicit", {"penalty": "semi-implicit"}), ("projection", {}), ("newmark", {}))


def peer_of(name: str, refactor: str = "splu"):
    """The NumPy peer (`peers.py`) of a run of RUNS."""
    if name == "paper":
        return peers.paper_peer
    peer = {
        "paper semi-implicit": peers.semi_implicit_peer,
        "projection": peers.projection_peer,
        "newmark": peers.newmark_peer,
    }[name]
    return lambda scene, steps: peer(scene, steps, refactor)


def check_compiled(lib, scene, res) -> float:
    """Print the C loop's max |Δη|, |Δv| against `simulate`'s rows `res` (without and with the energy identity),
    and its ledger against `simulate`'s energies at T (relative to E(0)); returns the largest of them."""
    worst = 0.0
    E0 = res.energy["kinetic"][0] + res.energy["elastic"][0]
    for energies in (False, True):
        eta, v, ledger, _ = peers.compiled_peer(lib, scene, res.steps, energies)
        d_eta, d_v = np.max(np.abs(eta - res.eta)), np.max(np.abs(v - res.velocity))
        line = f"compiled ({'with' if energies else 'without'} energies): max |Δη| {d_eta:.2e}, max |Δv| {d_v:.2e}"
        worst = max(worst, d_eta)
        if energies:
            gaps = {k: abs(ledger[k] - res.energy[k][-1]) / E0 for k in peers.LEDGER[:-1]}
            line += "; ledger at T, |Δ|/E(0): " + ", ".join(f"{k} {g:.1e}" for k, g in gaps.items())
            line += f"; min η {ledger['min_eta']:.6g} (simulate {res.min_eta:.6g})"
            worst = max(worst, *gaps.values(), abs(ledger["min_eta"] - res.min_eta))
        print(line)
    return worst


def compiled_alone(cflags: str) -> int:
    """The C loop alone on Example 1: its rows and ledger against `simulate`'s, then µs per step of both variants
    (medians of 9); 1 if it is off by more than 1e-6."""
    from mpi4py import MPI

    import stringcontact as sc

    scene = sc.load_scene("example1")
    res = sc.simulate(scene, comm=MPI.COMM_SELF)
    lib = peers.build_compiled(tuple(cflags.split()))
    worst = check_compiled(lib, scene, res)
    for energies in (False, True):
        times = [peers.compiled_peer(lib, scene, res.steps, energies)[3] / scene.nt * 1e6 for _ in range(9)]
        print(
            f"compiled, {'with' if energies else 'without'} the energy identity: median {np.median(times):.1f} µs/step "
            f"(min {min(times):.1f}, 9 runs)"
        )
    return 1 if worst > 1e-6 else 0


def child(repeats: int, refactor: str) -> dict:
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    scene, lib = sc.load_scene("example1"), peers.build_compiled()
    times = {key: [] for name, _ in RUNS for key in (name, f"{name} peer")} | {"compiled": [], "compiled, energies": []}
    for _ in range(repeats + 1):  # the first round warms up (JIT cache, page faults) and is not counted
        for name, kw in RUNS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = sc.simulate(scene, scheme=name.split()[0], comm=MPI.COMM_SELF, **kw)
            times[name].append(res.timings["solve"] / scene.nt * 1e6)
            t0 = time.perf_counter()
            peer_of(name, refactor)(scene, res.steps)
            times[f"{name} peer"].append((time.perf_counter() - t0) / scene.nt * 1e6)
            if name == "paper":
                for key, energies in (("compiled", False), ("compiled, energies", True)):
                    times[key].append(peers.compiled_peer(lib, scene, res.steps, energies)[3] / scene.nt * 1e6)
    return {"file": sc.__file__, **{k: v[1:] for k, v in times.items()}}


def check_peers(refactor: str) -> int:
    """Each peer against `simulate` at every stored row: max |Δη| and |Δv|; 1 if a peer is off by more than 1e-6
    (the schemes' own round-off at this resolution is about 1e-9, docs/explanation/performance.md)."""
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    scene, worst = sc.load_scene("example1"), 0.0
    for name, kw in RUNS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = sc.simulate(scene, scheme=name.split()[0], comm=MPI.COMM_SELF, **kw)
        eta, v = peer_of(name, refactor)(scene, res.steps)
        d_eta, d_v = np.max(np.abs(eta - res.eta)), np.max(np.abs(v - res.velocity))
        print(f"{name}: max |Δη| {d_eta:.2e}, max |Δv| {d_v:.2e} over {len(res.steps)} stored rows")
        worst = max(worst, d_eta)
        if name == "paper":  # the compiled loop, and its energy ledger against simulate's
            worst = max(worst, check_compiled(peers.build_compiled(), scene, res))
    return 1 if worst > 1e-6 else 0


def run_child(src: str | None, repeats: int, refactor: str) -> dict:
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = str(Path(src) / "src") + os.pathsep + env.get("PYTHONPATH", "")
    command = [sys.executable, __file__, "--child", str(repeats), "--refactor", refactor]
    proc = subprocess.run(command, check=False, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise SystemExit(proc.stderr)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def law_timing(repeats: int) -> None:
    """The penalty F(η^n, v^n) on every node (the UFL graph's closures) against the candidate path, at the states
    of Example 1's stored rows, alternately."""
    import timeit

    import numpy as np
    from mpi4py import MPI

    import stringcontact as sc
    from stringcontact.run.stepper import Stepper

    scene = sc.load_scene("example1")
    res = sc.simulate(scene, comm=MPI.COMM_SELF)
    problem = Stepper(scene, "paper", "explicit", "lumped", comm=MPI.COMM_SELF).core.discrete  # what the scheme steps
    law = problem.laws.compile(problem.laws.model.penalty(problem.laws.eta, problem.laws.quotient, problem.laws.params))
    full, sub = [], []
    for row in range(1, len(res.t)):
        problem.laws.set(eta=res.eta[row].copy(), eta_old=res.eta[row] - scene.dt * res.velocity[row])
        with np.errstate(all="ignore"):
            for _ in range(repeats):
                full.append(
                    min(timeit.repeat(lambda: np.where(True, law._f(problem.laws.env), 0.0), number=20, repeat=3)) / 20
                )
                sub.append(min(timeit.repeat(lambda: law.evaluate_env(problem.laws.env), number=20, repeat=3)) / 20)
    print(
        f"penalty at {len(res.t) - 1} stored states of Example 1 (mean over them): every node "
        f"{1e6 * statistics.mean(full):.1f} µs, candidates only {1e6 * statistics.mean(sub):.1f} µs"
    )


def _module_of(src: str, name: str):
    """Module `name` (e.g. "stringcontact.timestepping.paper") of the checkout at `src`, loaded beside this one's
    under another name: its relative imports resolve in this checkout's package."""
    import importlib.util

    path = Path(src) / "src" / Path(*name.split(".")).with_suffix(".py")
    spec = importlib.util.spec_from_file_location(f"{name}_before", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class _Still:
    """A scheme that does nothing: `Stepper._advance` alone, the core's and the observers' per-step Python."""

    PENALTIES, situation, remedy, energy_slack = (), "", "", 0.0
    terms = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def __init__(self):
        import numpy as np

        self.eta = self.velocity = np.zeros(5001)
        self.fields = {}

    def step(self):
        return self.terms


def _still_stepper(scene):
    """A `Stepper` of Example 1 whose scheme does nothing and whose rows store nothing: its `_advance` is the driver's
    per-step Python alone."""
    import numpy as np
    from mpi4py import MPI

    from stringcontact.core.ledger import EnergyLedger
    from stringcontact.run.stepper import Stepper

    st = Stepper(scene, comm=MPI.COMM_SELF)
    st.core.scheme = _Still()
    st.core.ledger = EnergyLedger(_Still.terms, conservative=False)
    st.rows.steps = np.array([scene.nt + 1])  # no row is stored: the observer's per-step work alone
    return st


def loop_timing(src: str, runs: int) -> None:
    """In one process, alternately: the paper scheme's 1500 steps (`Scheme.step` alone) of this checkout and of
    `src`'s, and this checkout's per-step driver Python (`Stepper._advance` with a scheme that does nothing). Thread
    CPU time, so that other jobs on the machine weigh less; medians and the median of paired ratios."""
    import numpy as np
    from mpi4py import MPI

    import stringcontact as sc
    from stringcontact.run.stepper import Stepper
    from stringcontact.timestepping import paper

    scene = sc.load_scene("example1")
    problem = Stepper(scene, "paper", "explicit", "lumped", comm=MPI.COMM_SELF).core.discrete  # what the scheme steps
    eta0 = np.asarray(scene.initial_displacement(problem.x), dtype=float).copy()
    eta0[problem.bc] = problem.g  # the start the driver gives a scheme: the ends at their heights, at rest
    v0 = np.asarray(scene.initial_velocity(problem.x), dtype=float) * problem.interior
    schemes = {"this checkout": paper, src: _module_of(src, "stringcontact.timestepping.paper")}
    steps = {k: [] for k in schemes}
    march = []
    np.seterr(all="ignore")
    for r in range(runs):
        for label in list(schemes) if r % 2 == 0 else list(schemes)[::-1]:
            module = schemes[label]
            scheme = getattr(module, "PaperScheme", None) or module.Scheme  # the class's name before the core
            scheme = scheme(problem)
            scheme.start(eta0, v0)
            t0 = time.thread_time()
            for _ in range(scene.nt):
                scheme.step()
            steps[label].append((time.thread_time() - t0) / scene.nt * 1e6)
        st = _still_stepper(scene)
        t0 = time.thread_time()
        for _ in range(scene.nt):
            st._advance()
        march.append((time.thread_time() - t0) / scene.nt * 1e6)
    print(
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {os.getloadavg()[0]:.2f}; {runs} runs each, "
        "thread CPU time\n"
    )
    print("| checkout | paper's step alone [µs] |")
    print("|---|---:|")
    for label in schemes:
        print(f"| {label} | {statistics.median(steps[label]):.1f} |")
    first, second = schemes
    print(f"step: median paired ratio {statistics.median(a / b for a, b in zip(steps[first], steps[second])):.3f}")
    print(f"this checkout's driver per step (`Stepper._advance`, a still scheme): {statistics.median(march):.2f} µs")


def save_fields(path: str, scenes: list[str]) -> None:
    """Every stored array (fields, energies, series) of each scheme's run of each scene into `path` (.npz); Example 1's
    keys are "run/field", another scene's "scene/run/field". A run the scene refuses is saved as its error's name."""
    import warnings

    from mpi4py import MPI

    import stringcontact as sc

    arrays = {}
    for scene in scenes:
        prefix = "" if scene == "example1" else f"{scene}/"
        for name, kw in RUNS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    res = sc.simulate(sc.load_scene(scene), scheme=name.split()[0], comm=MPI.COMM_SELF, **kw)
                except (ValueError, sc.InstabilityError) as exc:  # e.g. a penalty too stiff for the scene's dt
                    arrays[f"{prefix}{name}/refused"] = np.frombuffer(type(exc).__name__.encode(), np.uint8)
                    continue
            for field in ("eta", "velocity", "contact", "contact_force"):
                arrays[f"{prefix}{name}/{field}"] = getattr(res, field)
            arrays.update({f"{prefix}{name}/energy/{k}": v for k, v in res.energy.items()})
            arrays.update({f"{prefix}{name}/series/{k}": v for k, v in res.series.items()})
    np.savez(path, **arrays)
    print(f"{sc.__file__}: {len(arrays)} arrays into {path}")


def same_bits(first: str, second: str) -> int:
    """Compare two `--save` files byte for byte (NaN and -0.0 included); 0 if every array is identical."""
    import numpy as np

    a, b = np.load(first), np.load(second)
    differ = [k for k in a.files if k not in b.files or a[k].shape != b[k].shape or a[k].tobytes() != b[k].tobytes()]
    print(
        f"{len(a.files) - len(differ)} of {len(a.files)} arrays bit-identical"
        + "".join(f"\n  differs: {k}" for k in differ)
    )
    return 1 if differ else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="fresh processes per checkout, alternately")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each scheme per process")
    ap.add_argument("--against", help="another checkout (its src/ is put first on PYTHONPATH)")
    ap.add_argument("--law", action="store_true", help="time the contact law alone")
    ap.add_argument(
        "--loop", metavar="CHECKOUT", help="paper's step and the march loop alone, against CHECKOUT's, in one process"
    )
    ap.add_argument("--check-peers", action="store_true", help="each peer against simulate at every stored row")
    ap.add_argument("--compiled", action="store_true", help="the C loop alone: against simulate, then µs per step")
    ap.add_argument(
        "--cflags",
        default=" ".join(peers.CFLAGS),
        help=f"--compiled: the compiler's flags (default: {' '.join(peers.CFLAGS)})",
    )
    ap.add_argument("--save", metavar="FILE.npz", help="save every stored array of the four runs, then stop")
    ap.add_argument("--scenes", default="example1", help="--save: the built-in scenes, comma-separated")
    ap.add_argument("--same", nargs=2, metavar="FILE.npz", help="compare two --save files bit for bit")
    ap.add_argument(
        "--refactor",
        choices=("splu", "lapack"),
        default="splu",
        help="how the peers solve with a step matrix that changed (see _factor)",
    )
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.save:
        save_fields(args.save, args.scenes.split(","))
        return 0
    if args.same:
        return same_bits(*args.same)
    if args.child is not None:
        print(json.dumps(child(args.child, args.refactor)))
        return 0
    if args.law:
        law_timing(args.repeats)
        return 0
    if args.check_peers:
        return check_peers(args.refactor)
    if args.compiled:
        return compiled_alone(args.cflags)
    if args.loop:
        loop_timing(args.loop, 2 * args.repeats)
        return 0
    checkouts = {"this checkout": None} | ({f"{args.against}": args.against} if args.against else {})
    load_before = os.getloadavg()
    results = {label: [] for label in checkouts}
    for _ in range(args.rounds):
        for label, src in checkouts.items():
            results[label].append(run_child(src, args.repeats, args.refactor))
    load_after = os.getloadavg()
    print(
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average before {load_before[0]:.2f}, after "
        f"{load_after[0]:.2f}; {args.rounds} rounds × {args.repeats} runs; peers refactorise with {args.refactor}\n"
    )
    for label, rounds in results.items():
        print(f"{label}: {rounds[0]['file']}")
    print()
    limits = {
        label: [statistics.median(t for r in rounds for t in r[key]) for key in ("compiled", "compiled, energies")]
        for label, rounds in results.items()
    }  # µs/step of the C loop: the solve alone, with the energy identity
    for label, (solve, with_energies) in limits.items():
        print(
            f"{label}: compiled limit {solve:.1f} µs/step (solve alone), {with_energies:.1f} µs/step (with the energy identity)"
        )
    print()
    print(
        "| checkout | scheme | µs/step | its NumPy peer [µs/step] | ratio to its peer | ratio to compiled, solve alone | "
        "ratio to compiled, with energies |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    for label, rounds in results.items():
        solve, with_energies = limits[label]
        for name, _ in RUNS:
            mine = [t for r in rounds for t in r[name]]
            peer = [t for r in rounds for t in r[f"{name} peer"]]
            ratios = [a / b for a, b in zip(mine, peer)]  # runs made next to each other
            print(
                f"| {label} | {name} | {statistics.median(mine):.0f} | {statistics.median(peer):.0f} | "
                f"{statistics.median(ratios):.2f} | {statistics.median(mine) / solve:.1f} | {statistics.median(mine) / with_energies:.1f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
