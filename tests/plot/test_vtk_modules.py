"""VTK's module search over a listing made once (`plot.vtk_start`) finds what VTK's own search finds."""

from __future__ import annotations

from pathlib import Path

import pytest

vtkmodules = pytest.importorskip("vtkmodules")

from stringcontact.plot import vtk_start


def test_the_search_finds_what_vtks_own_finds_for_every_module():
    assert vtk_start.search_once()
    assert vtkmodules.find_lib_path is vtk_start.find_lib_path
    own, paths = vtk_start.VTK_OWN, list(vtkmodules.__path__)
    names = sorted({p.name.split(".")[0] for p in Path(paths[0]).iterdir() if p.name.startswith("vtk")})
    assert len(names) > 100
    # VTK's own caution: vtkIOXML is not vtkIOXMLParser; a prefix of a name and a name that is absent
    names += ["vtkIOXML", "vtkIOXMLParser", "vtkCommon", "vtkNoSuchModule", "vtkmodules", ""]
    found = {name: vtk_start.find_lib_path(paths, name) for name in names}
    assert found == {name: own(paths, name) for name in names}
    assert found["vtkCommonCore"].endswith(".so") and found["vtkNoSuchModule"] is None
    assert vtk_start.find_lib_path([str(Path(paths[0]) / "absent")], "vtkCommonCore") is None
    assert vtk_start.search_once()  # again: still ours, VTK's own kept
    assert vtk_start.VTK_OWN is own


def test_another_finder_is_left_alone(monkeypatch):
    def theirs(paths, name):  # a finder for other extensions than the one mirrored
        return None

    monkeypatch.setattr(vtkmodules, "LIB_EXTS", [".so"])
    monkeypatch.setattr(vtkmodules, "find_lib_path", theirs)
    assert not vtk_start.search_once()
    assert vtkmodules.find_lib_path is theirs
