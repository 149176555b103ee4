"""The stiff string (model "stiff_string", model/stiff_string.py): its dispersion relation, its contact, its output,
its constant's checks, its schemes and their energy ledgers, and the linear path its affine residual takes
(timestepping/newton.py). No timing here: benchmarks/bench_stiff_string.py measures its step."""

import dataclasses
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
import tomli_w

import stringcontact as sc
from stringcontact.errors import InstabilityError
from stringcontact.fem.compat import trapezoid
from stringcontact.io.readback import read_xdmf
from stringcontact.model import stiff_string as model

H, AMPLITUDE = 1.0, 1e-3


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, **kwargs)


def mode_scene(m: int, beta: float, nx: int, T: float = 2.0, dt: float = 1e-3):
    """A single mode h + a sin(mπx) high above the obstacle (a/h = 1e-3: no contact), at rest, α = 0."""
    return sc.Scene.from_dict({"name": "mode", "length": 1.0, "T": T, "dt": dt, "nx": nx, "alpha": 0.0,
                               "scheme": {"eps": 1e-3},
                               "h": H, "eta0": f"{H} + {AMPLITUDE}*sin({m}*pi*x)", "v0": "0", "model": "stiff_string",
                               "parameters": {"beta": beta}})


def measured_omega(result, m: int) -> float:
    """ω from the zero crossings of the mode's amplitude a(t) = 2∫(η − h) sin(mπx) dx (a(0) = a, a'(0) = 0: its
    crossings are (k + ½)π/ω apart by π/ω; linear interpolation between stored steps, where a is nearly straight)."""
    a = 2 * trapezoid((result.eta - H) * np.sin(m * np.pi * result.x), result.x, axis=1)
    t = result.t
    k = np.flatnonzero(np.sign(a[:-1]) * np.sign(a[1:]) < 0)
    crossings = t[k] - a[k] * (t[k + 1] - t[k]) / (a[k + 1] - a[k])
    assert crossings.size >= 3
    return math.pi * (crossings.size - 1) / (crossings[-1] - crossings[0])


def exact_omega(m: int, beta: float) -> float:
    k = m * math.pi
    return math.sqrt(k**2 + beta * k**4)


# --- the oracle: a mode's frequency, ω² = (mπ)² + β(mπ)⁴ --------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("beta", [1e-3, 1e-2])
def test_a_mode_oscillates_at_the_dispersion_relation_converging_in_space(beta):
    """newmark (conservative, Δt = 1e-3: its own phase error (ωΔt)²/24 ~ 2e-6): the frequency error falls by about 4
    per halving of Δx (P1's O(Δx²); measured 2.5e-2, 6.2e-3, 1.5e-3 at β = 1e-3 and 1.8e-2, 4.6e-3, 1.2e-3 at
    β = 1e-2) to within 2e-3 of ω at nx = 32. The bending's share of ω² is 4% (β = 1e-3) and 28% (β = 1e-2): a
    bending force off by 10% would leave 2e-3 (5e-3 at 1e-2) at the finest mesh, and a missing one 2e-2."""
    m = 2
    exact = exact_omega(m, beta)
    errors = []
    for nx in (8, 16, 32):
        scene = mode_scene(m, beta, nx)
        result = run(scene, scheme="newmark", storage=sc.Storage(max_rows=scene.nt + 1))
        assert result.status == "complete" and not result.contact.any()
        errors.append(abs(measured_omega(result, m) - exact) / exact)
    assert errors[1] < 0.35 * errors[0] and errors[2] < 0.35 * errors[1], errors
    assert errors[2] < 2e-3, errors


def test_the_curvature_of_a_mode_is_minus_its_second_derivative():
    """κ = −η_xx = a (mπ)² sin(mπx) at t = 0 (the fields start from η0, not from 0), to P1's O(Δx²): 1% at nx = 32
    (measured 0.32%)."""
    m, nx = 2, 32
    result = run(mode_scene(m, 1e-2, nx, T=0.01), scheme="newmark")
    kappa = result.fields["curvature"][0]
    exact = AMPLITUDE * (m * np.pi) ** 2 * np.sin(m * np.pi * result.x)
    assert np.max(np.abs(kappa - exact)) < 1e-2 * np.max(np.abs(exact))
    assert kappa[0] == 0.0 and kappa[-1] == 0.0  # held at 0 at the pinned ends


@pytest.mark.slow
def test_the_initial_energy_holds_the_bending():
    """E(0) = ½∫η_x² + ½β∫κ² = (a²(mπ)²/4)(1 + β(mπ)²) for the mode at rest, to O(Δx²) (1% at nx = 32); without the
    bending (β = 1e-2, m = 2) it would be 28% lower (measured −0.23%)."""
    m, beta = 2, 1e-2
    result = run(mode_scene(m, beta, 32, T=0.01), scheme="paper")
    k = m * np.pi
    exact = AMPLITUDE**2 * k**2 / 4 * (1 + beta * k**2)
    assert result.energy["elastic"][0] == pytest.approx(exact, rel=1e-2)


# --- β = 0 is the paper's string --------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["paper", "newmark"])
def test_beta_zero_is_the_papers_string(scheme):
    """At β = 0 the curvature's row decouples: η is the paper's model's (the linear path's solve against the
    constant operators', 1e-10), through Example 1's landing."""
    ex1 = sc.load_scene("example1").replace(nx=100, nt=600, output_times=None)
    stiff = run(ex1.replace(model="stiff_string", parameters={"beta": 0.0}), scheme=scheme)
    paper = run(ex1, scheme=scheme)
    assert paper.contact.any()
    assert np.max(np.abs(stiff.eta - paper.eta)) <= 1e-10 * np.max(np.abs(paper.eta))


# --- contact: a landing under projection ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def landing():
    """A stiff string thrown onto the obstacle y = 0, under `projection` (its contact step: η ≥ ψ exactly)."""
    scene = sc.Scene.from_dict({"name": "landing", "length": 1.0, "T": 0.4, "dt": 4e-4, "nx": 100, "alpha": 0.01,
                                "scheme": {"eps": 1e-3}, "h": 0.1, "eta0": "0.1 + 0.2*sin(pi*x)", "v0": "-4*sin(pi*x)",
                                "model": "stiff_string", "parameters": {"beta": 1e-3}})
    return run(scene, scheme="projection", storage=sc.Storage(max_rows=scene.nt + 1))


@pytest.mark.slow
def test_a_landing_under_projection_stays_above_the_obstacle(landing):
    assert landing.status == "complete", landing.message
    assert landing.contact.any() and landing.contact[-1].sum() < landing.contact.sum(axis=1).max()  # lands, lifts
    assert np.min(landing.eta) >= -1e-12  # η ≥ ψ = 0 at every node and stored step (to round-off)


def test_the_contact_force_is_nonnegative_and_zero_off_the_contact_set(landing):
    force = landing.contact_force
    assert np.max(force) > 0
    assert np.min(force) >= 0.0
    assert np.all(force[~landing.contact] == 0.0)


def test_the_landing_bends_the_string_at_the_contact_set(landing):
    """Where the string lies flat on the obstacle its curvature is small against the bend at the contact set's
    edges (a stiff string meets the obstacle with a bend, not the string's kink)."""
    kappa = landing.fields["curvature"]
    n = int(np.argmax(landing.contact.sum(axis=1)))
    assert landing.contact[n].sum() >= 5
    assert np.max(np.abs(kappa[n])) > 0
    assert landing.checks["energy_balance"]["closes"]


def test_projection_refuses_a_step_its_explicit_bending_cannot_take():
    """The bending enters projection's explicit elastic term: its stable Δt is that of K + βKM⁻¹K, not K's
    (2/√λ: 2.9e-4 at nx = 100, β = 1e-2, against K's 1e-2): refused at the start, naming the curvature."""
    scene = sc.load_scene("example1").replace(model="stiff_string", parameters={"beta": 1e-2}, nx=100, dt=1e-3,
                                              output_times=None)
    with pytest.raises(InstabilityError, match="curvature"):
        run(scene, scheme="projection")
    assert model.stable_dt(0.01, 1e-2) == pytest.approx(2.9e-4, rel=0.05)


# --- every scheme, its ledger -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ex1_stiff():
    return sc.load_scene("example1").replace(model="stiff_string", parameters={"beta": 1e-3}, nx=100,
                                             output_times=None)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["paper", "projection", "newmark"])
def test_every_contact_scheme_runs_it_and_its_ledger_closes(ex1_stiff, scheme):
    result = run(ex1_stiff, scheme=scheme)
    assert result.status == "complete", result.message
    assert result.contact.any()
    balance = result.checks["energy_balance"]
    assert balance["closes"]
    e0 = balance["initial"]
    num = np.diff(result.energy["numerical_dissipation"])
    if scheme == "paper":  # backward Euler dissipates: D_num ≥ 0 step by step (measured ≥ 5e-7 E(0))
        assert np.all(num >= -1e-10 * e0)
    if scheme == "newmark":  # the midpoint rule of a linear model conserves: D_num is round-off (measured 2.5e-14
        assert abs(balance["numerical_dissipation"]) <= 1e-8 * e0  # E(0); the bending holds 16% of E(0) at t = 0)
    assert result.counters["linear solves"] >= 1 and "affine" in result.solver["nonlinear solver"]
    # the stored curvature is the stored η's at every row (projection reports η a step behind its solve; its κ is
    # solved from that η): M κ = K η on the interior nodes, (h/6)(κ_{i−1} + 4κ_i + κ_{i+1}) = (2η_i − η_{i±1})/h
    h, eta, kappa = np.diff(result.x)[0], result.eta, result.fields["curvature"]
    mass = h / 6 * (kappa[:, :-2] + 4 * kappa[:, 1:-1] + kappa[:, 2:])
    stiffness = (2 * eta[:, 1:-1] - eta[:, :-2] - eta[:, 2:]) / h
    assert np.max(np.abs(mass - stiffness)) <= 1e-10 * np.max(np.abs(stiffness))  # measured 1e-14 to 4e-13


@pytest.mark.slow
def test_the_linear_path_gives_newtons_answer(ex1_stiff):
    """The affine residual's one linear solve per step against the same model forced through SNES (`newton=True`):
    the same η to Newton's tolerance (measured 1.4e-11 relative, the curvature 1.4e-12), and no Newton iteration on
    the linear path."""
    linear = run(ex1_stiff, scheme="paper")
    newton = run(ex1_stiff, scheme="paper", model=dataclasses.replace(model.stiff_string, name="forced", newton=True))
    assert linear.counters["newton iterations"] == 0 and linear.counters["linear solves"] == ex1_stiff.nt
    assert newton.counters["newton iterations"] >= ex1_stiff.nt
    assert np.max(np.abs(linear.eta - newton.eta)) <= 1e-8 * np.max(np.abs(linear.eta))
    assert np.max(np.abs(linear.fields["curvature"] - newton.fields["curvature"])[1:]) <= 1e-6 * np.max(
        np.abs(linear.fields["curvature"]))


# --- output ------------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_the_curvature_is_written_to_the_xdmf_and_the_result(tmp_path, ex1_stiff):
    out = tmp_path / "run"
    result = run(ex1_stiff.replace(T=0.02), scheme="paper", output=sc.Output(out, force=True, pictures=False))
    assert "curvature" in result.fields and result.fields["curvature"].shape == result.eta.shape
    _, series = read_xdmf(out / "solution.xdmf")
    assert "curvature" in series and len(series["curvature"]) == len(series["eta"])


# --- the constant's checks, through the command line ----------------------------------------------------------


def scene_file(tmp_path, parameters: dict):
    data = {"name": "stiff", "length": 1.0, "T": 0.01, "nt": 10, "nx": 20, "alpha": 0.01, "h": 1.0,
            "eta0": "1 + 0.1*sin(pi*x)", "v0": "0", "model": "stiff_string", "parameters": parameters,
            "scheme": {"eps": 1e-3}}
    path = tmp_path / "stiff.toml"
    path.write_bytes(tomli_w.dumps(data).encode())
    return path


@pytest.mark.slow
@pytest.mark.parametrize("parameters, named", [({"beta": -1e-3}, "beta"), ({"beta": 1e-3, "gamma": 1.0}, "gamma")])
def test_the_cli_refuses_a_bad_constant_in_one_line_and_writes_nothing(tmp_path, parameters, named):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", str(scene_file(tmp_path, parameters)),
                           "--no-progress", "--out", str(out)], check=False, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and named in lines[0], proc.stderr
    assert not out.exists()
    assert not any(p.name.startswith(".out") for p in tmp_path.iterdir())


def test_the_model_declares_its_constant_and_field():
    (beta,) = model.stiff_string.constants
    assert beta.name == "beta" and beta.default == 0.0 and beta.low == 0.0
    assert model.CURVATURE.symmetric and model.CURVATURE.unit
    assert "curvature" not in model.stiff_string.dissipative_fields
    assert model.stiff_string.fields == ("curvature",) and model.stiff_string.held_fields == ("curvature",)
