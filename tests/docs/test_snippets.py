"""Every Python snippet of the tutorial and the how-tos runs as written: a page's snippets one after the other in one
namespace, in a fresh working folder (a page that reads another's output folder runs that page first). The BDF2
scheme of "Write a time scheme of your own" converges at second order without contact."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import stringcontact as sc
from stringcontact.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted((ROOT / "docs" / "tutorial").glob("*.md")) + sorted((ROOT / "docs" / "howto").glob("*.md"))
#: a page whose snippets read what another page's wrote (an output folder)
NEEDS = {"output_folder.md": "first_run.md"}
#: pages whose snippets run long (Example 1 at nx = 5000 with its pictures, a drum, several models)
LONG = {"first_run.md", "output_folder.md", "own_time_loop.md", "models.md", "nonlinear_models.md", "first_variant.md"}


def snippets(page: Path) -> list[str]:
    """The page's ```python blocks, in order."""
    return re.findall(r"```python\n(.*?)```", page.read_text(), re.DOTALL)


def _run(page: Path) -> dict:
    namespace = {"__name__": f"snippets_{page.stem}"}
    for number, code in enumerate(snippets(page), 1):
        where = f"{page.relative_to(ROOT)} snippet {number}"
        exec(compile(code, where, "exec"), namespace)  # noqa: S102 - the docs' own code, not a user's text
    return namespace


@pytest.mark.parametrize("page", [pytest.param(p, id=p.name, marks=[pytest.mark.slow] if p.name in LONG else [])
                                  for p in PAGES if snippets(p)])
def test_every_snippet_of_the_page_runs_as_written(page, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["show", "example1"]) == 0  # the scene file a page's reader made before (`my_scene.toml`)
    (tmp_path / "my_scene.toml").write_text(capsys.readouterr().out)
    if page.name in NEEDS:
        _run(page.parent / NEEDS[page.name])
    _run(page)


def test_the_docs_bdf2_scheme_converges_at_second_order_without_contact(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    Scheme = _run(ROOT / "docs" / "howto" / "own_scheme.md")["Scheme"]
    free = sc.load_scene("example1").replace(nx=100, T=0.2, eta0="1 + 0.5*sin(pi*x)", v0="0", output_times=[], eps=0.01)

    def eta(nt):
        st = sc.Stepper(free.replace(nt=nt), scheme=Scheme)
        while st.step < st.nt:
            st.advance()
        assert st.eta.min() > 0.5  # no contact
        return st.eta

    reference = eta(3200)
    errors = [np.max(np.abs(eta(nt) - reference)) for nt in (50, 100, 200)]
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(orders > 1.9), (errors, orders)  # 1.98, 2.00; the first-order start or quotients give 1
