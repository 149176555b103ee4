"""A stepper is consistent or refuses to go on, in one line: after Ctrl-C inside a step or an observer, after an
instability, after a plugin's failure; its result() says how the run stopped. A plugin's broken contract (sys.exit,
a wrong return value, an initial energy that is not finite, a constant switched on mid-run) is one line naming it."""

import json
import re
import ufl
import warnings

import pytest

import stringcontact as sc
from stringcontact.timestepping.implicit import ImplicitScheme
from stringcontact.timestepping.base import PETSC_OPTIONS, mass_option
from stringcontact.timestepping.paper import PAPER, PaperScheme

SCENE = dict(nx=40, T=0.01, dt=0.0005, output_times=[])


def scene(**changes):
    return sc.load_scene("example1").replace(**(SCENE | changes))


def stepper(s=None, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.Stepper(s or scene(), **kwargs)


def fail_at(st, n: int, failure):
    """The ledger's booking of step `n` (after the scheme stepped, before the counter moved) fails with `failure`:
    an exception raised, or the reason the energy guard gives."""
    add = st.core.ledger.add

    def booked(terms, *args):
        why = add(terms, *args)
        if st.core.step + 1 == n:
            if isinstance(failure, BaseException):
                raise failure
            return failure
        return why

    st.core.ledger.add = booked


@pytest.mark.parametrize("output", [False, True])
def test_ctrl_c_inside_a_step_stops_the_stepper_and_result_says_interrupted(tmp_path, output):
    st = stepper(output=sc.Output(tmp_path / "o", pictures=False) if output else None)
    fail_at(st, 5, KeyboardInterrupt())
    with pytest.raises(KeyboardInterrupt):
        while st.step < st.nt:
            st.advance()
    for _ in range(2):  # a notebook's loop run again: refused every time, nothing stepped
        with pytest.raises(ValueError, match=r"^advance: the run stopped at step 4 \(interrupted.*cannot go on"):
            st.advance()
    result = st.result()
    assert result.status == "interrupted" and st.step == 4 and result.t[-1] < st.scene.T
    if output:
        assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "interrupted"


def test_after_an_instability_the_stepper_refuses_and_result_says_unstable(tmp_path):
    st = stepper(output=sc.Output(tmp_path / "o", pictures=False))
    fail_at(st, 3, "the energy rose from 1 to 2")
    with pytest.raises(sc.InstabilityError, match="unstable at step 3"):
        while st.step < st.nt:
            st.advance()
    with pytest.raises(ValueError, match=r"the run stopped at step 3 \(unstable: unstable at step 3"):
        st.advance()
    assert st.result().status == "unstable" and st.result() is st.result()
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "unstable"


def test_ctrl_c_inside_an_observer_stops_the_core_stepper():
    st = stepper()
    core = st.core

    class Interrupting:
        def stepped(self, stepper):
            if stepper.step == 2:
                raise KeyboardInterrupt

    core.attach(Interrupting())
    core.advance()
    with pytest.raises(KeyboardInterrupt):
        core.advance()
    with pytest.raises(ValueError, match="advance: the stepper cannot go on: step 3 did not finish"):
        core.advance()


class _Exits(ImplicitScheme):
    """The paper's quotients, whose step calls sys.exit(0), or returns three numbers."""

    DESCRIPTION = "a scheme that breaks its contract"
    QUOTIENTS = PAPER
    how = "exit"

    def step(self):
        terms = super().step()
        if self.how == "exit":
            raise SystemExit(0)
        return tuple(terms)[:3]


@pytest.mark.parametrize(("how", "fragment"), [
    ("exit", "called sys.exit(0)"),
    ("three", "step() returned tuple (1"),
])
def test_a_schemes_broken_step_is_one_line_naming_it(how, fragment):
    scheme = type("Broken", (_Exits,), {"how": how})
    st = stepper(scheme=scheme)
    with pytest.raises(sc.SceneError, match=r"model 'inelastic' with scheme '.*:Broken'.*" + re.escape(fragment)):
        st.advance()
    with pytest.raises(ValueError, match="the run stopped at step 0"):
        st.advance()


class _EpsFree(PaperScheme):
    """Declares no penalty option (so no eps), yet applies the model's explicit penalty, which reads eps."""

    DESCRIPTION = "a scheme that claims to need no eps"
    OPTIONS = (mass_option("lumped", "consistent"), PETSC_OPTIONS)

    def __init__(self, problem):
        super().__init__(problem)
        self.explicit = True  # the paper's explicit penalty F(eta^n, v^n)

    def _penalty_law(self, problem):
        laws = problem.laws
        return laws.compile(laws.model.penalty(laws.eta, laws.quotient, laws.params))


def test_a_scheme_without_eps_that_applies_the_penalty_is_one_line_naming_it():
    with pytest.raises(sc.SceneError, match=r"model 'inelastic' with scheme '.*:_EpsFree' failed with TypeError: it "
                                            r"applies model 'inelastic''s penalty, whose eps it has not got"):
        stepper(scene(eta0="0", h_left=0.0, h_right=0.0), scheme=_EpsFree).advance()  # refused before the first step


def test_an_initial_energy_that_is_not_finite_is_refused_before_the_first_step():
    import dataclasses

    model = dataclasses.replace(sc.load_model("cubic_foundation"), name="nan_energy",
                                stored_energy=lambda eta, p: ufl.sqrt(eta - 10.0))  # NaN at eta0 ~ 1
    with pytest.raises(sc.SceneError, match=r"model 'nan_energy' with scheme 'paper': the initial state's energy is "
                                            r"not finite"):
        stepper(model=model)


def test_an_optional_constant_cannot_be_switched_on_mid_run_and_huge_values_are_one_line():
    s = sc.load_scene("film_landing").replace(nx=40, T=0.002, dt=0.0005, output_times=[])
    st = stepper(s)
    assert "p_cav" not in st.parameters
    with pytest.raises(sc.SceneError, match="p_cav: model 'film''s optional constant was not given"):
        st.parameters["p_cav"] = 0.0
    with pytest.raises(sc.SceneError, match=r"mu: .* is not finite"):
        st.parameters["mu"] = 10**400
    st.advance()


@pytest.mark.slow
def test_ranks_given_different_input_refuse_on_every_rank_and_none_waits(tmp_path):
    """Two ranks: a scene whose alpha differs per rank, then beta set between steps on rank 1 only: both are refused
    on both ranks in one line, and the job ends (no rank waits in a collective call the other does not make)."""
    import sys
    from pathlib import Path

    from conftest import mpirun

    proc = mpirun([sys.executable, Path(__file__).resolve()], ranks=2, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    out = proc.stdout  # mpirun forwards the ranks' lines in chunks: two ranks' lines may run together
    for rank in (0, 1):
        assert f"rank {rank} scene: the scene, scheme, options and model: rank 1 was given other values" in out, out
        assert f"rank {rank} parameters: parameters: rank 1 was given other" in out, out


def _disagreeing_ranks() -> None:
    from mpi4py import MPI

    rank = MPI.COMM_WORLD.rank
    try:
        stepper(scene(alpha=0.01 * (1 + rank)))
    except sc.SceneError as exc:
        print(f"rank {rank} scene: {exc}", flush=True)
    st = stepper(scheme="paper", model="stiff_string")
    st.advance()
    if rank == 1:
        st.parameters["beta"] = 1e-4
    try:
        st.advance()
    except sc.SceneError as exc:
        print(f"rank {rank} parameters: {exc}", flush=True)


if __name__ == "__main__":
    _disagreeing_ranks()


def test_a_contact_springs_constant_changed_while_pressed_keeps_the_balance_closed():
    """examples/soft_ground's k doubled while the string presses into the ground: the spring's energy jumps with
    the state at rest, booked as work on the string and held as the contact's, so the balance still closes."""
    from stringcontact.model import registry

    if "soft_ground" not in registry.registered():
        pytest.skip("examples/soft_ground is not installed (scripts/setup installs it)")
    st = stepper(scene(nx=100, T=0.3, dt=0.0002), model="soft_ground")
    pressed = False
    while st.step < st.nt:
        st.advance()
        if not pressed and st.eta.min() < -0.01:
            pressed = True
            st.parameters["k"] = 2 * st.parameters["k"]
    result = st.result()
    assert pressed and result.status == "complete", result.message
    assert result.checks["energy_balance"]["relative_residual"] < 1e-9
