"""The model contract: what a model is (`Model`, `Parameters`) and what it declares besides its UFL (its constants,
output fields and solver hints). These are data; the core never names a particular model. docs/howto/models.md has
the table of the fields; a variant replaces one function of the paper's model (`model.inelastic`,
``dataclasses.replace(inelastic, name="mine", penalty=my_penalty)``; demos/demo_model_variant.py).

``momentum_form(eta, eta_t, eta_tt, force, w, p)``
    The semi-discrete weak momentum equation as a residual R (a UFL `Form`), written once in the placeholders that
    the scheme replaces by its difference quotients (as in Irksome) and `force`, the contact force density. Linear
    in them: constant operators, assembled once; nonlinear in `eta` or `eta_t` (``k3*eta**3*w*dx``): every step a
    Newton solve (`timestepping.newton`). It must be affine in `eta_tt` and `force` with constant coefficients;
    terms in none of them (a load ``- f*w*dx``) are the constant load b = -R(0, 0, 0, 0).

``penalty(eta, v, p)``
    The contact force density F, a *pointwise* UFL expression in η^n and v^n = (η^n − η^{n−1})/Δt and the fields
    in ``p.extra``: evaluated at the nodes (`fem/nodal.py`: arithmetic, conditional, max/min, abs, sqrt, exp, ln,
    sin, cos, tanh), lumped with the row sums of ∂R/∂force, explicit: the matrices never change.

``penalty_damping(eta, v, p)`` (optional)
    The same law as a damping coefficient d ≥ 0, F = −d v^{n+1} (`penalty="semi-implicit"`): only the step
    matrix's diagonal changes, when d does. ``None``: not a velocity damping (only the explicit penalty).

``contact_set(eta, p)``; ``gap(eta, p)`` (optional)
    The contact indicator written to the results (a UFL condition); the signed distance to the obstacle η − ψ
    (affine in η, slope 1), whose admissible set gap ≥ 0 ``projection`` enforces (``None``: a law meant to let
    the string through, a spring).

``stability(dt, eps, penalty)``, ``contact_energy(eta, p)`` (optional)
    The law's own bound on Δt and ε (``penalty`` "explicit" or "semi-implicit"): ``None``, ``("warn", why)`` or
    ``("refuse", why)`` (the velocity penalty's restitution is r − 1, r = Δt/ε; a spring's bound is on Δt²/ε). A
    conservative law's stored energy density Φ (F = −∂Φ/∂η), which the energy guard counts.

``stored_energy(eta, p)`` (optional)
    The energy density Π(η) the form stores (UFL), booked by the Newton path's ledger. ``None``: the potential
    of the form's static force (`fem.operators.potential_energy`), which starts at η = 0: a form not finite there
    (k/η) must declare it. A model with ``fields`` declares ``stored_energy(U, p)`` in ``U = (η, *fields)``.

``penetration_bound`` (default ``"auto"``), ``energy_label``, ``newton``
    The run's penetration check (`run.checks`): ``"velocity"`` (within (ε + Δt)·V), ``"spring"`` (√ε·V) or
    ``None`` (the depth alone); ``"auto"``: the ``penalty`` function's attribute ``penetration_bound``, else
    ``None``, so a law of one's own is never judged by the paper's bound. The legend of the stored energy in
    ``energy.png`` (``None``: "elastic ½∫η_x²"). ``newton``: every step by Newton even for a linear form.

``fields`` and ``residual(U, U_t, U_tt, force, W, p)``, with ``held_fields``, ``field_lower(p)``,
``dissipative_fields``, ``schemes`` and ``scheme_note`` (optional)
    More P1 unknowns on the same mesh: the residual over tuples ``U = (η, *fields)``, ``W = (w, *tests)`` replaces
    `momentum_form`, every step a Newton solve on the mixed space; the fields enter through their values and first
    time derivatives; η is the first (held at the ends, in contact), the others free unless held or bounded. The
    fields held at 0 on the boundary; a lower bound per field (a variational inequality);
    the fields whose work on η is booked as viscous dissipation; the schemes that may run the model (empty: all)
    and why the others may not.

``constants``, ``check_constants(values)``, ``outputs``, ``solver``, ``release`` (optional)
    The model's own constants (`ModelConstant`: a scene's ``[parameters]``, read by the forms as dolfinx
    Constants ``p.constants[name]``) and its rule between them (a `SceneError` naming one); the fields it writes
    besides η, v, the contact set and force (`OutputField`; every unknown is written); its solver defaults
    (`SolverHints`); how ``projection`` and ``fitted`` let a resting node leave the obstacle: ``"inelastic"`` (the paper's
    (A4)) or ``"signorini"`` (a resting node has no mass, leaves at its neighbours' equilibrium and gives back at most
    what its landings took, `timestepping.release`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Callable

import ufl

from ..scene.parameters import ModelConstant
from .inelastic import contact_set, gap, momentum_form, penalty, penalty_damping, restitution_bound

__all__ = ["DIVERGING", "MUMPS_LU", "PENETRATION_BOUNDS", "REDUNDANT_LU", "SEQUENTIAL", "Model", "ModelConstant",
           "OutputField", "Parameters", "SolverHints", "direct_options", "inelastic", "output_fields",
           "penetration_bound_of", "reads_eps", "unused_fields"]

#: A diverging field's colours at −P, 0 and P (RGB in 0 … 1): blue, a middle grey, red. The grey middle stays seen on
#: a white background and on the light grey obstacle, and black labels on it are read.
DIVERGING = ((0.085, 0.40, 0.85), (0.55, 0.55, 0.55), (0.85, 0.10, 0.08))
#: A one-signed field's colours from its least to its largest value: viridis' ends and middle.
SEQUENTIAL = ((0.267, 0.005, 0.329), (0.128, 0.567, 0.551), (0.993, 0.906, 0.144))
#: The scales a field may be drawn on.
SCALES = ("linear", "symlog")
#: Names an output field may not take: the fields every run stores beside it (`io.result.FIELDS`, the coordinates,
#: a moving obstacle) share its row, and one of these names would overwrite them.
RESERVED = ("eta", "velocity", "contact", "contact_force", "obstacle", "x", "t")
#: Names a model's output field may not take besides those: the names a run's files give their own members, columns
#: and pictures (rows.npz's ``steps``, diagnostics.csv's ``min_gap``, ``energy.png``, ...), and their prefix ``field_``.
TAKEN = ("steps", "cells", "weights", "gap", "contact_set", "contact_area", "velocity_field", "snapshots", "energy",
         "space_time", "membrane")
#: The longest name (its picture's file name stays within the file systems' 255 bytes) and label or unit.
MAX_NAME, MAX_LABEL = 60, 200


@dataclass(frozen=True)
class OutputField:
    """A field a model writes at every stored time: `Result.fields[name]`, ``rows.npz``, ``solution.xdmf``,
    ``NAME.png`` and ParaView's view.

    `expression`, ``(U, p) -> UFL``: a scalar expression of the unknowns ``U = (η, *fields)``, interpolated into P1
    at each stored time (``None``: the unknown `name` itself). How it is shown is metadata, not code: `label`,
    `unit`; `colours`, RGB triples in 0 … 1 from the least value to the largest; `scale`, ``"linear"`` or
    ``"symlog"`` (linear within ``linear_share`` of its largest absolute value, logarithmic beyond: a landing's
    pressure peak is 1e3-1e4 times the pressure around it); `symmetric`, a range −P … P (``"symlog"`` always is);
    `surface`, that it colours a membrane instead of the contact set (one field of a model at most).
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

    `newton_options`: (name, value) pairs of PETSc options (``(("snes_linesearch_type", "l2"),)``). `linear_options`:
    ``(dim, ranks, constants) -> pairs`` for the step's linear solver on a mesh of dimension `dim` on `ranks` ranks;
    naming ``ksp_type`` or ``pc_type`` replaces the size rule's choice (`timestepping.linear.solver_options`).
    `setup_bytes_per_node`: a membrane's measured set-up memory per node with this model, against which a run's
    size is checked before the mesh is built (None: `scene.limits.SETUP_BYTES_PER_NODE`).
    """

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
#: A string's on several ranks: each rank factorises the whole banded system (MUMPS' analysis and communication per
#: factorisation cost more at these sizes; docs/explanation/film.md, "Cost").
REDUNDANT_LU = (("ksp_type", "preonly"), ("pc_type", "redundant"))


def direct_options(dim: int, ranks: int, constants: dict | None = None) -> tuple:
    """A direct linear solver whatever the size (`SolverHints.linear_options`): `MUMPS_LU` on a membrane,
    `REDUNDANT_LU` on a string on several ranks, in serial the size rule's (LU)."""
    return MUMPS_LU if dim == 2 else REDUNDANT_LU if ranks > 1 else ()


def output_fields(model) -> tuple[OutputField, ...]:
    """The fields a model writes: its declared `outputs`, and for each of its unknowns (`Model.fields`) that none
    of them names, a plain `OutputField` of that name."""
    declared = tuple(getattr(model, "outputs", ()))
    named = {getattr(f, "name", None) for f in declared}
    plain = tuple(OutputField(name) for name in getattr(model, "fields", ()) if name not in named)
    return plain + declared


@dataclass(frozen=True)
class Parameters:
    """What a model may use, as UFL objects.

    `alpha` and `eps` are `fem.Constant`s, `x` the spatial coordinate, `length` the string's length,
    `extra` maps each scene field (``load``, ``obstacle``; see `Scene.fields`) to its P1 `Function`, and
    `constants` each of the model's constants (`Model.constants`: the scene's ``[parameters]``, else their
    defaults) to a `fem.Constant`.
    """

    alpha: object
    eps: object
    x: object
    length: float
    extra: dict = field(default_factory=dict)
    constants: dict = field(default_factory=dict)  # the model's constants (`Model.constants`) as fem.Constants


@dataclass(frozen=True)
class Model:
    """A model is a few UFL functions; replace one to make a variant.

    ``dataclasses.replace(inelastic, name="mine", penalty=my_penalty)`` keeps the rest of the paper's
    model. The signatures and what each function must return are in the module docstring.
    """

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
    """The penetration bound of the model's contact law: its ``penetration_bound``, or for ``"auto"`` the one
    its ``penalty`` function declares (attribute ``penetration_bound``), else None (no known bound)."""
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
    """Names of the scene fields in ``p.extra`` that none of the model's functions uses.

    A scene that gives a `load` to a model that ignores it is almost surely a mistake, so the
    solver refuses it (a load silently dropped would give a plausible but wrong answer).
    """
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
    for law in (model.contact_energy, model.gap):
        if law is not None:
            exprs.append(law(eta, p))
    used = set()
    for e in exprs:
        used |= set(ufl.algorithms.extract_coefficients(e))
    return [name for name, f in p.extra.items() if f not in used]


def reads_eps(model: Model, V, p: Parameters) -> bool:
    """Whether the model's contact law (its `penalty`, and `penalty_damping` if it has one) reads ε (`p.eps`): a law
    of the model's own constants (a spring) does not, and the pictures and the report then name no ε."""
    from dolfinx import fem
    from ufl.algorithms.analysis import extract_constants

    eta, v = fem.Function(V), fem.Function(V)
    laws = [model.penalty(eta, v, p)] + ([model.penalty_damping(eta, v, p)] if model.penalty_damping is not None else [])
    return any(p.eps in extract_constants(law) for law in laws)

