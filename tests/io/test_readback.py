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
    sc.simulate(sc.load_scene("example1").replace(nx=40, nt=600), output=sc.Output(out, max_frames=8, pictures=False),
                storage=sc.Storage(max_rows=30))
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


CASES = {
    "random rows": ("rows.npz", _random, "is not a readable .npz file"),
    "truncated rows": ("rows.npz", _truncate, "is not a readable .npz file"),
    "rows without eta": ("rows.npz", _rows_without("eta"), "has no array 'eta'"),
    "rows one short": ("rows.npz", _rows_with("velocity", lambda v: v[:-1]), "does not hold the 31 rows of diagnostics.csv"),
    "rows at other times": ("rows.npz", _rows_with("t", lambda t: t * 2), "its times are not those of diagnostics.csv"),
    "emptied rows": ("rows.npz", _empty, "is not a readable .npz file"),
    "summary is a list": ("summary.json", _json("[]"), "holds a JSON list"),
    "summary without scene": ("summary.json", _without_scene, "has no 'scene'"),
    "summary not JSON": ("summary.json", _json("{\"status\": "), "is not valid JSON"),
    "summary with a bad scene": ("summary.json", _scene_out_of_range, "its scene is not valid"),
    "random summary": ("summary.json", _random, "is not valid JSON"),
    "diagnostics without a column": ("diagnostics.csv", _no_energy_column, "has no column 'kinetic'"),
    "random diagnostics": ("diagnostics.csv", _random, "diagnostics.csv"),
    "a field named as a path": ("summary.json", _summary_with("fields", {"../x": {}}), "output field '../x' is not valid"),
    "a field's colour beyond 1": ("summary.json", _summary_with("fields", _field(colours=[[0, 0, 0], [2, 0, 0]])),
                                  "output field 'reaction' is not valid"),
    "a field on no scale": ("summary.json", _summary_with("fields", _field(scale="cubic")), "output field 'reaction' is not valid"),
    "a field's label a number": ("summary.json", _summary_with("fields", _field(label=3)), "label must be text"),
    "a field's derived flag a word": ("summary.json", _summary_with("fields", _field(derived="yes")),
                                      "its derived and internal must be true or false"),
    "fields not an object": ("summary.json", _summary_with("fields", [1]), "its 'fields' is not an object"),
    "parameters not numbers": ("summary.json", _summary_with("parameters", {"mu": "thick"}), "its 'parameters' is not"),
}


@pytest.mark.parametrize("case", CASES)
def test_plot_on_a_damaged_folder_exits_2_naming_the_file(tmp_path, folder, capsys, case):
    name, damage, words = CASES[case]
    copy, err = plot_refusal(folder, lambda copy: damage(copy / name), tmp_path, capsys)
    assert str(copy / name) in err and words in err, err


@pytest.mark.parametrize("name", ["rows.npz", "diagnostics.csv", "summary.json"])
def test_plot_on_a_folder_without_a_file_it_reads_exits_2_naming_it(tmp_path, folder, capsys, name):
    """`plot` reads rows.npz, diagnostics.csv and summary.json (never solution.h5): a folder without one is refused."""
    copy, err = plot_refusal(folder, lambda copy: (copy / name).unlink(), tmp_path, capsys)
    assert f"{copy} is not a stringcontact output folder (missing {name})" in err, err


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


def test_plot_refuses_a_field_that_summary_json_names_and_rows_npz_lacks(tmp_path, folder, capsys):
    copy, err = plot_refusal(folder, lambda copy: _summary_with("fields", _field())(copy / "summary.json"), tmp_path, capsys)
    assert f"{copy / 'rows.npz'} has no array 'reaction'" in err, err
