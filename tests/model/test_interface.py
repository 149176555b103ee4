"""The model interface as a user meets it: a model's own constants (a scene's [parameters]), its own output fields
(unknowns and derived expressions), a model with several fields and no stored energy, and `stringcontact show`."""

import dataclasses
import subprocess
import sys
import tomllib
import warnings

import numpy as np
import pytest
import ufl

import stringcontact as sc
from stringcontact.errors import SceneError
from stringcontact.fem.operators import ModelError


def winkler_residual(U, U_t, U_tt, force, W, p):
    """The paper's string on a Winkler foundation whose reaction λ = k η is a second unknown."""
    (eta, reaction), (eta_t, _), (eta_tt, _) = U, U_t, U_tt
    w, r = W
    return (eta_tt * w + p.alpha * ufl.inner(ufl.grad(eta_t), ufl.grad(w)) + ufl.inner(ufl.grad(eta), ufl.grad(w))
            + reaction * w - force * w + (reaction - p.constants["k"] * eta) * r) * ufl.dx


def winkler_energy(U, p):
    return 0.5 * ufl.inner(ufl.grad(U[0]), ufl.grad(U[0])) + 0.5 * p.constants["k"] * U[0] ** 2


K = sc.ModelConstant("k", 10.0, 0.0, 1e6, unit="force/η", description="the foundation's stiffness")
REACTION = sc.OutputField("reaction", label="foundation reaction", unit="force")
SQUARE = sc.OutputField("eta_squared", expression=lambda U, p: U[0] ** 2, label="η²")
#: the newcomer's two-field model, without a stored energy (refused) and with one
BARE = dataclasses.replace(sc.inelastic, name="winkler2", fields=("reaction",), residual=winkler_residual,
                           constants=(K,), outputs=(REACTION, SQUARE))
WINKLER = dataclasses.replace(BARE, stored_energy=winkler_energy)


def small(**changes):
    return sc.load_scene("example1").replace(nx=40, T=0.2, dt=0.0005, output_times=[], **changes)


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, **kwargs)


@pytest.mark.slow
def test_a_constant_from_parameters_reaches_the_form_and_the_result():
    """k from the scene's [parameters] is the k in the form: the solved reaction is k η at every node and time after
    the start (a field starts at 0: its value at t = 0 is not solved), for two values of k; the derived field is
    η² at every row."""
    for k in (10.0, 2000.0):
        r = run(small(parameters={"k": k}), model=WINKLER)
        assert r.status == "complete" and r.parameters == {"k": k}
        assert np.allclose(r.fields["reaction"][1:], k * r.eta[1:], rtol=1e-9, atol=1e-9 * k)
        assert np.allclose(r.fields["eta_squared"], r.eta ** 2, rtol=1e-12, atol=1e-14)
        assert r.field_info["reaction"]["label"] == "foundation reaction" and r.field_info["eta_squared"]["derived"]


def test_the_default_constant_is_used_and_recorded():
    r = run(small(), model=WINKLER)
    assert r.parameters == {"k": 10.0} and np.allclose(r.fields["reaction"][1:], 10.0 * r.eta[1:], atol=1e-9)


@pytest.mark.parametrize("given, match", [
    ({"k": -1.0}, r"^k: -1 is out of range; allowed: a number in \[0, 1000000\]$"),
    ({"kk": 1.0}, r"^kk: model 'winkler2' has no constant 'kk' \(its constants: k\)")])
def test_a_bad_constant_is_refused_in_one_line_before_the_mesh(given, match):
    with pytest.raises(SceneError, match=match):
        run(small(parameters=given), model=WINKLER)


def test_a_model_with_fields_and_no_stored_energy_is_refused_in_one_line():
    """Not a false instability later: one line saying what to declare."""
    with pytest.raises(ModelError, match=r"must declare stored_energy\(U, p\)") as info:
        run(small(), model=BARE)
    assert "\n" not in str(info.value)


def test_the_energy_ledger_closes_with_the_declared_energy():
    r = run(small(parameters={"k": 2000.0}), model=WINKLER)
    assert r.checks["energy_balance"]["closes"], r.checks["energy_balance"]


@pytest.mark.slow
def test_show_lists_the_models_constants_and_loads_again(tmp_path):
    """`stringcontact show` writes the model's [parameters]: the scene's values, the defaults, and an optional constant
    without a value as a comment; its output loads as the same scene."""
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "show", "film_landing"], check=True,
                          capture_output=True, text=True)
    table = tomllib.loads(proc.stdout)["parameters"]
    assert table == {"mu": 0.001, "p_ambient": 0.0, "h_min": 0.001}
    assert "# p_cav: not given" in proc.stdout
    path = tmp_path / "shown.toml"
    path.write_text(proc.stdout)
    assert dict(sc.load_scene(path).parameters) == table


def test_a_constant_declaration_checks_itself():
    with pytest.raises(ValueError, match="identifier"):
        sc.ModelConstant("not a name")
    with pytest.raises(SceneError, match="out of range"):
        sc.ModelConstant("k", default=-1.0, low=0.0)
    with pytest.raises(ValueError, match="scale"):
        sc.OutputField("q", scale="log")
    with pytest.raises(ValueError, match="a name every run stores already"):
        sc.OutputField("velocity")
