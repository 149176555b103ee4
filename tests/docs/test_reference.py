"""The reference cannot drift from the code: every scene key the loader accepts is on the scene-keys page with
the text its error messages give, every public name has a docstring, the namespace shows only public names,
and the pages carry no history."""

from __future__ import annotations

import importlib
import inspect
import re
import sys
import tomllib
from pathlib import Path

import pytest

import stringcontact
from stringcontact.errors import SceneError
from stringcontact.scene import Scene, checks, limits, load_scene

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import reference_pages

README_WORDS = 1200
HISTORY = re.compile(r"issue [0-9]+|(first|second|third|fourth|fifth|sixth|seventh|eighth) pass", re.IGNORECASE)


def _page_keys(table: str) -> list[str]:
    return re.findall(r"^\| `([^`]+)` \|", table, re.MULTILINE)


def test_every_key_the_loader_accepts_is_on_the_scene_keys_page():
    keys = _page_keys(reference_pages.scene_keys())
    assert sorted(keys) == sorted(limits.FILE_KEYS) and len(keys) == len(set(keys))
    checks.check_keys(dict.fromkeys(keys))  # the loader accepts every key the page lists
    with pytest.raises(SceneError, match="unknown key"):
        checks.check_keys({"not_a_key": 1})


def test_a_key_without_a_description_fails_the_reference(monkeypatch):
    monkeypatch.setattr(limits, "FILE_KEYS", (*limits.FILE_KEYS, "new_key"))
    with pytest.raises(RuntimeError, match="new_key"):
        reference_pages.scene_keys()


def _rows(table: str, columns: int) -> list[list[str]]:
    """The rows of the markdown tables in `table` that have `columns` cells, each cell stripped."""
    rows = [[c.strip() for c in line.strip().strip("|").split(" | ")] for line in table.splitlines()
            if line.startswith("| `")]
    return [r for r in rows if len(r) == columns]


def test_every_shipped_models_constants_and_fields_are_on_the_scene_keys_page():
    """The models this package registers (pyproject.toml's entry points) with each constant's default, range, unit
    and meaning and each output field's label and unit; a plugin's models are not on the page."""
    from stringcontact.model.interface import output_fields

    page = reference_pages.models()
    ours = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]["stringcontact.models"]
    shipped = reference_pages.shipped_models()
    assert set(shipped) == set(ours) and "soft_ground" not in page
    constants = {(r[1].strip("`"), r[0].strip("`")): r[2:] for r in _rows(page, 6)}
    fields = {(r[1].strip("`"), r[0].strip("`")): r[2:] for r in _rows(page, 5)}
    expected_constants, expected_fields = {}, {}
    for name, model in shipped.items():
        for c in model.constants:
            expected_constants[name, c.name] = [c.default_text, c.allowed, c.unit or "–", c.description]
        for f in output_fields(model):
            expected_fields[name, f.name] = [f.label or f.name, f.unit or "–"]
    assert {k: v for k, v in constants.items()} == expected_constants
    assert {k: v[:2] for k, v in fields.items()} == expected_fields
    assert ("film", "mu") in constants and ("stiff_string", "beta") in constants  # the page is not empty
    assert ("film", "pressure") in fields and ("stiff_string", "curvature") in fields
    without = [n for n, m in shipped.items() if not m.constants]
    assert f"Without constants: {', '.join(f'`{n}`' for n in without)}." in page


def test_a_shipped_models_new_constant_reaches_the_page(monkeypatch):
    import dataclasses

    from stringcontact.model.interface import ModelConstant

    shipped = reference_pages.shipped_models()
    film = shipped["film"]
    extra = ModelConstant("gamma", 0.5, 0.0, 1.0, description="a constant added to the film")
    monkeypatch.setattr(reference_pages, "shipped_models",
                        lambda: shipped | {"film": dataclasses.replace(film, constants=(*film.constants, extra))})
    assert ["`gamma`", "`film`", "0.5", "a number in [0, 1]", "–", "a constant added to the film"] in \
        _rows(reference_pages.models(), 6)


def test_the_models_page_says_what_the_constants_error_message_says():
    from stringcontact.scene.parameters import MAGNITUDE, resolve_parameters

    page = reference_pages.models()
    for name, model in reference_pages.shipped_models().items():
        required = {c.name: (c.low + c.high) / 2 for c in model.constants if c.required}  # inside their ranges
        for c in model.constants:
            outside = c.high * 2 + 1 if c.high < MAGNITUDE else c.low * 2 - 1
            with pytest.raises(SceneError, match=f"^{re.escape(c.name)}: ") as error:
                resolve_parameters(name, model.constants, required | {c.name: outside})
            assert f"allowed: {c.allowed}" in str(error.value) and f"| {c.allowed} |" in page
            with pytest.raises(SceneError, match=f"model {name!r} has no constant 'not_a_constant'"):
                resolve_parameters(name, model.constants, {"not_a_constant": 1.0})


EXAMPLE1 = load_scene("example1").as_dict()
_MEMBRANE = {"T": 0.1, "alpha": 0.01, "scheme": {"eps": 0.01}, "nt": 10, "eta0": "1", "v0": "0"}
RECTANGLE = {"domain": "rectangle", "size": [1, 1], "cells": [4, 4], **_MEMBRANE}
DISK = {"domain": "disk", "radius": 1.0, "mesh_size": 0.5, **_MEMBRANE}
BAD = [  # key, a value outside its range, the scene it goes into
    ("length", 0.0, EXAMPLE1), ("T", -1.0, EXAMPLE1), ("alpha", -1.0, EXAMPLE1), ("eps", 0.0, EXAMPLE1),
    ("nx", 1, EXAMPLE1), ("nt", 0, EXAMPLE1), ("h_left", 1e7, EXAMPLE1), ("h_right", -1e7, EXAMPLE1),
    ("name", ".hidden", EXAMPLE1), ("scheme", "euler", EXAMPLE1), ("domain", "sphere", EXAMPLE1),
    ("size", [0, 1], RECTANGLE), ("cells", [0, 4], RECTANGLE), ("radius", 0.0, DISK), ("mesh_size", 2.0, DISK),
    ("petsc_options", {"ksp_view": 1}, EXAMPLE1), ("mesh", "mesh.msh", {**DISK, "domain": "file"}),
]


@pytest.mark.parametrize(("key", "value", "base"), BAD, ids=[b[0] for b in BAD])
def test_the_page_says_what_the_error_message_says(key, value, base):
    data = {k: v for k, v in base.items() if not (key == "mesh" and k in ("radius", "mesh_size"))}
    if key in ("eps", "restitution") and isinstance(data.get("scheme"), dict):  # options of the [scheme] table
        data["scheme"] = {**data["scheme"], key: value}
    else:
        data[key] = value
    with pytest.raises(SceneError) as error:
        Scene.from_dict(data)
    assert str(error.value).startswith(f"scene 'scene': {key}:") or f": {key}:" in str(error.value)
    assert checks.allowed(key) in str(error.value)


def _documented(obj) -> bool:
    doc = obj.__dict__.get("__doc__") if isinstance(obj, type) else getattr(obj, "__doc__", None)
    return bool(doc and doc.strip())


def _public_objects():
    found = {name: (f"stringcontact.{name}", getattr(stringcontact, name)) for name in stringcontact.__all__}
    for module_name in reference_pages.PUBLIC_MODULES:
        module = importlib.import_module(module_name)
        for name in reference_pages.public_names(module_name):
            found.setdefault(name, (f"{module_name}.{name}", getattr(module, name)))
    return [(qualified, name, obj) for name, (qualified, obj) in found.items()]


def test_every_public_name_has_a_docstring():
    missing = []
    for qualified, name, obj in _public_objects():
        if inspect.isclass(obj) or inspect.isfunction(obj):
            if not _documented(obj):
                missing.append(qualified)
            if inspect.isclass(obj):  # its public methods and properties, those it defines
                missing += [f"{qualified}.{attr}" for attr, member in vars(obj).items() if not attr.startswith("_")
                            and (inspect.isfunction(member) or isinstance(member, (property, classmethod, staticmethod)))
                            and not _documented(member.__func__ if hasattr(member, "__func__") else member)]
        elif reference_pages.data_doc(name, obj) is None:  # data: a #: comment where it is defined
            missing.append(qualified)
    assert not missing, f"public names without a docstring: {', '.join(missing)}"


def test_the_committed_reference_pages_are_what_the_code_makes():
    """docs/reference/*.md read in the repository as on the site: their generated parts are the code's now."""
    stale = reference_pages.stale(ROOT / "docs" / "reference")
    assert not stale, f"stale reference pages {stale}: `make reference` writes them again"


def test_a_stale_page_is_found(tmp_path):
    import shutil

    shutil.copytree(ROOT / "docs" / "reference", tmp_path / "reference")
    page = tmp_path / "reference" / "cli.md"
    page.write_text(page.read_text().replace("stringcontact plot", "stringcontact draw", 1))
    assert reference_pages.stale(tmp_path / "reference") == ["cli"]
    reference_pages.write_all(tmp_path / "reference")
    assert reference_pages.stale(tmp_path / "reference") == []


def test_the_api_page_lists_every_public_name_with_its_signature():
    """Each public name (`stringcontact.__all__` and the public modules') under its own heading, a function's or
    class's signature as the source writes it (no object's address), its docstring's first line."""
    page = (ROOT / "docs" / "reference" / "api.md").read_text()
    assert " at 0x" not in page and "autofunction" not in page and "eval-rst" not in page
    for qualified, name, obj in _public_objects():
        assert f"`{qualified}`" in page, qualified
        if inspect.isclass(obj) or inspect.isfunction(obj):
            assert reference_pages.signature(name, obj) in page, qualified
            first = reference_pages.markdown(inspect.getdoc(obj)).split("\n", 1)[0]
            assert first in page, (qualified, first)
    assert "comm=MPI.COMM_WORLD" in page and "penalty: Callable = penalty" in page  # defaults as written


def test_the_namespace_shows_only_public_names():
    shown = dir(stringcontact)
    assert shown == sorted([*stringcontact.__all__, "__version__"])
    for helper in ("jitlog", "quiet_compiler", "_lazy", "_stack"):
        assert helper not in shown
    from stringcontact.jitlog import quiet_compiler  # still importable from its module

    assert callable(quiet_compiler)


def _site_pages() -> list[Path]:
    """README.md, the site's markdown pages (docs/index.md and the sections) and the demos its demo pages show."""
    pages = [ROOT / "README.md", ROOT / "docs" / "index.md", *sorted((ROOT / "demos").glob("demo_*.py"))]
    for section in ("tutorial", "howto", "reference", "explanation"):
        pages += [p for p in sorted((ROOT / "docs" / section).rglob("*.md")) if not p.name.startswith("demo_")]
    return pages


def test_no_history_in_readme_and_docs():
    # the check of `git grep -nE "issue [0-9]+|(first|...|eighth) pass"`, also on files not yet committed and in
    # the image (no .git there); case-insensitive, so stricter
    found = [f"{p.relative_to(ROOT)}:{i}: {line.strip()}" for p in _site_pages()
             for i, line in enumerate(p.read_text().splitlines(), 1) if HISTORY.search(line)]
    assert not found, "\n".join(found)


def test_readme_is_short_and_cites_the_paper():
    text = (ROOT / "README.md").read_text()
    assert len(text.split()) <= README_WORDS
    assert "Analysis of an Inelastic Contact Problem for the Damped Wave Equation" in text
    assert "Muha" in text and "Trifunović" in text
    assert "output_dir=" not in text and "progress=" not in text



def test_license_and_citation_agree_with_pyproject():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["license"] == {"text": "MIT"}
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n\nCopyright (c) stringcontact developers\n")
    cff = (ROOT / "CITATION.cff").read_text()
    assert cff.startswith("cff-version: 1.2.0\n") and "\ntype: software\n" in cff and "\nlicense: MIT\n" in cff
    assert f"\nversion: {project['version']}\n" in cff
    assert "title: Analysis of an Inelastic Contact Problem for the Damped Wave Equation\n" in cff
