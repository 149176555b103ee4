"""Per step of every scheme at the paper's resolution, against the NumPy peer and (optionally) another checkout.

    .venv/bin/python benchmarks/bench_step.py                          # this checkout, 3 rounds
    .venv/bin/python benchmarks/bench_step.py --against /tmp/before    # and a checkout's src/ alternately
    .venv/bin/python benchmarks/bench_step.py --loop /tmp/before --repeats 6   # the step and the march loop alone
    .venv/bin/python benchmarks/bench_step.py --refactor lapack        # the peers' changed matrices by LAPACK's dgtsv
    .venv/bin/python benchmarks/bench_step.py --check-peers            # each peer's rows against simulate's
    .venv/bin/python benchmarks/bench_step.py --law                    # the contact law alone: all nodes or candidates
    PYTHONPATH=/tmp/before/src .venv/bin/python benchmarks/bench_step.py --save before.npz   # every stored array,
    .venv/bin/python benchmarks/bench_step.py --save after.npz                               # then: bit for bit?
    .venv/bin/python benchmarks/bench_step.py --same before.npz after.npz
    ... --save FILE.npz --scenes example2,bump,loaded_string,single_impact,drum             # the other built-in scenes

Example 1 (nx = 5000, Δt = 2e-4, 1500 steps). Each round starts one fresh process per checkout, alternately; in it
each scheme (paper explicit, paper semi-implicit, projection, newmark), each followed by its own NumPy peer (the
paper's is `bench_solver.numpy_peer`; the others are below: splu, vectorised right-hand side, the scheme's own
contact step, the same stored rows), run `--repeats` times, alternately. `--check-peers` first: every peer's η
against `simulate`'s at every stored row. "µs/step" is `simulate`'s time loop (`timings["solve"]`: the steps and
the stored rows, no output) over the steps; the peer's is its whole loop. Medians over all runs; "ratio to its
peer" is the median of the ratios of runs made next to each other. The compiled limit is measured in the same
process, beside each run of the paper's scheme (`compiled_peer.py`: a C loop of the same scheme with the system's
compiler, -O3 -march=native): the solve alone (the issue's "Thomas loop") and the same with the energy identity
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
import scipy.sparse as sp
from scipy.sparse.linalg import splu

HERE = Path(__file__).resolve().parent
RUNS = (("paper", {}), ("paper semi-implicit", {"penalty": "semi-implicit"}), ("projection", {}), ("newmark", {}))


# --- the NumPy/SciPy peers of the other schemes (Example 1's string: finite differences = the lumped FEM) -------------
#
# Each is what a researcher would write with scipy.sparse for the same scheme on a uniform string, ψ = 0 and no load
# (the paper's model): the interior unknowns, the step matrix factorised once with `splu` (and again with `splu`
# whenever the scheme's matrix changes: a new active set), a vectorised right-hand side, the same contact step, and
# η, v stored at the same rows as `simulate`. Like the paper's peer (`bench_solver.numpy_peer`) they compute no
# energies. Scaled by Δt²/Δx (paper) or Δt²/(4Δx) (newmark), with T = tridiag(−1, 2, −1):
# M = Δx I, K = T/Δx, C = αK, m_F = Δx.


def _string(scene):
    N, dt = scene.nx, scene.dt
    dx = scene.length / N
    x = np.linspace(0.0, scene.length, N + 1)
    eta = np.asarray(scene.initial_displacement(x), dtype=float).copy()
    eta[0], eta[-1] = scene.h_left, scene.h_right
    v = np.asarray(scene.initial_velocity(x), dtype=float) * np.ones(N + 1)
    v[[0, -1]] = 0.0
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(N - 1, N - 1), format="csc")
    return dt, dx, eta, v, T


def _factor(A, refactor: str):
    """The solve of a step matrix that changed: `splu` (the sparse LU, 2.1 ms for this string), or with `refactor`
    "lapack" LAPACK's tridiagonal solver dgtsv, which factorises and solves in one call (115 µs), every step the
    matrix differs from the one factorised once."""
    if refactor == "splu":
        return splu(A.tocsc()).solve
    from scipy.linalg.lapack import dgtsv

    A = A.tocsr()
    dl, d, du = A.diagonal(-1), A.diagonal(), A.diagonal(1)
    return lambda b: dgtsv(dl, d, du, b)[3]


def _laplacian(e: np.ndarray) -> np.ndarray:
    """(T η) at the interior nodes, the ends included as neighbours."""
    return 2.0 * e[1:-1] - e[:-2] - e[2:]


class _Stored:
    def __init__(self, steps, n):
        self.steps, self.row = steps, 0
        self.eta, self.v = np.empty((len(steps), n)), np.empty((len(steps), n))

    def __call__(self, step, eta, v):
        if self.row < len(self.steps) and self.steps[self.row] == step:
            self.eta[self.row], self.v[self.row] = eta, v
            self.row += 1


def projection_peer(scene, stored_steps, refactor: str = "splu"):
    """`projection` (α > 0): (I + aT) η¹ = 2η − η⁰ + (a − r₀) Tη + F' with η¹ ≥ 0, F' ≥ 0, F'·η¹ = 0, a = αΔt/Δx²,
    r₀ = Δt²/Δx². The contact step as the scheme does it: the free step; if a node is below 0, the primal–dual
    active set from {η̃ < 0}: the active rows replaced by identity rows (refactorised with splu when the set differs
    from the last one factorised), F' = (A η − b) on it, until the set stays. The stored v is the centred one."""
    dt, dx, eta, v0, T = _string(scene)
    a, r0 = scene.alpha * dt / dx**2, dt**2 / dx**2
    n = eta.size - 2
    A = (sp.identity(n, format="csc") + a * T).tocsc()
    free_lu = splu(A)
    held, held_solve = None, None
    tol = -1e-14 * max(np.max(np.abs(eta)), 1.0) * (1 + 2 * a)  # the scheme's allowance for round-off in F
    store = _Stored(stored_steps, eta.size)
    eta_old = eta - dt * v0
    levels = [eta_old, eta]  # η^{n−1}, η^n
    store(0, eta, v0)
    for step in range(scene.nt + 1):  # one step ahead: the row at n needs η^{n+1}
        e_old, e = levels
        b = 2.0 * e[1:-1] - e_old[1:-1] + (a - r0) * _laplacian(e)
        b[0] += a * e[0]
        b[-1] += a * e[-1]
        new = e.copy()
        inner = free_lu.solve(b)
        active = inner < 0.0
        while active.any():
            if held is None or not np.array_equal(active, held):
                held = active
                keep = sp.diags((~active).astype(float))
                held_solve = _factor(keep @ A + sp.diags(active.astype(float)), refactor)
            inner = held_solve(np.where(active, 0.0, b))
            R = A @ inner - b
            new_active = np.where(active, R > tol, inner < 0.0)
            if np.array_equal(new_active, active):
                break
            active = new_active
        new[1:-1] = inner
        if step >= 1:
            store(step, e, (new - e_old) / (2 * dt))
        levels = [e, new]
    return store.eta, store.v


def _damped_peer(scene, stored_steps, newmark: bool, refactor: str):
    dt, dx, eta, v, T = _string(scene)
    a, r0, k = scene.alpha * dt / dx**2, dt**2 / dx**2, dt / scene.eps
    n = eta.size - 2
    lhs = (a / 2 + r0 / 4) if newmark else (a + r0)
    A0 = (sp.identity(n, format="csc") + lhs * T).tocsc()
    undamped = splu(A0).solve
    solve, damped = undamped, np.zeros(n, dtype=bool)
    store = _Stored(stored_steps, eta.size)
    store(0, eta, v)
    eta_old = eta - dt * v
    for step in range(1, scene.nt + 1):
        e = eta[1:-1]
        vi = v[1:-1] if newmark else (e - eta_old[1:-1]) / dt
        chi = (e < 0.0) & (vi < 0.0)
        if newmark:
            base = e + dt * vi + (a / 2 - r0 / 4) * _laplacian(eta)
        else:
            base = 2.0 * e - eta_old[1:-1] + a * _laplacian(eta)
        while True:
            if not np.array_equal(chi, damped):  # the damping on the diagonal changed: refactorise
                damped = chi
                solve = _factor(A0 + sp.diags(k * chi), refactor) if chi.any() else undamped
            b = base + k * chi * e + ((dt * k / 2) * chi * vi if newmark else 0.0)
            b[0] += lhs * eta[0]
            b[-1] += lhs * eta[-1]
            new = eta.copy()
            new[1:-1] = solve(b)
            if not newmark:
                break
            v_new = 2.0 / dt * (new - eta) - v
            v_new[[0, -1]] = 0.0
            sticky = chi & (v_new[1:-1] > 0.0)  # a damping that would hold a node down lets it go
            if not sticky.any():
                break
            chi = chi & ~sticky
        if newmark:
            v = v_new
        else:
            v = (new - eta) / dt
        eta_old, eta = eta, new
        store(step, eta, v)
    return store.eta, store.v


def newmark_peer(scene, stored_steps, refactor: str = "splu"):
    """`newmark` (lumped): (I + (a/2 + r₀/4) T + kχ) η¹ = η + Δt v + (a/2 − r₀/4) Tη + kχ η + (kΔt/2) χ v with
    k = Δt/ε on χ = {η < 0, v < 0}, v¹ = 2(η¹ − η)/Δt − v; refactorised with splu when χ changes; a node the
    damping would hold down (v¹ > 0) is released and the step solved again."""
    return _damped_peer(scene, stored_steps, True, refactor)


def semi_implicit_peer(scene, stored_steps, refactor: str = "splu"):
    """`paper` with the semi-implicit penalty: (I + rT + kχ) η¹ = 2η − η⁰ + aTη + kχ η, r = a + r₀, k = Δt/ε on
    χ = {η < 0, v < 0}, v = (η − η⁰)/Δt; refactorised with splu when χ changes."""
    return _damped_peer(scene, stored_steps, False, refactor)


def peer_of(name: str, refactor: str = "splu"):
    """The NumPy peer of a run of RUNS (the paper's is `bench_solver.numpy_peer`; its matrix never changes)."""
    if name == "paper":
        sys.path.insert(0, str(HERE))
        from bench_solver import numpy_peer

        return numpy_peer
    peer = {"paper semi-implicit": semi_implicit_peer, "projection": projection_peer, "newmark": newmark_peer}[name]
    return lambda scene, steps: peer(scene, steps, refactor)


def child(repeats: int, refactor: str) -> dict:
    import warnings

    from compiled_peer import build, compiled_peer
    from mpi4py import MPI

    import stringcontact as sc

    scene, lib = sc.load_scene("example1"), build()
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
                    times[key].append(compiled_peer(lib, scene, res.steps, energies)[3] / scene.nt * 1e6)
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
            from compiled_peer import build, check

            worst = max(worst, check(build(), scene, res))
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
    from stringcontact.run import setup

    scene = sc.load_scene("example1")
    res = sc.simulate(scene, comm=MPI.COMM_SELF)
    model = setup._resolve_model(None, scene)
    V, params, ops = setup.discretise(scene, model, MPI.COMM_SELF)
    s = setup._setting(scene, model, V, params, ops, "explicit", "lumped", MPI.COMM_SELF)
    law = s.laws.compile(model.penalty(s.laws.eta, s.laws.quotient, params))
    full, sub = [], []
    for row in range(1, len(res.t)):
        s.laws.set(eta=res.eta[row].copy(), eta_old=res.eta[row] - scene.dt * res.velocity[row])
        with np.errstate(all="ignore"):
            for _ in range(repeats):
                full.append(min(timeit.repeat(lambda: np.where(True, law._f(s.laws.env), 0.0), number=20, repeat=3)) / 20)
                sub.append(min(timeit.repeat(lambda: law.evaluate_env(s.laws.env), number=20, repeat=3)) / 20)
    print(f"penalty at {len(res.t) - 1} stored states of Example 1 (mean over them): every node "
          f"{1e6 * statistics.mean(full):.1f} µs, candidates only {1e6 * statistics.mean(sub):.1f} µs")


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
    """A scheme that does nothing: `Stepper._advance` alone, the driver's per-step Python."""

    PENALTIES, situation, remedy, energy_slack = (), "", "", 0.0
    terms = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def __init__(self):
        import numpy as np

        self.eta = np.zeros(5001)

    def step(self):
        return self.terms


def _still_stepper(scene):
    """A `Stepper` of Example 1 whose scheme does nothing and whose rows store nothing: its `_advance` is the driver's
    per-step Python alone."""
    import numpy as np
    from mpi4py import MPI

    from stringcontact.run import ledger, rows
    from stringcontact.run.stepper import Stepper

    st = Stepper(scene, comm=MPI.COMM_SELF)
    st.scheme = _Still()
    st.ledger = ledger._Ledger(_Still.terms, conservative=False)
    st.rows = rows.StoredRows(np.array([scene.nt + 1]), rows._Gather(MPI.COMM_SELF, st.setting.x))
    st.rows.min_eta = 0.0
    return st


def loop_timing(src: str, runs: int) -> None:
    """In one process, alternately: the paper scheme's 1500 steps (`Scheme.step` alone) of this checkout and of
    `src`'s, and this checkout's per-step driver Python (`Stepper._advance` with a scheme that does nothing). Thread
    CPU time, so that other jobs on the machine weigh less; medians and the median of paired ratios."""
    import numpy as np
    from mpi4py import MPI

    import stringcontact as sc
    from stringcontact.run import setup
    from stringcontact.timestepping import paper

    scene = sc.load_scene("example1")
    model = setup._resolve_model(None, scene)
    V, params, ops = setup.discretise(scene, model, MPI.COMM_SELF)
    s = setup._setting(scene, model, V, params, ops, "explicit", "lumped", MPI.COMM_SELF)
    schemes = {"this checkout": paper, src: _module_of(src, "stringcontact.timestepping.paper")}
    steps = {k: [] for k in schemes}
    march = []
    np.seterr(all="ignore")
    for r in range(runs):
        for label in (list(schemes) if r % 2 == 0 else list(schemes)[::-1]):
            scheme = schemes[label].Scheme(s)
            scheme.start(*setup._initial_state(scene, s))
            t0 = time.thread_time()
            for _ in range(scene.nt):
                scheme.step()
            steps[label].append((time.thread_time() - t0) / scene.nt * 1e6)
        st = _still_stepper(scene)
        t0 = time.thread_time()
        for _ in range(scene.nt):
            st._advance()
        march.append((time.thread_time() - t0) / scene.nt * 1e6)
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {os.getloadavg()[0]:.2f}; {runs} runs each, "
          "thread CPU time\n")
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
    differ = [k for k in a.files if k not in b.files or a[k].shape != b[k].shape
              or a[k].tobytes() != b[k].tobytes()]
    print(f"{len(a.files) - len(differ)} of {len(a.files)} arrays bit-identical" + "".join(f"\n  differs: {k}" for k in differ))
    return 1 if differ else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="fresh processes per checkout, alternately")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each scheme per process")
    ap.add_argument("--against", help="another checkout (its src/ is put first on PYTHONPATH)")
    ap.add_argument("--law", action="store_true", help="time the contact law alone")
    ap.add_argument("--loop", metavar="CHECKOUT", help="paper's step and the march loop alone, against CHECKOUT's, "
                    "in one process")
    ap.add_argument("--check-peers", action="store_true", help="each peer against simulate at every stored row")
    ap.add_argument("--save", metavar="FILE.npz", help="save every stored array of the four runs, then stop")
    ap.add_argument("--scenes", default="example1", help="--save: the built-in scenes, comma-separated")
    ap.add_argument("--same", nargs=2, metavar="FILE.npz", help="compare two --save files bit for bit")
    ap.add_argument("--refactor", choices=("splu", "lapack"), default="splu",
                    help="how the peers solve with a step matrix that changed (see _factor)")
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
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average before {load_before[0]:.2f}, after "
          f"{load_after[0]:.2f}; {args.rounds} rounds × {args.repeats} runs; peers refactorise with {args.refactor}\n")
    for label, rounds in results.items():
        print(f"{label}: {rounds[0]['file']}")
    print()
    limits = {label: [statistics.median(t for r in rounds for t in r[key]) for key in ("compiled", "compiled, energies")]
              for label, rounds in results.items()}  # µs/step of the C loop: the solve alone, with the energy identity
    for label, (solve, with_energies) in limits.items():
        print(f"{label}: compiled limit {solve:.1f} µs/step (solve alone), {with_energies:.1f} µs/step (with the energy identity)")
    print()
    print("| checkout | scheme | µs/step | its NumPy peer [µs/step] | ratio to its peer | ratio to compiled, solve alone | "
          "ratio to compiled, with energies |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for label, rounds in results.items():
        solve, with_energies = limits[label]
        for name, _ in RUNS:
            mine = [t for r in rounds for t in r[name]]
            peer = [t for r in rounds for t in r[f"{name} peer"]]
            ratios = [a / b for a, b in zip(mine, peer)]  # runs made next to each other
            print(f"| {label} | {name} | {statistics.median(mine):.0f} | {statistics.median(peer):.0f} | "
                  f"{statistics.median(ratios):.2f} | {statistics.median(mine) / solve:.1f} | {statistics.median(mine) / with_energies:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
