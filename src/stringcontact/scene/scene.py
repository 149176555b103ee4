"""Scenes: the data of one simulation (domain, time span, material, initial data), checked key by key.

A scene file is TOML (``T = 0.3``, ``nx = 5000``, ``eta0 = "1 + 0.5*sin(10*pi*x)**2"``, a ``[scheme]`` table, ...;
docs/reference/scene_keys.md lists every key). ``load_scene("example1").replace(nx=100, nt=30)`` is a new, checked
scene. Every invalid value raises `SceneError`, one line naming the key and what is allowed; legal but doubtful data
(a string starting below the obstacle, ends held away from eta0) gives a `SceneWarning`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from . import checks, expressions, names
from .limits import DOMAIN_KEYS, FIELD_KEYS, FILE_KEYS, REQUIRED_KEYS, SCHEME_KEYS_AT_TOP

__all__ = ["Scene", "SceneWarning"]


class SceneWarning(UserWarning):
    """Legal but doubtful scene data (reproduced as given, with a warning)."""


#: Each plain value's check, (key, value) -> the value normalised, in order; None (not given) only where needed.
_CHECKS = {**dict.fromkeys(("T", "alpha", "eps", "length", "h_left", "h_right"), checks.number),
           **dict.fromkeys(("nx", "nt"), checks.integer), **dict.fromkeys(("description", "notes"), checks.text),
           "model": lambda key, value: names.check_name(value), "scheme": checks.check_scheme,
           "restitution": checks.number, "options": checks.check_scheme_options}
_NEEDED = ("T", "alpha", "nt", "description", "notes")  # and on the interval its keys


@dataclass(frozen=True)
class Scene:
    """One validated scene. Build it with :func:`load_scene`, :meth:`from_dict` or :meth:`replace`.

    ``eta0`` and ``v0`` are expressions in ``x`` (:mod:`stringcontact.scene.expressions`), or for a string its
    nx + 1 nodal values (a restart from a state); ``h_left``/``h_right`` are the (resolved) heights of the ends;
    ``load`` and ``obstacle`` are optional expressions for a model that reads them (:attr:`fields`). Direct
    construction validates too, but resolves no defaults and gives no warnings.
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
    fields0: tuple = ()  # (name, value) pairs: the initial values of the model's further unknowns, as eta0's

    @property
    def dim(self) -> int:
        """1 on the interval (a string), 2 on the membrane domains."""
        return 1 if self.domain == "interval" else 2

    def __post_init__(self):
        def put(key, value):  # frozen: normalised in place (ints to floats, lists to tuples)
            object.__setattr__(self, key, value)

        put("name", checks.check_name(self.name))
        checks.check_domain(self, put)
        for key, check in _CHECKS.items():
            if getattr(self, key) is not None or key in _NEEDED or self.dim == 1 and key in DOMAIN_KEYS["interval"]:
                put(key, check(key, getattr(self, key)))
        if self.h is not None:
            h_is_text = isinstance(self.h, str) and self.dim == 2
            put("h", checks.expression_text("h", self.h) if h_is_text else checks.number("h", self.h))
            if self.dim == 1 and (self.h_left != self.h or self.h_right != self.h):
                raise SceneError(f"h: h = {checks.fmt(self.h)} but h_left = {checks.fmt(self.h_left)}, h_right = "
                                 f"{checks.fmt(self.h_right)}; give either h or h_left/h_right")
        checks.check_parameters(self, put)
        put("output_times", checks.check_output_times(self.output_times, self.T))
        put("petsc_options", checks.check_petsc_options(dict(o) if isinstance(o := self.petsc_options, tuple) else o))
        checks.check_storage(self)
        nx = self.nx if self.dim == 1 else None
        for key in ("eta0", "v0"):
            put(key, checks.initial_values(key, getattr(self, key), nx))
        put("fields0", checks.initial_fields(self.fields0, nx))
        for name, value in self.fields0:
            if isinstance(value, str):
                self._evaluate(f"fields0.{name}", value, self.probe_points())
        for key in ("eta0", "v0", *FIELD_KEYS, "h"):
            value = getattr(self, key)
            if isinstance(value, str) or (key in FIELD_KEYS and value is not None):
                put(key, checks.expression_text(key, value))
                for t in (0.0, self.T / 2, self.T) if key == "obstacle" else (0.0,):  # a moving one over [0, T]
                    self._evaluate(key, getattr(self, key), self.probe_points(), t)
        if self.dim == 1:  # an end held inside the obstacle at t = 0: no scheme can move a held node (on it is fine)
            psi = self.obstacle_values(np.array([0.0, self.length]))
            for side, key, at, value in (("left", "h_left", 0.0, psi[0]), ("right", "h_right", self.length, psi[1])):
                height = getattr(self, key)
                if height < value and not checks.close(height, float(value)):
                    name = "h" if self.h is not None else key
                    obstacle = "the obstacle " + (repr(self.obstacle) if self.obstacle is not None else "psi = 0")
                    when = " at t = 0" if self.obstacle_moves else ""
                    raise SceneError(f"{name}: the {side} end is held at {checks.fmt(height)}, inside {obstacle}, which "
                                     f"is {float(value):.6g} at x = {checks.fmt(at)}{when}; allowed: {name} >= the "
                                     "obstacle at the ends (an end on or above it)")

    @property
    def dt(self) -> float:
        """Time step T/nt."""
        return self.T / self.nt

    @property
    def dx(self) -> float:
        """Mesh size: length/nx; the rectangle's largest cell side, the disk's mesh_size (nan for a file)."""
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
        """Points at which the scene checks its expressions before a mesh exists: 101 on the interval, the rectangle's
        nodes (up to 41 x 41), a polar grid in the disk, none for a mesh file."""
        if self.domain == "interval":
            return np.linspace(0.0, self.length, expressions.PROBE_POINTS)
        if self.domain == "rectangle":
            xs = [np.linspace(0.0, L, min(n, 40) + 1) for L, n in zip(self.size, self.cells)]
            return np.column_stack([X.ravel() for X in np.meshgrid(*xs, indexing="ij")])
        if self.domain == "disk":
            r, th = np.meshgrid(np.linspace(0.0, self.radius * (1 - 1e-9), 11),  # inside: sqrt(R²-r²) is fine
                                np.linspace(0.0, 2 * np.pi, 24, endpoint=False))
            return np.column_stack([(r * np.cos(th)).ravel(), (r * np.sin(th)).ravel()])
        return np.zeros((0, 2))

    def _evaluate(self, key: str, expr, points, t: float = 0.0) -> np.ndarray:
        """`expr` at the points, (N,) or (N, 2), with the names l (1D), h (a single height), t (the obstacle only);
        nodal values (a tuple): their piecewise-linear interpolant."""
        p = np.asarray(points, dtype=float)
        if isinstance(expr, tuple):
            return np.interp(p.reshape(-1), self.x(), np.asarray(expr))
        names = ({"l": self.length} if self.dim == 1 else {}) | ({"t": t} if key == "obstacle" else {})
        names |= {"h": self.h} if self.h is not None and not isinstance(self.h, str) else {}
        y = {} if self.dim == 1 else {"y": p[:, 1]}
        return expressions.evaluate(expr, p if self.dim == 1 else p[:, 0], field=key, names=names, **y)

    def boundary_height(self, points) -> np.ndarray:
        """2D: the height at which the boundary is held at the points (N, 2): h, else eta0 there."""
        return (self.initial_displacement(points) if self.h is None else
                self._evaluate("h", checks.expression_text("h", self.h), points))

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

    def initial_field(self, name: str, x) -> np.ndarray:
        """The further unknown `name`'s initial value (``fields0``) at the points x."""
        return self._evaluate(f"fields0.{name}", dict(self.fields0)[name], x)

    def initial_velocity(self, x) -> np.ndarray:
        """v0 at the points x (as given: the solver holds the boundary, so its velocity is ignored)."""
        return self._evaluate("v0", self.v0, x)

    @property
    def fields(self) -> dict[str, str]:
        """The optional expression fields the scene gives (``load``, ``obstacle``), name -> expression: the model's
        ``Parameters.extra[name]``."""
        return {key: getattr(self, key) for key in FIELD_KEYS if getattr(self, key) is not None}

    def field_values(self, name: str, x, t: float = 0.0) -> np.ndarray:
        """The field `name` (a key of :attr:`fields`) at the points x (the obstacle at the time t)."""
        fields = self.fields
        if name not in fields:
            raise SceneError(f"{name}: the scene gives no field {name!r} (fields given: {', '.join(fields) or 'none'})")
        return self._evaluate(name, fields[name], x, t)

    def obstacle_values(self, x, t: float = 0.0) -> np.ndarray:
        """The obstacle profile ψ at the points x and the time t: the ``obstacle`` field, or 0 (the paper's y = 0)."""
        x = np.asarray(x, dtype=float)
        return self.field_values("obstacle", x, t) if self.obstacle is not None else np.zeros(x.shape[:1])

    @property
    def scheme_options(self) -> dict:
        """The scheme's options the scene gives (its ``[scheme]`` table but the name), by name."""
        given = {k: v for k, v in (("eps", self.eps), ("restitution", self.restitution)) if v is not None}
        return given | dict(self.options)

    @property
    def obstacle_moves(self) -> bool:
        """Whether the obstacle is an expression in t (a moving obstacle ψ(x, t))."""
        return self.obstacle is not None and expressions.uses_name(self.obstacle, "t")

    def as_dict(self) -> dict:
        """The scene as file keys in the order of `FILE_KEYS` (``Scene.from_dict(s.as_dict()) == s``): nt, not dt."""
        omit = {"dt", "eps", "restitution"} | ({"domain"} if self.dim == 1 else set())
        omit |= {"h_left", "h_right"} if self.h is not None else set()
        d = {}
        for key in FILE_KEYS:
            value = None if key in omit else getattr(self, key)
            if key in ("parameters", "petsc_options", "fields0"):
                value = {k: list(v) if isinstance(v, tuple) else v for k, v in value} or None
            elif key == "scheme":
                options = self.scheme_options
                value = ({"name": value} if value is not None else {}) | options if options else value
            if value is not None or key in ("description", "notes"):
                d[key] = list(value) if isinstance(value, tuple) else value
        return d

    @classmethod
    def from_dict(cls, data: dict, *, source: str | None = None, default_name: str | None = None) -> Scene:
        """Build a scene from file keys: checks, defaults, warnings; ``source`` prefixes the messages."""
        label = source if source is not None else str(data.get("name", default_name or "scene"))
        try:
            data = _top_level_constants(dict(data), data.get("model"), label)
            data, options, top = _scheme_table(data)
            scene = _build(data, default_name=default_name, options=options)
            _warn_doubtful(scene, label)
            if top:  # once the scene is valid: a refused one says one line only
                many = len(top) > 1
                warnings.warn(f"scene {label!r}: {', '.join(top)} at the top level: the scheme's option"
                              f"{'s' if many else ''}; write {'them' if many else 'it'} in the [scheme] table",
                              SceneWarning, stacklevel=2)
        except SceneError as exc:
            raise SceneError(f"scene {label!r}: {exc}") from None
        return scene

    def replace(self, **changes) -> Scene:
        """A new validated scene with some file keys changed, each meaning what it says: ``dt`` replaces ``nt``;
        ``T`` keeps ``nt``, ``length`` keeps ``nx``; ``h`` replaces ``h_left``/``h_right`` and vice versa; an end
        height that equalled eta0's end follows a new ``eta0`` or ``length``; ``None`` removes a key; ``parameters``
        replaces the whole table; ``scheme`` a name keeps its options, a table replaces them; ``eps`` and
        ``restitution`` set one option each."""
        changes = _top_level_constants(changes, changes.get("model", self.model), self.name, self.parameters)
        checks.check_keys(changes)
        data = self.as_dict()
        domain = changes.get("domain") or ("file" if changes.get("mesh") else self.domain)
        if domain != self.domain:  # the old domain's geometry keys go (1D: also the end heights)
            for key in (*DOMAIN_KEYS[self.domain], "h", "domain"):
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
        table = dict(table) if isinstance(table, dict) else {"name": table}
        if "scheme" in changes:
            new = changes.pop("scheme")
            table = dict(new) if isinstance(new, dict) else table | {"name": new}
        table |= {key: changes.pop(key) for key in SCHEME_KEYS_AT_TOP if key in changes}  # scene.replace(eps=...)
        data |= changes | {"scheme": {k: v for k, v in table.items() if v is not None} or None}
        return Scene.from_dict({k: v for k, v in data.items() if v is not None}, source=self.name)  # eps: in [scheme]


def _top_level_constants(data: dict, model, label: str, table=()) -> dict:
    """`data` with top-level keys the named `model` declares as constants moved into ``parameters`` (on top of
    `table`), with a `SceneWarning`; the model is loaded only for keys a scene does not know."""
    unknown = [k for k in data if k not in FILE_KEYS]
    if not unknown or not isinstance(model, str) or model not in names.registered():
        return data
    declared = {c.name for c in names.declared(model)[0]}
    moved = [k for k in unknown if k in declared]
    if not moved:
        return data
    given = data.get("parameters") or {}
    merged = dict(given or table)
    for key in moved:
        if key in given:
            raise SceneError(f"{key}: given twice, at the top level and in [parameters]; keep the one in [parameters]")
        merged[key] = data[key]
    warnings.warn(f"scene {label!r}: {', '.join(moved)} at the top level of a scene is deprecated; put "
                  f"{'it' if len(moved) == 1 else 'them'} in the [parameters] table (model {model!r})",
                  SceneWarning, stacklevel=3)
    return {k: v for k, v in data.items() if k not in moved} | {"parameters": merged}


def _scheme_table(data: dict) -> tuple[dict, tuple, list]:
    """`data` with a ``[scheme]`` table taken apart (name, eps and restitution as keys, the rest as pairs), and the
    options given at the top level (they work, with a warning)."""
    top = [k for k in SCHEME_KEYS_AT_TOP if k in data]
    if not isinstance(data.get("scheme"), dict):
        return data, (), top
    data, table = dict(data), dict(data["scheme"])
    for key in SCHEME_KEYS_AT_TOP:
        if key in table:
            if key in data:
                raise SceneError(f"{key}: given twice, at the top level and in [scheme]; keep the one in [scheme]")
            data[key] = table.pop(key)
    data["scheme"] = table.pop("name", None)
    return data, tuple(table.items()), top


def _build(data: dict, *, default_name: str | None, options: tuple = ()) -> Scene:
    """The scene of file keys `data`: required keys, nt from dt, the geometry's defaults and (1D) the end heights."""
    checks.check_keys(data)
    domain = checks.domain_of(data)
    missing = [k for k in REQUIRED_KEYS if k not in data and (k != "nx" or domain == "interval")]
    either = [] if "nt" in data or "dt" in data else ["one of nt or dt"]
    if missing or either:
        raise SceneError(f"missing required key(s): {' and '.join(filter(None, (', '.join(missing), *either)))}")
    if "nt" in data and "dt" in data:
        raise SceneError("nt, dt: give exactly one of nt or dt, not both")
    if "h" in data and ("h_left" in data or "h_right" in data):
        raise SceneError("h: give either h (both ends) or h_left/h_right, not both")
    T = checks.number("T", data["T"])
    values = dict.fromkeys(("eps", *DOMAIN_KEYS["interval"])) | DOMAIN_KEYS[domain]
    values |= {k: v for k, v in data.items() if k != "dt"}
    values |= {"name": data.get("name", default_name or "scene"), "domain": domain, "T": T, "options": options,
               "nt": checks.nt_from_dt(data["dt"], T) if "dt" in data else data["nt"]}
    if domain == "interval":
        values |= _ends(data, checks.number("length", values["length"]))
    return Scene(**values)


def _ends(data: dict, length: float) -> dict:
    """1D: the heights of the ends: h at both, else h_left/h_right, by default eta0's values there."""
    if "h" in data:
        h = checks.number("h", data["h"])
        return {"h_left": h, "h_right": h}
    need = [k for k in ("h_left", "h_right") if k not in data]
    if not need:
        return {}
    eta0 = checks.initial_data("eta0", data["eta0"])
    if not isinstance(eta0, tuple):  # on the probe grid: an expression not finite inside is refused first
        eta0 = expressions.evaluate(eta0, np.linspace(0.0, length, expressions.PROBE_POINTS), field="eta0",
                                    names={"l": length})
    return {key: float(end) for key, end in zip(("h_left", "h_right"), (eta0[0], eta0[-1])) if key in need}


def _warn_doubtful(scene: Scene, label: str) -> None:
    """Refuse values beyond ±MAX_MAGNITUDE at the nodes or probe points; warn of eta0 below the obstacle and of an
    end held away from eta0."""
    x = scene.x() if scene.dim == 1 else scene.probe_points()
    values = {"eta0": scene.initial_displacement(x), "v0": scene.initial_velocity(x)}
    values |= {key: scene.field_values(key, x) for key in scene.fields}
    for key, value in values.items():
        checks.check_magnitude(key, value)
    eta = values["eta0"]
    gap = eta - values.get("obstacle", np.zeros_like(eta))  # the obstacle profile, or the paper's y = 0
    if (gap < 0).any():
        i = int(np.argmin(gap))
        what, at = (("eta0 < 0", f"min {eta[i]:.6g}") if scene.obstacle is None else
                    ("eta0 < obstacle", f"min eta0 - obstacle {gap[i]:.6g}"))
        where = f"x={x[i]:.6g}" if x.ndim == 1 else f"x={x[i, 0]:.6g}, y={x[i, 1]:.6g}"
        warnings.warn(f"scene {label!r}: eta0 is below the obstacle ({what}) at {int((gap < 0).sum())} of {len(x)} "
                      f"nodes ({at} at {where}); used as given", SceneWarning, stacklevel=3)
    if scene.dim == 1:  # a membrane's boundary is held at h, by default eta0 there
        for key, end, at in (("h_left", eta[0], 0.0), ("h_right", eta[-1], scene.length)):
            if not checks.close(value := getattr(scene, key), end):
                warnings.warn(f"scene {label!r}: {key} = {checks.fmt(value)} differs from eta0 at x={checks.fmt(at)} "
                              f"({end:.6g}); the end is held at {key}", SceneWarning, stacklevel=3)
