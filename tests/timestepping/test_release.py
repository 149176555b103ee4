"""Scheme projection with a Signorini release (`Model.release`, `timestepping.release`) on GetFEM's impacting rod.

The rod (docs/explanation/getfem.md) is solved at Δt = h with the paper's point contact declared Signorini's. The
GetFEM figures it is compared with are GetFEM's own, stored by `benchmarks/bench_getfem.py` in
docs/getfem_comparison.csv (the rows whose side is "getfem"), so this test needs no GetFEM.
"""

import csv
import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.model.interface import inelastic
from stringcontact.verification import rod

CSV = Path(__file__).resolve().parents[2] / "docs" / "getfem_comparison.csv"
AHEAD = 1.2  # the least factor by which the rod's errors must be below GetFEM's best


def _rod(nx: int, dt_over_h: float = 1.0, release: str | None = "signorini", **kwargs):
    """The rod at NX = nx, Δt = dt_over_h·h, by `projection`; `release` None keeps the model's own (the default)."""
    h = 1.0 / nx
    scene = rod.rod_scene(nx, dt_over_h * h, 1e-9)
    model = rod.point_contact(inelastic, h)
    if release is not None:
        model = dataclasses.replace(model, release=release)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, scheme="projection", model=model, max_rows=scene.nt + 1, **kwargs)


def _getfem_best(nx: int) -> tuple[float, float, int]:
    with CSV.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["side"] == "getfem" and int(r["nx"]) == nx]
    return min(float(r["err_u"]) for r in rows), min(float(r["err_v"]) for r in rows), len(rows)


@pytest.mark.parametrize("nx", [80, 160])
def test_the_rod_is_more_accurate_than_getfem_s_best_method(nx):
    best_u, best_v, methods = _getfem_best(nx)
    assert methods >= 8  # GetFEM's methods at this NX: the best is taken over all of them
    res = _rod(nx)
    err_u = rod.relative_error(res.x, res.t, res.eta)
    err_v = rod.relative_velocity_error(res.x, res.t, res.velocity)
    assert best_u / err_u >= AHEAD, (err_u, best_u)
    assert best_v / err_v >= AHEAD, (err_v, best_v)


def test_at_dt_h_the_rod_is_exact_at_the_nodes_and_keeps_its_energy():
    """The second-order start and the carried half of the holding force make the leapfrog at Courant number 1 exact
    through the landing, the contact phase and the release; either alone leaves an error of order h."""
    res = _rod(40)
    exact = np.array([rod.string_exact(res.x, t) for t in res.t])
    assert np.max(np.abs(res.eta - exact)) <= 1e-12
    E = res.total_energy
    assert res.status == "complete"
    assert abs(E[-1] / E[0] - 1) <= 1e-12
    assert np.max(np.abs(E / E[0] - 1)) <= 1.0 / 40  # the contact node's kinetic energy, given back at the release
    F = res.contact_force
    assert F.max() > 0 and np.all(F >= 0) and np.all(F[~res.contact] == 0)


def test_the_paper_s_release_is_the_default_and_unchanged():
    a, b = _rod(20, release=None), _rod(20, release="inelastic")
    assert inelastic.release == "inelastic"
    assert np.array_equal(a.eta, b.eta) and np.array_equal(a.contact_force, b.contact_force)
    err = rod.relative_error(a.x, a.t, a.eta)
    assert err == pytest.approx(0.05, rel=1e-6)  # the first-order start's kink: h/2 at alternate nodes


def test_a_landing_stays_inelastic():
    """The contact node stops dead where it lands (t = 1), as under the paper's release."""
    res = _rod(40)
    node = np.argmin(np.abs(res.x - rod.CONTACT_POINT))
    landed = (res.t > 1.0 + 1e-9) & (res.t < 2.0 - 1e-9)
    assert np.all(res.eta[landed, node] == 0.0)
    assert np.all(res.velocity[landed, node] == 0.0)


def test_a_restitution_or_an_unknown_release_is_refused_in_one_line():
    with pytest.raises(ValueError, match=r"^release: .*restitution") as exc:
        _rod(20, restitution=0.5)
    assert "\n" not in str(exc.value)
    with pytest.raises(ValueError, match=r"^release: .*allowed: inelastic, signorini"):
        _rod(20, release="elastic")
