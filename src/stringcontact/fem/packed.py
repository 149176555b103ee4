"""A compiled form whose packed coefficients are refreshed in place, by a gather, instead of packed again.

dolfinx packs a form's coefficients at every assembly unless handed them: at nx = 5000 the cubic foundation's residual
assembles in 0.24 ms packed by dolfinx, 0.13 ms handed over (`benchmarks/bench_nonlinear.py`). The slots are found by
dolfinx itself (`_probe`) and the gather checked against its packing; where they differ, dolfinx packs.
"""

from __future__ import annotations

import dolfinx.fem.petsc  # noqa: F401 - dolfinx 0.9 no longer imports the PETSc layer with dolfinx.fem
import numpy as np
from dolfinx import fem

from .compat import pack_coefficients

__all__ = ["PackedForm"]


class PackedForm:
    """`ufl_form` compiled, its coefficients packed once: `refresh(f, …)` gathers the slots of changed coefficients
    (default: all); `assemble_vector` and `assemble_scalar` then assemble without packing. `fast` is False where the
    gather did not reproduce dolfinx's packing: every assembly packs afresh.
    """

    def __init__(self, ufl_form):
        self.form = fem.form(ufl_form)
        self.functions = list(ufl_form.coefficients())
        self.coeffs = {key: np.ascontiguousarray(a) for key, a in pack_coefficients(self.form).items()}
        self.flat = {key: a.reshape(-1) for key, a in self.coeffs.items()}  # views: a flat index is the fastest gather
        self.slots = {f: _probe(self.form, f) for f in self.functions}
        self.fast = _gather_matches(self)
        self.refresh()  # the check above left its random values in the packed arrays

    def refresh(self, *functions) -> None:
        """The packed slots of `functions` (default: every coefficient) set from their values."""
        if self.fast:
            self._gather(functions or self.functions)

    def _gather(self, functions) -> None:
        for f in functions:
            values = f.x.array
            for key, (slots, dofs) in self.slots[f].items():
                self.flat[key][slots] = values[dofs]

    def assemble_vector(self, b) -> None:
        """The form assembled into the PETSc vector `b` (added, no ghost update), with the packed coefficients."""
        fem.petsc.assemble_vector(b, self.form, coeffs=self.coeffs if self.fast else None)

    def assemble_scalar(self) -> float:
        """The functional on this rank's cells, with the packed coefficients."""
        return float(fem.assemble_scalar(self.form, coeffs=self.coeffs if self.fast else None))


def _probe(form, f) -> dict:
    """For each packed array of `form`: `f`'s slots and the local dof each holds (packing f = 1, …, N against 0)."""
    saved = f.x.array.copy()
    try:
        f.x.array[:] = 0.0
        zero = pack_coefficients(form)
        f.x.array[:] = np.arange(1, f.x.array.size + 1)
        numbered = pack_coefficients(form)
    finally:
        f.x.array[:] = saved
    slots = {}
    for key, values in numbered.items():
        where = np.flatnonzero(values != zero[key])
        slots[key] = (where, np.rint(values.reshape(-1)[where]).astype(np.int64) - 1)
    return slots


def _gather_matches(packed: PackedForm) -> bool:
    """Whether gathering random values gives dolfinx's packing, bit for bit (the functions restored)."""
    saved = [f.x.array.copy() for f in packed.functions]
    rng = np.random.default_rng(0)
    try:
        for f in packed.functions:
            f.x.array[:] = rng.random(f.x.array.size)
        packed._gather(packed.functions)
        reference = pack_coefficients(packed.form)
        return all(np.array_equal(packed.coeffs[key], reference[key]) for key in reference)
    except IndexError:  # transformed values name no dof
        return False
    finally:
        for f, values in zip(packed.functions, saved):
            f.x.array[:] = values
