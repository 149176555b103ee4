"""What a model's form must be, checked in UFL before anything is compiled: a `Form` with a ``dx`` term, linear in
the test function (rank 1), with a mass (the coefficient of η_tt) constant in the unknowns (a bilinear form aborts
the assembler; a zero mass runs to 1e30 unnoticed). `mass_density` gives the mass as a pointwise UFL expression.
"""

from __future__ import annotations

import ufl
from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering
from ufl.algorithms.apply_derivatives import apply_derivatives

from ..errors import ModelError

__all__ = ["FormError", "check_declarations", "check_form", "mass_density"]

#: What a model's momentum form is made of, for the messages.
_ALLOWED = "a UFL Form linear in the test function w, with terms times ufl.dx (e.g. eta_tt*w*dx + ...)"


class FormError(ModelError):
    """A model's form is not a residual a scheme can take: not a Form, without ``dx``, of rank other than 1, or with
    a mass that is not constant in the unknowns. The message names the model and the function."""


def check_form(model_name: str, what: str, R, test) -> None:
    """FormError (one line) unless `R`, the form the model's function `what` returned, is a UFL `Form` with at
    least one ``dx`` integral, whose only argument is `test` (the test function: linear in it, rank 1)."""
    where = f"model '{model_name}': {what}"
    if not isinstance(R, ufl.Form):
        raise FormError(f"{where} returned a {type(R).__name__}, not a form (no ufl.dx?); allowed: {_ALLOWED}")
    if not R.integrals_by_type("cell"):
        raise FormError(f"{where} has no term integrated over the domain (ufl.dx); allowed: {_ALLOWED}")
    arguments = R.arguments()
    if len(arguments) != 1 or arguments[0] != test:
        found = {0: "a functional (rank 0: no test function w)", 1: "linear in another test function than the w it "
                 "was given", 2: "bilinear (rank 2: a TrialFunction in it)"}.get(len(arguments), f"of rank {len(arguments)}")
        raise FormError(f"{where} is {found}; allowed: {_ALLOWED}")
    try:
        from ufl.algorithms.check_arities import ArityMismatch, check_form_arity
        from ufl.algorithms.remove_complex_nodes import remove_complex_nodes

        check_form_arity(remove_complex_nodes(apply_derivatives(apply_algebra_lowering(R))), arguments)  # real mode
    except (ArityMismatch, NotImplementedError):  # UFL's own message about a product of w with itself fails so
        raise FormError(f"{where} is not linear in the test function w (w times w, or w in a nonlinear function); "
                        f"allowed: {_ALLOWED}") from None


def mass_density(model_name: str, what: str, R, eta_tt, test, unknowns) -> object:
    """The mass per length (per area) of `R`: the coefficient ρ of η_tt (∂R/∂η_tt applied to 1, tested with 1), a
    pointwise UFL expression; FormError if ρ depends on the `unknowns` (the schemes need a constant mass)."""
    direction = ufl.TrialFunction(test.ufl_function_space())
    a = apply_derivatives(ufl.derivative(apply_algebra_lowering(R), eta_tt, direction))
    if set(ufl.algorithms.extract_coefficients(a)) & set(unknowns):
        raise FormError(f"model '{model_name}': {what} must be affine in eta_tt with a constant coefficient (a mass "
                        "that does not depend on eta, eta_t or eta_tt); it may be nonlinear in eta and eta_t")
    one = ufl.as_ufl(1.0)
    tested = apply_derivatives(ufl.replace(a, {direction: one, test: one}))
    integrands = [i.integrand() for i in tested.integrals_by_type("cell")]
    return sum(integrands[1:], integrands[0]) if integrands else ufl.as_ufl(0.0)


def check_declarations(model) -> None:
    """FormError (one line) unless what a model declares is of its kind: ``fields``, ``constants`` and ``outputs``
    tuples of identifiers, `ModelConstant`s and `OutputField`s, no name twice, no output field under a name a run's
    files use themselves (`interface.TAKEN`, ``field_...``); ``stored_energy`` and the other laws functions or None;
    each of its ``held_fields`` and ``dissipative_fields`` one of its ``fields``."""
    from .interface import TAKEN, ModelConstant, OutputField, output_fields

    where = f"model '{model.name}'"
    for what, kind in (("fields", str), ("constants", ModelConstant), ("outputs", OutputField)):
        named = getattr(model, what, ())
        if not isinstance(named, (tuple, list)) or not all(isinstance(item, kind) for item in named):
            raise FormError(f"{where}: {what} must be a tuple of {kind.__name__}s, not {named!r:.80}")
    for what in ("stored_energy", "contact_energy", "gap", "penalty_damping", "stability", "check_constants"):
        if getattr(model, what, None) is not None and not callable(getattr(model, what)):
            raise FormError(f"{where}: {what} must be a function or None, not {getattr(model, what)!r:.80}")
    for what, names in (("constants", [c.name for c in model.constants]), ("outputs", [f.name for f in output_fields(model)])):
        twice = sorted({name for name in names if names.count(name) > 1})
        taken = [name for name in names if what == "outputs" and (name in TAKEN or name.startswith("field_"))]
        if twice or taken:
            raise FormError(f"{where}: {what} name {', '.join(map(repr, twice or taken))} "
                            + ("twice" if twice else "a name the run's files use themselves (rows.npz, diagnostics.csv, "
                               f"the pictures); allowed: another name, not {', '.join(TAKEN)} or field_..."))
    if getattr(model, "release", "inelastic") not in ("inelastic", "signorini"):  # read by some schemes only
        raise FormError(f"release: {where} declares release {model.release!r:.40}; allowed: inelastic, signorini")
    fields = tuple(getattr(model, "fields", ()))
    for what in ("held_fields", "dissipative_fields"):
        named = getattr(model, what, ())
        if isinstance(named, str) or not isinstance(named, (tuple, list)):
            raise FormError(f"model '{model.name}': {what} must be a tuple of field names, not {named!r}")
        unknown = [name for name in named if name not in fields]
        if unknown:
            allowed = ", ".join(map(repr, fields)) or "none (the model has no fields)"
            raise FormError(f"model '{model.name}': {what} names {', '.join(map(repr, unknown))}, not a field of the "
                            f"model; allowed: {allowed}")
