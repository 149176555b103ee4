"""Storage (issue 15): the row budget thins the stored rows (0, T and the output times kept, one warning),
the paper's scenes fit it, bad storage options are refused in one line, and a Result without its rows
(an MPI rank other than 0) gives its series and refuses its per-node arrays. The MPI runs themselves are
in test_mpi.py and test_membrane.py.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.io.result import PER_NODE, RowsElsewhere
from stringcontact.run.checks import penetration_check
from stringcontact.run.options import ROW_BUDGET
from stringcontact.run.rows import StorageWarning
from stringcontact.scene import STORED_ROWS
from stringcontact.run.rows import budget_steps, output_steps, stored_steps
from stringcontact.scene import BYTES_PER_STORED_NODE


def small_string():
    """Example 1 coarsened: 101 nodes, 600 steps (r = 1), its six output times."""
    return sc.load_scene("example1").replace(nx=100, nt=600)


def test_budget_steps_keeps_what_fits_untouched():
    steps, note = budget_steps(1000, 1e-3, [0.0, 0.5], 400, nodes=101, budget=10**9)
    assert note is None
    np.testing.assert_array_equal(steps, stored_steps(1000, 1e-3, [0.0, 0.5], 400))


@pytest.mark.parametrize("allowed", [5, 6, 17, 60, 300])
def test_budget_steps_thins_to_the_budget_and_keeps_0_T_and_the_output_times(allowed):
    nt, dt, times = 1000, 1e-3, [0.0, 0.123, 0.5, 0.777]
    budget = allowed * 101 * BYTES_PER_STORED_NODE
    steps, note = budget_steps(nt, dt, times, 400, nodes=101, budget=budget)
    assert len(steps) <= allowed
    assert {0, nt} | output_steps(nt, dt, times) <= set(steps.tolist())
    assert "max_rows = 400" in note and f"keeping {len(steps)} rows" in note and "\n" not in note
    assert len(steps) >= allowed // 2  # thinned to the budget, not far below it


def test_budget_steps_refuses_when_the_output_times_alone_do_not_fit():
    with pytest.raises(ValueError, match=r"^output_times: 0, T and the output times are 4 stored rows") as err:
        budget_steps(1000, 1e-3, [0.1, 0.2], 400, nodes=101, budget=3 * 101 * BYTES_PER_STORED_NODE)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("name", ["example1", "example2", "single_impact", "loaded_string"])
def test_the_paper_scenes_fit_the_budget(name):
    scene = sc.load_scene(name)
    _, note = budget_steps(scene.nt, scene.dt, scene.output_times, STORED_ROWS, scene.nx + 1, ROW_BUDGET)
    assert note is None


def test_a_run_over_its_budget_stores_fewer_rows_with_one_warning():
    scene = small_string()
    full = sc.simulate(scene, storage=sc.Storage(max_rows=scene.nt))
    budget = 40 * 101 * BYTES_PER_STORED_NODE
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        thin = sc.simulate(scene, storage=sc.Storage(max_rows=scene.nt, row_budget=budget))
    notes = [w for w in caught if issubclass(w.category, StorageWarning)]
    assert len(notes) == 1 and f"max_rows = {scene.nt}" in str(notes[0].message)
    assert 10 < len(thin.t) <= 40 < len(full.t)
    kept = set(thin.steps.tolist())
    assert {0, scene.nt} | output_steps(scene.nt, scene.dt, scene.output_times) <= kept
    # the kept rows are the full run's rows at those steps, and the series too
    at = np.searchsorted(full.steps, thin.steps)
    np.testing.assert_array_equal(full.steps[at], thin.steps)
    for name in ("eta", "velocity", "contact", "contact_force"):
        np.testing.assert_array_equal(getattr(thin, name), getattr(full, name)[at], err_msg=name)
    for key in full.energy:
        np.testing.assert_array_equal(thin.energy[key], full.energy[key][at], err_msg=key)
    assert thin.min_eta == full.min_eta


@pytest.mark.parametrize("keys, field", [
    (dict(max_rows=0), "max_rows"), (dict(max_rows=2.5), "max_rows"), (dict(gather="rank0"), "gather"),
    (dict(row_budget=0), "row_budget"), (dict(row_budget=5 * 101 * BYTES_PER_STORED_NODE), "output_times"),
])
def test_bad_storage_options_are_refused_in_one_line(keys, field):
    with pytest.raises(ValueError, match=f"^{field}: ") as err:
        sc.simulate(small_string(), storage=sc.Storage(**keys))
    assert "\n" not in str(err.value)


def test_a_misspelt_option_is_a_type_error_and_a_bad_value_a_one_line_value_error():
    """`simulate` takes its storage and output options only in `Storage` and `Output`: any other keyword is a
    TypeError, as for any function; a bad value is refused in one line naming the option."""
    with pytest.raises(TypeError, match="max_rows"):
        sc.simulate(small_string(), max_rows=20)
    with pytest.raises(ValueError, match="^gather: ") as err:
        sc.Storage(gather="rank0")
    assert "\n" not in str(err.value)


@pytest.fixture(scope="module")
def bump_run():
    """The bump scene coarsened: an obstacle of its own, contact on both humps."""
    return sc.simulate(sc.load_scene("bump").replace(cells=[12, 12], T=0.4, nt=80, output_times=[0.2]))


@pytest.mark.parametrize("which", ["string", "bump"])
def test_a_result_without_rows_gives_the_same_series_and_refuses_its_arrays(bump_run, which):
    res = bump_run if which == "bump" else sc.simulate(small_string())
    assert res.contact_measure.max() > 0  # a landing: the series is not trivially zero
    elsewhere = dataclasses.replace(res, has_rows=False)  # what a rank other than 0 holds
    np.testing.assert_allclose(elsewhere.contact_measure, res.contact_measure, rtol=1e-12, atol=1e-14)
    mine, theirs = penetration_check(elsewhere), penetration_check(res)
    assert mine.keys() == theirs.keys()
    for key, value in theirs.items():
        assert mine[key] == (pytest.approx(value, rel=1e-14, abs=0) if isinstance(value, float) else value), key
    assert elsewhere.dim == res.dim
    for name in PER_NODE:
        with pytest.raises(RowsElsewhere, match=f"^Result.{name}: the per-node rows are on rank 0 only"):
            getattr(elsewhere, name)
    assert "rank 0" in repr(elsewhere)


@pytest.mark.parametrize("which", ["string", "bump"])
def test_contact_measure_in_chunks_equals_the_whole_rows(bump_run, which, monkeypatch):
    from stringcontact.fem import compat
    from stringcontact.io import result

    res = bump_run if which == "bump" else sc.simulate(small_string())
    c = res.contact.astype(float)
    whole = c @ res.weights if res.dim == 2 else compat.trapezoid(c, res.x, axis=1)
    monkeypatch.setattr(result, "CHUNK_VALUES", 3 * res.contact.shape[1] + 1)  # 3 rows at a time
    np.testing.assert_array_equal(res.contact_measure, whole)
    assert whole.max() > 0


def test_a_big_membrane_scene_loads_and_its_rows_are_left_to_the_budget():
    """The loader refuses a 2D scene only when 0, T and the output times alone would not fit: the solver thins the rest."""
    big = sc.load_scene("bump").replace(cells=[999, 999], dt=0.0005)  # 1e6 nodes, 2000 steps: 400 rows would be 10 GB
    assert big.nt == 2000
    with pytest.raises(sc.SceneError, match=r"output_times: .* allowed: at most 2 GB"):
        sc.load_scene("bump").replace(cells=[1000, 1000], output_times=[0.01 * k for k in range(100)])


def test_stored_times_are_the_scheduled_times_exactly(tmp_path):
    """Issue 26: n·Δt is 0.039999999999999994 at Δt = 0.3/1500; the run stores 0.04 (an output time as given)
    and 0.0402 (n·Δt rounded), in the Result, diagnostics.csv and solution.xdmf alike."""
    from stringcontact.io.readback import read_output
    from stringcontact.run.rows import step_times

    dt = 0.3 / 1500
    assert 200 * dt != 0.04
    np.testing.assert_array_equal(step_times([0, 200, 201, 1500], dt, [0.04]), [0.0, 0.04, 0.0402, 0.3])
    assert step_times([201], dt)[0] == 0.0402
    res = sc.simulate(sc.load_scene("example1").replace(nx=40, nt=1500),
                      output=sc.Output(tmp_path / "out", max_frames=10, pictures=False))
    assert np.flatnonzero(res.t == 0.04).size == 1 and res.t[-1] == 0.3
    assert all(t in res.t for t in res.scene.output_times)
    back = read_output(tmp_path / "out")
    assert np.flatnonzero(back.t == 0.04).size == 1
    with open(tmp_path / "out" / "diagnostics.csv") as f:
        column = f.readline().strip().split(",").index("t")
    assert 0.04 in np.loadtxt(tmp_path / "out" / "diagnostics.csv", delimiter=",", skiprows=1, usecols=column)


def test_an_eps_free_run_states_a_bound_without_eps():
    """The projection scheme has no ε: its penetration bound is 2Δt max|v| and the CLI's line names no eps."""
    from stringcontact.cli.report import _fmt_penetration_line

    res = sc.simulate(small_string(), scheme="projection")
    p = penetration_check(res)
    assert p["eps_free"] and p["eps_times_speed"] == 0.0 and "penalty" in p["law"]
    line, ok = _fmt_penetration_line(res)
    assert ok and "eps" not in line and "dt max|v|" in line, line
    assert "eps max|v|" in _fmt_penetration_line(sc.simulate(small_string()))[0]  # a penalty run keeps it
