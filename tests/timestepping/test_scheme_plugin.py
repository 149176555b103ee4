"""A time scheme of one's own is one file plus its registration: a module with a `Scheme` class, registered under
the entry-point group ``stringcontact.schemes``, runs linear and nonlinear models by its name in a scene; the
same class can be handed to `simulate` directly. `ImplicitScheme` with the paper's quotients is the paper's Newton
path, to the bit."""

from __future__ import annotations

import dataclasses
import sys
import textwrap
import warnings

import numpy as np
import pytest
import ufl
from conftest import register_distribution

import stringcontact as sc
from stringcontact.scene import names
from stringcontact.timestepping.implicit import ImplicitScheme
from stringcontact.timestepping.paper import PAPER

#: The whole scheme: BDF2's velocity in the paper's step (η and η_tt as the paper's).
BDF2_MODULE = textwrap.dedent(
    '''
    """BDF2 in the velocity: η_t → (3η^{n+1} − 4η^n + η^{n−1})/(2Δt)."""
    from stringcontact.timestepping.implicit import ImplicitScheme


    class Scheme(ImplicitScheme):
        DESCRIPTION = "BDF2 in the velocity, the paper's penalty from the previous step"
        QUOTIENTS = {
            "eta": lambda u, e0, em, v0, dt: u,
            "eta_t": lambda u, e0, em, v0, dt: (3 * u - 4 * e0 + em) / (2 * dt),
            "eta_tt": lambda u, e0, em, v0, dt: (u - 2 * e0 + em) / dt**2,
        }
    '''
)


def _cubic_form(eta, eta_t, eta_tt, force, w, p):
    return sc.inelastic.momentum_form(eta, eta_t, eta_tt, force, w, p) + 20.0 * eta**3 * w * ufl.dx


def _cubic_energy(eta, p):
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + 5.0 * eta**4


CUBIC = dataclasses.replace(sc.inelastic, name="cubic20", momentum_form=_cubic_form, stored_energy=_cubic_energy)


@pytest.fixture
def bdf2(tmp_path, monkeypatch):
    """The scheme's one file and an installed distribution registering it as `bdf2` (a .dist-info folder)."""
    (tmp_path / "bdf2_scheme.py").write_text(BDF2_MODULE)
    register_distribution(tmp_path, "bdf2-scheme", names.SCHEME_GROUP, "bdf2 = bdf2_scheme:Scheme")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    sys.modules.pop("bdf2_scheme", None)
    names.scheme_class.cache_clear()


def _run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, storage=sc.Storage(max_rows=scene.nt), **kwargs)


SCENE = sc.load_scene("example1").replace(nx=100, nt=200, T=0.5, eps=0.0025, output_times=[])  # r = dt/eps = 1


@pytest.mark.slow
@pytest.mark.parametrize("model", [sc.inelastic, CUBIC], ids=["linear", "nonlinear"])
def test_a_registered_scheme_runs_by_its_name(bdf2, model):
    """Listed with its description, named in a scene, it lands the string like the paper's scheme (first order
    both: within a few Δt of it) but is not the paper's scheme."""
    assert "bdf2" in sc.SCHEMES and sc.SCHEMES["bdf2"].startswith("BDF2 in the velocity")
    r = _run(SCENE.replace(scheme="bdf2"), model=model)
    paper = _run(SCENE, model=model)
    assert r.status == "complete" and r.scheme == "bdf2", r.message
    assert r.checks["energy_balance"]["closes"]
    assert r.contact.any() and r.contact_force.min() >= 0.0
    gap = np.max(np.abs(r.eta - paper.eta))
    assert 1e-6 < gap < 0.1, gap
    assert r.counters["newton iterations"] >= (SCENE.nt if model is CUBIC else 0)


@pytest.mark.slow
def test_a_scheme_class_can_be_handed_over(bdf2):
    """In Python the class itself is the scheme: named by where it lives, run by the same path."""
    import bdf2_scheme

    r = _run(SCENE, model=CUBIC, scheme=bdf2_scheme.Scheme)
    by_name = _run(SCENE.replace(scheme="bdf2"), model=CUBIC)
    assert r.scheme == "bdf2"  # the registered class keeps its registered name
    assert np.array_equal(r.eta, by_name.eta)


class _Unregistered(ImplicitScheme):
    """The paper's quotients on the generic implicit step: the paper's own Newton path."""

    DESCRIPTION = "the paper's quotients, unregistered"
    QUOTIENTS = PAPER


@pytest.mark.slow
@pytest.mark.parametrize("penalty", ["explicit", "semi-implicit"])
def test_the_generic_implicit_step_is_the_papers_newton_path(penalty):
    """A nonlinear model: bit for bit the paper's Newton path, whichever penalty; an unregistered class is named
    module:Class."""
    r = _run(SCENE, model=CUBIC, scheme=_Unregistered, penalty=penalty)
    paper = _run(SCENE, model=CUBIC, scheme="paper", penalty=penalty)
    assert r.scheme.endswith(":_Unregistered")
    assert np.array_equal(r.eta, paper.eta) and np.array_equal(r.velocity, paper.velocity)


def test_a_linear_model_through_newton_is_the_linear_path():
    """A linear model reaches a scheme without a linear path of its own through its residual, whose Newton step is
    one back-substitution: the paper's fast linear path to round-off, without a Newton iteration."""
    r = _run(SCENE, model=sc.inelastic, scheme=_Unregistered)
    paper = _run(SCENE, model=sc.inelastic, scheme="paper")
    assert np.max(np.abs(r.eta - paper.eta)) < 1e-10
    assert r.counters["newton iterations"] == 0


def test_a_class_that_is_no_scheme_is_refused():
    with pytest.raises(TypeError, match="is not a subclass of stringcontact.timestepping.base.Scheme"):
        sc.simulate(SCENE, scheme=dict)


@pytest.fixture
def registered_as(tmp_path, monkeypatch):
    """Register `name = target` (a module `plugin_schemes` with `source`) as an installed scheme."""

    def register(entries: dict, source: str = "def function():\n    pass\n"):
        (tmp_path / "plugin_schemes.py").write_text(source)
        lines = "\n".join(f"{name} = {target}" for name, target in entries.items())
        register_distribution(tmp_path, "plugin-schemes", names.SCHEME_GROUP, lines)
        monkeypatch.syspath_prepend(str(tmp_path))
        names.scheme_class.cache_clear()

    yield register
    sys.modules.pop("plugin_schemes", None)
    names.scheme_class.cache_clear()


def test_a_stale_scheme_entry_point_breaks_no_scheme_class_handed_over_and_no_other_message(registered_as):
    registered_as({"stale": "gone_module:Scheme"})
    r = _run(SCENE.replace(nt=4, T=0.01), scheme=_Unregistered)
    assert r.status == "complete" and r.scheme.endswith(":_Unregistered")
    with pytest.raises(ValueError, match=r"restitution: scheme 'paper' takes no restitution .* only scheme 'fitted' or 'projection' does"):
        _run(SCENE, scheme="paper", restitution=0.5)
    with pytest.raises(sc.SceneError, match="scheme: cannot load 'stale'"):
        _run(SCENE, scheme="stale")


@pytest.mark.parametrize(("target", "source", "fragment"), [
    ("plugin_schemes:function", "def function():\n    pass\n", "is registered as a function, not a subclass"),
    ("plugin_schemes:NoMass", "from stringcontact.timestepping.paper import PaperScheme\n"
                              "from stringcontact.timestepping.base import SchemeOption\n"
                              "class NoMass(PaperScheme):\n    OPTIONS = (SchemeOption('mass', None, ()),)\n",
     "its penalty and mass options must list their choices"),
    ("plugin_schemes:BadOptions", "from stringcontact.timestepping.paper import PaperScheme\n"
                                  "class BadOptions(PaperScheme):\n    pass\nBadOptions.OPTIONS = ['mass']\n",
     "OPTIONS must be a tuple of SchemeOptions"),
])
def test_a_scheme_entry_point_that_is_no_scheme_is_one_line_naming_it(registered_as, target, source, fragment):
    registered_as({"odd": target}, source)
    with pytest.raises(sc.SceneError, match=f"scheme.*'odd'.*{fragment}"):
        _run(SCENE, scheme="odd")


def test_a_schemes_linear_solver_failure_names_the_step_and_time(monkeypatch):
    from stringcontact.timestepping.paper import PaperScheme

    def failing(self):
        raise sc.SolverError("the CG did not converge (DIVERGED_ITS)")

    monkeypatch.setattr(PaperScheme, "step", failing)  # the linear path of a linear model
    with pytest.raises(sc.SolverError, match=r"step 1, t = 0.0025: the CG did not converge"):
        _run(SCENE, scheme="paper")
