"""The README's ParaView recipe, in ParaView: `pvpython` (Debian's python3-paraview) under `xvfb-run`.

`scripts/setup --test` (run by `make test`) installs both; `make test` sets STRINGCONTACT_REQUIRE_PARAVIEW=1,
so there the test fails instead of skipping when they are missing.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.io.readback import read_output
from stringcontact.io.result import FIELDS

SCRIPT = Path(__file__).with_name("paraview_readme.py")
CONTACT_RGB = (180, 4, 38)  # the top of ParaView's default map (Cool to Warm): contact = 1
FREE_RGB = (59, 76, 192)  # its bottom: contact = 0


def pvpython() -> list[str]:
    missing = [tool for tool in ("pvpython", "xvfb-run") if shutil.which(tool) is None]
    if missing:
        why = f"{' and '.join(missing)} not found (scripts/setup --test installs python3-paraview and xvfb)"
        if os.environ.get("STRINGCONTACT_REQUIRE_PARAVIEW"):
            pytest.fail(why)
        pytest.skip(why)
    # -a from a display number of our own: two xvfb-runs started at once from :99 can race for the same one
    display = str(100 + os.getpid() % 800)
    return ["xvfb-run", "-a", "-n", display, "-s", "-screen 0 1280x1024x24", "pvpython"]  # 24-bit colour for GLX


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("paraview") / "run"
    res = sc.simulate(sc.load_scene("example1").replace(nx=200, nt=600), output_dir=out, max_frames=10, pictures=False)
    return out, res


def _pixels_near(img, rgb, tol=40):
    return int(np.all(np.abs(img[..., :3].astype(int) - np.array(rgb)) <= tol, axis=-1).sum())


def test_the_readme_recipe_colours_the_warped_string_by_contact(tmp_path, run):
    from PIL import Image

    command = pvpython()
    out, res = run
    back = read_output(out)
    k = int(np.argmax([0.3 < c.mean() < 1 for c in back.contact]))  # a frame with contact on part of the string
    t = float(back.t[k])
    row = int(np.flatnonzero(res.t == t)[0])
    solver_fraction = float(res.contact[row].mean())
    assert 0.3 < solver_fraction < 1

    png = tmp_path / "contact.png"
    proc = subprocess.run([*command, str(SCRIPT), str(out / "solution.xdmf"), repr(t), str(png)],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[:2000] + " ... " + proc.stderr[-1000:]
    reports = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert [r["reader"] for r in reports] == ["Xdmf3ReaderT", "Xdmf3ReaderS", "XDMFReader"]
    for r in reports:
        assert r["class"] == "vtkUnstructuredGrid", r  # one grid, not a block per field
        assert r["points"] == len(res.x) and set(r["arrays"]) == set(FIELDS), r
        np.testing.assert_allclose(r["times"], back.t, rtol=1e-12, atol=0)
        assert r["eta_type"] == "double"  # Precision="8"
        assert r["contact_range"] == [0.0, 1.0]
        assert r["contact_fraction"] == pytest.approx(solver_fraction, abs=1e-12), r["reader"]
        assert r["max_warp_error"] < 1e-6  # the points were moved by eta ...
        assert r["max_y_in_contact"] <= 1e-6  # ... and those marked in contact lie on or below the obstacle

    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[:2] == (450, 900)
    assert _pixels_near(img, CONTACT_RGB) > 300, "no string drawn in the contact colour"
    assert _pixels_near(img, FREE_RGB) > 100, "no free part of the string drawn"


def test_the_readme_membrane_recipe_shows_the_drum_patch(tmp_path):
    """A membrane's solution.xdmf in ParaView: triangles warped by eta (z), the solver's contact nodes, the patch drawn."""
    from PIL import Image

    command = pvpython()
    out = tmp_path / "drum"
    res = sc.simulate(sc.load_scene("drum").replace(mesh_size=0.2), output_dir=out, max_frames=10, pictures=False)
    back = read_output(out)
    k = int(np.argmax(back.contact_measure))  # the frame with the largest patch
    t = float(back.t[k])
    row = int(np.flatnonzero(res.t == t)[0])
    assert 0 < res.contact[row].sum() < len(res.x)

    png = tmp_path / "membrane.png"
    proc = subprocess.run([*command, str(SCRIPT.with_name("paraview_membrane.py")), str(out / "solution.xdmf"), repr(t),
                           str(png)], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[:2000] + " ... " + proc.stderr[-1000:]
    (report,) = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert report["class"] == "vtkUnstructuredGrid"
    assert (report["points"], report["cells"]) == (len(res.x), len(res.cells)), report
    assert report["cell_types"] == [5]  # VTK_TRIANGLE
    np.testing.assert_allclose(report["times"], back.t, rtol=1e-12, atol=0)
    assert report["max_warp_error"] < 1e-6  # the points were lifted by eta along z (ParaView stores them as float32)
    assert report["contact_nodes"] == int(res.contact[row].sum())
    assert report["max_z_in_contact"] <= 1e-6  # the nodes marked in contact lie on the floor
    img = np.asarray(Image.open(png).convert("RGB"))
    assert _pixels_near(img, CONTACT_RGB) > 500, "no contact patch drawn in the contact colour"
    bluish = (img[..., 2].astype(int) - np.maximum(img[..., 0], img[..., 1]).astype(int)) > 60  # lit: shades of FREE_RGB
    assert int(bluish.sum()) > 1000, "no free membrane drawn"
