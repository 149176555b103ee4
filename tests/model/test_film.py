"""The fluid film (model "film", model/film.py): its oracles, its energy identity, its limits, its scene keys
and its output. docs/explanation/film.md derives the formulas these tests compare with."""

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import ufl
from dolfinx import fem, mesh
from dolfinx.fem.petsc import LinearProblem
from mpi4py import MPI

import stringcontact as sc
from stringcontact.errors import SceneError
from stringcontact.fem import compat
from stringcontact.model import film as film_model
from stringcontact.model.interface import Parameters

H, DELTA, ALPHA = 0.5, 5e-4, 0.01


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, **kwargs)


def flat(T=1.0, nt=100, nx=32, eta0=f"{H}", v0=0, mu=0.1, h=H, **keys):
    return sc.Scene.from_dict(dict(name="flat", length=1.0, T=T, nt=nt, nx=nx, alpha=ALPHA, scheme={"eps": 1.0},
                                   eta0=eta0, v0=v0, h=h, model="film", parameters={"mu": mu},
                                   **keys))


# --- (a) the film alone: a flat gap h closing at the rate hdot --------------------------------------------


@pytest.mark.parametrize("mu, h, hdot", [(0.1, 0.2, -3.0), (2.0, 0.05, 0.5)])
def test_a_flat_gap_closing_gives_the_parabola(mu, h, hdot):
    """The film's row of the model's residual with η = h, η_t = ḣ prescribed: p − p_a = 6μḣ(x² − lx)/h³ (P1 in
    1D is exact at the nodes), and the force on the strip, ∫(p − p_a) = −μḣl³/h³."""
    msh = mesh.create_interval(MPI.COMM_WORLD, 64, [0.0, 1.0])
    V = compat.function_space(msh, "Lagrange", 1)
    p = Parameters(alpha=fem.Constant(msh, 0.0), eps=fem.Constant(msh, 1.0), x=ufl.SpatialCoordinate(msh), length=1.0,
                   constants={"mu": fem.Constant(msh, mu), "h_min": fem.Constant(msh, film_model.H_MIN)})
    q, r = ufl.TrialFunction(V), ufl.TestFunction(V)
    eta, eta_t = fem.Constant(msh, h), fem.Constant(msh, hdot)
    zero = fem.Constant(msh, 0.0)
    R = film_model.film_residual((eta, q), (eta_t, zero), (zero, zero), zero, (zero, r), p)
    ends = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], 1.0))
    bc = fem.dirichletbc(np.float64(0.0), ends, V)
    prefix = {"petsc_options_prefix": "film_parabola_"} if compat.dolfinx_version() >= (0, 10) else {}  # 0.10: required
    pressure = LinearProblem(ufl.lhs(R), ufl.rhs(R), bcs=[bc], petsc_options={"ksp_type": "preonly", "pc_type": "lu"},
                             **prefix).solve()
    x = V.tabulate_dof_coordinates()[:, 0]
    exact = 6 * mu * hdot * (x**2 - x) / h**3
    assert np.max(np.abs(pressure.x.array - exact)) < 1e-10 * np.max(np.abs(exact))
    force = fem.assemble_scalar(fem.form(pressure * ufl.dx))
    assert abs(force - (-mu * hdot / h**3)) < 1e-3 * abs(mu * hdot / h**3)  # the trapezoid's O(dx²) error


# --- (b) a small mode about a uniform gap: the linearised dispersion relation ----------------------------


def mode_exact(m, mu, t):
    """a(t)/δ for a(0) = δ, a'(0) = 0: s² + (αk² + 12μ/(H³k²)) s + k² = 0, k = mπ/l."""
    k = m * np.pi
    s1, s2 = np.roots([1.0, ALPHA * k**2 + 12 * mu / (H**3 * k**2), k**2]).astype(complex)
    return ((s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s2 - s1)).real


def mode_amplitude(m, mu, nx, nt, T):
    """The stored times and a_h(t)/δ, a_h the sin(kx) coefficient of the computed η − H."""
    r = run(flat(T=T, nt=nt, nx=nx, eta0=f"{H} + {DELTA}*sin({m}*pi*x)", mu=mu), storage=sc.Storage(max_rows=nt))
    return r.t, 2 * compat.trapezoid((r.eta - H) * np.sin(m * np.pi * r.x), r.x, axis=1) / DELTA


def mode_error(m, mu, nx, nt, T):
    """max over the stored times of |a_h(t) − a(t)|/δ."""
    t, a = mode_amplitude(m, mu, nx, nt, T)
    return float(np.max(np.abs(a - mode_exact(m, mu, t))))


@pytest.mark.slow
@pytest.mark.parametrize("m, mu", [(1, 0.01), (2, 0.1), (3, 1.0)])
def test_b_a_small_mode_follows_the_dispersion_relation(m, mu):
    """δ/H = 1e-3; Δt and Δx halved together: the error halves (backward Euler's first order; measured 0.020,
    0.050, 0.039 at nx = 128, nt = 800 over T = 2), and the Richardson extrapolation of the last two, 2a_{h/2} − a_h,
    is within 8e-3 of the exact mode (measured 5e-4, 4.8e-3, 5.6e-3; with 10μ for 12μ in the mobility 1.3e-2,
    1.7e-2, 3.1e-2: the halving alone would not see a wrong coefficient at these sizes)."""
    runs = [mode_amplitude(m, mu, nx, nt, 2.0) for nx, nt in ((32, 200), (64, 400), (128, 800))]
    errors = [np.max(np.abs(a - mode_exact(m, mu, t))) for t, a in runs]
    assert errors[1] < 0.6 * errors[0] and errors[2] < 0.6 * errors[1]
    (t, coarse), (_, fine) = runs[1], runs[2]
    assert np.max(np.abs(2 * fine[::2] - coarse - mode_exact(m, mu, t))) < 8e-3


@pytest.mark.slow
def test_b_the_dispersion_error_falls_with_nx():
    """At a small Δt the spatial error leads: it falls by about 4 per halving of Δx (measured 0.169, 0.042, 0.011)."""
    errors = [mode_error(2, 0.1, nx, 4000, 1.0) for nx in (6, 12, 24)]
    assert errors[1] < 0.35 * errors[0] and errors[2] < 0.35 * errors[1]


# --- (c) the energy identity, step by step -----------------------------------------------------------------


def _cell_terms(x, eta, q, mu, h_min):
    """Per step from stored rows: α/Δt ∫δ_x² is computed by the caller; here ∫ m(η)|q_x|², m = max(η, h_min)³/(12μ),
    by 3-point Gauss on each cell (exact for the cubic η³ of a P1 η above h_min)."""
    dx = np.diff(x)
    q_x = np.diff(q) / dx
    g, wts = np.polynomial.legendre.leggauss(3)
    total = 0.0
    for gi, wi in zip(g, wts):
        e = eta[:-1] + (eta[1:] - eta[:-1]) * (gi + 1) / 2
        total += np.sum(0.5 * wi * dx * np.maximum(e, h_min) ** 3 / (12 * mu) * q_x**2)
    return total


@pytest.mark.slow
@pytest.mark.parametrize("nt", [200, 400])
def test_c_the_ledger_books_the_films_dissipation_step_by_step(nt):
    """No contact: E^n − E^{n+1} = α/Δt ∫δ_x² + Δt ∫ m(η^{n+1})|q_x^{n+1}|² + D_num at every step, the first two
    computed here from the stored rows, the viscous column holding both; D_num ≥ 0 (backward Euler) and of first
    order: the exact law dE/dt = −α‖η_tx‖² − ∫ m|p_x|² in the limit."""
    mu, T = 0.05, 0.4
    r = run(flat(T=T, nt=nt, nx=40, eta0=f"{H} + 0.2*sin(pi*x)", v0="-2*sin(pi*x)", mu=mu),
            storage=sc.Storage(max_rows=nt))
    assert np.array_equal(r.steps, np.arange(nt + 1)) and r.min_eta > 0.05
    dt, dx = T / nt, np.diff(r.x)
    booked = np.diff(r.energy["viscous_dissipation"])
    mine = np.array([ALPHA / dt * np.sum(np.diff(r.eta[n + 1] - r.eta[n]) ** 2 / dx)
                     + dt * _cell_terms(r.x, r.eta[n + 1], r.fields["pressure"][n + 1], mu, film_model.H_MIN)
                     for n in range(nt)])
    film_part = mine - np.array([ALPHA / dt * np.sum(np.diff(r.eta[n + 1] - r.eta[n]) ** 2 / dx) for n in range(nt)])
    assert film_part.sum() > 0.5 * booked.sum()  # the film dissipates most: the test sees it
    assert np.max(np.abs(booked - mine)) < 1e-7 * np.max(booked)
    num = np.diff(r.energy["numerical_dissipation"])
    assert np.all(num > -1e-10 * r.total_energy[0])
    assert np.max(np.abs(r.balance_residual)) < 1e-9 * r.total_energy[0]


@pytest.mark.slow
def test_c_numerical_dissipation_is_first_order():
    """Backward Euler's numerical dissipation halves with Δt: the discrete identity tends to the exact law."""
    totals = []
    for nt in (200, 400):
        r = run(flat(T=0.4, nt=nt, nx=40, eta0=f"{H} + 0.2*sin(pi*x)", v0="-2*sin(pi*x)", mu=0.05))
        totals.append(r.energy["numerical_dissipation"][-1])
    assert 0.4 < totals[1] / totals[0] < 0.6


# --- (d) the limits μ → 0 (the film vanishes: the paper's model) and μ → ∞ (the film freezes the string) --


@pytest.mark.slow
def test_d_small_mu_gives_the_papers_model():
    """μ → 0: p = O(μ), so η tends to the paper's model under the same scheme and penalty. Before the landing the
    difference is proportional to μ; after it, where η sits below the floor h_min, the mobility is
    h_min³/(12μ) and the film lets go of the string only once μ ≪ h_min³ (measured: 0.24, 0.12, 0.017, 7e-4 at
    μ = 1e-5, 1e-6, 1e-7, 1e-8 with h_min = 1e-3)."""
    scene = sc.load_scene("film_landing").replace(nx=100, dt=0.00025, T=0.05, output_times=[])
    base = run(scene.replace(model=None, parameters=None, scheme="paper"))
    before = base.t <= 0.015
    gaps, early = [], []
    for mu in (1e-8, 1e-9):
        d = np.max(np.abs(run(scene.replace(parameters={"mu": mu})).eta - base.eta), axis=1)
        gaps.append(d.max())
        early.append(d[before].max())
    assert 0.08 < early[1] / early[0] < 0.12
    assert gaps[0] < 2e-3 and gaps[1] < 0.2 * gaps[0]


@pytest.mark.parametrize("mu", [1e2, 1e3, 1e4])
def test_d_large_mu_freezes_the_string(mu):
    """μ → ∞: the slow root s ≈ −H³k⁴/(12μ) → 0 and the fast one kills v0 = −sin(πx) within the time
    τ = 1/(αk² + 12μ/(H³k²)): η → η0, displaced by v0 τ (measured within 0.3 % at μ = 1e2, 1e3, 1e4)."""
    r = run(flat(T=0.1, nt=50, nx=32, v0="-sin(pi*x)", mu=mu))
    tau = 1 / (ALPHA * np.pi**2 + 12 * mu / (H**3 * np.pi**2))
    assert abs(np.max(np.abs(r.eta[-1] - r.eta[0])) - tau) < 0.01 * tau


# --- cavitation, the scene keys, the schemes, the output -------------------------------------------------------


def test_cavitation_bounds_the_pressure():
    """Thrown up from the obstacle, the film pulls the string down (p < p_a); with p_cav the pressure stays ≥ p_cav."""
    scene = flat(T=0.1, nt=100, nx=40, eta0="0.05", v0="5*sin(pi*x)", mu=0.01, h=0.05)
    free = run(scene)
    assert free.fields["pressure"].min() < -1.0
    bound = run(scene.replace(parameters={"mu": 0.01, "p_cav": -0.5, "p_ambient": 0.0}))
    assert bound.fields["pressure"].min() >= -0.5 - 1e-9
    assert np.max(bound.eta[-1] - free.eta[-1]) > 1e-3  # the string rises higher without the film's suction


@pytest.mark.parametrize("change, key", [({"mu": None}, "mu"), ({"mu": 0.0}, "mu"), ({"mu": -1.0}, "mu"),
                                         ({"p_cav": 1.0}, "p_cav"), ({"p_cav": 1.0, "p_ambient": 0.5}, "p_cav"),
                                         ({"h_min": 0.0}, "h_min")])
def test_bad_film_keys_are_refused_in_one_line(change, key):
    constants = {k: v for k, v in ({"mu": 0.001} | change).items() if v is not None}
    with pytest.raises(SceneError) as info:
        sc.load_scene("film_landing").replace(parameters=constants)
    message = str(info.value)
    assert f": {key}:" in message and "allowed" in message and "\n" not in message


def test_a_film_key_under_another_model_is_refused():
    """Under a model without constants the table waits for the run (a `--model` may bring them), which refuses it
    against the model it runs; under a model with constants, at once."""
    scene = sc.load_scene("example1").replace(parameters={"mu": 1.0}, model="inelastic", nx=20)
    with pytest.raises(SceneError, match="^mu: model 'inelastic' has no constant 'mu'"):
        run(scene)
    with pytest.raises(SceneError, match="mu: model 'stiff_string' has no constant 'mu'"):
        scene.replace(model="stiff_string")


def test_a_top_level_film_key_still_works_with_a_one_line_warning(tmp_path):
    """The film's constants at the top level of a scene file (the form before [parameters]): moved into the table,
    with a warning naming it; the scene equals the one written with the table."""
    text = (sc.load_scene("film_landing").replace(parameters=None, model=None).as_dict()
            | {"model": "film", "mu": 0.002, "h_min": 0.01})
    path = tmp_path / "old.toml"
    path.write_text(tomli_w.dumps({k: v for k, v in text.items() if k != "notes"}))
    with pytest.warns(sc.SceneWarning, match=r"mu, h_min at the top level .* \[parameters\] table") as seen:
        old = sc.load_scene(path)
    assert len(seen) == 1 and "\n" not in str(seen[0].message)
    assert dict(old.parameters) == {"mu": 0.002, "h_min": 0.01}
    assert old == sc.load_scene("film_landing").replace(parameters={"mu": 0.002, "h_min": 0.01}, notes="")
    with pytest.warns(sc.SceneWarning):
        assert dict(sc.load_scene("film_landing").replace(mu=0.5).parameters) == {"mu": 0.5}


def test_the_film_refuses_a_scheme_that_is_not_l_stable():
    for scheme in ("newmark", "projection"):
        with pytest.raises(ValueError, match=f"scheme '{scheme}': model 'film' runs with scheme paper only") as info:
            run(sc.load_scene("film_landing").replace(nx=20, nt=10), scheme=scheme)
        assert "\n" not in str(info.value)


@pytest.mark.slow
def test_cli_missing_mu_exits_2_in_one_line(tmp_path):
    scene = sc.load_scene("film_landing").as_dict() | {"nx": 20}
    scene.pop("parameters")
    path = tmp_path / "nomu.toml"
    path.write_text(tomli_w.dumps({k: v for k, v in scene.items() if k not in ("notes", "output_times")}))
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", str(path), "--out", str(tmp_path / "out")],
                          check=False, capture_output=True, text=True)
    assert proc.returncode == 2 and "mu:" in proc.stderr and proc.stderr.strip().count("\n") == 0
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_film_landing_writes_the_pressure_everywhere(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", "film_landing", "--nx", "100", "--out",
                           str(out)], check=False, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    rows = np.load(out / "rows.npz")
    assert rows["pressure"].shape == rows["eta"].shape and rows["pressure"].max() > 1.0
    header = (out / "diagnostics.csv").read_text().splitlines()[0].split(",")
    assert "max_pressure" in header
    assert 'Attribute Name="pressure"' in (out / "solution.xdmf").read_text()
    peak = float(np.max(np.abs(rows["pressure"])))
    assert f"{-peak!r}, {peak!r}" in (out / "view.py").read_text()  # its colour range: `view.py T PNG pressure`
    summary = json.loads((out / "summary.json").read_text())
    assert summary["model"] == "film" and summary["energy_balance"]["closes"]
    assert (out / "pressure.png").stat().st_size > 10_000
    (out / "pressure.png").unlink()  # `stringcontact plot` reads the pressure back from rows.npz and redraws it
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "plot", str(out)], check=False, capture_output=True,
                          text=True)
    assert proc.returncode == 0 and (out / "pressure.png").is_file(), proc.stderr


@pytest.mark.slow
def test_study_film_quick_writes_its_rows_rates_and_chart(tmp_path):
    """`stringcontact study film --quick`: the references and the film's rows, the fitted laws, the chart; the
    inelastic reference is its own zero distance and the film's thinnest gap grows with μ on the flat landing."""
    out = tmp_path / "study"
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "study", "film", "--quick", "--out", str(out)],
                          check=False, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("study film:"))
    assert line.endswith("the cases ran one after another on rank 0") and "per rank: " not in line, line
    from stringcontact.analysis.study import read_csv

    rows = read_csv(out / "study_film.csv")
    inelastic = [r for r in rows if r["method"] == "inelastic"]
    assert len(inelastic) == 2 and all(r["dist_before"] == 0.0 for r in inelastic)
    flat = sorted((r for r in rows if r["problem"] == "flat" and r["method"] == "film" and r["p_cav"] != r["p_cav"]),
                  key=lambda r: r["mu"])
    assert len(flat) == 2 and 0 < flat[0]["min_gap"] < flat[1]["min_gap"]
    assert (out / "study_film.png").stat().st_size > 10_000 and (out / "study_film_rates.csv").is_file()


@pytest.mark.slow
@pytest.mark.mpi
def test_study_film_on_two_ranks_runs_its_sweep_on_rank_0_and_gives_the_serial_rows(tmp_path):
    """Under mpirun the film's sweep runs on rank 0 alone, its runs on that rank's own communicator: they waited
    for the other ranks, which never joined them, and the study hung."""
    from conftest import mpirun

    serial, parallel = tmp_path / "serial", tmp_path / "mpi"
    command = ["-m", "stringcontact", "study", "film", "--quick", "--out"]
    subprocess.run([sys.executable, *command, str(serial)], check=True, capture_output=True)
    proc = mpirun([sys.executable, *command, parallel], ranks=2)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "2 rank(s)" in proc.stdout
    for name in ("study_film.csv", "study_film_rates.csv"):  # no timing columns: the rows must be equal
        assert (serial / name).read_text() == (parallel / name).read_text()


@pytest.mark.slow
def test_film_drum_a_membrane_on_its_film(tmp_path):
    """2D: the membrane's film, p = p_a on the rim; the pressure builds under the falling skin, the ledger closes."""
    r = run(sc.load_scene("film_drum").replace(cells=[8, 8], T=0.1, nt=40, output_times=[]))
    assert r.status == "complete" and r.fields["pressure"].shape == r.eta.shape
    rim = np.abs(r.fields["pressure"][:, r.x[:, 0] == 0.0]).max()  # p = p_a held by the Krylov solve, to its tolerance
    assert r.fields["pressure"].max() > 0.1 and rim <= 1e-12 * r.fields["pressure"].max()
    assert np.max(np.abs(r.balance_residual)) < 1e-9 * r.total_energy[0]
    from stringcontact.plot.run_pictures import draw

    assert draw("pressure.png", r, tmp_path).stat().st_size > 10_000


def test_the_film_model_named_in_python_without_mu_is_refused_in_one_line():
    scene = sc.load_scene("film_landing").replace(parameters=None, model=None, nx=20)
    with pytest.raises(SceneError, match=r"^mu: model 'film' needs it in \[parameters\]; allowed: ") as info:
        run(scene, model="film")
    assert "\n" not in str(info.value)


# --- the film's linear solvers (`film.linear_options`) ----------------------------------------------------


def _solver_cases():
    """The string through its landing (0.0235) and the shipped drum through its first contact."""
    return {"string": sc.load_scene("film_landing").replace(nx=200, T=0.03, output_times=[]),
            "drum": sc.load_scene("film_drum").replace(T=0.2, output_times=[])}


@pytest.mark.slow
def test_the_film_solvers_give_the_serial_lu_answer(tmp_path):
    """The film's own linear solvers (the string's redundant LU on 2 ranks, the membrane's MUMPS in serial and on
    2 ranks; the size rule's CG cannot solve the membrane there) against PETSc's serial LU. Measured: 1.2e-14 (η)
    and 6.5e-14 (the pressure) of their largest values at most."""
    from conftest import mpirun

    proc = mpirun([sys.executable, Path(__file__).resolve(), tmp_path], ranks=2, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    got = np.load(tmp_path / "film_solvers.npz")
    lu = {"ksp_type": "preonly", "pc_type": "lu"}
    for name, scene in _solver_cases().items():
        serial = run(scene, comm=MPI.COMM_SELF, petsc_options=lu)
        assert serial.contact.any() and serial.fields["pressure"].max() > 0
        runs = {"2 ranks": (got[f"{name}-eta"], got[f"{name}-pressure"])}
        if name == "drum":
            default = run(scene, comm=MPI.COMM_SELF)
            runs["serial MUMPS"] = (default.eta, default.fields["pressure"])
        for label, (eta, pressure) in runs.items():
            assert np.max(np.abs(eta - serial.eta)) <= 1e-9 * np.max(np.abs(serial.eta)), (name, label)
            exact = serial.fields["pressure"]
            assert np.max(np.abs(pressure - exact)) <= 1e-8 * np.max(np.abs(exact)), (name, label)


def _solver_worker(out: Path) -> None:
    arrays = {}
    for name, scene in _solver_cases().items():
        r = run(scene, comm=MPI.COMM_WORLD)
        if MPI.COMM_WORLD.rank == 0:
            arrays[f"{name}-eta"], arrays[f"{name}-pressure"] = r.eta, r.fields["pressure"]
    if MPI.COMM_WORLD.rank == 0:
        np.savez(out / "film_solvers.npz", **arrays)


if __name__ == "__main__":
    _solver_worker(Path(sys.argv[1]))
