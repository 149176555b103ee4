"""Every demo in demos/ runs at reduced resolution and writes only under its output folder.

The demos run as the site build runs them (docs/_ext/demo_pages.py: the script's code cells in order, in one
namespace, as `python demo.py` runs them, in a process of its own), once per test run: `conftest.demo_run`
shares the runs with tests/docs/test_site.py, whose build renders them as the demos' pages."""

from __future__ import annotations

import pytest
from conftest import DEMOS, demo_run

# What the paper's demos must report (the observations of Section 6, measured at reduced resolution;
# the full-resolution numbers are in docs/explanation/visualisation.md), and the files they must leave.
EXPECTED = {
    "demo_example1.py": ["largest contact fraction", "mirror node: 0", "contact fraction never grows after its peak: True"],
    "demo_example2.py": ["most components at one time", "two or more components"],
    "demo_membrane.py": ["the contact patch is a disk at every stored time: True", "two patches that join into one: True",
                         "the inelastic skin stays down longer: True", "the spring loses under 1% of E(0) in contact: True"],
    "demo_stiff_string.py": ["dispersion relation: largest relative error", "the landing stays above the obstacle: True",
                             "the contact force is >= 0 and 0 off the contact set: True", "energy ledger closes: True"],
}
PAPER_FILES = ("solution.xdmf", "solution.h5", "contact_set.png", "velocity_field.png", "snapshots.png", "energy.png")
FILES = {
    "demo_example1.py": PAPER_FILES,
    "demo_example2.py": PAPER_FILES,
    "demo_membrane.py": ("solution.xdmf", "solution.h5", "membrane.png", "contact_area.png", "energy.png", "membrane.gif",
                         "drum_variants.png"),
    "demo_stiff_string.py": ("stiff_string_modes.png", "stiff_string_landing.png"),
}


def test_there_are_demos():
    names = {d.name for d in DEMOS}
    assert {"demo_example1.py", "demo_example2.py"} <= names


@pytest.mark.slow  # each demo is a script of several whole runs with pictures, in its own process
@pytest.mark.parametrize("demo", DEMOS, ids=[d.stem for d in DEMOS])
def test_demo_runs(demo, demo_work):
    records, out, stderr = demo_run(demo, demo_work)  # fails the test if it fails or writes outside `out`
    written = [p for p in out.rglob("*") if p.is_file() and p.name != ".stringcontact-docs-demo"]
    assert written, f"{demo.name} wrote nothing under STRINGCONTACT_DEMO_OUT"
    assert "Traceback" not in stderr, stderr[-3000:]
    stdout = "".join(cell["printed"] for cell in records)
    for words in EXPECTED.get(demo.name, []):
        assert words in stdout, f"{demo.name}: {words!r} not in its output:\n{stdout}"
    for name in FILES.get(demo.name, ()):
        assert list(out.rglob(name)), f"{demo.name}: no {name}"
