"""`operators`: the semi-discrete operators from a model's momentum form, and the forms it refuses."""

import pytest
import ufl

import stringcontact as sc
from stringcontact.fem.operators import ModelError
from stringcontact.model.interface import Model


def test_a_momentum_form_nonlinear_in_eta_tt_is_refused():
    """Nonlinear in η and η_t is solved by Newton (tests/timestepping/test_nonlinear.py); a mass that depends on the
    state is not (the schemes lump M = ∂R/∂η_tt)."""

    def momentum_form(eta, eta_t, eta_tt, force, w, p):
        return ((1 + eta**2) * eta_tt * w + ufl.inner(ufl.grad(eta), ufl.grad(w)) - force * w) * ufl.dx

    with pytest.raises(ModelError, match="affine in eta_tt"):
        sc.simulate(
            sc.load_scene("example1").replace(nx=500, nt=750), model=Model(name="cubic", momentum_form=momentum_form)
        )
