"""A moving obstacle ψ(x, t) (the scene's ``obstacle`` in t): scheme projection puts ψ^{n+1} into each step's bound
(linear and Newton paths), the velocity penalties (paper's explicit and semi-implicit, newmark's) brake the gap rate
v − ψ_t, and the ledger books the obstacle's work as external work. Exact checks on a flat string carried by a flat
piston."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import ufl

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.errors import SceneError
from stringcontact.model.variants import loaded_obstacle


def piston_under_a_flat_string(obstacle: str, *, alpha: float, v0: str = "0", T: float = 0.1, nt: int = 20):
    """A flat string at height 0.1 (ends held there) on a flat piston under all of it, nx = 100."""
    return sc.Scene(name="flat_piston", length=1.0, T=T, alpha=alpha, eps=T / nt, nx=100, nt=nt, eta0="0.1", v0=v0,
                    h_left=0.1, h_right=0.1, model="loaded_obstacle", obstacle=obstacle)


def inside(res, margin: float) -> np.ndarray:
    """The nodes farther than `margin` from both ends (which are held, so the string bends there)."""
    return (res.x > margin) & (res.x < 1 - margin)


def test_a_piston_at_constant_speed_carries_the_string_with_no_force():
    """ψ = 0.1 + 0.5 t under a string moving with it (v0 = 0.5), α = 0: away from the ends (which the explicit
    elastic term reaches one node per step, 20 nodes by T) η = 0.1 + 0.5 t and the contact force is 0."""
    scene = piston_under_a_flat_string("0.1 + 0.5*t", alpha=0.0, v0="0.5")
    res = sc.simulate(scene, scheme="projection")
    far = inside(res, 0.25)
    np.testing.assert_allclose(res.eta[:, far], (0.1 + 0.5 * res.t)[:, None] * np.ones(far.sum()), rtol=0, atol=1e-13)
    assert np.max(np.abs(res.contact_force[:, far])) < 1e-9
    assert np.all(res.contact_force >= 0) and res.checks["energy_balance"]["closes"]


@pytest.mark.parametrize("newton", [False, True])
def test_a_piston_at_constant_acceleration_pushes_with_the_mass_times_a(newton):
    """ψ = 0.1 + t² (a = 2) under a string at rest, α = 0.1 (the active-set step on LU; the Newton path's VI):
    the string lies on the piston, η = ψ, and the force density is a·(mass per length) = 2 on the flat part."""
    scene = piston_under_a_flat_string("0.1 + t**2", alpha=0.1)
    model = dataclasses.replace(loaded_obstacle, name="loaded_obstacle_newton", newton=True) if newton else None
    res = sc.simulate(scene, scheme="projection", model=model)
    far, later = inside(res, 0.1), res.t >= 2 * scene.dt  # a stored force is the multiplier of the step ending there
    psi = 0.1 + res.t**2
    np.testing.assert_allclose(res.eta[:, far], psi[:, None] * np.ones(far.sum()), rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.contact_force[np.ix_(later, far)], 2.0, rtol=1e-6)
    assert np.all(res.contact_force >= 0)
    b = res.checks["energy_balance"]
    assert b["closes"] and b["external_work"] > 0  # the piston's work, booked as external work
    # the contact dissipation is what the contact takes from the gap, never what the piston gives: ≥ 0 and rising
    assert np.all(np.diff(res.energy["contact_dissipation"]) >= -1e-12 * b["external_work"])


def test_the_piston_scene_throws_the_string_and_its_ledger_books_the_pistons_work():
    scene = sc.load_scene("piston")
    res = sc.simulate(scene)
    mid = np.argmin(np.abs(res.x - 0.5))
    psi = np.array([scene.obstacle_values(res.x, t) for t in res.t])
    rising = (res.t > 0.02) & (res.t < 0.14)
    np.testing.assert_allclose(res.eta[rising, mid], psi[rising, mid], rtol=0, atol=1e-12)  # η = ψ on contact
    np.testing.assert_allclose(res.velocity[rising, mid], 2.0, rtol=1e-9)  # carried at the piston's speed
    flying = np.argmin(np.abs(res.t - 0.3))
    assert res.eta[flying, mid] > psi[flying, mid] + 0.2 and res.contact_force[flying].max() == 0  # thrown
    assert np.all(res.contact_force >= 0) and np.all(res.eta >= psi - 1e-12)
    b = res.checks["energy_balance"]
    assert b["closes"] and b["relative_residual"] < 1e-10
    assert b["external_work"] > 1.0 and b["contact_dissipation"] > 0  # the piston gives, the landing takes
    assert np.all(np.diff(res.energy["contact_dissipation"]) >= -1e-12)


def test_the_newton_path_follows_the_linear_path_on_a_moving_obstacle():
    scene = sc.load_scene("piston").replace(nx=100, nt=125, T=0.5, output_times=[0.0, 0.5])
    linear = sc.simulate(scene)
    newton = sc.simulate(scene, model=dataclasses.replace(loaded_obstacle, name="newton_path", newton=True))
    assert np.max(np.abs(newton.eta - linear.eta)) < 1e-8
    assert newton.checks["energy_balance"]["closes"]


def test_the_explicit_penalty_brakes_the_gap_rate():
    """ψ = 0.1 + t² pushes a string at rest: the velocity penalty acts on v − ψ_t, so the string is carried
    (lagging about ε a t); a penalty on v alone would let the piston through it (depth t² = 0.04 by T = 0.2)."""
    scene = piston_under_a_flat_string("0.1 + t**2", alpha=0.1, T=0.2, nt=400)
    res = sc.simulate(scene, scheme="paper", penalty="explicit")
    far = inside(res, 0.2)
    depth = (0.1 + res.t**2)[:, None] - res.eta[:, far]
    assert np.max(depth) < 0.005, np.max(depth)
    assert np.all(res.contact_force >= 0) and np.max(res.contact_force[-1, far]) > 1.0
    b = res.checks["energy_balance"]
    assert b["closes"] and b["external_work"] > 0


SEMI_IMPLICIT = [pytest.param({"scheme": "newmark"}, id="newmark"),
                 pytest.param({"scheme": "paper", "penalty": "semi-implicit"}, id="paper-semi-implicit")]


@pytest.mark.parametrize("kwargs", SEMI_IMPLICIT)
def test_a_semi_implicit_penalty_leaves_a_string_moving_with_the_piston_alone(kwargs):
    """ψ = 0.1 + 0.5 t under a string moving with it (v0 = 0.5), α = 0: the damping brakes v − ψ_t = 0, so
    η = 0.1 + 0.5 t away from the held ends and the force is round-off (a damping 1/ε times the quotients')."""
    scene = piston_under_a_flat_string("0.1 + 0.5*t", alpha=0.0, v0="0.5")
    res = sc.simulate(scene, **kwargs)
    far = inside(res, 0.25)
    np.testing.assert_allclose(res.eta[:, far], (0.1 + 0.5 * res.t)[:, None] * np.ones(far.sum()), rtol=0, atol=1e-13)
    assert np.max(np.abs(res.contact_force[:, far])) < 1e-9
    assert np.all(res.contact_force >= 0) and res.checks["energy_balance"]["closes"]


@pytest.mark.parametrize("newton", [False, True])
@pytest.mark.parametrize("kwargs", SEMI_IMPLICIT)
def test_a_semi_implicit_penalty_carries_the_string_with_the_mass_times_a(kwargs, newton):
    """ψ = 0.1 + t² (a = 2) under a string at rest, α = 0, r = Δt/ε = 1. The first step is free (η⁰ = ψ⁰ is not
    below ψ), then the damping brakes the gap rate. newmark: its centred ψ_t is exact on a parabola and its
    trapezoid follows it, so the force density is a = 2 from the second step on and the string lags by exactly
    a ε (t − Δt/2). paper: its gap rate is the backward quotient, F^k (1 + r) = r (Δψ^k/Δt − v^{k−1}), so F reaches
    a as 2 − 2^{1−k}, and the lag stays below a ε t. The ledger books the piston's work. The same on the linear
    path and the Newton path."""
    scene = piston_under_a_flat_string("0.1 + t**2", alpha=0.0)
    model = dataclasses.replace(loaded_obstacle, name="loaded_obstacle_newton", newton=True) if newton else None
    res = sc.simulate(scene, model=model, **kwargs)
    far, k = inside(res, 0.2), np.arange(res.t.size)
    lag = (0.1 + res.t**2)[:, None] - res.eta[:, far]
    F = res.contact_force[2:][:, far]
    if kwargs["scheme"] == "newmark":
        np.testing.assert_allclose(F, 2.0, rtol=1e-9)
        np.testing.assert_allclose(lag[2:], 2 * scene.eps * (res.t[2:, None] - scene.dt / 2) * np.ones(far.sum()),
                                   rtol=1e-9)
    else:
        np.testing.assert_allclose(F, (2 - 2.0 ** (1 - k[2:]))[:, None] * np.ones(far.sum()), rtol=1e-9)
        assert np.all(lag[1:] > 0) and np.all(lag <= 2 * scene.eps * res.t[:, None])
    assert np.all(res.contact_force[:2] == 0) and np.all(res.contact_force >= 0)
    b = res.checks["energy_balance"]
    assert b["closes"] and b["external_work"] > 0
    assert np.all(np.diff(res.energy["contact_dissipation"]) >= -1e-12 * b["external_work"])


@pytest.mark.parametrize("kwargs", SEMI_IMPLICIT)
def test_a_semi_implicit_penalty_throws_the_string_off_the_piston(kwargs):
    """The piston scene: carried up at the piston's speed (the damping lags it by ≤ 0.02 at the start, and the
    speed converges to 2 by halves, r = 1), released when the piston stops (a damping that would hold the string
    down is let go: F ≥ 0), thrown; the ledger closes."""
    scene = sc.load_scene("piston")
    res = sc.simulate(scene, **kwargs)
    mid = np.argmin(np.abs(res.x - 0.5))
    psi = np.array([scene.obstacle_values(res.x, t) for t in res.t])
    rising = (res.t > 0.1) & (res.t < 0.14)
    assert np.all(np.abs(psi - res.eta)[rising, mid] <= 0.0201)
    np.testing.assert_allclose(res.velocity[rising, mid], 2.0, rtol=0, atol=1e-6)
    flying = np.argmin(np.abs(res.t - 0.3))
    assert res.eta[flying, mid] > psi[flying, mid] + 0.2 and res.contact_force[flying].max() == 0
    assert np.all(res.contact_force >= 0)
    b = res.checks["energy_balance"]
    assert b["closes"] and b["relative_residual"] < 1e-10
    assert b["external_work"] > 1.0 and b["contact_dissipation"] > 0
    assert np.all(np.diff(res.energy["contact_dissipation"]) >= -1e-12)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"scheme": "projection", "restitution": 0.5}, "restitution: a moving obstacle"),
    ({"scheme": "paper", "model": dataclasses.replace(loaded_obstacle, name="no_rate",
                                                      penalty=lambda eta, v, p: (p.extra["obstacle"] - eta) / p.eps)},
     "model 'no_rate''s penalty does not read the obstacle's rate"),
    ({"scheme": "newmark", "model": dataclasses.replace(
        loaded_obstacle, name="no_rate_damping",
        penalty_damping=lambda eta, v, p: ufl.conditional(ufl.lt(eta, p.extra["obstacle"]), 1 / p.eps, 0))},
     "model 'no_rate_damping''s penalty_damping does not read the obstacle's rate"),
])
def test_what_a_moving_obstacle_does_not_run_is_refused_in_one_line(kwargs, message):
    with pytest.raises(SceneError, match=message) as info:
        sc.simulate(sc.load_scene("piston"), **kwargs)
    assert "\n" not in str(info.value)


PENALTIES = [pytest.param({"scheme": "paper", "penalty": "explicit"}, id="paper-explicit"), *SEMI_IMPLICIT]


def piston_half_way():
    """The piston scene to T = 0.5 on nx = 100: carried, thrown, landed; the semi-implicit penalties release a node."""
    return sc.load_scene("piston").replace(nx=100, nt=125, T=0.5, output_times=[0.0, 0.1, 0.15, 0.3, 0.5])


@pytest.mark.parametrize("kwargs", PENALTIES)
def test_the_newton_path_follows_the_linear_path_under_a_penalty_on_a_moving_obstacle(kwargs):
    """The Newton path (`newton=True`) of the linear model brakes the same gap rate as the linear path: the same
    η and force, and the same ledger, the piston's work booked as external work."""
    scene = piston_half_way()
    linear = sc.simulate(scene, **kwargs)
    newton = sc.simulate(scene, model=dataclasses.replace(loaded_obstacle, name="newton_path", newton=True), **kwargs)
    assert np.max(np.abs(newton.eta - linear.eta)) < 1e-10
    assert np.max(np.abs(newton.contact_force - linear.contact_force)) < 1e-10 * np.max(linear.contact_force)
    assert np.all(newton.contact_force >= 0)
    b, b_linear = newton.checks["energy_balance"], linear.checks["energy_balance"]
    assert b["closes"] and b["external_work"] > 1.0
    for term in ("external_work", "contact_dissipation", "viscous_dissipation"):
        assert b[term] == pytest.approx(b_linear[term], rel=1e-10), term


@pytest.mark.parametrize("kwargs", SEMI_IMPLICIT)
def test_the_newton_path_reads_the_linear_path_s_obstacle_rate(kwargs):
    """ψ = 0.1 + t² under a string at rest with ε = Δt/4: the string lags the obstacle's rate by a ε, less than
    the a Δt/2 between the backward and the centred ψ_t, so the active set χ{v^n < ψ_t^n} depends on which
    rate the law reads (newmark: the centred one; paper: the backward one). The Newton path equals the linear."""
    scene = piston_under_a_flat_string("0.1 + t**2", alpha=0.0).replace(eps=0.1 / 80)
    linear = sc.simulate(scene, **kwargs)
    newton = sc.simulate(scene, model=dataclasses.replace(loaded_obstacle, name="newton_path", newton=True), **kwargs)
    assert np.max(np.abs(newton.eta - linear.eta)) < 1e-12
    assert np.max(np.abs(newton.contact_force - linear.contact_force)) < 1e-9
    assert np.all(newton.contact_force >= 0) and newton.checks["energy_balance"]["closes"]


@pytest.mark.parametrize("name", ["cubic_foundation", "large_deflection"])
@pytest.mark.parametrize("kwargs", PENALTIES)
def test_a_nonlinear_model_rides_a_moving_obstacle_under_a_penalty(kwargs, name):
    """A nonlinear model with `loaded_obstacle`'s laws on the piston: carried up at the piston's speed, thrown;
    F ≥ 0, the ledger closes with the piston's work booked as external work; a semi-implicit penalty's contact
    dissipation never falls (the explicit one's dips once, on the linear path too: the step after the piston
    stops applies the force of the step before)."""
    base = sc.load_model(name)
    model = dataclasses.replace(loaded_obstacle, name=f"{name}_on_a_piston", momentum_form=base.momentum_form,
                                stored_energy=base.stored_energy, energy_label=base.energy_label)
    scene = piston_half_way()
    res = sc.simulate(scene, model=model, **kwargs)
    mid = np.argmin(np.abs(res.x - 0.5))
    psi = np.array([scene.obstacle_values(res.x, t) for t in res.t])
    assert abs(res.velocity[np.argmin(np.abs(res.t - 0.1)), mid] - 2.0) < 1e-3  # carried at the piston's speed
    flying = np.argmin(np.abs(res.t - 0.3))
    assert res.eta[flying, mid] > psi[flying, mid] + 0.2 and res.contact_force[flying].max() == 0  # thrown
    assert np.all(res.contact_force >= 0)
    b = res.checks["energy_balance"]
    assert b["closes"] and b["relative_residual"] < 1e-10
    assert b["external_work"] > 1.0 and b["contact_dissipation"] > 0
    if kwargs.get("penalty") != "explicit":
        assert np.all(np.diff(res.energy["contact_dissipation"]) >= -1e-12 * b["external_work"])


@pytest.mark.slow
def test_the_cli_runs_the_piston_and_refuses_a_restitution(capfd, tmp_path):
    assert main(["run", "piston", "--nx", "100", "--no-progress", "--no-pictures", "--out", str(tmp_path / "o")]) == 0
    out = capfd.readouterr().out
    assert "external work" in out and ": closes" in out and "within the bound" in out
    assert main(["run", "piston", "--scheme", "newmark", "--nx", "100", "--no-progress", "--no-pictures",
                 "--out", str(tmp_path / "n")]) == 0
    out = capfd.readouterr().out  # a penalty's depth against a moving obstacle has no bound: no verdict
    assert "external work" in out and "EXCEEDS" not in out and "moving obstacle has no known penetration bound" in out
    assert main(["run", "piston", "--restitution", "0.5", "--no-progress", "--no-pictures"]) == 2
    assert "restitution: a moving obstacle" in capfd.readouterr().err


def test_only_the_obstacle_may_read_t_and_it_is_checked_over_0_T():
    base = sc.load_scene("piston")
    assert base.obstacle_moves and not sc.load_scene("loaded_string").obstacle_moves
    np.testing.assert_allclose(base.obstacle_values(np.array([0.5, 0.9]), 0.075), [0.15, -1.0])
    with pytest.raises(SceneError, match=r"load: unknown name 't'"):
        base.replace(load="-10*t")
    with pytest.raises(SceneError, match=r"obstacle: .* is not finite") as info:  # fine at t = 0, not at t = T
        base.replace(obstacle="1/(1 - t)")
    assert "\n" not in str(info.value)


def test_a_membrane_on_a_rising_plate_is_carried_with_the_mass_times_a():
    """ψ(x, y, t) = 0.1 + t² under a flat membrane at rest (boundary held at 0.1), projection: η = ψ and the
    force density a = 2 on the plate's middle."""
    scene = sc.Scene(name="plate", domain="rectangle", size=(1.0, 1.0), cells=(16, 16), T=0.2, nt=40, alpha=0.1,
                     eps=0.005, length=None, nx=None, h_left=None, h_right=None, h=0.1, eta0="0.1", v0="0",
                     model="loaded_obstacle", obstacle="0.1 + t**2")
    res = sc.simulate(scene, scheme="projection")
    middle = (np.abs(res.x[:, 0] - 0.5) < 0.2) & (np.abs(res.x[:, 1] - 0.5) < 0.2)
    np.testing.assert_allclose(res.eta[:, middle], (0.1 + res.t**2)[:, None] * np.ones(middle.sum()), rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.contact_force[-1, middle], 2.0, rtol=1e-9)
    assert res.checks["energy_balance"]["closes"] and res.checks["energy_balance"]["external_work"] > 0


@pytest.mark.parametrize("kwargs", SEMI_IMPLICIT)
def test_a_membrane_on_a_rising_plate_is_carried_by_a_semi_implicit_penalty(kwargs):
    """ψ(x, y, t) = 0.1 + t² under a flat membrane at rest (boundary held at 0.1), α = 0: the damping of the gap
    rate pushes the plate's middle with the force density a = 2 (the held boundary's pull reaches it at 1e-4 on
    16 × 16 cells by T = 0.2), F ≥ 0, and the ledger books the plate's work."""
    scene = sc.Scene(name="plate", domain="rectangle", size=(1.0, 1.0), cells=(16, 16), T=0.2, nt=40, alpha=0.0,
                     eps=0.005, length=None, nx=None, h_left=None, h_right=None, h=0.1, eta0="0.1", v0="0",
                     model="loaded_obstacle", obstacle="0.1 + t**2")
    res = sc.simulate(scene, **kwargs)
    middle = (np.abs(res.x[:, 0] - 0.5) < 0.2) & (np.abs(res.x[:, 1] - 0.5) < 0.2)
    np.testing.assert_allclose(res.contact_force[-1, middle], 2.0, rtol=1e-3)
    assert np.all(res.contact_force >= 0)
    assert res.checks["energy_balance"]["closes"] and res.checks["energy_balance"]["external_work"] > 0
