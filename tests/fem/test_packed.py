"""A form assembled with coefficients gathered into its packed arrays (`packed.PackedForm`) is the form assembled by
dolfinx, which packs them afresh, bit for bit: on a string, a blocked (several-field) space and a membrane; and an
element whose packing transforms its values (N1curl) falls back to dolfinx's packing instead of gathering."""

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from stringcontact.fem import compat
from stringcontact.fem.packed import PackedForm


def _assembled(form, packed: PackedForm | None = None) -> np.ndarray:
    b = compat.create_vector(form)
    with b.localForm() as local:
        local.set(0.0)
    if packed is None:
        fem.petsc.assemble_vector(b, form)
    else:
        packed.assemble_vector(b)
    return b.array.copy()


def _spaces():
    string = mesh.create_unit_interval(MPI.COMM_SELF, 50)
    membrane = mesh.create_unit_square(MPI.COMM_SELF, 6, 5)
    return {"string": compat.function_space(string), "fields": compat.mixed_space(string, 2),
            "membrane": compat.function_space(membrane)}


@pytest.mark.parametrize("name", ["string", "fields", "membrane"])
def test_gathered_coefficients_assemble_as_dolfinx_packs_them(name):
    V = _spaces()[name]
    u, e0, k = (fem.Function(V) for _ in range(3))
    w = ufl.TestFunction(V)
    rng = np.random.default_rng(1)
    for f in (u, e0, k):
        f.x.array[:] = rng.random(f.x.array.size)
    G = (ufl.inner(ufl.grad(u - e0), ufl.grad(w)) + ufl.inner(u, u) * ufl.inner(k, w)) * ufl.dx
    packed = PackedForm(G)
    assert packed.fast
    for _ in range(3):  # u changes at every assembly, e0 once: refreshing only what changed suffices
        u.x.array[:] = rng.random(u.x.array.size)
        packed.refresh(u)
        assert np.array_equal(_assembled(packed.form, packed), _assembled(packed.form))
    e0.x.array[:] = rng.random(e0.x.array.size)
    packed.refresh(e0)
    assert np.array_equal(_assembled(packed.form, packed), _assembled(packed.form))
    energy = PackedForm(ufl.inner(k, k) * ufl.inner(u, u) ** 2 * ufl.dx)
    u.x.array[:] = rng.random(u.x.array.size)
    energy.refresh()
    assert energy.assemble_scalar() == fem.assemble_scalar(energy.form)


def test_a_coefficient_left_unrefreshed_is_stale():
    """What `refresh` is for: without it the packed arrays keep the old values (so the test above can fail)."""
    V = _spaces()["string"]
    u, w = fem.Function(V), ufl.TestFunction(V)
    packed = PackedForm(u * u * w * ufl.dx)
    u.x.array[:] = 1.0
    assert not np.array_equal(_assembled(packed.form, packed), _assembled(packed.form))


def test_an_element_with_transformed_values_is_packed_by_dolfinx():
    V = compat.function_space(mesh.create_unit_square(MPI.COMM_SELF, 4, 4), "N1curl", 1)
    u, w = fem.Function(V), ufl.TestFunction(V)
    packed = PackedForm(ufl.inner(u, u) * ufl.inner(u, w) * ufl.dx)
    assert not packed.fast
    u.x.array[:] = np.random.default_rng(2).random(u.x.array.size)
    assert np.array_equal(_assembled(packed.form, packed), _assembled(packed.form))
