"""`check` with a moving obstacle ψ(x, t): every check reads ψ at the row's time and the velocity relative to the
obstacle, v − ψ_t; (A2) and Theorem 2.3(1), which a carried string does not satisfy, are n/a and say why. Each
test also measures with the obstacle's motion ignored (ψ at rest, v instead of v − ψ_t), where the same check fails."""

from __future__ import annotations

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.analysis import measurements
from stringcontact.analysis import theorems as th
from stringcontact.cli import main as cli


@pytest.fixture
def motion_ignored(monkeypatch):
    """The checks as they would be with the obstacle taken at rest: no ψ(x, t) rows, no ψ_t."""
    def ignore():
        monkeypatch.setattr(measurements, "obstacle_rows", lambda result: None)
        monkeypatch.setattr(th, "moving_obstacle", lambda result: False)
    return ignore


@pytest.fixture(scope="module")
def piston_results():
    return th.refine(sc.load_scene("piston"), levels=2, penalty=None)


def test_the_piston_pushing_the_string_removes_no_energy_from_the_gap(piston_results, motion_ignored):
    """(A1): while the piston lifts the string, −F (v − ψ_t) is 0 (to round-off), never negative; the piston's
    own work is external work. With the motion ignored, −F v < 0 all the way up: (A1) fails."""
    removed = th.check_dissipation_sign(piston_results)
    assert removed.verdict == th.HOLDS and removed.measured < 1e-12 and "psi_t" in removed.name
    assert th.check_force_sign(piston_results).verdict == th.HOLDS
    for a3 in th.check_upward(piston_results):
        assert a3.verdict == th.HOLDS and a3.measured == 0 and "v - psi_t > 0" in a3.name.replace("v^n", "v")
    energy = th.check_energy(piston_results[-1])[0]
    assert energy.verdict == th.HOLDS and "external work W_ext = 2.7" in energy.detail
    for check in (th.check_support(piston_results), th.check_stress_jump(piston_results)):
        assert check.verdict == th.NOT_APPLICABLE and "obstacle at rest" in check.expectation
        assert "psi_tt - psi_xx" in check.detail
    motion_ignored()
    removed = th.check_dissipation_sign(piston_results)
    assert removed.verdict == th.FAILS and removed.measured > 0.5
    assert th.check_support(piston_results).verdict != th.NOT_APPLICABLE


def test_a_string_caught_by_a_rising_piston_is_at_rest_on_it(motion_ignored):
    """(A4) for a string at rest at 0.2 that a piston rising at speed 2 catches at t = 0.15 and carries: the
    relative velocity |v − ψ_t| falls from 2 at contact to 0 (projection: at once, to round-off). With the
    motion ignored the impact speed would be 0 and the speed after it 2."""
    scene = sc.Scene(name="caught", length=1.0, T=0.3, alpha=0.01, eps=0.004, nx=100, nt=75, eta0="0.2", v0="0",
                     h_left=0.2, h_right=0.2, model="loaded_obstacle",
                     obstacle="where(abs(x - 0.5) < 0.2, -0.1 + 2*t, -1)")
    results = th.refine(scene, levels=2, penalty=None, scheme="projection")
    a4 = th.check_velocity_after_contact(results)
    assert a4.verdict == th.HOLDS and a4.measured < 1e-8 and "|v - psi_t|" in a4.name
    mid = np.argmin(np.abs(results[-1].x - 0.5))
    np.testing.assert_allclose(measurements.relative_velocity(results[-1])[-5:, mid], 0.0, atol=1e-9)
    assert th.check_dissipation_sign(results).verdict == th.HOLDS
    landing = th.check_landing(results)  # the impulse per length is the jump of the string's own velocity, 2
    assert landing.verdict == th.HOLDS, landing
    motion_ignored()
    a4 = th.check_velocity_after_contact(results)
    assert a4.verdict != th.HOLDS and a4.measured > 1.0


@pytest.mark.slow
def test_the_cli_checks_the_piston(capsys):
    code = cli.main(["check", "piston", "--levels", "1"])
    out = capsys.readouterr().out
    assert code == 0 and "(A1) removed energy -F^n (v^n - psi_t^n) >= 0" in out
    assert "only for an obstacle at rest" in out and "external work W_ext" in out
