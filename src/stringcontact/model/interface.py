"""The model contract: what a model is (`Model`, `Parameters`) and what it declares besides its UFL (its constants,
output fields and solver hints). These are data; the core never names a particular model.

A model is a `Model`: a few plain functions that return UFL, and data. Its defaults are the paper's model
(`model.inelastic`, registered as ``inelastic``); a variant replaces one function (see `docs/howto/models.md` and
`demos/demo_model_variant.py`). The time loop (`timestepping`) never looks inside these functions; it only asks them
for UFL.

``momentum_form(eta, eta_t, eta_tt, force, w, p)``
    The semi-discrete weak momentum equation as a residual R (a UFL `Form`), written once in the
    unknowns' time derivatives, as in Irksome: `eta`, `eta_t`, `eta_tt` are placeholders that the
    time scheme (`timestepping`) replaces by its difference quotients, and `force` is a placeholder for
    the contact force density. R linear in the four placeholders gives constant operators, assembled once;
    R nonlinear in `eta` or `eta_t` (``k3*eta**3*w*dx``) makes every step a Newton solve
    (`timestepping.newton`); R must be affine in `eta_tt` and `force` with constant coefficients (the
    scheme checks). Terms in none of them (an external load ``- f*w*dx``) are the constant load
    b = -R(0, 0, 0, 0). `w` is the test function.

``penalty(eta, v, p)``
    The contact force density F as a *pointwise* UFL expression in the previous step's η^n and
    v^n = (η^n − η^{n−1})/Δt (P1 functions) and the P1 scene fields in ``p.extra``. It may be
    nonlinear: it is evaluated at the nodes (`fem/nodal.py`: arithmetic, conditional, max/min, abs,
    sqrt, exp, ln, sin, cos, tanh) and lumped onto them with the row sums of ∂R/∂force, so it is
    explicit: the matrices never change.

``penalty_damping(eta, v, p)`` (optional)
    The same law as a damping coefficient d ≥ 0 with F = −d v^{n+1} (`penalty="semi-implicit"`):
    only the diagonal of the step matrix changes, and only when d changes (for the paper's law, when the
    active set changes). ``None`` when the law is not a velocity damping (then only the explicit
    penalty is available).

``contact_set(eta, p)``
    The contact indicator written to the results (a UFL condition, evaluated at the nodes).

``gap(eta, p)`` (optional)
    The signed distance to the obstacle, η − ψ (a UFL expression, affine in η with slope 1): the
    admissible set is gap ≥ 0. Schemes that enforce the constraint itself (``projection``) need it;
    ``None`` for a law that is meant to let the string through (a spring that bounces).

``stability(dt, eps, penalty)`` (optional)
    The bound this contact law puts on Δt and ε when a scheme evaluates it (``penalty`` is "explicit" or
    "semi-implicit"): returns ``None`` (fine), ``("warn", why)`` or ``("refuse", why)``. It belongs to the
    law, not to the solver: the velocity penalty's restitution is r − 1 with r = Δt/ε; a spring's bound is on
    Δt²/ε (`variants.spring_bound`).

``contact_energy(eta, p)`` (optional)
    For a *conservative* law (F = −∂Φ/∂η, a spring): the stored energy density Φ(η), so that the
    solver's energy guard counts the energy held in the spring instead of calling its release
    an instability. ``None`` for a dissipative law such as the paper's.

``stored_energy(eta, p)`` (optional)
    The energy density Π(η) the momentum form stores (UFL), for a model whose form is nonlinear: the
    Newton path's ledger books ∫Π(η) as the elastic energy. ``None``: the potential of the form's static force,
    ∫₀¹ G(sη; η) ds (`fem.operators.potential_energy`; ½|∇η|² for the paper's form), which starts at η = 0: a
    form not finite there (k/η) must declare its energy (its load is then taken at the initial state). A model
    with ``fields`` must declare it, as ``stored_energy(U, p)`` in all its unknowns ``U = (η, *fields)`` (a field that stores no
    energy, such as a film's pressure, simply does not appear in it).

``penetration_bound`` (default ``"auto"``)
    The penetration bound the contact law has (`run.checks.penetration_check`): ``"velocity"`` (the paper's
    velocity penalty (1/ε)(v)⁻ stops a node falling at V within (ε + Δt)·V), ``"spring"`` (a spring of stiffness
    1/ε: √ε·V), or ``None`` (no known bound: the run reports the depth alone). ``"auto"``: the bound the
    ``penalty`` function declares as its attribute ``penetration_bound`` (the paper's ``"velocity"``), else
    ``None``; so ``replace(inelastic, penalty=mine)`` is never judged by the paper's bound.

``energy_label`` (optional)
    The legend of the stored energy in ``energy.png`` (matplotlib mathtext allowed), recorded in
    summary.json; ``None``: the paper's "elastic ½∫η_x²".

``newton`` (a flag, default False)
    Solve every step by Newton (`timestepping.newton`) even when the form is linear: a form nonlinear in
    η or η_t always is; a linear one otherwise keeps the constant operators (a comparison or a test).

``fields`` and ``residual(U, U_t, U_tt, force, W, p)`` (optional, together)
    More unknowns on the same mesh (P1 each), named in ``fields`` (e.g. ``("pressure",)``): the model then
    writes its residual over tuples, ``U = (η, *fields)`` and their derivatives, ``W = (w, *test_functions)``
    (the fields' test functions), instead of `momentum_form`, and every step is a Newton solve on the mixed space. The first
    component is η (ends held, contact on it); the others have no boundary condition and no bound unless
    the model gives them (below). They
    may enter through their values and first time derivatives (their second derivatives are not lumped).

``held_fields``, ``field_lower(p)``, ``dissipative_fields`` and ``schemes`` (optional, with ``fields``)
    The fields held at 0 on the boundary (η's fixed ends or boundary nodes); a lower bound per field name
    (a dict of floats: the step is then a variational inequality on those fields); the fields whose terms
    in η's equation dissipate (their work on η over a step is booked with the viscous dissipation); and the
    schemes that may run the model (empty: all), with ``scheme_note`` saying why the others may not.

``constants`` (optional)
    The model's own constants, a tuple of `ModelConstant` (name, default, allowed range, unit, one line): a
    scene sets them in its ``[parameters]`` table, Python through ``Scene.replace(parameters={...})``; the forms
    read each as a dolfinx ``Constant`` ``p.constants[name]``, so a value can change between steps without
    recompiling. ``check_constants(values)`` (optional) refuses combinations (a `SceneError` naming one).

``outputs`` (optional)
    The fields the model writes besides η, v, the contact set and force (`OutputField`: an unknown of
    ``fields`` by name, or a derived UFL expression of the unknowns, with how it is shown). Every unknown of
    ``fields`` is written whether named here or not.

``release`` (default ``"inelastic"``)
    How scheme `projection` lets a node that rests on the obstacle leave it: ``"inelastic"``, the paper's (A4),
    with the free step's velocity; ``"signorini"``, Signorini contact without (A4), as at the massless contact
    point of an elastic rod: the force that held the node still acts over the first half of the leapfrog's
    impulse cell, and the scheme starts at second order (`timestepping.release`). The other schemes have no
    release rule of their own (their penalty law decides).

``solver`` (optional)
    `SolverHints`: the model's defaults for its Newton step (``newton_options``) and its linear solver
    (``linear_options(dim, ranks, constants)``): above the schemes' defaults, below the user's options.

The paper's model (Definition 2.1) is the default: `inelastic`, every field at its default.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import ufl

from ..scene.parameters import ModelConstant
from .inelastic import contact_set, gap, momentum_form, penalty, penalty_damping, restitution_bound

__all__ = ["DIVERGING", "PENETRATION_BOUNDS", "SEQUENTIAL", "Model", "ModelConstant", "OutputField", "Parameters",
           "SolverHints", "inelastic", "output_fields", "penetration_bound_of", "reads_eps", "unused_fields"]

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


@dataclass(frozen=True)
class OutputField:
    """A field a model writes at every stored time: to `Result.fields[name]`, ``rows.npz``, ``solution.xdmf``, the
    pictures (``NAME.png``) and ParaView's view.

    `expression` is ``(U, p) -> UFL``, a scalar expression of the unknowns ``U = (η, *fields)`` and the
    `Parameters` `p`, interpolated into P1 at each stored time (a reaction, a flux); ``None``: the model's unknown
    of this `name` itself. How it is shown is metadata here, not code in the pictures: its `label` and `unit`;
    its `colours` (RGB triples in 0 … 1 from the least value through the middle to the largest); its `scale`,
    ``"linear"`` or ``"symlog"`` (symmetric about 0, linear within ``linear_share`` of its largest absolute value,
    logarithmic beyond: a landing's pressure peak is 1e3-1e4 times the pressure around it); `symmetric`, a range
    −P … P about 0 (a diverging field; ``"symlog"`` always is); `surface`, that it colours a membrane in the
    pictures and ParaView's view instead of the contact set (one field of a model at most).
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
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"OutputField: name must be an identifier, not {self.name!r}")
        if self.name in RESERVED:
            raise ValueError(f"OutputField {self.name!r}: a name every run stores already; choose another")
        if self.scale not in SCALES:
            raise ValueError(f"OutputField {self.name!r}: scale must be one of {', '.join(SCALES)}, not {self.scale!r}")
        if len(self.colours) < 2 or any(len(c) != 3 or not all(0 <= v <= 1 for v in c) for c in self.colours):
            raise ValueError(f"OutputField {self.name!r}: colours must be two or more RGB triples in 0 ... 1")
        if not 0 < self.linear_share < 1:
            raise ValueError(f"OutputField {self.name!r}: linear_share must be in (0, 1)")

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
    """How a model's Newton step is best solved: defaults, never physics; the user's PETSc options win.

    `newton_options`: (name, value) pairs of the PETSc options a scene may give (``(("snes_linesearch_type",
    "l2"),)``), above the schemes' defaults. `linear_options`: ``(dim, ranks, constants) -> pairs`` for the Newton
    step's linear solver on a mesh of dimension `dim` on `ranks` ranks with the model's constants (a dict of
    floats); naming ``ksp_type`` or ``pc_type`` replaces the size rule's choice
    (`timestepping.linear.solver_options`). `setup_bytes_per_node`: the memory a membrane's set-up takes per node
    with this model (mesh, operators, the Newton step's factor), measured; None: the core's estimate for one unknown
    per node (`scene.limits.SETUP_BYTES_PER_NODE`). A run's size is checked against it before the mesh is built.
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


def output_fields(model) -> tuple[OutputField, ...]:
    """The fields a model writes: its declared `outputs`, and for each of its unknowns (`Model.fields`) that none
    of them names, a plain `OutputField` of that name."""
    declared = tuple(getattr(model, "outputs", ()))
    named = {f.name for f in declared}
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

