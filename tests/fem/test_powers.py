"""`powers`: a form's integer powers compiled as products."""

import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from ufl.corealg.traversal import unique_pre_traversal

from stringcontact.fem.compat import function_space
from stringcontact.fem.powers import powers_as_products


def test_integer_powers_are_compiled_as_products():
    """`powers_as_products`: η³ and η⁴ become products (no libm pow in the kernel), with the same value."""
    eta = fem.Function(function_space(mesh.create_unit_interval(MPI.COMM_SELF, 8)))
    eta.interpolate(lambda x: 1.5 + x[0])
    energy = (0.25 * eta**4 + eta**3 - eta**2 + eta**-2 + eta**0.5) * ufl.dx
    products = powers_as_products(energy)
    powers = [o for o in unique_pre_traversal(products.integrals()[0].integrand()) if isinstance(o, ufl.classes.Power)]
    assert sorted(str(p.ufl_operands[1]) for p in powers) == ["-2", "0.5"]  # only these stay powers
    assert fem.assemble_scalar(fem.form(products)) == pytest.approx(fem.assemble_scalar(fem.form(energy)), rel=1e-14)
