"""The peers the benchmarks time `simulate` against step as `simulate` does, on a coarser Example 1 (no timing
here): each scheme's NumPy peer gives its η and v, and the C loop (benchmarks/compiled_peer.c, built with the
system's C compiler) the paper scheme's η, v and energy ledger."""

import warnings

import numpy as np
import peers
import pytest
from mpi4py import MPI

import stringcontact as sc


@pytest.fixture(scope="module")
def lib():
    return peers.build_compiled()


@pytest.fixture(scope="module")
def run():
    scene = sc.load_scene("example1").replace(nx=200)  # the paper's 1500 steps on a coarser string
    return scene, sc.simulate(scene, comm=MPI.COMM_SELF)


@pytest.mark.parametrize("energies", [False, True])
def test_the_c_loop_steps_as_simulate_does(lib, run, energies):
    scene, res = run
    assert res.contact.any(), "the run must reach the obstacle, or the penalty is not compared"
    eta, v, _, _ = peers.compiled_peer(lib, scene, res.steps, energies)
    # the same equations in another order of operations (the FEM form scaled by 1/Δt², the loop's by Δt²/Δx):
    # round-off, 1.8e-11 in η and 2e-10 in v here (4.6e-11 and 5.5e-10 at 400 cells); benchmarks/bench_solver's
    # tolerance for η is 1e-10 up to N = 1000
    np.testing.assert_allclose(eta, res.eta, rtol=0, atol=1e-10)
    np.testing.assert_allclose(v, res.velocity, rtol=0, atol=1e-8)


def test_the_c_loops_ledger_is_simulates(lib, run):
    scene, res = run
    _, _, ledger, _ = peers.compiled_peer(lib, scene, res.steps, energies=True)
    E0 = res.energy["kinetic"][0] + res.energy["elastic"][0]
    assert res.energy["contact_dissipation"][-1] > 1e-3 * E0  # contact took energy: its booking is compared
    for name in peers.LEDGER[:-1]:  # 1.2e-12 E(0) at most here
        assert ledger[name] == pytest.approx(res.energy[name][-1], abs=1e-10 * E0), name
    assert ledger["min_eta"] == pytest.approx(res.min_eta, abs=1e-10)  # η's tolerance; 5e-13 here


def test_the_c_loops_min_eta_counts_the_ends_as_the_driver_does(lib, run):
    """One arch thrown up stays above its ends (η = 1 there, 1 + 1.2e-4 at the next nodes): min η is the ends',
    as `simulate` keeps it."""
    scene = run[0].replace(eta0="1 + 0.5*sin(pi*x)**2", v0="20", T=0.01, output_times=[])
    res = sc.simulate(scene, comm=MPI.COMM_SELF)
    _, _, ledger, _ = peers.compiled_peer(lib, scene, res.steps, energies=True)
    assert res.min_eta == 1.0
    assert ledger["min_eta"] == pytest.approx(res.min_eta, abs=1e-10)


@pytest.mark.parametrize(
    ("scheme", "options", "peer"),
    [
        ("paper", {}, peers.paper_peer),
        ("paper", {"penalty": "semi-implicit"}, peers.semi_implicit_peer),
        ("projection", {}, peers.projection_peer),
        ("newmark", {}, peers.newmark_peer),
    ],
    ids=["paper", "paper semi-implicit", "projection", "newmark"],
)
def test_each_numpy_peer_steps_as_its_scheme_does(run, scheme, options, peer):
    scene = run[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the penalty's stability note
        res = sc.simulate(scene, scheme=scheme, comm=MPI.COMM_SELF, **options)
    assert res.contact.any(), "the run must reach the obstacle, or the contact step is not compared"
    eta, v = peer(scene, res.steps)
    # round-off of the same equations in another order: 2.7e-11 (η) and 1.6e-9 (v) at most here
    np.testing.assert_allclose(eta, res.eta, rtol=0, atol=1e-10)
    np.testing.assert_allclose(v, res.velocity, rtol=0, atol=1e-8)
