"""Reading an output folder back: `readback.read_output` and `stringcontact plot` on damaged folders."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import plot_refusal

import stringcontact as sc
from stringcontact.io import readback


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("readback") / "run"
    sc.simulate(sc.load_scene("example1").replace(nx=40, nt=600), output_dir=out, max_rows=30, max_frames=8, pictures=False)
    return out


def _empty(p):
    p.write_bytes(b"")


def _truncate(p):
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])


def _random(p):
    p.write_bytes(np.random.default_rng(1).bytes(p.stat().st_size))


def _json(text):
    return lambda p: p.write_text(text)


def _without_scene(p):
    summary = json.loads(p.read_text())
    del summary["scene"]
    p.write_text(json.dumps(summary))


def _scene_out_of_range(p):
    summary = json.loads(p.read_text())
    summary["scene"]["nx"] = -3
    p.write_text(json.dumps(summary))


def _no_energy_column(p):
    header, rest = p.read_text().split("\n", 1)
    p.write_text(header.replace("kinetic", "kinetik") + "\n" + rest)


def _a_missing_dataset(p):
    p.write_text(p.read_text().replace("solution.h5:/eta_3<", "solution.h5:/no_such_data<"))


def _a_time_that_is_not_a_number(p):
    p.write_text(p.read_text().replace('<Time Value="0.0"/>', '<Time Value="soon"/>', 1))


def _rows_without(name):
    def damage(p):
        with np.load(p) as npz:
            kept = {key: npz[key] for key in npz.files if key != name}
        with open(p, "wb") as f:
            np.savez(f, **kept)

    return damage


def _rows_with(name, change):
    def damage(p):
        with np.load(p) as npz:
            arrays = {key: npz[key] for key in npz.files}
        arrays[name] = change(arrays[name])
        with open(p, "wb") as f:
            np.savez(f, **arrays)

    return damage


def _summary_with(key, value):
    def damage(p):
        summary = json.loads(p.read_text())
        summary[key] = value
        p.write_text(json.dumps(summary))

    return damage


def _field(**given):
    return {"reaction": {"label": "reaction", "colours": [[0, 0, 0], [1, 0, 0]], "scale": "linear"} | given}


#: the XDMF's damage matters to `plot` when the folder has no rows.npz (written before it existed)
XDMF_FILES = ("solution.h5", "solution.xdmf")

CASES = {
    "random rows": ("rows.npz", _random, "is not a readable .npz file"),
    "truncated rows": ("rows.npz", _truncate, "is not a readable .npz file"),
    "rows without eta": ("rows.npz", _rows_without("eta"), "has no array 'eta'"),
    "rows one short": ("rows.npz", _rows_with("velocity", lambda v: v[:-1]), "does not hold the 31 rows of diagnostics.csv"),
    "rows at other times": ("rows.npz", _rows_with("t", lambda t: t * 2), "its times are not those of diagnostics.csv"),
    "emptied h5": ("solution.h5", _empty, "not a readable HDF5 file"),
    "truncated h5": ("solution.h5", _truncate, "not a readable HDF5 file"),
    "random h5": ("solution.h5", _random, "not a readable HDF5 file"),
    "h5 without a dataset": ("solution.xdmf", _a_missing_dataset, "solution.h5 has no dataset /no_such_data"),
    "summary is a list": ("summary.json", _json("[]"), "holds a JSON list"),
    "summary without scene": ("summary.json", _without_scene, "has no 'scene'"),
    "summary not JSON": ("summary.json", _json("{\"status\": "), "is not valid JSON"),
    "summary with a bad scene": ("summary.json", _scene_out_of_range, "its scene is not valid"),
    "random summary": ("summary.json", _random, "is not valid JSON"),
    "diagnostics without a column": ("diagnostics.csv", _no_energy_column, "has no column 'kinetic'"),
    "random diagnostics": ("diagnostics.csv", _random, "diagnostics.csv"),
    "xdmf time not a number": ("solution.xdmf", _a_time_that_is_not_a_number, "solution.xdmf cannot be read"),
    "a field named as a path": ("summary.json", _summary_with("fields", {"../x": {}}), "output field '../x' is not valid"),
    "a field's colour beyond 1": ("summary.json", _summary_with("fields", _field(colours=[[0, 0, 0], [2, 0, 0]])),
                                  "output field 'reaction' is not valid"),
    "a field on no scale": ("summary.json", _summary_with("fields", _field(scale="cubic")), "output field 'reaction' is not valid"),
    "a field's label a number": ("summary.json", _summary_with("fields", _field(label=3)), "its label is a JSON int"),
    "fields not an object": ("summary.json", _summary_with("fields", [1]), "its 'fields' is not an object"),
    "parameters not numbers": ("summary.json", _summary_with("parameters", {"mu": "thick"}), "its 'parameters' is not"),
}


@pytest.mark.parametrize("case", CASES)
def test_plot_on_a_damaged_folder_exits_2_naming_the_file(tmp_path, folder, capsys, case):
    name, damage, words = CASES[case]
    def damage_copy(copy):
        if name in XDMF_FILES:
            (copy / "rows.npz").unlink()
        damage(copy / name)

    copy, err = plot_refusal(folder, damage_copy, tmp_path, capsys)
    named = str(copy / name) if case != "h5 without a dataset" else str(copy / "solution.h5")
    assert named in err and words in err, err


def test_read_output_reads_what_the_writer_wrote(folder):
    res = readback.read_output(folder)
    assert res.eta.shape == res.velocity.shape == res.contact.shape == (len(res.t), 41)
    assert res.t[0] == 0.0 and res.t[-1] == pytest.approx(0.3) and np.all(np.diff(res.x) > 0)
    np.testing.assert_allclose(res.eta[0], 1 + 0.5 * np.sin(10 * np.pi * res.x) ** 2, atol=1e-12)


def test_read_output_gives_the_output_fields_summary_json_names(folder, tmp_path):
    """The fields come back by the names and descriptions summary.json gives, their rows from rows.npz; the
    model's constants from its "parameters"."""
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    _rows_with("eta", lambda eta: eta)(copy / "rows.npz")  # rewritten whole, then a field added
    with np.load(copy / "rows.npz") as npz:
        arrays = {key: npz[key] for key in npz.files}
    arrays["field_steps"] = -arrays["eta"]  # a field named steps is stored past rows.npz's own steps
    with open(copy / "rows.npz", "wb") as f:
        np.savez(f, **arrays)
    info = {"steps": {"label": "minus η", "colours": [[0, 0, 1], [1, 1, 1]], "symmetric": True}}
    _summary_with("fields", info)(copy / "summary.json")
    _summary_with("parameters", {"stiffness": 2})(copy / "summary.json")
    res = readback.read_output(copy)
    np.testing.assert_array_equal(res.fields["steps"], -res.eta)
    assert res.field_info["steps"]["label"] == "minus η" and res.field_info["steps"]["symmetric"] is True
    assert res.field_info["steps"]["scale"] == "linear" and res.field_info["steps"]["surface"] is False  # defaults
    assert res.parameters == {"stiffness": 2.0}
    assert res.steps.ndim == 1 and np.all(np.diff(res.steps) > 0)  # rows.npz's own steps, not the field


def test_a_folder_without_field_descriptions_gives_its_further_rows_as_plain_fields(folder, tmp_path):
    """A folder written before summary.json described its fields: rows.npz's further arrays of the rows' shape
    come back as fields, shown as a plain `OutputField` of their name."""
    import shutil

    from stringcontact.model.interface import OutputField

    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    with np.load(copy / "rows.npz") as npz:
        arrays = {key: npz[key] for key in npz.files}
    arrays["reaction"] = arrays["eta"] ** 2
    with open(copy / "rows.npz", "wb") as f:
        np.savez(f, **arrays)
    summary = json.loads((copy / "summary.json").read_text())
    summary.pop("fields", None)
    (copy / "summary.json").write_text(json.dumps(summary))
    res = readback.read_output(copy)
    np.testing.assert_array_equal(res.fields["reaction"], res.eta**2)
    assert res.field_info == {"reaction": OutputField("reaction").metadata()}


def test_plot_refuses_a_field_that_summary_json_names_and_rows_npz_lacks(tmp_path, folder, capsys):
    copy, err = plot_refusal(folder, lambda copy: _summary_with("fields", _field())(copy / "summary.json"), tmp_path, capsys)
    assert f"{copy / 'rows.npz'} has no array 'reaction'" in err, err
