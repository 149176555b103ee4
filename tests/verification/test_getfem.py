"""GetFEM's impacting rod (benchmarks/rod.py): the exact solution against the PDE, the mirrored point
contact in `simulate`, and, when GetFEM is installed, GetFEM's own schemes against the same exact solution."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import rod

ROOT = Path(__file__).resolve().parents[2]
RNG = np.random.default_rng(19)
TIMES = RNG.uniform(0.0, 9.0, 40)


def test_initial_data_and_fixed_end():
    x = np.linspace(0, 1, 101)
    assert np.allclose(rod.rod_exact(x, 0.0), 0.5 - 0.5 * x)
    assert np.allclose(rod.rod_exact(x[1:], 0.0, "t"), 0.0)  # at (0, 0) u_t jumps; the table gives the phase's −1/2
    assert np.allclose([rod.rod_exact(1.0, t) for t in TIMES], 0.0)


def test_period_is_3_and_not_shorter():
    x = np.linspace(0, 1, 101)
    for t in TIMES:
        assert np.allclose(rod.rod_exact(x, t + rod.PERIOD), rod.rod_exact(x, t))
    assert not np.allclose(rod.rod_exact(x, 1.5), rod.rod_exact(x, 0.0))


def test_energy_is_one_eighth_at_all_times():
    x = (np.arange(200_000) + 0.5) / 200_000  # midpoints: the integrand is piecewise constant
    for t in TIMES:
        e = 0.5 * np.mean(rod.rod_exact(x, t, "x") ** 2 + rod.rod_exact(x, t, "t") ** 2)
        assert e == pytest.approx(rod.ROD_ENERGY, abs=1e-4)


def test_wave_equation_by_the_parallelogram_rule():
    """d'Alembert on a characteristic rectangle: u(x, t+s) + u(x, t−s) = u(x+s, t) + u(x−s, t) inside (0, 1)."""
    for _ in range(300):
        s = RNG.uniform(0.0, 0.2)
        x, t = RNG.uniform(s, 1 - s), RNG.uniform(s, 9.0)
        lhs = rod.rod_exact(x, t + s) + rod.rod_exact(x, t - s)
        assert lhs == pytest.approx(rod.rod_exact(x + s, t) + rod.rod_exact(x - s, t), abs=1e-12)


def test_signorini_conditions_at_the_contact_end():
    gap = np.array([rod.rod_exact(0.0, t) for t in TIMES])
    stress = np.array([rod.rod_exact(0.0, t, "x") for t in TIMES])
    assert gap.min() >= 0 and stress.max() <= 0
    assert np.allclose(gap * stress, 0.0)
    assert gap.min() == 0 and stress.min() < 0  # the rod does touch, with a force


def test_continuous_in_space_and_time():
    x = np.linspace(0, 1, 2001)
    for t in TIMES:
        assert np.max(np.abs(np.diff(rod.rod_exact(x, t)))) <= 0.5 * (x[1] - x[0]) + 1e-12
        assert np.max(np.abs(rod.rod_exact(x, t + 1e-4) - rod.rod_exact(x, t))) <= 0.5e-4 + 1e-12


def test_string_is_the_rod_mirrored():
    y = np.linspace(0, 1, 51)
    for t in TIMES[:10]:
        assert np.allclose(rod.string_exact(1 + y, t), rod.rod_exact(y, t), atol=1e-14)
        assert np.allclose(rod.string_exact(1 - y, t), rod.rod_exact(y, t), atol=1e-14)


def test_p1_norm_is_exact_for_linear_functions():
    x = np.linspace(0, 1, 11)
    assert rod.p1_l2_norms(np.stack([x, 1 - x]), 0.1) == pytest.approx([3**-0.5, 3**-0.5], rel=1e-12)


def _run(nx, penalty, eps_over_dt, T=1.5):
    import stringcontact as sc
    from stringcontact.model.interface import inelastic

    h = 1.0 / nx
    dt = 0.04 * h
    scene = rod.rod_scene(nx, dt, eps_over_dt * dt, T=T)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sc.simulate(scene, penalty=penalty, model=rod.point_contact(inelastic, h),
                          storage=sc.Storage(max_rows=scene.nt + 1))
    at_point = np.argmin(np.abs(res.x - 1.0))
    return res, rod.relative_error(res.x, res.t, res.eta), res.eta[:, at_point].min()


def test_point_contact_holds_only_the_middle_node_and_converges():
    res20, err20, min20 = _run(20, "semi-implicit", 1e-9)
    _, err40, _ = _run(40, "semi-implicit", 1e-9)
    assert min20 >= -0.04 * 0.05 * 0.5 - 1e-12  # at most one step's penetration, Δt·|u_t|
    assert res20.eta.min() < -0.2  # away from x = 1 the string passes below the obstacle's level freely
    assert np.array_equal(res20.contact.any(axis=0), np.isclose(res20.x, 1.0))
    assert err40 < err20 < 0.15


def test_explicit_penalty_sinks_at_a_point():
    """r = 1: a damper of strength h/ε on the node cannot hold the string's pull through the contact phase."""
    _, _, min_explicit = _run(20, "explicit", 1.0, T=rod.PERIOD)
    assert min_explicit < -0.025


@pytest.mark.skipif(importlib.util.find_spec("getfem") is None, reason="GetFEM is not installed (python3-getfem)")
def test_getfem_schemes_converge_to_the_exact_solution():
    bench = ROOT / "benchmarks" / "bench_getfem.py"
    cmd = [sys.executable, str(bench), "--getfem-side", "--nx", "20", "40", "--T", "1.5"]
    rows = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=ROOT).stdout)
    for scheme in ("taylor-flanagan", "redistributed-mass"):
        err = [r["err_u"] for r in rows if r["method"] == scheme]
        assert len(err) == 2 and err[1] < err[0] < 0.1
        assert all(r["min_u_contact"] >= -1e-3 for r in rows if r["method"] == scheme)
