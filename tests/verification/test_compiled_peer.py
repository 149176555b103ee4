"""The compiled limit of benchmarks/bench_step.py is a loop of the same scheme: benchmarks/compiled_peer.c, built
with the system's C compiler, gives simulate's η, v and energy ledger on a shortened Example 1 (no timing here)."""

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
    scene = sc.load_scene("example1").replace(nx=400)  # the paper's 1500 steps on a coarser string
    return scene, sc.simulate(scene, comm=MPI.COMM_SELF)


@pytest.mark.parametrize("energies", [False, True])
def test_the_c_loop_steps_as_simulate_does(peer, run, energies):
    module, lib = peer
    scene, res = run
    assert res.contact.any(), "the run must reach the obstacle, or the penalty is not compared"
    eta, v, _, _ = module.compiled_peer(lib, scene, res.steps, energies)
    # the same equations in another order of operations (the FEM form scaled by 1/Δt², the loop's by Δt²/Δx):
    # round-off, 5e-11 here; benchmarks/bench_solver.tolerance allows 1e-10 up to N = 1000
    np.testing.assert_allclose(eta, res.eta, rtol=0, atol=1e-10)
    np.testing.assert_allclose(v, res.velocity, rtol=0, atol=1e-10 / scene.dt)


def test_the_c_loops_ledger_is_simulates(peer, run):
    module, lib = peer
    scene, res = run
    _, _, ledger, _ = module.compiled_peer(lib, scene, res.steps, energies=True)
    E0 = res.energy["kinetic"][0] + res.energy["elastic"][0]
    assert res.energy["contact_dissipation"][-1] > 1e-3 * E0  # contact took energy: its booking is compared
    for name in module.LEDGER[:-1]:
        assert ledger[name] == pytest.approx(res.energy[name][-1], abs=1e-10 * E0), name
    assert ledger["min_eta"] == pytest.approx(res.min_eta, abs=1e-12)
