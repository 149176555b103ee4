"""A model with an internal variable (a string on a Maxwell foundation: a spring k1 to q, a dashpot c from q to the
ground, c q_t = k1 (η − q)): its dashpot is booked as physical dissipation, and a run continued from its whole state
(η, v and q) ends where the uninterrupted run ends."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import ufl

import stringcontact as sc
from stringcontact.errors import ModelError

K1, C = 1000.0, 5.0


def residual(U, U_t, U_tt, force, W, p):
    (eta, q), (w, s) = U, W
    k1, c = p.constants["k1"], p.constants["c"]
    string = sc.inelastic.momentum_form(eta, U_t[0], U_tt[0], force, w, p)
    return string + k1 * (eta - q) * w * ufl.dx + (c * U_t[1] - k1 * (eta - q)) * s * ufl.dx


def stored_energy(U, p):
    eta, q = U
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + 0.5 * p.constants["k1"] * (eta - q) ** 2


MAXWELL = dataclasses.replace(
    sc.inelastic, name="maxwell", fields=("q",), residual=residual, stored_energy=stored_energy,
    constants=(sc.ModelConstant("k1", default=K1, low=0.0, high=1e6, description="the spring to q"),
               sc.ModelConstant("c", default=C, low=0.0, high=1e6, low_open=True, description="the dashpot")),
    description="a string on a Maxwell foundation")


@pytest.fixture(scope="module")
def run():
    """Example 1 at nx = 400 on the Maxwell foundation: the Stepper at T, the dashpot's work summed independently
    (c |Δq|² with the lumped mass, over Δt, every step) and q's history."""
    scene = sc.load_scene("example1").replace(nx=400)
    st = sc.Stepper(scene, model=MAXWELL)
    h = np.diff(st.x)
    m = np.concatenate([[h[0] / 2], (h[:-1] + h[1:]) / 2, [h[-1] / 2]])
    q, dashpot = st.field("q"), 0.0
    while st.step < st.nt:
        st.advance()
        dq = st.field("q") - q
        dashpot += C * float(np.dot(m, dq * dq)) / scene.dt
        q = st.field("q")
    return scene, st, dashpot


def test_the_dashpot_of_an_internal_variable_is_booked_as_physical_dissipation(run):
    _, st, dashpot = run
    result = st.result()
    e, E0 = result.energy, result.total_energy[0]
    assert st.ledger.internal["q"] == pytest.approx(dashpot, rel=0.01)  # 252.4: a fifth of E(0)
    assert e["internal_dissipation"][-1] == pytest.approx(dashpot, rel=0.01)
    assert abs(e["numerical_dissipation"][-1]) <= 0.02 * E0  # the scheme's own loss only (-2.6 of 1308)
    assert result.checks["energy_balance"]["closes"] and abs(result.balance_residual[-1]) < 1e-9 * E0
    assert result.field_info["q"]["internal"]


def test_a_run_continued_from_every_unknown_ends_where_the_uninterrupted_run_ends(run):
    scene, full, _ = run
    st = sc.Stepper(scene, model=MAXWELL)
    while st.t < 0.15 - 1e-12:
        st.advance()
    rest = sc.continued(scene, st)
    assert rest.T == pytest.approx(scene.T - 0.15) and dict(rest.fields0)["q"]
    again = sc.Stepper(rest, model=MAXWELL)
    while again.step < again.nt:
        again.advance()
    assert np.max(np.abs(again.eta - full.eta)) <= 1e-8
    assert np.max(np.abs(again.field("q") - full.field("q"))) <= 1e-8
    assert np.max(np.abs(again.velocity - full.velocity)) <= 1e-8 * np.max(np.abs(full.velocity))


def test_a_run_continued_from_an_output_folder_carries_its_fields(tmp_path):
    scene = sc.load_scene("example1").replace(nx=100, T=0.2, nt=400, output_times=[0.1])
    whole = sc.simulate(scene, model=MAXWELL, output=sc.Output(tmp_path / "run"))
    rest = sc.continued(scene, tmp_path / "run" / "rows.npz", t=0.1)
    assert rest.nt == 200 and rest.output_times == ()
    k = int(np.argmin(np.abs(whole.t - 0.1)))
    assert np.array_equal(dict(rest.fields0)["q"], whole.fields["q"][k])
    end = sc.simulate(rest, model=MAXWELL)
    assert np.max(np.abs(end.eta[-1] - whole.eta[-1])) <= 1e-8
    with pytest.raises(ValueError, match="not a stored time"):
        sc.continued(scene, whole, t=0.1234)


def test_a_field_starts_at_the_value_given_by_the_scene_or_the_stepper():
    scene = sc.load_scene("example1").replace(nx=50, nt=20, T=0.01, output_times=[])
    solved = sc.Stepper(scene, model=MAXWELL)  # not given: the root of its row with q_t = 0, q = eta0
    assert np.allclose(solved.field("q"), solved.eta)
    given = sc.Stepper(scene.replace(fields0={"q": "0.25*x"}), model=MAXWELL)
    assert np.allclose(given.field("q"), 0.25 * given.x)
    argument = sc.Stepper(scene, model=MAXWELL, fields0={"q": 0.5})
    assert np.allclose(argument.field("q"), 0.5)
    with pytest.raises(sc.SceneError, match="fields0.p: not a field of model 'maxwell'"):
        sc.Stepper(scene.replace(fields0={"p": 1.0}), model=MAXWELL)


def test_an_internal_variable_named_a_dissipative_field_is_refused():
    """Its dissipation comes from its rate terms; as a dissipative field its spring's work would be booked as viscous
    (+880.6 viscous, -630.8 numerical on Example 1)."""
    scene = sc.load_scene("example1").replace(nx=50, nt=20, T=0.01, output_times=[])
    with pytest.raises(ModelError, match="dissipative_fields names q"):
        sc.Stepper(scene, model=dataclasses.replace(MAXWELL, dissipative_fields=("q",)))
