"""The picture process of `stringcontact run` (plot/picture_process.py): the painter, its forked helper, the payload,
and how they stop."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.plot import handover as payload
from stringcontact.plot import picture_process as painter
from stringcontact.plot import run_pictures as viz
from stringcontact.plot.picture_process import PictureProcess


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A coarse Example 1 written to disk with pictures (drawn in this process), and its in-memory result."""
    folder = tmp_path_factory.mktemp("painter") / "ex1"
    res = sc.simulate(sc.load_scene("example1").replace(nx=80, nt=600), output_dir=folder, max_rows=60)
    return folder, res


def group(pgid: int) -> list[int]:
    """The live (not zombie) processes of the process group `pgid`."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            state, _, pgrp = stat.read_text().rsplit(")", 1)[1].split()[:3]
        except (OSError, IndexError):
            continue
        if int(pgrp) == pgid and state != "Z":
            pids.append(int(stat.parent.name))
    return pids


def until(condition, what: str, limit: float = 120.0) -> None:
    """Poll `condition` (a bounded wait: running out of it is a failure, not a timing claim)."""
    deadline = time.monotonic() + limit
    while not condition():
        assert time.monotonic() < deadline, f"never: {what}"
        time.sleep(0.05)


def started_with_helper(names=viz.PICTURES) -> PictureProcess:
    process = PictureProcess.start(names)
    until(lambda: len(group(process.proc.pid)) == 2, "the painter forked its helper")
    return process


@pytest.mark.slow
def test_the_run_hands_every_picture_over_and_imports_no_plotting_library(run, tmp_path):
    """Issue 28: the run drew snapshots.png and energy.png itself, importing matplotlib after its solve."""
    folder, _ = run
    code = ("import sys\nfrom stringcontact.plot.picture_process import PictureProcess\np = PictureProcess.start()\n"
            "from stringcontact.io.readback import read_output\nfrom stringcontact.plot import run_pictures as viz\n"
            f"viz.write_pictures(read_output({str(folder)!r}), {str(tmp_path)!r}, painter=p)\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'matplotlib', 'pyvista', 'vtk', 'PIL'}), sorted(p.drawn))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == f"[] {sorted(viz.PICTURES)}"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(viz.PICTURES)


@pytest.mark.slow
def test_two_processes_never_draw_the_same_picture(run, tmp_path):
    """A claim is taken once: the second taker draws nothing; the helper (no pyvista) skips the mesh pictures."""
    _, res = run
    claims, out = tmp_path / "claims", tmp_path / "out"
    claims.mkdir(), out.mkdir()
    job = (str(out), viz.WINDOW_SIZE, viz.PICTURES)
    charts_only = painter.draw_claimed(res, job, claims, lambda name: name not in viz.MESH_PICTURES)
    assert sorted(charts_only) == sorted(viz.CHART_PICTURES)
    assert charts_only[:2] == ["energy.png", "snapshots.png"]  # the costliest first
    assert painter.draw_claimed(res, job, claims, lambda name: True) == ["space_time.png"]
    assert painter.draw_claimed(res, job, claims, lambda name: True) == []


def test_the_payload_maps_the_large_arrays_and_keeps_every_value(run, tmp_path):
    _, res = run
    big = res.eta.nbytes
    old = payload.MAPPED_BYTES
    try:
        payload.MAPPED_BYTES = big  # eta and velocity, not the rest
        payload.write_payload(tmp_path, res, ("out", (10, 10), ("energy.png",)))
    finally:
        payload.MAPPED_BYTES = old
    back, job = payload.read_payload(tmp_path)
    assert job == ("out", (10, 10), ("energy.png",))
    assert sorted(p.name for p in tmp_path.glob("*.npy")) == ["eta.npy", "velocity.npy"]
    assert isinstance(back.eta, np.memmap) and not back.eta.flags.writeable
    for name in ("x", "t", "eta", "velocity", "contact"):
        np.testing.assert_array_equal(getattr(back, name), getattr(res, name), err_msg=name)
    assert back.scene == res.scene and back.contact_force.size == 0  # no picture shows the force


def test_the_payload_maps_the_large_output_fields_too(run, tmp_path):
    """An output field as large as eta is mapped from its own file, a small one pickled with the rest."""
    import dataclasses

    _, res = run
    fields = {"reaction": res.eta**2, "small": np.arange(4.0).reshape(2, 2)}
    old = payload.MAPPED_BYTES
    try:
        payload.MAPPED_BYTES = res.eta.nbytes
        payload.write_payload(tmp_path, dataclasses.replace(res, fields=fields), ("out", (10, 10), ("energy.png",)))
    finally:
        payload.MAPPED_BYTES = old
    assert sorted(p.name for p in tmp_path.glob("fields.*")) == ["fields.reaction.npy"]
    back, _ = payload.read_payload(tmp_path)
    assert isinstance(back.fields["reaction"], np.memmap) and not isinstance(back.fields["small"], np.memmap)
    for name, values in fields.items():
        np.testing.assert_array_equal(back.fields[name], values, err_msg=name)


def test_the_payload_maps_the_rows_file_the_run_wrote(run, tmp_path):
    """eta and velocity are mapped from the output folder's rows.npz (stored uncompressed there), not written again."""
    from stringcontact.io.tables import write_rows

    _, res = run
    out, private = tmp_path / "out", tmp_path / "private"
    out.mkdir(), private.mkdir()
    write_rows(out / "rows.npz", res)
    old = payload.MAPPED_BYTES
    try:
        payload.MAPPED_BYTES = res.contact.nbytes  # eta, velocity and contact are "large" here
        payload.write_payload(private, res, (str(out), (10, 10), ("energy.png",)))
    finally:
        payload.MAPPED_BYTES = old
    assert sorted(p.name for p in private.iterdir()) == ["contact.npy", "payload.pickle"]  # contact: compressed there
    back, _ = payload.read_payload(private)
    for name in ("eta", "velocity", "contact"):
        assert isinstance(getattr(back, name), np.memmap), name
        np.testing.assert_array_equal(getattr(back, name), getattr(res, name), err_msg=name)


def test_the_payload_writes_what_the_rows_file_does_not_hold_as_it_is(run, tmp_path):
    """A rows file of other rows (another shape) or none at all: the arrays are written into the payload."""
    import dataclasses

    from stringcontact.io.tables import write_rows

    _, res = run
    fewer = dataclasses.replace(res, **{name: getattr(res, name)[:-1] for name in ("t", "steps", "eta", "velocity",
                                                                                   "contact", "contact_force")})
    write_rows(tmp_path / "rows.npz", fewer)
    assert set(payload.stored_in(tmp_path / "rows.npz", {"eta": res.eta})) == set()
    assert set(payload.stored_in(tmp_path / "rows.npz", {"eta": fewer.eta})) == {"eta"}
    assert payload.stored_in(tmp_path / "absent.npz", {"eta": res.eta}) == {}
    (tmp_path / "broken.npz").write_bytes(b"not a zip")
    assert payload.stored_in(tmp_path / "broken.npz", {"eta": res.eta}) == {}


def test_the_payload_carries_the_readings_the_run_made(run, tmp_path):
    """contact_measure and contact_components, computed by the run for its diagnostics, are not computed again."""
    _, res = run
    res.contact_measure, res.contact_components  # noqa: B018 - what writing diagnostics.csv reads
    payload.write_payload(tmp_path, res, ("out", (10, 10), ("snapshots.png",)))
    back, _ = payload.read_payload(tmp_path)
    assert {"contact_measure", "contact_components"} <= set(vars(back))  # cached: the pictures read, not compute
    np.testing.assert_array_equal(back.contact_measure, res.contact_measure)
    np.testing.assert_array_equal(back.contact_components, res.contact_components)


def test_cancel_stops_the_helper_too(run, tmp_path):
    process = started_with_helper()
    pgid = process.proc.pid
    process.cancel()
    assert process.folder is None
    # SIGKILLed with its group, the helper may still be tearing down (files closed, not yet a zombie) on a busy machine
    until(lambda: group(pgid) == [], "the helper gone after cancel", limit=5.0)


def test_cancel_while_drawing_leaves_no_process(run, tmp_path):
    _, res = run
    process = started_with_helper()
    pgid, private = process.proc.pid, Path(process.folder)
    assert process.send(res, tmp_path)
    until(lambda: list(private.glob("*.claim")), "a picture taken")
    process.cancel()
    assert group(pgid) == [] and not private.exists()


@pytest.mark.slow
def test_the_painter_draws_the_helpers_share_when_the_helper_dies(run, tmp_path):
    _, res = run
    process = started_with_helper()
    [helper] = [pid for pid in group(process.proc.pid) if pid != process.proc.pid]
    os.kill(helper, 9)
    until(lambda: helper not in group(process.proc.pid), "the helper gone")
    assert process.send(res, tmp_path) and process.wait()
    assert sorted(process.drawn) == sorted(viz.PICTURES)


@pytest.mark.slow
def test_what_the_painter_did_not_draw_is_drawn_here(run, tmp_path, monkeypatch):
    """A painter that reports only some pictures drawn: the run draws the others itself."""
    _, res = run
    process = PictureProcess.start(("space_time.png",))  # no helper for one picture
    drawn_here = []
    draw = viz.draw
    monkeypatch.setattr(viz, "draw", lambda name, *a, **kw: drawn_here.append(name) or draw(name, *a, **kw))
    viz.write_pictures(res, tmp_path, painter=process)
    assert process.drawn == ("space_time.png",) and sorted(drawn_here) == sorted(viz.CHART_PICTURES)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(viz.PICTURES)


@pytest.mark.slow
@pytest.mark.parametrize("wait_for_helper", [False, True])
def test_the_picture_processes_end_and_clean_up_when_the_run_dies(tmp_path, wait_for_helper):
    code = ("from stringcontact.plot.picture_process import PictureProcess; p = PictureProcess.start(); "
            "print(p.proc.pid, p.folder, flush=True)")  # and exit at once, without cancel(): a killed run
    if wait_for_helper:  # exit once the helper is forked
        code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); from test_painter import started_with_helper; "
                "p = started_with_helper(); print(p.proc.pid, p.folder, flush=True)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    pgid, private = int(out[0]), Path(out[1])
    until(lambda: not group(pgid) and not private.exists(), "the painter and its helper gone, the payload removed")
