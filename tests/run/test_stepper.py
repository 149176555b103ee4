"""`Stepper`: a run stepped by the caller gives `simulate`'s bits; a restart from its state as arrays continues the
run; bad arrays are refused in one line; two ranks give the serial state."""

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from mpi4py import MPI

import stringcontact as sc
from stringcontact.errors import SceneError

#: a scene no other test runs: the bump's obstacle under a loaded string, thrown down
SCENE = dict(nx=120, T=0.25, dt=0.0005, eta0="0.4 + 0.2*sin(pi*x)", v0="-4*sin(pi*x)", h=0.4, output_times=[0.1])


def scene(**changes):
    return sc.load_scene("example1").replace(**(SCENE | changes))


def quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


def stepped(s, **kwargs):
    st = quiet(sc.Stepper, s, **kwargs)
    times = []
    while st.step < st.nt:
        quiet(st.advance)
        times.append(st.t)
    return st, times


CASES = {"paper": {"scheme": "paper"}, "projection": {"scheme": "projection"}, "newmark": {"scheme": "newmark"},
         "nonlinear": {"scheme": "paper", "model": "cubic_foundation"},
         "moving obstacle": {"scheme": "projection", "model": "loaded_obstacle",
                             "scene": {"obstacle": "0.1*sin(2*pi*t)", "eta0": "0.4 + 0.2*sin(pi*x)"}}}


@pytest.mark.parametrize("case", CASES)
def test_stepping_to_t_gives_simulates_result(case):
    kwargs = dict(CASES[case])
    s = scene(**kwargs.pop("scene", {}))
    reference = quiet(sc.simulate, s, **kwargs)
    st, times = stepped(s, **kwargs)
    result = st.result()
    assert st.t == s.T and times[-1] == s.T and len(times) == s.nt
    assert 0.1 in times  # the output time as given, like Result.t
    np.testing.assert_array_equal(st.eta, reference.eta[-1])
    np.testing.assert_array_equal(st.x, reference.x)
    for name in ("t", "eta", "velocity", "contact", "contact_force"):
        np.testing.assert_array_equal(getattr(result, name), getattr(reference, name), err_msg=name)
    assert result.energy.keys() == reference.energy.keys()
    for key, values in reference.energy.items():
        np.testing.assert_array_equal(result.energy[key], values, err_msg=key)
    assert result.status == reference.status == "complete" and st.result() is result


def test_a_restart_from_the_state_as_arrays_continues_the_run():
    """Under `paper` (explicit penalty) the state is (η, v): the restart at half-way ends where the run does."""
    s = scene(output_times=[])
    whole = quiet(sc.simulate, s, scheme="paper")
    st = quiet(sc.Stepper, s, scheme="paper")
    while st.step < s.nt // 2:
        st.advance()
    rest = s.replace(eta0=st.gather(st.eta), v0=st.gather(st.velocity), T=s.T - st.t, nt=s.nt - st.step)
    again = quiet(sc.simulate, rest, scheme="paper")
    assert np.max(np.abs(again.eta[-1] - whole.eta[-1])) <= 1e-8 * np.max(np.abs(whole.eta[-1]))
    assert np.max(np.abs(again.velocity[-1] - whole.velocity[-1])) <= 1e-8 * np.max(np.abs(whole.velocity))


def test_a_models_field_between_steps():
    st = quiet(sc.Stepper, scene(), model="stiff_string", scheme="paper")
    for _ in range(10):
        st.advance()
    kappa = st.field("curvature")
    assert kappa.shape == st.eta.shape and np.all(np.isfinite(kappa)) and np.abs(kappa).max() > 0
    with pytest.raises(KeyError, match="writes curvature"):
        st.field("pressure")


def test_stepping_past_t_and_a_result_before_t_are_refused():
    st = quiet(sc.Stepper, scene(T=0.005, output_times=[]))
    with pytest.raises(ValueError, match="advance"):
        st.result()
    while st.step < st.nt:
        st.advance()
    with pytest.raises(ValueError, match="at T"):
        st.advance()


@pytest.mark.slow
@pytest.mark.parametrize("values, match", [(np.zeros(7), "7 nodal values for nx = 120 cells; allowed: nx \\+ 1 = 121"),
                                           (np.full(121, np.nan), "value nan at node 0 is not finite")])
def test_bad_arrays_are_refused_in_one_line(values, match, tmp_path):
    with pytest.raises(SceneError, match=match) as info:
        scene().replace(eta0=values)
    assert "\n" not in str(info.value)
    data = {k: v for k, v in scene().as_dict().items() if k != "notes"} | {"v0": [float(v) for v in values]}
    path = tmp_path / "bad.toml"
    path.write_text(tomli_w.dumps(data).replace("nan", "nan"))
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", str(path), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "v0:" in proc.stderr, proc.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_two_ranks_step_to_the_serial_state(tmp_path):
    from conftest import mpirun

    proc = mpirun([sys.executable, Path(__file__).resolve(), tmp_path], ranks=2, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    serial, _ = stepped(scene(), scheme="projection")
    parallel = np.load(tmp_path / "eta.npy")
    assert np.max(np.abs(parallel - serial.eta)) <= 1e-8 * np.max(np.abs(serial.eta))


def _two_ranks(folder: Path) -> None:
    st, _ = stepped(scene(), scheme="projection")
    eta = st.gather(st.eta)  # collective
    if MPI.COMM_WORLD.rank == 0:
        np.save(folder / "eta.npy", eta)


if __name__ == "__main__":
    _two_ranks(Path(sys.argv[1]))


@pytest.mark.slow
def test_a_constant_changed_between_steps_is_taken_up_and_booked():
    """β changed at step 100: the run goes on as a restart from that state with the new β (to the bit, under the
    paper's explicit penalty), and the ledger books the jump of the bending energy as external work: it closes."""
    s = scene(model="stiff_string", parameters={"beta": 1e-3}, output_times=[])
    st = quiet(sc.Stepper, s, scheme="paper")
    while st.step < s.nt:
        if st.step == 100:
            work_before = st.ledger.ext
            st.parameters["beta"] = 4e-3
        quiet(st.advance)
        if st.step == 101:
            work = st.ledger.ext - work_before
    result = st.result()
    assert result.parameters == {"beta": 4e-3} and result.checks["energy_balance"]["closes"]
    assert work > 0  # a stiffer string stores more energy in the same bent state
    st2 = quiet(sc.Stepper, s, scheme="paper")
    while st2.step < 100:
        st2.advance()
    rest = s.replace(eta0=st2.gather(st2.eta), v0=st2.gather(st2.velocity), T=s.T - st2.t, nt=s.nt - 100,
                     parameters={"beta": 4e-3})
    np.testing.assert_array_equal(quiet(sc.simulate, rest, scheme="paper").eta[-1], result.eta[-1])


def test_a_bad_constant_between_steps_is_refused_in_one_line():
    st = quiet(sc.Stepper, scene(model="stiff_string", output_times=[]))
    with pytest.raises(SceneError, match=r"^beta: -1 is out of range; allowed: a number in \[0, 1000\]$"):
        st.parameters["beta"] = -1.0
    with pytest.raises(SceneError, match="has no constant 'gamma'"):
        st.parameters["gamma"] = 1.0
    assert dict(st.parameters) == {"beta": 0.0} and not st.parameters.changed


def test_a_run_with_a_moving_obstacle_refuses_a_new_dt_in_one_line():
    """The stored rows read ψ on the run's own time grid: a new Δt mid-run is refused, the state kept, and it goes on."""
    st = quiet(sc.Stepper, scene(model="loaded_obstacle", obstacle="0.1*sin(2*pi*t)", output_times=[]),
               scheme="projection")
    quiet(st.advance)
    eta, dt = st.eta.copy(), st.core.dt
    with pytest.raises(ValueError, match=r"^dt: the time step of a run with a moving obstacle cannot change"):
        st.core.dt = dt / 2
    np.testing.assert_array_equal(st.eta, eta)
    quiet(st.advance)
    assert st.step == 2 and st.core.dt == dt


@pytest.mark.slow
def test_the_command_line_simulate_and_a_stepper_record_the_same_settings(tmp_path):
    """The same run started three ways: summary.json records the same scene (with the PETSc options and the
    restitution it ran with), scheme, penalty, mass, model and constants."""
    s = scene(model="stiff_string", parameters={"beta": 1e-3}, output_times=[], T=0.01, notes="", name="three_ways")
    path = tmp_path / "three_ways.toml"
    path.write_text(tomli_w.dumps(s.as_dict()))
    options = {"ksp_type": "preonly", "pc_type": "lu"}
    subprocess.run([sys.executable, "-m", "stringcontact", "run", str(path), "--scheme", "paper", "--petsc-option",
                    "ksp_type=preonly", "--petsc-option", "pc_type=lu", "--out", str(tmp_path / "cli"),
                    "--no-pictures"], check=True, capture_output=True)
    quiet(sc.simulate, s, scheme="paper", petsc_options=options, output=sc.Output(tmp_path / "py", pictures=False))
    st = quiet(sc.Stepper, s, scheme="paper", petsc_options=options, output=sc.Output(tmp_path / "st", pictures=False))
    while st.step < st.nt:
        st.advance()
    st.result()
    keys = ("scene", "scheme", "penalty", "mass", "model", "model_origin", "parameters", "fields", "petsc_options")
    import json

    recorded = [{k: json.loads((tmp_path / d / "summary.json").read_text())[k] for k in keys} for d in ("cli", "py", "st")]
    assert recorded[0]["scene"]["petsc_options"] == options and recorded[0]["petsc_options"]["pc_type"] == "lu"
    assert recorded[0] == recorded[1] == recorded[2]


def test_a_failed_newton_step_is_sub_stepped_as_the_smaller_dt_would_take_it(monkeypatch):
    """Newton forced to fail once, on the first step at Δt: the step is taken again as two sub-steps of Δt/2 from the
    restored state, and ends where a run with Δt/2 from the start is after 2 steps, to round-off; the run goes on at
    Δt, closes its balance and counts the sub-steps."""
    from stringcontact.errors import SolverError
    from stringcontact.timestepping.newton import NewtonStep

    s = scene(output_times=[], T=0.02)
    calls = {"n": 0}
    solve = NewtonStep.solve

    def failing(self, guess):
        calls["n"] += 1
        if calls["n"] == 1 and self.problem.dt == s.dt:
            raise SolverError("Newton did not converge (SNES reason -5) after 50 iterations (forced)")
        return solve(self, guess)

    monkeypatch.setattr(NewtonStep, "solve", failing)
    st = quiet(sc.Stepper, s, scheme="paper", model="cubic_foundation")
    st.advance()
    monkeypatch.setattr(NewtonStep, "solve", solve)
    fine = quiet(sc.Stepper, s.replace(nt=2 * s.nt), scheme="paper", model="cubic_foundation")
    for _ in range(2):
        fine.advance()
    assert np.max(np.abs(st.eta - fine.eta)) <= 1e-12 * np.max(np.abs(fine.eta))
    while st.step < st.nt:
        st.advance()
    result = st.result()
    assert result.counters["sub-stepped steps"] == 1 and result.counters["sub-steps"] == 2
    assert result.status == "complete" and result.checks["energy_balance"]["closes"]


@pytest.mark.parametrize("scheme", ["paper", "newmark"])
def test_a_failed_newton_step_against_a_moving_obstacle_is_sub_stepped_at_its_time(monkeypatch, scheme):
    """A moving obstacle pressing the string, every Newton solve at Δt forced to fail: each step is taken as two
    sub-steps of Δt/2 that see the obstacle at their own times, and the run goes on from the right time, so it ends
    where a run at Δt/2 ends, to round-off, complete."""
    import dataclasses

    from stringcontact.errors import SolverError
    from stringcontact.timestepping.newton import NewtonStep

    s = scene(output_times=[], T=0.05, obstacle="0.3 + 0.15*sin(20*pi*t)")
    model = dataclasses.replace(sc.load_model("loaded_obstacle"), name="loaded_obstacle_by_newton", newton=True)
    solve = NewtonStep.solve

    def failing(self, guess):
        if self.problem.dt == s.dt:
            raise SolverError("Newton did not converge (SNES reason -5) after 50 iterations (forced)")
        return solve(self, guess)

    monkeypatch.setattr(NewtonStep, "solve", failing)
    st, _ = stepped(s, scheme=scheme, model=model)
    result = st.result()
    monkeypatch.setattr(NewtonStep, "solve", solve)
    fine = quiet(sc.simulate, s.replace(nt=2 * s.nt), scheme=scheme, model=model)
    assert fine.contact.any() and result.status == "complete", result.message
    assert result.counters["sub-stepped steps"] == s.nt
    assert np.max(np.abs(result.eta[-1] - fine.eta[-1])) <= 1e-11 * np.max(np.abs(fine.eta[-1]))


def test_a_step_that_fails_at_every_sub_step_stops_the_run_in_one_line(monkeypatch):
    from stringcontact.errors import SolverError
    from stringcontact.timestepping.newton import NewtonStep

    def failing(self, guess):
        raise SolverError("Newton did not converge (SNES reason -5) after 50 iterations (forced)")

    monkeypatch.setattr(NewtonStep, "solve", failing)
    st = quiet(sc.Stepper, scene(output_times=[]), scheme="paper", model="cubic_foundation")
    with pytest.raises(SolverError, match=r"^step 1, t = 0.0005: Newton did not converge .* again in 16 sub-steps "
                                          r"of dt/16; use a smaller dt \(nt >= 8000\)") as info:
        st.advance()
    assert "\n" not in str(info.value) and "scheme 'paper'" not in str(info.value)  # the scheme it runs
