"""A user's model with an output field of its own: the run writes it everywhere by name (rows.npz, diagnostics.csv,
summary.json, solution.xdmf, view.py), draws ``NAME.png`` in the field's own colours, and `stringcontact plot`
reads it back and draws the same picture."""

from __future__ import annotations

import csv
import dataclasses
import json
import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import xdmf_frames

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.io import readback, tables
from stringcontact.io.paraview_view import field_points, field_range
from stringcontact.model.interface import OutputField, inelastic
from stringcontact.plot import run_pictures as viz
from stringcontact.plot.fields import FieldScale

#: the field's colours, low to high: black to pure red (no core picture draws pure red)
COLOURS = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
REACTION = OutputField("reaction", expression=lambda U, p: U[0] ** 2, label="reaction ρ", unit="force", colours=COLOURS)
#: the paper's model with one derived output field, η² at the nodes
REACTING = dataclasses.replace(inelastic, name="reacting", outputs=(REACTION,))


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Example 1 under the reacting model, written with its pictures (drawn in this process)."""
    folder = tmp_path_factory.mktemp("fields") / "reacting"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sc.simulate(sc.load_scene("example1").replace(nx=40, nt=600), model=REACTING,
                          output=sc.Output(folder, max_frames=8, progress=False),
                          storage=sc.Storage(max_rows=30))
    return folder, res


def _image(path):
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).astype(int)


@pytest.mark.slow
def test_the_run_holds_the_field_and_how_it_is_shown(run):
    _, res = run
    np.testing.assert_allclose(res.fields["reaction"], res.eta**2, rtol=1e-12, atol=0)  # P1 at the nodes: η_i²
    assert res.field_info == {"reaction": REACTION.metadata()} and res.field_info["reaction"]["derived"]
    assert res.parameters == {}


def test_the_field_is_in_rows_npz_diagnostics_and_summary(run):
    folder, res = run
    with np.load(folder / tables.ROWS_FILE) as npz:
        np.testing.assert_array_equal(npz["reaction"], res.fields["reaction"])
    with open(folder / "diagnostics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[-2:] == ["min_reaction", "max_reaction"]
    for key, reduce in (("min_reaction", np.min), ("max_reaction", np.max)):
        np.testing.assert_array_equal([float(r[key]) for r in rows], reduce(res.fields["reaction"], axis=1))
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["fields"] == {"reaction": REACTION.metadata()}
    assert summary["fields"]["reaction"]["colours"] == [[0, 0, 0], [1, 0, 0]]
    assert summary["parameters"] == {}


def test_the_field_is_read_back_as_the_run_held_it(run):
    folder, res = run
    back = readback.read_output(folder)
    assert set(back.fields) == {"reaction"} and back.field_info == res.field_info
    np.testing.assert_array_equal(back.fields["reaction"], res.fields["reaction"])
    frames = xdmf_frames(folder)  # solution.xdmf's attribute of the same name
    rows = [int(np.flatnonzero(res.t == t)[0]) for t in frames.t]
    assert 'Attribute Name="reaction"' in (folder / "solution.xdmf").read_text()
    np.testing.assert_array_equal(frames.fields["reaction"], res.fields["reaction"][rows])
    assert frames.field_info == res.field_info


@pytest.mark.slow
def test_the_fields_picture_is_drawn_in_its_colours_and_redrawn_alike(run, tmp_path, capsys):
    folder, res = run
    assert "reaction.png" in viz.pictures_of(res)
    img = _image(folder / "reaction.png")
    red = (img[..., 0] > 240) & (img[..., 1] < 15) & (img[..., 2] < 15)  # its high end, η² = 2.25 at t = 0
    assert red.sum() > 200
    assert main(["plot", str(folder), "--out", str(tmp_path / "again")]) == 0
    assert "reaction.png" in capsys.readouterr().out
    np.testing.assert_array_equal(_image(tmp_path / "again" / "reaction.png"), img)


def test_view_py_colours_the_field_on_its_range_in_its_colours(run):
    folder, res = run
    text = (folder / "view.py").read_text()
    maps = re.search(r"^FIELD_MAPS = (.*)$", text, re.MULTILINE).group(1)
    low, high = float(res.fields["reaction"].min()), float(res.fields["reaction"].max())
    assert maps.startswith(f"{{'reaction': [[{low!r}, {high!r}], [[{low!r}, 0.0, 0.0, 0.0], [{high!r}, 1.0, 0.0, 0.0]]]")


# --- the generic pieces, without a run ------------------------------------------------------------------------


def test_a_fields_picture_never_takes_a_core_pictures_name():
    result = SimpleNamespace(dim=1, fields=dict.fromkeys(["energy", "reaction", "membrane"]))
    names = viz.field_picture_names(result)
    assert names == {"field_energy.png": "energy", "reaction.png": "reaction", "field_membrane.png": "membrane"}
    assert viz.pictures_of(result) == viz.PICTURES + tuple(names)


def test_a_fields_name_taken_by_the_files_own_is_prefixed():
    assert tables.field_members(["reaction", "x", "weights"]) == {"reaction": "reaction", "x": "field_x",
                                                                  "weights": "field_weights"}
    columns = tables.field_columns(["eta", "contact_force", "reaction"])
    assert columns == {"eta": ("min_field_eta", "max_field_eta"),
                       "contact_force": ("min_field_contact_force", "max_field_contact_force"),
                       "reaction": ("min_reaction", "max_reaction")}
    assert not {c for pair in columns.values() for c in pair} & set(tables.DIAGNOSTIC_COLUMNS)


def test_a_linear_fields_scale_spans_its_values_and_a_symmetric_ones_zero_in_the_middle():
    values = np.array([[2.0, 3.0], [7.0, 4.5]])
    plain = FieldScale.of(values, OutputField("q", colours=COLOURS).metadata())
    assert (plain.low, plain.high) == (2.0, 7.0) == field_range(values, OutputField("q").metadata())
    np.testing.assert_allclose(plain.unit([2.0, 4.5, 7.0, 9.0]), [-1.0, 0.0, 1.0, 1.0])
    assert plain.ticks()[0] == 2.0 and plain.ticks()[-1] == 7.0 and np.all(np.diff(plain.ticks()) > 0)
    symmetric = FieldScale.of(values - 5.0, OutputField("q", symmetric=True).metadata())
    assert (symmetric.low, symmetric.high) == (-3.0, 3.0) and symmetric.unit(0.0) == 0.0
    assert symmetric.tick_label(-3.0) == "−3" and symmetric.tick_label(0.0) == "0"
    flat = FieldScale.of(np.full((2, 2), 4.0), OutputField("q").metadata())
    assert flat.low < 4.0 < flat.high  # a constant field: a range about its value, not of width 0
    np.testing.assert_allclose(plain.norm()([2.0, 7.0]), [0.0, 1.0])


def test_paraviews_points_are_the_pictures_colours_at_their_values():
    info = OutputField("q", colours=((0.0, 0.0, 1.0), (1.0, 1.0, 1.0), (1.0, 0.0, 0.0))).metadata()
    points = np.array(field_points(-2.0, 6.0, info))
    np.testing.assert_array_equal(points, [[-2.0, 0, 0, 1], [2.0, 1, 1, 1], [6.0, 1, 0, 0]])
    scale = FieldScale.of([-2.0, 6.0], info)
    pictures = np.asarray(scale.colour_map()(0.5 * (scale.unit(points[:, 0]) + 1)))[:, :3]
    np.testing.assert_allclose(points[:, 1:], pictures, atol=4e-3)


def test_field_info_gives_a_plain_description_to_a_field_the_result_does_not_describe():
    result = SimpleNamespace(fields={"q": np.zeros((2, 3))}, field_info={})
    assert tables.field_info(result)["q"] == OutputField("q").metadata()

