"""The scheme layer: every scheme's ledger closes, the stability bound belongs to the law, `projection`.

No timing here: the speed figures are in benchmarks/bench_schemes.py.
"""

import dataclasses
import math
import re

import numpy as np
import pytest
from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis import study
from stringcontact.model import variants
from stringcontact.scene import SceneWarning
from stringcontact.verification import reference


def run(scene, **kwargs):
    return sc.simulate(scene, comm=MPI.COMM_SELF, **kwargs)


def fd_projection(scene, obstacle=None):
    x = scene.x()
    return reference.fd_projection(
        scene.initial_displacement(x), scene.initial_velocity(x), length=scene.length, T=scene.T, nt=scene.nt,
        alpha=scene.alpha, h_left=scene.h_left, h_right=scene.h_right, obstacle=obstacle,
    )


@pytest.fixture(scope="module")
def ex1():
    return sc.load_scene("example1").replace(nx=400, nt=600)


def test_schemes_are_listed_with_a_description():
    assert {"paper", "projection"} <= set(sc.SCHEMES)
    assert all(isinstance(text, str) and len(text) > 20 for text in sc.SCHEMES.values())


@pytest.mark.parametrize("name", ["example1", "example2"])
def test_projection_is_its_finite_difference_reference(name):
    scene = sc.load_scene(name).replace(nx=300, nt=600)
    with pytest.warns(SceneWarning) if name == "example2" else _nothing():  # example2 starts below the obstacle
        res = run(scene, scheme="projection")
    _, eta, vel = fd_projection(scene)
    assert res.contact.any()
    assert np.max(np.abs(res.eta - eta[res.steps])) <= 1e-10
    assert np.max(np.abs(res.velocity - vel[res.steps])) <= 1e-10 / scene.dt


@pytest.mark.slow
def test_projection_keeps_the_string_above_a_profiled_obstacle():
    scene = sc.load_scene("loaded_string").replace(nx=100, nt=4000, T=0.8, output_times=[0.4])
    res = run(scene, scheme="projection", model=variants.loaded_obstacle)
    psi = scene.obstacle_values(res.x)
    assert np.all(res.eta >= psi - 1e-12)  # the admissible set is gap = η − ψ ≥ 0
    assert res.contact[-1].any()


def test_projection_never_goes_below_the_obstacle_and_conserves_apart_from_contact(ex1):
    res = run(ex1, scheme="projection")
    e = res.energy
    E0 = res.total_energy[0]
    assert res.min_eta >= 0.0
    assert np.max(np.abs(res.balance_residual)) <= 1e-9 * E0
    assert np.all(e["numerical_dissipation"] == 0.0)
    assert e["contact_dissipation"][-1] > 0.3 * E0  # the landing's loss is booked as contact
    assert np.all(np.diff(res.total_energy) <= 1e-9 * E0)


def test_projection_refuses_a_step_above_its_stability_limit():
    scene = study.flat_landing_scene(200, T=0.3, nt=50)  # dt = 6e-3 > dx = 5e-3, alpha = 0
    with pytest.raises(sc.InstabilityError, match=r"dt_max = 0\.005.*nt >= 60") as info:
        run(scene, scheme="projection")
    assert info.value.step == 0


def test_projection_dt_max_is_dx_without_viscosity_and_grows_with_it():
    from stringcontact.timestepping.spectrum import largest_stable_dt

    for alpha in (0.0, 0.01):  # C = αK: Δt < α + √(α² + 4/λ_max), and 4/λ_max → Δx² on a uniform mesh
        scene = study.flat_landing_scene(200, T=0.3, nt=300, alpha=alpha)
        ops = _operators(scene)
        dt_max = largest_stable_dt(ops, _interior(ops))
        assert dt_max >= alpha + math.sqrt(alpha**2 + scene.dx**2)
        assert dt_max == pytest.approx(alpha + math.sqrt(alpha**2 + scene.dx**2), rel=1e-3)


def test_projection_refuses_a_penalty_and_a_model_without_gap(ex1):
    with pytest.raises(ValueError, match="scheme 'projection' accepts no penalty"):
        run(ex1, scheme="projection", penalty="explicit")
    with pytest.raises(ValueError, match=r"model 'elastic' declares no gap.*runs with scheme paper$"):
        run(ex1, scheme="projection", model=variants.elastic)


def test_projection_lifts_initial_data_below_the_obstacle():
    scene = sc.load_scene("example2").replace(nx=200, nt=500)
    with pytest.warns(SceneWarning, match="projected onto it at t = 0"):
        res = run(scene, scheme="projection")
    assert np.min(res.eta[0]) >= 0.0
    assert np.min(scene.initial_displacement(scene.x())) < 0


@pytest.mark.parametrize("scheme", list(sc.SCHEMES))
def test_every_ledger_closes_and_the_scheme_is_recorded(ex1, scheme):
    res = run(ex1, scheme=scheme)
    assert res.scheme == scheme
    E0 = res.total_energy[0]
    assert np.max(np.abs(res.balance_residual)) <= 1e-9 * E0
    assert res.energy["contact_dissipation"][-1] > 0


def test_the_landing_loss_is_contact_dissipation_under_the_semi_implicit_penalty():
    # issue: with ε → 0 the loss ½V² per unit length was booked as numerical dissipation
    scene = study.flat_landing_scene(200, T=0.3, eps=1e-10)
    res = run(scene, penalty="semi-implicit")
    e, E = res.energy, res.total_energy
    loss = E[0] - E[-1]  # α = 0: the landing's loss, and the implicit Euler's own
    assert loss > 0.5 * E[0]
    assert e["contact_dissipation"][-1] > 0.8 * loss  # was 0.4 % of it: booked as numerical
    assert e["numerical_dissipation"][-1] < 0.2 * loss  # what is left: the implicit Euler's own damping


def test_the_stability_bound_belongs_to_the_law():
    scene = study.flat_landing_scene(100, T=0.3, eps=1.0 / 100 / 4)  # r = 4
    with pytest.raises(sc.InstabilityError, match="restitution"):
        run(scene)
    res = run(scene, model=variants.elastic)  # a spring has no r bound: it runs
    assert res.status == "complete"
    free = dataclasses.replace(sc.inelastic, stability=None)
    with pytest.raises(sc.InstabilityError, match="energy rose") as info:  # the guard still stops the growth
        run(scene, model=free)
    assert info.value.step > 0


def test_a_scene_file_chooses_the_scheme(tmp_path):
    text = sc.load_scene("example1").replace(nx=100, nt=150, scheme="projection")
    res = run(text)
    assert res.scheme == "projection"
    with pytest.raises(sc.SceneError, match=re.escape(f"scheme: invalid value str 'leapfrog'; allowed: {', '.join(sc.SCHEMES)}")):
        text.replace(scheme="leapfrog")


# --- helpers ------------------------------------------------------------------------------------------


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def _operators(scene):
    from stringcontact.model.interface import inelastic
    from stringcontact.run.adapter import scene_problem

    return scene_problem(scene, inelastic, MPI.COMM_SELF).operators()


def _interior(ops):
    mask = np.ones(ops.m.size, dtype=bool)
    mask[np.argsort(ops.m)[:2]] = False  # the two ends: the only nodes with half a cell of mass
    return mask



def test_projection_energy_guard_allows_the_viscous_term_of_its_energy():
    """`projection`'s leapfrog energy E^{n+1/2} may rise by the change of (Δt/4)|v|²_C while E + (Δt/4)|v|²_C falls:
    Example 1 at nx = 100, Δt = Δx is stable (`run --tol`'s first pilots), and the guard must not call it unstable."""
    scene = sc.load_scene("example1").replace(nx=100, nt=30)
    res = run(scene, scheme="projection", storage=sc.Storage(max_rows=scene.nt + 1))
    assert res.status == "complete", res.message
    leapfrog = res.energy["kinetic"] + res.energy["elastic"]
    assert np.any(np.diff(leapfrog) > 1e-9 * leapfrog[0])  # the case the slack is for: E^{n+1/2} alone rose
