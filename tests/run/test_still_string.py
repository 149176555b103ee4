"""A run is complete only if its string moved when it was not at rest: the project checks η against η(0) itself, so a
scheme whose step leaves η where it is, whatever balanced energies it reports, is not marked complete; a string at
rest (flat, or lying on the obstacle) under the same scheme is."""

import json
import sys
import textwrap
import warnings

import numpy as np
import pytest
from conftest import register_distribution

import stringcontact as sc
from stringcontact.scene import names

#: A scheme plugin that keeps (η0, v0) for ever and reports the initial kinetic energy at every step: its balance closes.
FROZEN_MODULE = textwrap.dedent('''
    import numpy as np

    from stringcontact.timestepping.base import Scheme, StepEnergy


    class Frozen(Scheme):
        DESCRIPTION = "a scheme whose step leaves eta where it is"

        def start(self, eta0, v0):
            self._eta, self._v = eta0.copy(), v0.copy()
            self._energy = StepEnergy(0.5 * float(np.dot(self.problem.ops.m, v0**2)), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            return self._energy

        def step(self):
            return self._energy

        @property
        def eta(self):
            return self._eta

        @property
        def velocity(self):
            return self._v

        @property
        def contact_force(self):
            return np.zeros_like(self._eta)
''')


@pytest.fixture
def frozen(tmp_path, monkeypatch):
    """The frozen scheme's module, installed and registered as `frozen`; yields its class."""
    (tmp_path / "frozen_scheme.py").write_text(FROZEN_MODULE)
    register_distribution(tmp_path, "frozen-scheme", names.SCHEME_GROUP, "frozen = frozen_scheme:Frozen")
    monkeypatch.syspath_prepend(str(tmp_path))
    names.scheme_class.cache_clear()
    import frozen_scheme

    yield frozen_scheme.Frozen
    sys.modules.pop("frozen_scheme", None)
    names.scheme_class.cache_clear()


SCENE = dict(nx=40, T=0.01, dt=0.0005, output_times=[])


def _run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, **kwargs)


@pytest.mark.parametrize("v0", ["-50", "0"], ids=["thrown", "released from a curved shape"])
def test_a_scheme_that_never_moves_eta_is_not_complete(frozen, tmp_path, v0):
    """example1 thrown down (v0 = -50), or released at rest from its curved shape (the net force b - K eta0 moves
    it): the frozen scheme's balance closes, yet the run is marked unbalanced in one line naming the scheme."""
    scene = sc.load_scene("example1").replace(**SCENE, v0=v0)
    r = _run(scene, scheme="frozen", output=sc.Output(tmp_path / "o", pictures=False))
    assert r.checks["energy_balance"]["closes"]
    assert r.status == "unbalanced" and "\n" not in r.message, r.message
    assert r.message.startswith("eta never moved") and "scheme 'frozen' did not step" in r.message
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "unbalanced"


@pytest.mark.parametrize(("changes", "model"), [
    (dict(eta0="1", v0="0"), None),  # straight between its ends: no force, no velocity
    (dict(eta0="0", v0="0", h_left=0.0, h_right=0.0, load="-100"), "loaded_obstacle"),  # lying on the obstacle
], ids=["at rest", "lying on the obstacle"])
def test_a_string_at_rest_is_complete_under_a_scheme_that_leaves_it_there(frozen, changes, model):
    scene = sc.load_scene("example1").replace(**SCENE, **changes)
    r = _run(scene, scheme=frozen, model=model)
    assert r.status == "complete", r.message
    assert np.array_equal(r.eta[-1], r.eta[0])


def test_the_command_line_exits_3_for_a_string_that_never_moved(frozen, tmp_path, capsys):
    """`stringcontact run` with the frozen plugin: exit 3, one line, the folder kept marked unbalanced."""
    from stringcontact.cli.main import main

    out = tmp_path / "o"
    code = main(["run", "example1", "--scheme", "frozen", "--nx", "40", "--nt", "20", "--no-progress", "--no-pictures",
                 "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 3 and err.startswith("stringcontact: error: eta never moved") and "\n" not in err, err
    assert json.loads((out / "summary.json").read_text())["status"] == "unbalanced"
