"""The compiled limit of benchmarks/bench_step.py is a loop of the same scheme: benchmarks/compiled_peer.c, built
with the system's C compiler, gives simulate's η, v and energy ledger on a coarser Example 1 (no timing here)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import stringcontact as sc

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def peer():
    spec = importlib.util.spec_from_file_location("compiled_peer", ROOT / "benchmarks" / "compiled_peer.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module, module.build()


@pytest.fixture(scope="module")
def run():
    scene = sc.load_scene("example1").replace(nx=200)  # the paper's 1500 steps on a coarser string
    return scene, sc.simulate(scene, comm=MPI.COMM_SELF)


@pytest.mark.parametrize("energies", [False, True])
def test_the_c_loop_steps_as_simulate_does(peer, run, energies):
    module, lib = peer
    scene, res = run
    assert res.contact.any(), "the run must reach the obstacle, or the penalty is not compared"
    eta, v, _, _ = module.compiled_peer(lib, scene, res.steps, energies)
    # the same equations in another order of operations (the FEM form scaled by 1/Δt², the loop's by Δt²/Δx):
    # round-off, 1.8e-11 in η and 2e-10 in v here (4.6e-11 and 5.5e-10 at 400 cells); benchmarks/bench_solver's
    # tolerance for η is 1e-10 up to N = 1000
    np.testing.assert_allclose(eta, res.eta, rtol=0, atol=1e-10)
    np.testing.assert_allclose(v, res.velocity, rtol=0, atol=1e-8)


def test_the_c_loops_ledger_is_simulates(peer, run):
    module, lib = peer
    scene, res = run
    _, _, ledger, _ = module.compiled_peer(lib, scene, res.steps, energies=True)
    E0 = res.energy["kinetic"][0] + res.energy["elastic"][0]
    assert res.energy["contact_dissipation"][-1] > 1e-3 * E0  # contact took energy: its booking is compared
    for name in module.LEDGER[:-1]:  # 1.2e-12 E(0) at most here
        assert ledger[name] == pytest.approx(res.energy[name][-1], abs=1e-10 * E0), name
    assert ledger["min_eta"] == pytest.approx(res.min_eta, abs=1e-10)  # η's tolerance; 5e-13 here


def test_the_c_loops_min_eta_counts_the_ends_as_the_driver_does(peer, run):
    """One arch thrown up stays above its ends (η = 1 there, 1 + 1.2e-4 at the next nodes): min η is the ends',
    as `simulate` keeps it."""
    module, lib = peer
    scene = run[0].replace(eta0="1 + 0.5*sin(pi*x)**2", v0="20", T=0.01, output_times=[])
    res = sc.simulate(scene, comm=MPI.COMM_SELF)
    _, _, ledger, _ = module.compiled_peer(lib, scene, res.steps, energies=True)
    assert res.min_eta == 1.0
    assert ledger["min_eta"] == pytest.approx(res.min_eta, abs=1e-10)
