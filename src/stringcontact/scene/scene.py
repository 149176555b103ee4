"""Scenes: the data of one simulation (geometry, time span, material, initial data), as TOML files.

A scene file looks like::

    description = "A string dropped on the obstacle"
    T = 0.3           # final time
    alpha = 0.01      # viscoelasticity
    nx = 5000         # cells
    dt = 0.0002       # or nt = 1500; dt must divide T
    eta0 = "1 + 0.5*sin(10*pi*x)**2"
    v0 = -50
    load = "-10"      # optional: external load f(x), for a model that reads it
    obstacle = "0"    # optional: obstacle profile psi(x), for a model that reads it
    model = "loaded_obstacle"  # optional: a registered model's name (`stringcontact models`)
    petsc_options = { ksp_type = "cg", pc_type = "hypre", ksp_rtol = 1e-12 }  # optional: the linear solver

    [scheme]          # optional: the time scheme (default "paper") and its options (what it declares)
    name = "paper"
    eps = 0.0005      # the penalty's ε (the penalty schemes need it)
    penalty = "semi-implicit"

Usage::

    scene = load_scene("example1")            # built-in, or a path to a .toml file
    coarse = scene.replace(nx=100, nt=30)     # a new, validated scene
    x = coarse.x()
    eta = coarse.initial_displacement(x)
    coarse.fields                             # {"load": "-10", ...}: only the fields the file gives
    f = coarse.field_values("load", x)

A membrane (2D) scene names a domain instead of ``length``/``nx``::

    domain = "rectangle"   # size = [Lx, Ly], cells = [nx, ny]; or "disk" (radius, mesh_size, centre 0),
    size = [1, 1]          # or mesh = "file.xdmf" (a triangle mesh); "interval" is the default (1D)
    cells = [32, 32]
    eta0 = "0.2 + 0.1*sin(pi*x)*sin(pi*y)"   # expressions in x and y
    h = "0.2"              # boundary height, an expression in x, y (default: eta0 on the boundary)

Every invalid value raises :class:`SceneError` with a one-line message naming the key
and what is allowed; doubtful but legal data (a string starting below the obstacle,
boundary heights that do not match ``eta0``) gives a :class:`SceneWarning`.
"""


from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from . import checks, expressions, names
from .limits import DOMAIN_KEYS, FIELD_KEYS, FILE_KEYS, REQUIRED_KEYS, SCHEME_KEYS_AT_TOP

__all__ = ["DeprecatedKeyWarning", "Scene", "SceneWarning"]


class SceneWarning(UserWarning):
    """Legal but doubtful scene data (reproduced as given, with a warning)."""


@dataclass(frozen=True)
class Scene:
    """One validated scene. Build it with :func:`load_scene`, :meth:`from_dict` or :meth:`replace`.

    ``eta0`` and ``v0`` are expressions in ``x`` (see :mod:`stringcontact.scene.expressions`), or for a string
    its nx + 1 nodal values in the order of x (a tuple of floats; a restart from a `Stepper`'s state);
    ``h_left``/``h_right`` are the (resolved) heights at which the ends are held.
    ``load`` (an external force density f) and ``obstacle`` (a profile ψ) are optional expressions
    in ``x`` too; they are data for a model that reads them (``loaded_obstacle``),
    available as :attr:`fields`.
    Direct construction validates too, but resolves no defaults and gives no warnings.
    """

    name: str
    length: float
    T: float
    alpha: float
    eps: float | None  # None: not given, under scheme "projection" only (which does not read it)
    nx: int  # cells
    nt: int  # time steps
    eta0: str | tuple  # initial displacement, expression in x (1D: or nx + 1 nodal values)
    v0: str | tuple  # initial velocity, expression in x (1D: or nx + 1 nodal values)
    h_left: float  # height of the left end
    h_right: float  # height of the right end
    h: float | None = None  # the single h if the file gave one (also an expression variable)
    output_times: tuple[float, ...] = ()
    description: str = ""
    notes: str = ""  # interpretations of the source data
    model: str | None = None  # a registered model name (`stringcontact models`), never a module path
    load: str | None = None  # external load f(x), expression in x (None: not given)
    obstacle: str | None = None  # obstacle profile psi(x), expression in x (None: not given)
    scheme: str | None = None  # a name in stringcontact.SCHEMES (None: "paper")
    domain: str = "interval"  # one of DOMAIN_KEYS; 2D domains have length, nx, h_left, h_right None
    size: tuple | None = None  # rectangle [Lx, Ly]
    cells: tuple | None = None  # rectangle [nx, ny]
    radius: float | None = None  # disk, centred at the origin
    mesh_size: float | None = None  # disk: gmsh's largest element size
    mesh: str | None = None  # file: path of an XDMF triangle mesh
    petsc_options: tuple = ()  # (name, value) pairs for the linear solver (`check_petsc_options`)
    restitution: float | None = None  # scheme 'projection's restitution coefficient e in [0, 1] (None: 0)
    parameters: tuple = ()  # (name, value) pairs: the model's constants the scene gives ([parameters])
    options: tuple = ()  # (name, value) pairs: the [scheme] table's other options (penalty, mass, a scheme's own)

    @property
    def dim(self) -> int:
        """1 on the interval (a string), 2 on the membrane domains."""
        return 1 if self.domain == "interval" else 2

    def __post_init__(self):
        # Normalise in place (frozen, hence object.__setattr__): ints to floats, lists to tuples.
        def put(key, value):
            object.__setattr__(self, key, value)

        put("name", checks.check_name(self.name))
        checks.check_domain(self, put)
        numbers = ("T", "alpha") + (("eps",) if self.eps is not None else ())
        for key in numbers + (("length", "h_left", "h_right") if self.dim == 1 else ()):
            put(key, checks.number(key, getattr(self, key)))
        if self.dim == 1:
            put("nx", checks.integer("nx", self.nx))
        put("nt", checks.integer("nt", self.nt))
        if self.dim == 2:
            if self.h is not None:
                put("h", checks.expression_text("h", self.h) if isinstance(self.h, str) else checks.number("h", self.h))
        elif self.h is not None:
            put("h", checks.number("h", self.h))
            if self.h_left != self.h or self.h_right != self.h:
                raise SceneError(
                    f"h: h = {checks.fmt(self.h)} but h_left = {checks.fmt(self.h_left)}, h_right = {checks.fmt(self.h_right)}; "
                    "give either h or h_left/h_right"
                )
        for key in ("description", "notes"):
            put(key, checks.text(key, getattr(self, key)))
        if self.model is not None:
            put("model", checks.check_model(self.model))
        if self.scheme is not None:
            put("scheme", checks.check_scheme(self.scheme))
        if self.restitution is not None:
            put("restitution", checks.number("restitution", self.restitution))
        put("options", checks.check_scheme_options(self.options))
        checks.check_parameters(self, put)
        put("output_times", checks.check_output_times(self.output_times, self.T))
        options = self.petsc_options
        put("petsc_options", checks.check_petsc_options(dict(options) if isinstance(options, tuple) else options))
        if self.dim == 1:
            checks.check_storage(self.node_estimate - 1, self.nt, len(self.output_times))
        else:  # the solver thins a membrane's rows to its budget (solver.ROW_BUDGET): 0, T and the output times must fit
            checks.check_membrane_storage(self.node_estimate, len(self.output_times))
        for key in ("eta0", "v0"):
            put(key, checks.initial_data(key, getattr(self, key)))
            if isinstance(getattr(self, key), tuple):
                checks.check_nodal_values(key, getattr(self, key), self.nx if self.dim == 1 else None)
        keys = tuple(k for k in ("eta0", "v0") if isinstance(getattr(self, k), str))
        keys += tuple(self.fields) + (("h",) if isinstance(self.h, str) else ())
        for key in keys:
            put(key, checks.expression_text(key, getattr(self, key)))
            for t in (0.0, self.T / 2, self.T) if key == "obstacle" else (0.0,):  # a moving obstacle over [0, T]
                if self.dim == 1:
                    expressions.check(getattr(self, key), field=key, names=self._names(key, t))
                else:
                    self._evaluate(key, getattr(self, key), self.probe_points(), t)
        if self.dim == 1:
            self._check_ends()

    def _check_ends(self) -> None:
        """1D: refuse an end held inside the obstacle (its height below ψ there), whose node no scheme can move: the
        penalty schemes push the string up from it and projection lifts every other node onto ψ, so the run would
        answer another question. An end on the obstacle (h = ψ, Example 2's left end) is allowed. A moving obstacle
        is checked at t = 0: one that later rises over a held end (a piston as wide as the string) is run as given,
        the end held at h and the string next to it carried up from it."""
        ends = np.array([0.0, self.length])
        for t in (0.0,):
            psi = self.obstacle_values(ends, t)
            for side, key, height, at, value in (("left", "h_left", self.h_left, 0.0, psi[0]),
                                                 ("right", "h_right", self.h_right, self.length, psi[1])):
                if height < value and not checks.close(height, float(value)):
                    name = "h" if self.h is not None else key
                    obstacle = f"the obstacle {self.obstacle!r}" if self.obstacle is not None else "the obstacle psi = 0"
                    when = f" at t = {checks.fmt(t)}" if self.obstacle_moves else ""
                    raise SceneError(
                        f"{name}: the {side} end is held at {checks.fmt(height)}, inside {obstacle}, which is "
                        f"{float(value):.6g} at x = {checks.fmt(at)}{when}; allowed: {name} >= the obstacle at the "
                        "ends (an end on or above it)")

    # --- derived quantities -----------------------------------------------------------

    @property
    def dt(self) -> float:
        """Time step T/nt."""
        return self.T / self.nt

    @property
    def dx(self) -> float:
        """Mesh size: length/nx; in 2D the largest cell side of the rectangle, the disk's mesh_size (nan for a file)."""
        if self.domain == "rectangle":
            return max(L / n for L, n in zip(self.size, self.cells))
        if self.domain == "disk":
            return self.mesh_size
        return self.length / self.nx if self.dim == 1 else math.nan

    @property
    def node_estimate(self) -> int:
        """The number of nodes (exact for the interval and the rectangle; about, for the disk; 1 for a file)."""
        if self.domain == "rectangle":
            return (self.cells[0] + 1) * (self.cells[1] + 1)
        if self.domain == "disk":  # a Delaunay mesh has about 2/√3 nodes per h²
            return round(2 / math.sqrt(3) * math.pi * (self.radius / self.mesh_size) ** 2) + 1
        return self.nx + 1 if self.dim == 1 else 1

    def probe_points(self) -> np.ndarray:
        """2D: points at which the scene checks its expressions before a mesh exists, shape (k, 2).

        The rectangle's nodes (up to 41 x 41 of them), a polar grid in the disk, none for a mesh file (its
        expressions are checked for names and syntax here, for values at its nodes in the solver).
        """
        if self.domain == "rectangle":
            xs = [np.linspace(0.0, L, min(n, 40) + 1) for L, n in zip(self.size, self.cells)]
            X, Y = np.meshgrid(*xs, indexing="ij")
            return np.column_stack([X.ravel(), Y.ravel()])
        if self.domain == "disk":
            r, th = np.meshgrid(np.linspace(0.0, self.radius * (1 - 1e-9), 11),  # inside: sqrt(R²-r²) is fine
                                np.linspace(0.0, 2 * np.pi, 24, endpoint=False))
            return np.column_stack([(r * np.cos(th)).ravel(), (r * np.sin(th)).ravel()])
        return np.zeros((0, 2))

    def _evaluate(self, key: str, expr, points, t: float = 0.0) -> np.ndarray:
        """`expr` at the points: (N,) in 1D, (N, 2) in 2D; the obstacle at the time t. Nodal values (a tuple, 1D):
        their piecewise-linear interpolant, exact at the nodes."""
        p = np.asarray(points, dtype=float)
        if isinstance(expr, tuple):
            return np.interp(p.reshape(-1), self.x(), np.asarray(expr))
        if self.dim == 1:
            return expressions.evaluate(expr, p, field=key, names=self._names(key, t))
        return expressions.evaluate(expr, p[:, 0], field=key, names=self._names(key, t), y=p[:, 1])

    def boundary_height(self, points) -> np.ndarray:
        """2D: the height at which the boundary is held at the points (N, 2): h, else eta0 there."""
        if self.h is None:
            return self.initial_displacement(points)
        return self._evaluate("h", self.h if isinstance(self.h, str) else repr(float(self.h)), points)

    @property
    def r(self) -> float:
        """dt/eps, the penalty's weight per step (explicit penalty: large r means trouble); nan without eps."""
        return self.dt / self.eps if self.eps is not None else math.nan

    def x(self) -> np.ndarray:
        """Node coordinates, shape (nx+1,) (1D only: a 2D mesh's nodes come from the solver)."""
        if self.dim != 1:
            raise ValueError(f"scene {self.name!r}: x() is for the interval; domain {self.domain!r} has a 2D mesh")
        return np.linspace(0.0, self.length, self.nx + 1)

    def initial_displacement(self, x) -> np.ndarray:
        """eta0 at the points x, (N,) in 1D or (N, 2) in 2D (as given: the boundary values are not replaced)."""
        return self._evaluate("eta0", self.eta0, x)

    def initial_velocity(self, x) -> np.ndarray:
        """v0 at the points x (as given: the solver holds the boundary, so its velocity is ignored)."""
        return self._evaluate("v0", self.v0, x)

    @property
    def fields(self) -> dict[str, str]:
        """The optional expression fields the scene gives (``load``, ``obstacle``), name -> expression.

        The solver interpolates each into a P1 function and hands it to the model as
        ``Parameters.extra[name]``.
        """
        return {key: getattr(self, key) for key in FIELD_KEYS if getattr(self, key) is not None}

    def field_values(self, name: str, x, t: float = 0.0) -> np.ndarray:
        """The field `name` (a key of :attr:`fields`) at the points x (the obstacle at the time t)."""
        fields = self.fields
        if name not in fields:
            given = ", ".join(fields) or "none"
            raise SceneError(f"{name}: the scene gives no field {name!r} (fields given: {given})")
        return self._evaluate(name, fields[name], x, t)

    def obstacle_values(self, x, t: float = 0.0) -> np.ndarray:
        """The obstacle profile ψ at the points x and the time t: the ``obstacle`` field, or 0 (the paper's y = 0)."""
        x = np.asarray(x, dtype=float)
        return self.field_values("obstacle", x, t) if self.obstacle is not None else np.zeros(x.shape[:1])

    @property
    def scheme_options(self) -> dict:
        """The scheme's options the scene gives (its ``[scheme]`` table but the name), by name: what the run checks
        against the scheme's own declaration (`timestepping.base.SchemeOption`)."""
        given = {k: v for k, v in (("eps", self.eps), ("restitution", self.restitution)) if v is not None}
        return given | dict(self.options)

    @property
    def obstacle_moves(self) -> bool:
        """Whether the obstacle is an expression in t (a moving obstacle ψ(x, t))."""
        return self.obstacle is not None and expressions.uses_name(self.obstacle, "t")

    def _names(self, key: str = "", t: float = 0.0) -> dict[str, float]:
        """The scalar names of `key`'s expressions: l (1D), h (a single height), t (the obstacle only)."""
        names = {"l": self.length} if self.dim == 1 else {}
        if key == "obstacle":
            names["t"] = t
        if self.h is not None and not isinstance(self.h, str):
            names["h"] = self.h
        return names

    # --- conversions ----------------------------------------------------------------------

    def as_dict(self) -> dict:
        """The scene as file keys (TOML-like; ``Scene.from_dict(s.as_dict()) == s``).

        Gives nt (not dt), and h if the scene has a single h, else h_left/h_right.
        """
        if self.dim == 2:
            return self._as_dict_2d()
        d = {
            "name": self.name,
            "description": self.description,
            "notes": self.notes,
            "length": self.length,
            "T": self.T,
            "alpha": self.alpha,
            "nx": self.nx,
            "nt": self.nt,
            "eta0": list(self.eta0) if isinstance(self.eta0, tuple) else self.eta0,
            "v0": list(self.v0) if isinstance(self.v0, tuple) else self.v0,
        }
        if self.h is not None:
            d["h"] = self.h
        else:
            d["h_left"] = self.h_left
            d["h_right"] = self.h_right
        d.update(self.fields)
        d["output_times"] = list(self.output_times)
        if self.model is not None:
            d["model"] = self.model
        d.update(self._tables())
        return d

    def _tables(self) -> dict:
        """The scheme (a name, or a [scheme] table with its options) and the TOML tables, last (a table ends the
        file's plain keys): scheme, parameters, petsc_options, where given."""
        options = self.scheme_options
        scheme = ({"scheme": self.scheme} if self.scheme is not None and not options else
                  {"scheme": ({"name": self.scheme} if self.scheme is not None else {}) | options} if options else {})
        return scheme | {key: dict(getattr(self, key)) for key in ("parameters", "petsc_options") if getattr(self, key)}

    def _as_dict_2d(self) -> dict:
        d = {"name": self.name, "description": self.description, "notes": self.notes, "domain": self.domain}
        d.update({key: list(v) if isinstance(v := getattr(self, key), tuple) else v for key in DOMAIN_KEYS[self.domain]})
        d.update({"T": self.T, "alpha": self.alpha, "nt": self.nt, "eta0": self.eta0, "v0": self.v0})
        if self.h is not None:
            d["h"] = self.h
        d.update(self.fields)
        d["output_times"] = list(self.output_times)
        if self.model is not None:
            d["model"] = self.model
        d.update(self._tables())
        return d

    @classmethod
    def from_dict(cls, data: dict, *, source: str | None = None, default_name: str | None = None) -> Scene:
        """Build a scene from file keys: checks keys, resolves defaults, validates, warns.

        ``source`` (a file or scene name) prefixes error and warning messages.
        """
        return cls._from_dict(data, source, default_name, warn=True)

    @classmethod
    def _from_dict(cls, data: dict, source, default_name, warn: bool) -> Scene:
        label = source if source is not None else str(data.get("name", default_name or "scene"))
        try:
            data = _top_level_constants(dict(data), data.get("model"), label)
            data, options, top = _scheme_table(data)
            scene = _build(data, default_name=default_name, options=options)
            x, values = _grid_values(scene)
            checks.check_magnitudes(values)
            _warn_doubtful(scene, label, x, values)
            if top and warn:  # once the scene is valid: a refused one says one line only
                warnings.warn(f"scene {label!r}: {', '.join(top)} at the top level: the scheme's option"
                              f"{'s' if len(top) > 1 else ''}; write {'them' if len(top) > 1 else 'it'} in the [scheme] "
                              "table", SceneWarning, stacklevel=3)
        except SceneError as exc:
            raise SceneError(f"scene {label!r}: {exc}") from None
        return scene

    def replace(self, **changes) -> Scene:
        """A new validated scene with some file keys changed (the same keys as a scene file).

        Rules, so that a change means what it says:

        * ``dt`` replaces ``nt``; changing ``T`` alone keeps ``nt`` (so dt changes);
          changing ``length`` keeps ``nx`` (so dx changes);
        * ``h`` replaces ``h_left``/``h_right`` and vice versa;
        * when ``eta0`` or ``length`` changes and no boundary height is given, an end
          height that equalled eta0's old end value follows the new eta0;
        * a value of ``None`` removes the key (e.g. ``h=None``, ``model=None``);
        * ``parameters`` (the model's constants, a dict) replaces the whole table;
        * ``scheme`` a name keeps the scheme's options, a table (``{"name": ..., "mass": ...}``) replaces them;
          ``eps`` and ``restitution`` set the one option each.
        """
        changes = _top_level_constants(changes, changes.get("model", self.model), self.name, self.parameters)
        checks.check_keys(changes)
        data = self.as_dict()
        domain = changes.get("domain") or ("file" if changes.get("mesh") else self.domain)
        if domain != self.domain:  # the old domain's geometry keys go (1D: also the end heights)
            for key in DOMAIN_KEYS.get(self.domain, ()) + ("h", "domain"):
                if key not in changes:
                    data.pop(key, None)
        if "dt" in changes:
            data.pop("nt", None)
        if "h" in changes:
            data.pop("h_left", None)
            data.pop("h_right", None)
        elif "h_left" in changes or "h_right" in changes:
            data.pop("h", None)
            data.setdefault("h_left", self.h_left)
            data.setdefault("h_right", self.h_right)
        elif ("eta0" in changes or "length" in changes) and self.h is None and self.dim == 1 and domain == self.domain:
            ends = self.initial_displacement(np.array([0.0, self.length]))
            for key, end in (("h_left", ends[0]), ("h_right", ends[1])):
                if checks.close(getattr(self, key), end):
                    data.pop(key)  # it followed eta0 before, so it follows the new one
        table = data.pop("scheme", None)
        table = dict(table) if isinstance(table, dict) else ({"name": table} if table is not None else {})
        if "scheme" in changes:
            new = changes.pop("scheme")
            table = dict(new) if isinstance(new, dict) else ({k: v for k, v in table.items() if k != "name"}
                                                             | ({"name": new} if new is not None else {}))
        for key in SCHEME_KEYS_AT_TOP:  # the Python shorthand: scene.replace(eps=...) sets the [scheme] table's eps
            if key in changes:
                value = changes.pop(key)
                table.pop(key, None) if value is None else table.__setitem__(key, value)
        if table:
            data["scheme"] = table
        for key, value in changes.items():
            if value is None:
                data.pop(key, None)
            else:
                data[key] = value
        return Scene._from_dict(data, self.name, None, warn=False)


# --- building and validating ------------------------------------------------------------------


def _top_level_constants(data: dict, model, label: str, table=()) -> dict:
    """`data` with the top-level keys that the named `model` declares as constants moved into its ``parameters``
    table (on top of `table`), with a one-line `SceneWarning`. The model is loaded only when `data`
    has keys a scene does not know."""
    unknown = [k for k in data if k not in FILE_KEYS]
    if not unknown or not isinstance(model, str) or model not in names.registered():
        return data
    declared = {c.name for c in names.declared(model)[0]}
    moved = [k for k in unknown if k in declared]
    if not moved:
        return data
    data = dict(data)
    merged = dict(data.get("parameters") or table)
    for key in moved:
        if key in merged and key in (data.get("parameters") or {}):
            raise SceneError(f"{key}: given twice, at the top level and in [parameters]; keep the one in [parameters]")
        merged[key] = data.pop(key)
    data["parameters"] = merged
    warnings.warn(f"scene {label!r}: {', '.join(moved)} at the top level of a scene is deprecated; put "
                  f"{'it' if len(moved) == 1 else 'them'} in the [parameters] table (model {model!r})",
                  SceneWarning, stacklevel=4)
    return data


def _scheme_table(data: dict) -> tuple[dict, tuple, list]:
    """`data` with a ``[scheme]`` table taken apart: its name as ``scheme``, its eps and restitution as those keys, its
    other options as (name, value) pairs; and the keys given at the top level of the file (they still work, with one
    warning saying where they go; in both places at once they are refused)."""
    top = [k for k in SCHEME_KEYS_AT_TOP if k in data]
    table = data.get("scheme")
    if not isinstance(table, dict):
        return data, (), top
    data = dict(data)
    table = dict(table)
    name = table.pop("name", None)
    for key in SCHEME_KEYS_AT_TOP:
        if key in table:
            if key in data:
                raise SceneError(f"{key}: given twice, at the top level and in [scheme]; keep the one in [scheme]")
            data[key] = table.pop(key)
    if name is None:
        data.pop("scheme")
    else:
        data["scheme"] = name
    return data, tuple(table.items()), top


def _build_2d(data: dict, domain: str, name: str, T: float, nt: int, options: tuple) -> Scene:
    """A membrane scene: the geometry keys of `domain` (checked in Scene), no ends."""
    geometry = {key: data[key] for key in DOMAIN_KEYS[domain] if key in data}
    if domain == "rectangle":
        geometry.setdefault("size", [1.0, 1.0])
    if domain == "disk":
        geometry.setdefault("radius", 1.0)
    output_times = data.get("output_times", ())
    return Scene(
        name=name, length=None, T=T, alpha=data["alpha"], eps=data.get("eps"), nx=None, nt=nt,
        eta0=checks.expression_text("eta0", data["eta0"]), v0=data["v0"], h_left=None, h_right=None, h=data.get("h"),
        output_times=tuple(output_times) if isinstance(output_times, (list, tuple)) else output_times,
        description=data.get("description", ""), notes=data.get("notes", ""), model=data.get("model"),
        scheme=data.get("scheme"), restitution=data.get("restitution"), domain=domain, **geometry, **{key: data[key] for key in FIELD_KEYS if key in data},
        petsc_options=checks.check_petsc_options(data.get("petsc_options", {})),
        parameters=data.get("parameters", ()), options=options,
    )


def _build(data: dict, *, default_name: str | None, options: tuple = ()) -> Scene:
    checks.check_keys(data)
    domain = checks.domain_of(data)
    checks.check_domain_keys(data, domain)
    required = REQUIRED_KEYS if domain == "interval" else tuple(k for k in REQUIRED_KEYS if k != "nx")
    missing = [k for k in required if k not in data]
    if missing or ("nt" not in data and "dt" not in data):
        parts = ", ".join(missing)
        if "nt" not in data and "dt" not in data:
            parts = f"{parts} and one of nt or dt" if parts else "one of nt or dt"
        raise SceneError(f"missing required key(s): {parts}")
    if "nt" in data and "dt" in data:
        raise SceneError("nt, dt: give exactly one of nt or dt, not both")
    if "h" in data and ("h_left" in data or "h_right" in data):
        raise SceneError("h: give either h (both ends) or h_left/h_right, not both")

    name = data.get("name", default_name or "scene")
    T = checks.number("T", data["T"])
    nt = checks.nt_from_dt(data["dt"], T) if "dt" in data else checks.integer("nt", data["nt"])
    if domain != "interval":
        return _build_2d(data, domain, name, T, nt, options)
    length = checks.number("length", data.get("length", 1.0))
    h = checks.number("h", data["h"]) if "h" in data else None
    eta0 = checks.initial_data("eta0", data["eta0"])

    names = {"l": length} if h is None else {"l": length, "h": h}
    if h is not None:
        h_left = h_right = h
    else:
        # The ends default to eta0's end values: a string held where it starts.
        need = [k for k in ("h_left", "h_right") if k not in data]
        if isinstance(eta0, tuple):
            ends = (eta0[0], eta0[-1])
        else:
            expressions.check(eta0, field="eta0", names=names)
            ends = expressions.evaluate(eta0, np.array([0.0, length]), field="eta0", names=names) if need else (None, None)
        h_left = data["h_left"] if "h_left" in data else float(ends[0])
        h_right = data["h_right"] if "h_right" in data else float(ends[1])

    output_times = data.get("output_times", ())
    if isinstance(output_times, (list, tuple)):
        output_times = tuple(output_times)
    return Scene(
        name=name,
        length=length,
        T=T,
        alpha=data["alpha"],
        eps=data.get("eps"),
        nx=data["nx"],
        nt=nt,
        eta0=eta0,
        v0=data["v0"],
        h_left=h_left,
        h_right=h_right,
        h=h,
        output_times=output_times,
        description=data.get("description", ""),
        notes=data.get("notes", ""),
        model=data.get("model"),
        scheme=data.get("scheme"),
        restitution=data.get("restitution"),
        **{key: data[key] for key in FIELD_KEYS if key in data},
        petsc_options=checks.check_petsc_options(data.get("petsc_options", {})),
        parameters=data.get("parameters", ()),
        options=options,
    )


def _grid_values(scene: Scene) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The nodes x and eta0, v0 and the scene's fields at them (checks finiteness on the real grid, not just the probe)."""
    x = scene.x() if scene.dim == 1 else scene.probe_points()
    values = {"eta0": scene.initial_displacement(x), "v0": scene.initial_velocity(x)}
    values.update({key: scene.field_values(key, x) for key in scene.fields})
    return x, values


def _warn_doubtful(scene: Scene, label: str, x: np.ndarray, values: dict[str, np.ndarray]) -> None:
    """Warn (not refuse) about data that is legal but probably not what was meant. `values`: `_grid_values` at x."""
    eta = values["eta0"]
    psi = values.get("obstacle", np.zeros_like(eta))  # the obstacle profile, or the paper's y = 0
    below = eta < psi
    if below.any():
        gap = eta - psi
        i = int(np.argmin(gap))
        what = "eta0 < 0" if scene.obstacle is None else "eta0 < obstacle"
        where = f"x={x[i]:.6g}" if x.ndim == 1 else f"x={x[i, 0]:.6g}, y={x[i, 1]:.6g}"
        at = f"min {eta[i]:.6g}" if scene.obstacle is None else f"min eta0 - obstacle {gap[i]:.6g}"
        warnings.warn(
            f"scene {label!r}: eta0 is below the obstacle ({what}) at {int(below.sum())} of {len(x)} nodes "
            f"({at} at {where}); used as given",
            SceneWarning,
            stacklevel=4,
        )
    if scene.dim == 2:
        return  # the end-height check is 1D-only: a membrane's boundary is held at h (default: eta0 there)
    ends = (("h_left", scene.h_left, eta[0], 0.0), ("h_right", scene.h_right, eta[-1], scene.length))
    for key, value, end, at in ends:
        if not checks.close(value, end):
            warnings.warn(
                f"scene {label!r}: {key} = {checks.fmt(value)} differs from eta0 at x={checks.fmt(at)} ({end:.6g}); "
                f"the end is held at {key}",
                SceneWarning,
                stacklevel=4,
            )


