"""The model contract: what a model is (`Model`, `Parameters`) and what it declares besides its UFL (constants,
output fields, solver hints). These are data; the core never names a particular model. docs/howto/models.md has the
table of the fields; a variant replaces one function of the paper's model (`model.inelastic`,
``dataclasses.replace(inelastic, name="mine", penalty=my_penalty)``; demos/demo_model_variant.py).

``momentum_form(eta, eta_t, eta_tt, force, w, p)``
    The semi-discrete weak momentum equation as a residual R (a UFL `Form`) in the placeholders the scheme replaces
    by its difference quotients (as in Irksome) and `force`, the contact force density. Linear in them: operators
    assembled once; nonlinear in `eta` or `eta_t` (``k3*eta**3*w*dx``): a Newton solve every step. Affine in
    `eta_tt` and `force` with constant coefficients; terms in none of them (``- f*w*dx``) are the load b = -R(0).

``penalty(eta, v, p)``
    The contact force density F, a *pointwise* UFL expression in η^n, v^n = (η^n − η^{n−1})/Δt and ``p.extra``,
    evaluated at the nodes (`fem/nodal.py`: arithmetic, conditional, max/min, abs, sqrt, exp, ln, sin, cos, tanh),
    lumped with the row sums of ∂R/∂force; explicit: the matrices never change.

``penalty_damping(eta, v, p)`` (optional)
    The same law as a damping coefficient d ≥ 0, F = −d v^{n+1} (`penalty="semi-implicit"`): only the step
    matrix's diagonal changes. ``None``: not a velocity damping (only the explicit penalty).

``contact_set(eta, p)``; ``gap(eta, p)`` (optional)
    The contact indicator written to the results (a UFL condition); the signed distance η − ψ (affine in η, slope
    1) whose gap ≥ 0 ``projection`` enforces (``None``: a law that lets the string through, a spring).

``stability(dt, eps, penalty)``, ``contact_energy(eta, p)`` (optional)
    The law's own bound on Δt and ε: ``None``, ``("warn", why)`` or ``("refuse", why)`` (the velocity penalty's
    restitution is r − 1, r = Δt/ε; a spring's bound is on Δt²/ε). A conservative law's energy density Φ
    (F = −∂Φ/∂η), which the energy guard counts.

``stored_energy(eta, p)`` (optional)
    The energy density Π(η) the form stores (UFL), booked by the Newton path's ledger. ``None``: the potential of
    the form's static force from η = 0 (`fem.operators.potential_energy`): a form not finite there (k/η) must
    declare it. A model with ``fields`` declares ``stored_energy(U, p)`` in ``U = (η, *fields)``.

``penetration_bound`` (default ``"auto"``), ``energy_label``, ``newton``
    The run's penetration check: ``"velocity"`` (within (ε + Δt)·V), ``"spring"`` (√ε·V) or ``None`` (the depth
    alone); ``"auto"``: the ``penalty`` function's attribute ``penetration_bound``, else ``None``. The legend of the
    stored energy in ``energy.png``. ``newton``: every step by Newton even for a linear form.

``fields`` and ``residual(U, U_t, U_tt, force, W, p)``, with ``held_fields``, ``field_lower(p)``,
``dissipative_fields``, ``schemes`` and ``scheme_note`` (optional)
    More P1 unknowns: the residual over ``U = (η, *fields)``, ``W = (w, *tests)`` replaces `momentum_form`, a
    Newton solve on the mixed space every step; η is the first (held at the ends, in contact). The fields held at
    0 on the boundary; a lower bound per field (a variational inequality); the fields whose work on η is booked as
    viscous dissipation; the schemes that may run the model (empty: all) and why the others may not.

``constants``, ``check_constants(values)``, ``outputs``, ``solver``, ``release`` (optional)
    The model's constants (`ModelConstant`: a scene's ``[parameters]``, the forms' ``p.constants[name]``) and its
    rule between them (a `SceneError` naming one); the fields it writes besides η, v, the contact set and force
    (`OutputField`); its solver defaults (`SolverHints`); how ``projection`` and ``fitted`` let a resting node leave
    the obstacle: ``"inelastic"`` (the paper's (A4)) or ``"signorini"`` (a resting node has no mass and gives back
    at most what its landings took, `timestepping.release`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import ufl

from ..scene.parameters import ModelConstant
from .inelastic import contact_set, gap, momentum_form, penalty, penalty_damping, restitution_bound

__all__ = ["DIVERGING", "MUMPS_LU", "PENETRATION_BOUNDS", "REDUNDANT_LU", "SEQUENTIAL", "Model", "ModelConstant",
           "OutputField", "Parameters", "SolverHints", "direct_options", "inelastic", "output_fields",
           "penetration_bound_of", "reads_eps", "unused_fields"]

#: A diverging field's colours at −P, 0 and P (RGB in 0 … 1): blue, a grey seen on white and on the obstacle, red.
DIVERGING = ((0.085, 0.40, 0.85), (0.55, 0.55, 0.55), (0.85, 0.10, 0.08))
#: A one-signed field's colours from its least to its largest value: viridis' ends and middle.
SEQUENTIAL = ((0.267, 0.005, 0.329), (0.128, 0.567, 0.551), (0.993, 0.906, 0.144))
#: The scales a field may be drawn on.
SCALES = ("linear", "symlog")
#: Names an output field may not take: the fields every run stores beside it in its row (`io.result.FIELDS`, ...).
RESERVED = ("eta", "velocity", "contact", "contact_force", "obstacle", "x", "t")
#: Nor these, nor the prefix ``field_``: the names a run's files give their own members, columns and pictures.
TAKEN = ("steps", "cells", "weights", "gap", "contact_set", "contact_area", "velocity_field", "snapshots", "energy",
         "space_time", "membrane")
#: The longest name (its picture's file name stays within the file systems' 255 bytes) and label or unit.
MAX_NAME, MAX_LABEL = 60, 200


@dataclass(frozen=True)
class OutputField:
    """A field a model writes at every stored time: `Result.fields[name]`, ``rows.npz``, ``solution.xdmf``,
    ``NAME.png`` and ParaView's view.

    `expression`, ``(U, p) -> UFL``: a scalar expression of ``U = (η, *fields)``, interpolated into P1 (``None``:
    the unknown `name` itself). How it is shown is metadata: `label`, `unit`; `colours`, RGB triples in 0 … 1
    from the least value to the largest; `scale`, ``"linear"`` or ``"symlog"`` (linear within ``linear_share`` of
    its largest absolute value: a landing's pressure peak is 1e3-1e4 times its surroundings); `symmetric`, a range
    −P … P (``"symlog"`` always is); `surface`, that it colours a membrane instead of the contact set (one at most).
    """

    name: str
    expression: Callable | None = None
    label: str = ""
    unit: str = ""
    colours: tuple = SEQUENTIAL
    scale: str = "linear"
    linear_share: float = 1e-3
    symmetric: bool = False
    surface: bool = False

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier() or len(self.name) > MAX_NAME:
            raise ValueError(f"OutputField: name must be an identifier of at most {MAX_NAME} characters, not "
                             f"{self.name!r:.80}")
        if self.name in RESERVED:
            raise ValueError(f"OutputField {self.name!r}: a name every run stores already; choose another")
        if self.scale not in SCALES:
            raise ValueError(f"OutputField {self.name!r}: scale must be one of {', '.join(SCALES)}, not {self.scale!r}")
        if len(self.colours) < 2 or any(len(c) != 3 or not all(0 <= v <= 1 for v in c) for c in self.colours):
            raise ValueError(f"OutputField {self.name!r}: colours must be two or more RGB triples in 0 ... 1")
        if not 0 < self.linear_share < 1:
            raise ValueError(f"OutputField {self.name!r}: linear_share must be in (0, 1)")
        for key in ("label", "unit"):  # what `plot` reads back from summary.json
            if not isinstance(getattr(self, key), str) or len(getattr(self, key)) > MAX_LABEL:
                raise ValueError(f"OutputField {self.name!r}: {key} must be text of at most {MAX_LABEL} characters, "
                                 f"not {getattr(self, key)!r:.80}")
        if not all(isinstance(getattr(self, key), bool) for key in ("symmetric", "surface")):
            raise ValueError(f"OutputField {self.name!r}: symmetric and surface must be True or False")

    @property
    def title(self) -> str:
        """The label with its unit, for a colour bar or an axis: ``"curvature κ [1/x]"``."""
        label = self.label or self.name
        return f"{label} [{self.unit}]" if self.unit else label

    def metadata(self) -> dict:
        """What the output folder records of it (summary.json's ``fields``): everything but the expression."""
        return {"name": self.name, "label": self.label, "unit": self.unit, "colours": [list(c) for c in self.colours],
                "scale": self.scale, "linear_share": self.linear_share, "symmetric": self.symmetric or
                self.scale == "symlog", "surface": self.surface, "derived": self.expression is not None}


@dataclass(frozen=True)
class SolverHints:
    """How a model's Newton step is best solved: defaults above the schemes', below the user's PETSc options.

    `newton_options`: (name, value) pairs of PETSc options. `linear_options`: ``(dim, ranks, constants) -> pairs``
    for the step's linear solver (naming ``ksp_type`` or ``pc_type`` replaces the size rule's choice).
    `setup_bytes_per_node`: a membrane's measured set-up memory per node (None: `scene.limits.SETUP_BYTES_PER_NODE`)."""

    newton_options: tuple = ()
    linear_options: Callable | None = None
    setup_bytes_per_node: float | None = None

    def options(self, dim: int, ranks: int, constants: dict) -> dict:
        """The model's defaults for a run: `newton_options`, then `linear_options` on top."""
        options = dict(self.newton_options)
        if self.linear_options is not None:
            options |= dict(self.linear_options(dim, ranks, constants))
        return options


#: A direct solver for a membrane's nonsymmetric mixed system, which the size rule's CG does not fit: MUMPS' LU.
MUMPS_LU = (("ksp_type", "preonly"), ("pc_type", "lu"), ("pc_factor_mat_solver_type", "mumps"))
#: A string's on several ranks: each rank factorises the whole banded system (cheaper than MUMPS at these sizes).
REDUNDANT_LU = (("ksp_type", "preonly"), ("pc_type", "redundant"))


def direct_options(dim: int, ranks: int, constants: dict | None = None) -> tuple:
    """A direct linear solver whatever the size (`SolverHints.linear_options`): `MUMPS_LU` on a membrane,
    `REDUNDANT_LU` on a string on several ranks, in serial the size rule's (LU)."""
    return MUMPS_LU if dim == 2 else REDUNDANT_LU if ranks > 1 else ()


def output_fields(model) -> tuple[OutputField, ...]:
    """The fields a model writes: its declared `outputs`, and a plain `OutputField` for each other unknown."""
    declared = tuple(getattr(model, "outputs", ()))
    named = {getattr(f, "name", None) for f in declared}
    plain = tuple(OutputField(name) for name in getattr(model, "fields", ()) if name not in named)
    return plain + declared


@dataclass(frozen=True)
class Parameters:
    """What a model may use, as UFL objects: `alpha` and `eps` (`fem.Constant`s), `x` the spatial coordinate,
    `length` the string's length, `extra` each scene field (``load``, ``obstacle``) as a P1 `Function`, and
    `constants` each of the model's constants (`Model.constants`) as a `fem.Constant`."""

    alpha: object
    eps: object
    x: object
    length: float
    extra: dict = field(default_factory=dict)
    constants: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Model:
    """A model is a few UFL functions; replace one to make a variant (``dataclasses.replace(inelastic,
    name="mine", penalty=my_penalty)``). The signatures and what each must return are in the module docstring."""

    name: str = "inelastic"
    momentum_form: Callable = momentum_form
    penalty: Callable = penalty
    penalty_damping: Callable | None = penalty_damping
    contact_set: Callable = contact_set
    gap: Callable | None = gap
    stability: Callable | None = restitution_bound
    contact_energy: Callable | None = None
    stored_energy: Callable | None = None
    newton: bool = False
    fields: tuple = ()
    residual: Callable | None = None
    held_fields: tuple = ()
    field_lower: Callable | None = None
    dissipative_fields: tuple = ()
    schemes: tuple = ()
    scheme_note: str = ""
    description: str = "the paper's model: viscoelastic string, inelastic velocity penalty on the obstacle y = 0"
    penetration_bound: str | None = "auto"
    energy_label: str | None = None
    constants: tuple = ()
    check_constants: Callable | None = None
    outputs: tuple = ()
    solver: SolverHints = SolverHints()
    release: str = "inelastic"


#: The penetration bounds a contact law may have (`Model.penetration_bound`; None: no known bound).
PENETRATION_BOUNDS = ("velocity", "spring", None)


def penetration_bound_of(model: Model) -> str | None:
    """The model's ``penetration_bound``; for ``"auto"`` its ``penalty`` function's attribute, else None."""
    bound = model.penetration_bound
    if bound == "auto":
        bound = getattr(model.penalty, "penetration_bound", None)
    if bound not in PENETRATION_BOUNDS:
        raise ValueError(f"model '{model.name}': penetration_bound must be one of 'velocity', 'spring', None or "
                         f"'auto', not {bound!r}")
    return bound


#: The paper's model (the default of every run): the viscoelastic string and the inelastic velocity penalty on
#: the obstacle y = 0. Registered as ``inelastic``.
inelastic = Model()


def unused_fields(model: Model, V, p: Parameters) -> list[str]:
    """Names of the scene fields in ``p.extra`` that none of the model's functions uses (the solver refuses a load
    a model would silently drop)."""
    if not p.extra:
        return []
    from dolfinx import fem

    eta, v, eta_t, eta_tt, force = (fem.Function(V) for _ in range(5))
    w = ufl.TestFunction(V)
    exprs = [model.momentum_form(eta, eta_t, eta_tt, force, w, p), model.penalty(eta, v, p), model.contact_set(eta, p)]
    if model.fields and model.residual is not None:  # read only for its coefficients: one P1 stand-in per component
        k = 1 + len(model.fields)
        U, U_t, U_tt = (tuple(fem.Function(V) for _ in range(k)) for _ in range(3))
        exprs.append(model.residual(U, U_t, U_tt, force, (w,) * k, p))
    if model.penalty_damping is not None:
        exprs.append(model.penalty_damping(eta, v, p))
    exprs += [law(eta, p) for law in (model.contact_energy, model.gap) if law is not None]
    used = {c for e in exprs for c in ufl.algorithms.extract_coefficients(e)}
    return [name for name, f in p.extra.items() if f not in used]


def reads_eps(model: Model, V, p: Parameters) -> bool:
    """Whether the model's contact law (`penalty`, `penalty_damping`) reads ε (`p.eps`); if not, no output names ε."""
    from dolfinx import fem
    from ufl.algorithms.analysis import extract_constants

    eta, v = fem.Function(V), fem.Function(V)
    laws = [model.penalty(eta, v, p)] + ([model.penalty_damping(eta, v, p)] if model.penalty_damping is not None else [])
    return any(p.eps in extract_constants(law) for law in laws)

