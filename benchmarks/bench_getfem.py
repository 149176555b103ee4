"""GetFEM's impacting rod, solved by GetFEM's own demo schemes and by stringcontact, side by side.

The problem is that of GetFEM's ``interface/tests/python/demo_dynamic_contact_1D.py`` (Y. Renard,
F. Chouly, LGPL 2.1; Debian ``python3-getfem`` 5.4): see `stringcontact.verification.rod` and docs/explanation/getfem.md.
`getfem_rod` below re-implements two of that demo's explicit (β = 0) Newmark schemes with GetFEM's own
assembly and MUMPS solves, following the demo line by line: Taylor-Flanagan (``version = 4``) and
exact contact with the redistributed mass matrix (``version = 0, mass_matrix_type = 1``). The demo's
``linsolve_superlu`` segfaults in Debian's build, so ``gf.linsolve_mumps`` is used, as in the demo once
per solve (it factorises M at every call). stringcontact runs the same problem mirrored into a string
on (0, 2) over a point obstacle at x = 1, for every method of `METHODS`.

Measured for each run: the relative max-in-time L² error of u against the exact solution (every time
step, the demo's ``LinfL2u``), the energy at T over the energy at 0, the lowest u at the contact
point, and the CPU time of the time loop (``time.process_time``: the machine is shared, so wall time is
noisier). The GetFEM side runs in a child process that never imports dolfinx (both bring a MUMPS).

    .venv/bin/python benchmarks/bench_getfem.py --out docs            # NX = 20, 40, 80 (about 2 minutes)
    .venv/bin/python benchmarks/bench_getfem.py --quick --out /tmp/g  # NX = 20 only
    .venv/bin/python benchmarks/bench_getfem.py --out docs --getfem-rows docs/getfem_comparison.csv  # no GetFEM here

Writes getfem_comparison.csv, getfem_sinking.csv, getfem_restitution.csv and getfem_comparison.png to --out
and prints the tables. Exits 0 with one line if GetFEM is not installed (``apt-get install python3-getfem``),
unless ``--getfem-rows`` gives GetFEM's rows of an earlier run (its CSV: the rows whose side is "getfem";
GetFEM's numbers are deterministic but for the CPU time). getfem_restitution.csv: `projection` with
restitution e = 0 and e = 1 over three periods at four resolutions (`RESTITUTION_NXS`), the energy at each
period and its largest deviation over the run.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from stringcontact.verification import rod

NXS = (20, 40, 80)  # rod cells; the string has twice as many, of the same size h = 1/NX
DT_OVER_H = 0.04  # the issue's Δt = 0.04 h, well inside the explicit schemes' CFL limit h/2
GETFEM_SCHEMES = ("taylor-flanagan", "redistributed-mass")
SINKING_NXS = (20, 40, 80, 160)
SINKING_DT_OVER_H = (0.04, 1.0)
LANDING = 1.0  # the rod first touches the obstacle at t = 1: energy lost before it is the bulk scheme's own


@dataclass(frozen=True)
class Method:
    """One way of running stringcontact: `scheme` is passed to `simulate` only when it is not "paper"."""

    label: str
    scheme: str
    penalty: str | None  # None: not passed (a scheme without a penalty choice)
    model: str  # "inelastic" (the paper's law) or "elastic" (the spring), both only at x = 1
    eps: Callable[[float, float], float]  # ε(h, Δt)
    mass: str = "lumped"
    dt_over_h: float = DT_OVER_H  # the schemes without a CFL limit below h may take their natural step
    restitution: float = 0.0  # scheme projection's restitution coefficient e (passed to `simulate` when > 0)
    nxs: tuple | None = None  # its own resolutions (default: the run's)


METHODS = (
    Method("paper, semi-implicit, eps=1e-9", "paper", "semi-implicit", "inelastic", lambda h, dt: 1e-9),
    Method("paper, semi-implicit, eps=1e-9, consistent", "paper", "semi-implicit", "inelastic",
           lambda h, dt: 1e-9, mass="consistent"),
    Method("paper, explicit, r=1", "paper", "explicit", "inelastic", lambda h, dt: dt),
    Method("elastic, explicit, r=1.9", "paper", "explicit", "elastic", lambda h, dt: dt / 1.9),
    Method("elastic, explicit, eps=h^2", "paper", "explicit", "elastic", lambda h, dt: h * h),
    Method("elastic, explicit, r=10", "paper", "explicit", "elastic", lambda h, dt: dt / 10),
    Method("elastic, explicit, r=100", "paper", "explicit", "elastic", lambda h, dt: dt / 100),
    Method("projection", "projection", None, "inelastic", lambda h, dt: 1e-9),
    Method("newmark, semi-implicit, eps=1e-9", "newmark", "semi-implicit", "inelastic", lambda h, dt: 1e-9),
    Method("projection, dt=h", "projection", None, "inelastic", lambda h, dt: 1e-9, dt_over_h=1.0),
    Method("newmark, semi-implicit, eps=1e-9, dt=h", "newmark", "semi-implicit", "inelastic", lambda h, dt: 1e-9,
           dt_over_h=1.0),
    Method("projection, e=1", "projection", None, "inelastic", lambda h, dt: 1e-9, restitution=1.0,
           nxs=(20, 40, 80, 160)),
    Method("projection, e=1, dt=h", "projection", None, "inelastic", lambda h, dt: 1e-9, dt_over_h=1.0,
           restitution=1.0, nxs=(20, 40, 80, 160)),
)
#: `restitution_rows`: scheme projection with e = 0 and 1 at these Δt/h, over RESTITUTION_PERIODS periods, at these NX.
RESTITUTION_NXS = (20, 40, 80, 160)
RESTITUTION_DT_OVER_H = (0.04, 0.5, 1.0)
RESTITUTION_PERIODS = 3
SINKING_METHODS = METHODS[0], METHODS[2]

FIELDS = ("side", "method", "nx", "dt", "eps", "r", "status", "cpu_s", "err_u", "energy_ratio", "energy_landing",
          "min_u_contact", "contact_loss")


# --- GetFEM's side (child process) ---------------------------------------------------------------


def getfem_rod(scheme: str, nx: int, dt: float, T: float = rod.PERIOD) -> dict:
    """One run of GetFEM's demo scheme on the rod: every step's u, the energy, the loop's CPU time."""
    import getfem as gf

    m = gf.Mesh("cartesian", np.linspace(0.0, 1.0, nx + 1))
    mfu = gf.MeshFem(m)
    mfu.set_classical_fem(1)
    mim = gf.MeshIm(m, 4)
    md = gf.Model("real")
    md.add_fem_variable("u", mfu)
    x = mfu.basic_dof_nodes()[0]
    if not (x[0] == 0.0 and x[-1] == 1.0 and np.all(np.diff(x) > 0)):  # the demo's rows 0 and n−1 need this order
        raise RuntimeError("GetFEM numbered the rod's dofs out of x order; the demo's scheme assumes x order")
    M = gf.asm_generic(mim, 2, "u*Test_u", -1, md)
    K = gf.asm_generic(mim, 2, "Grad_u*Grad_Test_u", -1, md)
    n = x.size
    for A in (M, K):  # Dirichlet row at x = 1
        A[n - 1, n - 2] = 0.0
        A[n - 1, n - 1] = 1.0
    M2 = gf.Spmat("copy", M)
    if scheme == "redistributed-mass":  # the contact node's mass goes to its neighbour
        M[1, 1] += M[0, 0] + M[1, 0]
        M[0, 0] = M[0, 1] = M[1, 0] = 0.0
        M2 = gf.Spmat("copy", M)
        M2[0, 0] = 1.0

    def solve(A, b):
        return gf.linsolve_mumps(A, b)[:, 0]

    U0 = 0.5 - 0.5 * x
    V0 = np.zeros(n)
    Fc = np.zeros(n)
    nt = round(T / dt)
    U = np.empty((nt + 1, n))
    U[0] = U0
    k_landing, energy_landing = round(LANDING / dt), float("nan")
    cpu = time.process_time()
    for k in range(1, nt + 1):
        FF = solve(M2, Fc - K.mult(U0))
        U1 = U0 + dt * V0 + (dt * dt / 2) * FF
        V1 = V0 + (dt / 2) * FF
        if scheme == "redistributed-mass":  # exact contact: the massless node solves its own equation
            a = K[0, 1] * U1[1]
            U1[0] = max(0.0, -a) / K[0, 0]
            Fc[0] = max(0.0, a)
        elif U1[0] < 0:  # Taylor-Flanagan: the contact force that brings u(0) back to 0
            e0 = np.zeros(n)
            e0[0] = 1.0
            s1 = V1[0] / (solve(M, e0)[0] * dt)
            e0[0] = -s1
            F2 = solve(M, e0)
            U1 += dt * dt * F2
            V1 += dt * F2
        V1 += (dt / 2) * solve(M2, Fc - K.mult(U1))
        if scheme == "redistributed-mass":
            V1[0] = (U1[0] - U0[0]) / dt
        U0, V0 = U1, V1
        U[k] = U0
        if k == k_landing:
            energy_landing = 0.5 * (V0 @ M.mult(V0) + U0 @ K.mult(U0))
    cpu = time.process_time() - cpu
    energy = 0.5 * (V0 @ M.mult(V0) + U0 @ K.mult(U0))
    return {"x": x, "u": U, "cpu_s": cpu, "energy": energy, "energy_landing": energy_landing, "nt": nt}


def getfem_rows(nxs, T: float) -> list[dict]:
    rows = []
    for scheme in GETFEM_SCHEMES:
        for nx in nxs:
            dt = DT_OVER_H / nx
            run = getfem_rod(scheme, nx, dt, T)
            t = dt * np.arange(run["nt"] + 1)
            err = rod.relative_error(run["x"], t, run["u"], exact=rod.rod_exact)
            rows.append({"side": "getfem", "method": scheme, "nx": nx, "dt": dt, "eps": "", "r": "",
                         "status": "complete", "cpu_s": run["cpu_s"], "err_u": err,
                         "energy_ratio": run["energy"] / rod.ROD_ENERGY,
                         "energy_landing": run["energy_landing"] / rod.ROD_ENERGY,
                         "min_u_contact": float(run["u"][:, 0].min()), "contact_loss": ""})
    return rows


# --- stringcontact's side --------------------------------------------------------------------------


def ours(method: Method, nx: int, dt_over_h: float, T: float) -> dict:
    """One stringcontact run of the mirrored rod; `status` says why a run gave no numbers."""
    import stringcontact as sc
    from stringcontact import InstabilityError
    from stringcontact.model.paper import inelastic
    from stringcontact.model.variants import elastic

    h = 1.0 / nx
    dt = dt_over_h * h
    eps = method.eps(h, dt)
    row = {"side": "stringcontact", "method": method.label, "nx": nx, "dt": dt, "eps": eps, "r": dt / eps}
    law = {"inelastic": inelastic, "elastic": elastic}[method.model]
    kwargs = {"mass": method.mass, "model": rod.point_contact(law, h)}
    if method.penalty is not None:
        kwargs["penalty"] = method.penalty
    if method.restitution:
        kwargs["restitution"] = method.restitution
    if method.scheme != "paper":
        if method.scheme not in getattr(sc, "SCHEMES", ()):
            return {**row, "status": "no such scheme yet"}
        kwargs["scheme"] = method.scheme
    scene = rod.rod_scene(nx, dt, eps, T)
    cpu = time.process_time()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the 1 < r < 2 rebound warning is about the velocity penalty
            res = sc.simulate(scene, max_rows=scene.nt + 1, **kwargs)
    except InstabilityError as exc:
        return {**row, "status": "refused" if exc.step == 0 else "unstable"}
    except (ValueError, TypeError) as exc:  # a combination (or, in an older checkout, an option) the solver does not offer
        return {**row, "status": f"n/a: {exc}"[:60]}
    cpu = time.process_time() - cpu
    E = res.total_energy
    at_contact = np.argmin(np.abs(res.x - rod.CONTACT_POINT))
    periods = np.arange(1, round(T / rod.PERIOD) + 1) * rod.PERIOD
    return {**row, "status": res.status, "cpu_s": cpu, "err_u": rod.relative_error(res.x, res.t, res.eta),
            "energy_ratio": E[-1] / E[0], "energy_landing": E[np.argmin(np.abs(res.t - LANDING))] / E[0],
            "min_u_contact": float(res.eta[:, at_contact].min()),
            "contact_loss": res.energy["contact_dissipation"][-1] / E[0],
            "energy_periods": " ".join(f"{E[np.argmin(np.abs(res.t - p))] / E[0]:.6f}" for p in periods),
            "energy_max_deviation": float(np.max(np.abs(E / E[0] - 1)))}


def our_rows(nxs, T: float) -> list[dict]:
    ours(METHODS[0], nxs[0], DT_OVER_H, T)  # fills the form cache, so no run below pays the JIT compiler
    return [ours(m, nx, m.dt_over_h, T) for m in METHODS for nx in _resolutions(m, nxs)]


def _resolutions(method: Method, nxs) -> tuple:
    """The method's own resolutions with the default NXS, else (--quick, --nx) the run's."""
    return method.nxs if method.nxs and tuple(nxs) == NXS else tuple(nxs)


def restitution_rows(nxs, periods: int) -> list[dict]:
    """`projection` with e = 0 and e = 1 on the rod over `periods` periods: its error and energy drift."""
    rows = []
    for q in RESTITUTION_DT_OVER_H:
        for e in (0.0, 1.0):
            method = Method(f"projection, e={e:g}", "projection", None, "inelastic", lambda h, dt: 1e-9,
                            restitution=e)
            rows += [ours(method, nx, q, periods * rod.PERIOD) | {"dt_over_h": q, "restitution": e} for nx in nxs]
    return rows


def sinking_rows(nxs, T: float) -> list[dict]:
    return [ours(m, nx, q, T) | {"dt_over_h": q} for q in SINKING_DT_OVER_H for m in SINKING_METHODS for nx in nxs]


# --- tables and chart -------------------------------------------------------------------------------


def write_csv(path: Path, rows: list[dict]) -> None:
    keys = list(dict.fromkeys([*FIELDS, *(k for row in rows for k in row)]))
    tmp = path.with_name("." + path.name)
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys, restval="")
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)


def fmt(value, spec: str) -> str:
    return format(value, spec) if isinstance(value, float) else str(value)


def print_table(rows: list[dict], columns: tuple[str, ...]) -> None:
    specs = {"dt": ".2e", "eps": ".2e", "r": ".3g", "cpu_s": ".2f", "err_u": ".3f", "energy_ratio": ".4f",
             "energy_landing": ".4f", "min_u_contact": ".4f", "contact_loss": ".3f", "dt_over_h": "g",
             "energy_max_deviation": ".2e"}
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    for row in rows:
        print("| " + " | ".join(fmt(row.get(c, ""), specs.get(c, "")) for c in columns) + " |")
    print()


def chart(path: Path, rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    fig, (ax_cpu, ax_nx) = plt.subplots(1, 2, figsize=(11, 5.5), constrained_layout=True)
    complete = [r for r in rows if r["status"] == "complete"]
    colours = plt.cm.tab20.colors  # one colour per method: there are more than ten
    for k, label in enumerate(dict.fromkeys(r["method"] for r in complete)):
        mine = sorted((r for r in complete if r["method"] == label), key=lambda r: r["nx"])
        getfem = mine[0]["side"] == "getfem"
        big_step = mine[0]["dt"] * mine[0]["nx"] > 0.5  # Δt = h rather than 0.04 h
        style = dict(marker="s" if getfem else ("D" if big_step else "o"), ls="--" if getfem else ("-." if big_step else "-"),
                     color=colours[(2 * k) % 20 if k < 10 else (2 * k + 1) % 20], label=f"{mine[0]['side']}: {label}")
        err = [r["err_u"] for r in mine]
        ax_cpu.loglog([r["cpu_s"] for r in mine], err, **style)
        ax_nx.loglog([r["nx"] for r in mine], err, **style)
    ax_cpu.set(xlabel="CPU time of one run [s] (process time)", ylabel="relative max-in-time L² error of u",
               title="error against CPU time")
    ax_nx.set(xlabel="NX (rod cells; h = 1/NX, Δt = 0.04 h unless the label says Δt = h; T = 3)",
              title="error against resolution")
    for ax in (ax_cpu, ax_nx):
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(ScalarFormatter())
            axis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
    ax_nx.set_xticks(sorted({r["nx"] for r in complete}))
    ax_nx.set_yticks([0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2])
    ax_cpu.set_yticks([0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2])
    try:
        fig.legend(*ax_nx.get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize=8)
    except ValueError:  # matplotlib < 3.7 (Debian bookworm's 3.6) has no "outside": below the figure instead
        fig.legend(*ax_nx.get_legend_handles_labels(), loc="upper center", bbox_to_anchor=(0.5, 0.0), ncols=2,
                   fontsize=8)
    fig.suptitle("GetFEM's impacting rod (demo_dynamic_contact_1D): "
                 "GetFEM's schemes (squares) and stringcontact's (circles; diamonds at Δt = h)", fontsize=10)
    tmp = path.with_name("." + path.name)
    fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)


# --- command line ---------------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/getfem"))
    ap.add_argument("--quick", action="store_true", help="NX = 20 only")
    ap.add_argument("--nx", type=int, nargs="+", help="rod cells (default 20 40 80)")
    ap.add_argument("--T", type=float, default=rod.PERIOD)
    ap.add_argument("--getfem-rows", type=Path, metavar="CSV",
                    help="GetFEM's rows from an earlier run's getfem_comparison.csv (when GetFEM is not installed here)")
    ap.add_argument("--getfem-side", action="store_true", help=argparse.SUPPRESS)  # the child: JSON rows on stdout
    args = ap.parse_args(argv)
    nxs = args.nx or (NXS[:1] if args.quick else NXS)
    if args.getfem_rows is not None:
        rows = stored_getfem_rows(args.getfem_rows, nxs)
    elif importlib.util.find_spec("getfem") is None:
        print("bench_getfem: GetFEM is not installed (apt-get install python3-getfem); skipped")
        return 0
    elif args.getfem_side:
        print(json.dumps(getfem_rows(nxs, args.T)))
        return 0
    else:
        child = [sys.executable, __file__, "--getfem-side", "--T", str(args.T), "--nx", *map(str, nxs)]
        rows = json.loads(subprocess.run(child, check=True, capture_output=True, text=True).stdout)
    rows += our_rows(nxs, args.T)
    sinking = sinking_rows(SINKING_NXS[:2] if args.quick else SINKING_NXS, args.T)
    restitution = restitution_rows(RESTITUTION_NXS[:2] if args.quick else RESTITUTION_NXS, RESTITUTION_PERIODS)
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(args.out / "getfem_comparison.csv", rows)
    write_csv(args.out / "getfem_sinking.csv", sinking)
    write_csv(args.out / "getfem_restitution.csv", restitution)
    chart(args.out / "getfem_comparison.png", rows)
    print_table(rows, ("side", "method", "nx", "r", "status", "err_u", "energy_ratio", "energy_landing",
                       "min_u_contact", "cpu_s"))
    print_table(sinking, ("method", "dt_over_h", "nx", "r", "min_u_contact", "err_u", "energy_ratio", "contact_loss"))
    print_table(restitution, ("method", "dt_over_h", "nx", "err_u", "energy_periods", "energy_max_deviation",
                              "min_u_contact", "cpu_s"))
    print(f"wrote {args.out}/getfem_comparison.csv, getfem_sinking.csv, getfem_restitution.csv, getfem_comparison.png")
    return 0


def stored_getfem_rows(path: Path, nxs) -> list[dict]:
    """GetFEM's rows (side "getfem") at the resolutions `nxs` from a getfem_comparison.csv this script wrote."""
    with path.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["side"] == "getfem" and int(r["nx"]) in nxs]
    numbers = ("dt", "cpu_s", "err_u", "energy_ratio", "energy_landing", "min_u_contact")
    return [{**r, "nx": int(r["nx"]), **{k: float(r[k]) for k in numbers}} for r in rows]


if __name__ == "__main__":
    sys.exit(main())
