"""Scenes: the data of one simulation (geometry, time span, material, initial data), as TOML files.

A scene file looks like::

    description = "A string dropped on the obstacle"
    T = 0.3           # final time
    alpha = 0.01      # viscoelasticity
    eps = 0.0005      # penalisation
    nx = 5000         # cells
    dt = 0.0002       # or nt = 1500; dt must divide T
    eta0 = "1 + 0.5*sin(10*pi*x)**2"
    v0 = -50
    load = "-10"      # optional: external load f(x), for a model that reads it
    obstacle = "0"    # optional: obstacle profile psi(x), for a model that reads it
    model = "loaded_obstacle"  # optional: a registered model's name (`stringcontact models`)
    petsc_options = { ksp_type = "cg", pc_type = "hypre", ksp_rtol = 1e-12 }  # optional: the linear solver

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

import importlib.resources
import json
import math
import numbers
import os
import re
import stat
import tomllib
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import expressions, names
from ..errors import SceneError, one_line

__all__ = [
    "Scene",
    "check_petsc_options",
    "SceneWarning",
    "load_scene",
    "list_scenes",
    "scene_to_toml",
    "FILE_KEYS",
    "FIELD_KEYS",
    "REQUIRED_KEYS",
    "MAX_FILE_BYTES",
    "MAX_OUTPUT_TIMES",
    "MAX_STORED_BYTES",
    "stored_bytes",
]

#: Keys a scene file (or Scene.replace) accepts, in the order they are written.
FILE_KEYS = (
    "name", "description", "notes", "length", "T", "alpha", "eps", "nx", "nt", "dt",
    "eta0", "v0", "h", "h_left", "h_right", "load", "obstacle", "output_times", "model", "scheme",
    "domain", "size", "cells", "radius", "mesh_size", "mesh", "petsc_options",
)
#: The domains and the geometry keys each one takes (docs/membranes.md). A `mesh` key alone means "file".
DOMAIN_KEYS = {
    "interval": ("length", "nx", "h_left", "h_right"),
    "rectangle": ("size", "cells"),
    "disk": ("radius", "mesh_size"),
    "file": ("mesh",),
}
#: Optional expression fields in x that reach the model as P1 functions (`Parameters.extra`).
FIELD_KEYS = ("load", "obstacle")
#: Required keys; besides these, exactly one of nt or dt.
REQUIRED_KEYS = ("T", "alpha", "eps", "nx", "eta0", "v0")
MAX_FILE_BYTES = 1_000_000
DT_RELATIVE_TOLERANCE = 1e-9  # dt must divide T up to this relative error

# Bounds: (low, high, low_open, high_open). Wide enough for any sensible run, tight enough
# to catch typos (a missing minus, a forgotten decimal point) before a solver sees them.
_BOUNDS = {
    "length": (0.0, 1e4, True, False),
    "radius": (0.0, 1e4, True, False),
    "T": (0.0, 1e4, True, False),
    "alpha": (0.0, 1e4, False, False),
    "eps": (1e-12, 1e6, False, False),  # below 1e-12: see docs/reliability.md, "Size and precision limits"
    "h": (-1e6, 1e6, False, False),
    "h_left": (-1e6, 1e6, False, False),
    "h_right": (-1e6, 1e6, False, False),
}
# nx: dolfinx sets up the mesh in C++, deaf to Ctrl-C: 0.5 s at 1e5 cells, minutes at 1e6
# (benchmarks/bench_mesh_size.py).
_INT_BOUNDS = {"nx": (2, 100_000), "nt": (1, 100_000_000)}
#: At most this many output times: each is a stored row (and an XDMF frame, within --frames).
MAX_OUTPUT_TIMES = 1000
#: The stored rows (eta, velocity, contact force as float64, contact as bool) may take at most this many bytes.
MAX_STORED_BYTES = 2_000_000_000
BYTES_PER_STORED_NODE = 3 * 8 + 1
#: The solver's default number of stored rows (`simulate(max_rows=400)`), besides 0, T and the output times.
STORED_ROWS = 400
_NAME_MAX = 100
#: petsc_options: a scene is data, so only solver settings, never an option that opens, writes or runs anything.
PETSC_PREFIXES = ("ksp_", "pc_", "mat_mumps_icntl_", "mat_mumps_cntl_", "mat_superlu_dist_")
#: Refused inside a name: viewers, monitors and reasons (they take a viewer: a file, a window), debuggers, logs,
#: Python classes. Refused names: MUMPS' ICNTL 1-4 are Fortran output units (files fort.N), ICNTL 22 is
#: out-of-core (temporary files).
PETSC_REFUSED_WORDS = ("view", "monitor", "draw", "debugger", "log", "print", "python", "file", "dump", "save",
                       "history", "reason")
PETSC_REFUSED_NAMES = tuple(f"mat_mumps_icntl_{i}" for i in (1, 2, 3, 4, 22))
PETSC_MAX_OPTIONS = 32
_PETSC_NAME = re.compile(r"[a-z][a-z0-9_]{0,59}")
_PETSC_WORD = re.compile(r"[A-Za-z][A-Za-z0-9_+\-]{0,31}")
_PETSC_ALLOWED = (f"a table of at most {PETSC_MAX_OPTIONS} PETSc options named {', '.join(p + '*' for p in PETSC_PREFIXES)} "
                  "(no viewers, monitors, files or debuggers), each a number, a boolean or a word (letters, digits, _ + -)")
_BUILTIN_PACKAGE = "stringcontact"
_BUILTIN_FOLDER = "scenes"


class SceneWarning(UserWarning):
    """Legal but doubtful scene data (reproduced as given, with a warning)."""


@dataclass(frozen=True)
class Scene:
    """One validated scene. Build it with :func:`load_scene`, :meth:`from_dict` or :meth:`replace`.

    ``eta0`` and ``v0`` are expressions in ``x`` (see :mod:`stringcontact.scene.expressions`);
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
    eps: float
    nx: int  # cells
    nt: int  # time steps
    eta0: str  # initial displacement, expression in x
    v0: str  # initial velocity, expression in x
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

    @property
    def dim(self) -> int:
        """1 on the interval (a string), 2 on the membrane domains."""
        return 1 if self.domain == "interval" else 2

    def __post_init__(self):
        # Normalise in place (frozen, hence object.__setattr__): ints to floats, lists to tuples.
        def put(key, value):
            object.__setattr__(self, key, value)

        put("name", _check_name(self.name))
        _check_domain(self, put)
        for key in ("T", "alpha", "eps") + (("length", "h_left", "h_right") if self.dim == 1 else ()):
            put(key, _number(key, getattr(self, key)))
        if self.dim == 1:
            put("nx", _integer("nx", self.nx))
        put("nt", _integer("nt", self.nt))
        if self.dim == 2:
            if self.h is not None:
                put("h", _expression_text("h", self.h) if isinstance(self.h, str) else _number("h", self.h))
        elif self.h is not None:
            put("h", _number("h", self.h))
            if self.h_left != self.h or self.h_right != self.h:
                raise SceneError(
                    f"h: h = {_fmt(self.h)} but h_left = {_fmt(self.h_left)}, h_right = {_fmt(self.h_right)}; "
                    "give either h or h_left/h_right"
                )
        for key in ("description", "notes"):
            put(key, _text(key, getattr(self, key)))
        if self.model is not None:
            put("model", _check_model(self.model))
        if self.scheme is not None:
            put("scheme", _check_scheme(self.scheme))
        put("output_times", _check_output_times(self.output_times, self.T))
        options = self.petsc_options
        put("petsc_options", check_petsc_options(dict(options) if isinstance(options, tuple) else options))
        if self.dim == 1:
            _check_storage(self.node_estimate - 1, self.nt, len(self.output_times))
        else:  # the solver thins a membrane's rows to its budget (solver.ROW_BUDGET): 0, T and the output times must fit
            _check_membrane_storage(self.node_estimate, len(self.output_times))
        keys = ("eta0", "v0") + tuple(self.fields) + (("h",) if isinstance(self.h, str) else ())
        for key in keys:
            put(key, _expression_text(key, getattr(self, key)))
            if self.dim == 1:
                expressions.check(getattr(self, key), field=key, names=self._names())
            else:
                self._evaluate(key, getattr(self, key), self.probe_points())

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

    def _evaluate(self, key: str, expr: str, points) -> np.ndarray:
        """`expr` at the points: (N,) in 1D, (N, 2) in 2D."""
        p = np.asarray(points, dtype=float)
        if self.dim == 1:
            return expressions.evaluate(expr, p, field=key, names=self._names())
        return expressions.evaluate(expr, p[:, 0], field=key, names=self._names(), y=p[:, 1])

    def boundary_height(self, points) -> np.ndarray:
        """2D: the height at which the boundary is held at the points (N, 2): h, else eta0 there."""
        if self.h is None:
            return self.initial_displacement(points)
        return self._evaluate("h", self.h if isinstance(self.h, str) else repr(float(self.h)), points)

    @property
    def r(self) -> float:
        """dt/eps, the penalty's weight per step (explicit penalty: large r means trouble)."""
        return self.dt / self.eps

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

    def field_values(self, name: str, x) -> np.ndarray:
        """The field `name` (a key of :attr:`fields`) at the points x."""
        fields = self.fields
        if name not in fields:
            given = ", ".join(fields) or "none"
            raise SceneError(f"{name}: the scene gives no field {name!r} (fields given: {given})")
        return self._evaluate(name, fields[name], x)

    def obstacle_values(self, x) -> np.ndarray:
        """The obstacle profile ψ at the points x: the ``obstacle`` field, or 0 (the paper's y = 0)."""
        x = np.asarray(x, dtype=float)
        return self.field_values("obstacle", x) if self.obstacle is not None else np.zeros(x.shape[:1])

    def _names(self) -> dict[str, float]:
        names = {"l": self.length} if self.dim == 1 else {}
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
            "eps": self.eps,
            "nx": self.nx,
            "nt": self.nt,
            "eta0": self.eta0,
            "v0": self.v0,
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
        if self.scheme is not None:
            d["scheme"] = self.scheme
        if self.petsc_options:
            d["petsc_options"] = dict(self.petsc_options)
        return d

    def _as_dict_2d(self) -> dict:
        d = {"name": self.name, "description": self.description, "notes": self.notes, "domain": self.domain}
        d.update({key: list(v) if isinstance(v := getattr(self, key), tuple) else v for key in DOMAIN_KEYS[self.domain]})
        d.update({"T": self.T, "alpha": self.alpha, "eps": self.eps, "nt": self.nt, "eta0": self.eta0, "v0": self.v0})
        if self.h is not None:
            d["h"] = self.h
        d.update(self.fields)
        d["output_times"] = list(self.output_times)
        d.update({key: getattr(self, key) for key in ("model", "scheme") if getattr(self, key) is not None})
        if self.petsc_options:
            d["petsc_options"] = dict(self.petsc_options)
        return d

    @classmethod
    def from_dict(cls, data: dict, *, source: str | None = None, default_name: str | None = None) -> "Scene":
        """Build a scene from file keys: checks keys, resolves defaults, validates, warns.

        ``source`` (a file or scene name) prefixes error and warning messages.
        """
        label = source if source is not None else str(data.get("name", default_name or "scene"))
        try:
            scene = _build(dict(data), default_name=default_name)
            x, values = _grid_values(scene)
            _check_magnitudes(values)
            _warn_doubtful(scene, label, x, values)
        except SceneError as exc:
            raise SceneError(f"scene {label!r}: {exc}") from None
        return scene

    def replace(self, **changes) -> "Scene":
        """A new validated scene with some file keys changed (the same keys as a scene file).

        Rules, so that a change means what it says:

        * ``dt`` replaces ``nt``; changing ``T`` alone keeps ``nt`` (so dt changes);
          changing ``length`` keeps ``nx`` (so dx changes);
        * ``h`` replaces ``h_left``/``h_right`` and vice versa;
        * when ``eta0`` or ``length`` changes and no boundary height is given, an end
          height that equalled eta0's old end value follows the new eta0;
        * a value of ``None`` removes the key (e.g. ``h=None``, ``model=None``).
        """
        _check_keys(changes)
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
                if _close(getattr(self, key), end):
                    data.pop(key)  # it followed eta0 before, so it follows the new one
        for key, value in changes.items():
            if value is None:
                data.pop(key, None)
            else:
                data[key] = value
        return Scene.from_dict(data, source=self.name)


# --- building and validating ------------------------------------------------------------------


def _domain_of(data: dict) -> str:
    domain = data.get("domain", "file" if "mesh" in data else "interval")
    if domain not in DOMAIN_KEYS:
        raise SceneError(f"domain: invalid value {_describe(domain)}; allowed: {', '.join(DOMAIN_KEYS)}")
    return domain


def _build_2d(data: dict, domain: str, name: str, T: float, nt: int) -> Scene:
    """A membrane scene: the geometry keys of `domain` (checked in Scene), no ends."""
    geometry = {key: data[key] for key in DOMAIN_KEYS[domain] if key in data}
    if domain == "rectangle":
        geometry.setdefault("size", [1.0, 1.0])
    if domain == "disk":
        geometry.setdefault("radius", 1.0)
    output_times = data.get("output_times", ())
    return Scene(
        name=name, length=None, T=T, alpha=data["alpha"], eps=data["eps"], nx=None, nt=nt,
        eta0=_expression_text("eta0", data["eta0"]), v0=data["v0"], h_left=None, h_right=None, h=data.get("h"),
        output_times=tuple(output_times) if isinstance(output_times, (list, tuple)) else output_times,
        description=data.get("description", ""), notes=data.get("notes", ""), model=data.get("model"),
        scheme=data.get("scheme"), domain=domain, **geometry, **{key: data[key] for key in FIELD_KEYS if key in data},
        petsc_options=check_petsc_options(data.get("petsc_options", {})),
    )


def _build(data: dict, *, default_name: str | None) -> Scene:
    _check_keys(data)
    domain = _domain_of(data)
    _check_domain_keys(data, domain)
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
    T = _number("T", data["T"])
    nt = _nt_from_dt(data["dt"], T) if "dt" in data else _integer("nt", data["nt"])
    if domain != "interval":
        return _build_2d(data, domain, name, T, nt)
    length = _number("length", data.get("length", 1.0))
    h = _number("h", data["h"]) if "h" in data else None
    eta0 = _expression_text("eta0", data["eta0"])

    names = {"l": length} if h is None else {"l": length, "h": h}
    if h is not None:
        h_left = h_right = h
    else:
        # The ends default to eta0's end values: a string held where it starts.
        expressions.check(eta0, field="eta0", names=names)
        need = [k for k in ("h_left", "h_right") if k not in data]
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
        eps=data["eps"],
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
        **{key: data[key] for key in FIELD_KEYS if key in data},
        petsc_options=check_petsc_options(data.get("petsc_options", {})),
    )


def _check_domain_keys(data: dict, domain: str) -> None:
    """Refuse a geometry key of another domain (and `domain` disagreeing with `mesh`)."""
    if "mesh" in data and domain != "file":
        raise SceneError(f"mesh: a mesh file is its own domain; remove domain = {domain!r} or mesh")
    for other, keys in DOMAIN_KEYS.items():
        for key in keys:
            if other != domain and key in data:
                raise SceneError(f"{key}: only for domain {other!r}, not {domain!r}; domain {domain!r} takes "
                                 f"{', '.join(DOMAIN_KEYS[domain]) or 'no geometry keys'}")


_MAX_CELLS = 2000  # per direction of a rectangle (4e6 nodes)
_MAX_DISK_RATIO = 1000  # radius / mesh_size: gmsh takes minutes beyond


def _check_domain(scene: Scene, put) -> None:
    """Validate the domain's geometry keys (Scene.__post_init__)."""
    domain = scene.domain
    if domain not in DOMAIN_KEYS:
        raise SceneError(f"domain: invalid value {_describe(domain)}; allowed: {', '.join(DOMAIN_KEYS)}")
    given = [k for ks in DOMAIN_KEYS.values() for k in ks if k not in DOMAIN_KEYS[domain] and getattr(scene, k) is not None]
    if given:
        raise SceneError(f"{given[0]}: only for domain 'interval', not {domain!r}" if domain != "interval" else
                         f"{given[0]}: not for domain 'interval'; give domain = 'rectangle', 'disk' or a mesh file")
    if domain == "rectangle":
        put("size", _pair("size", scene.size, lambda v: _number("length", v), "two numbers [Lx, Ly] in (0, 10000]"))
        put("cells", _pair("cells", scene.cells, lambda v: _cell_count(v), f"two integers [nx, ny] in [1, {_MAX_CELLS}]"))
    elif domain == "disk":
        put("radius", _number("radius", scene.radius))
        allowed = f"a number in [radius/{_MAX_DISK_RATIO}, radius]"
        if scene.mesh_size is None:
            raise SceneError(f"mesh_size: domain 'disk' needs mesh_size; allowed: {allowed}")
        h = float(scene.mesh_size) if _is_number(scene.mesh_size) else math.nan
        if not (scene.radius / _MAX_DISK_RATIO <= h <= scene.radius):
            raise SceneError(f"mesh_size: {_describe(scene.mesh_size)} is out of range; allowed: {allowed} (radius = {_fmt(scene.radius)})")
        put("mesh_size", h)
    elif domain == "file":
        if not isinstance(scene.mesh, str) or not scene.mesh.endswith(".xdmf"):
            raise SceneError(f"mesh: expected the path of an XDMF triangle mesh (*.xdmf), got {_describe(scene.mesh)}")
        if not Path(scene.mesh).is_file():
            raise SceneError(f"mesh: no such file {scene.mesh!r}; allowed: an XDMF triangle mesh file (*.xdmf)")
    if domain != "interval":
        for key in ("length", "nx", "h_left", "h_right"):
            if getattr(scene, key) is not None:
                raise SceneError(f"{key}: only for domain 'interval', not {domain!r}")
        if scene.h is not None and not isinstance(scene.h, str) and not _is_number(scene.h):
            raise SceneError(f"h: expected a number or an expression in x, y, got {_describe(scene.h)}")


def _pair(key: str, value, convert, allowed: str) -> tuple:
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) or len(value) != 2:
        raise SceneError(f"{key}: expected {allowed}, got {_describe(value)}")
    try:
        return tuple(convert(v) for v in value)
    except SceneError:
        raise SceneError(f"{key}: {_describe(list(value))} is out of range; allowed: {allowed}") from None


def _cell_count(value) -> int:
    if not _is_number(value) or not float(value).is_integer() or not 1 <= int(value) <= _MAX_CELLS:
        raise SceneError("cells")
    return int(value)


MAX_MAGNITUDE = 1e6  # largest |eta0|, |v0|, load or obstacle value a scene may give


def _grid_values(scene: Scene) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The nodes x and eta0, v0 and the scene's fields at them (checks finiteness on the real grid, not just the probe)."""
    x = scene.x() if scene.dim == 1 else scene.probe_points()
    values = {"eta0": scene.initial_displacement(x), "v0": scene.initial_velocity(x)}
    values.update({key: scene.field_values(key, x) for key in scene.fields})
    return x, values


def _check_magnitudes(values: dict[str, np.ndarray]) -> None:
    """Refuse values beyond ±MAX_MAGNITUDE: beyond this, energies of order |.|^2/eps overflow or lose all digits."""
    for key, arr in values.items():
        big = np.abs(np.asarray(arr, dtype=float))
        if big.size and big.max() > MAX_MAGNITUDE:
            raise SceneError(f"{key}: |{key}| reaches {big.max():.3g}; allowed: values in [-{MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}]")


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
        if not _close(value, end):
            warnings.warn(
                f"scene {label!r}: {key} = {_fmt(value)} differs from eta0 at x={_fmt(at)} ({end:.6g}); "
                f"the end is held at {key}",
                SceneWarning,
                stacklevel=4,
            )


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def _check_keys(data: dict) -> None:
    unknown = [k for k in data if k not in FILE_KEYS]
    if unknown:
        listed = ", ".join(repr(str(k)) for k in unknown)
        raise SceneError(f"unknown key(s) {listed}; allowed keys are {', '.join(FILE_KEYS)}")


def _range_text(key: str) -> str:
    if key in _INT_BOUNDS:
        lo, hi = _INT_BOUNDS[key]
        return f"an integer in [{lo}, {hi}]"
    lo, hi, lo_open, hi_open = _BOUNDS[key]
    return f"a number in {'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}{')' if hi_open else ']'}"


def _is_number(value) -> bool:
    # bool is an int in Python, but `nx = true` is surely a mistake.
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _number(key: str, value) -> float:
    if not _is_number(value):
        raise SceneError(f"{key}: expected a number, got {_describe(value)}; allowed: {_range_text(key)}")
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise SceneError(f"{key}: {value!r} is not finite; allowed: {_range_text(key)}")
    lo, hi, lo_open, hi_open = _BOUNDS[key]
    if v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
        raise SceneError(f"{key}: {_fmt(v)} is out of range; allowed: {_range_text(key)}")
    return v


def _integer(key: str, value) -> int:
    if not _is_number(value):
        raise SceneError(f"{key}: expected an integer, got {_describe(value)}; allowed: {_range_text(key)}")
    if isinstance(value, numbers.Integral):
        n = int(value)
    else:
        v = float(value)
        if not math.isfinite(v) or not v.is_integer():
            raise SceneError(f"{key}: expected an integer, got {value!r}; allowed: {_range_text(key)}")
        n = int(v)
    lo, hi = _INT_BOUNDS[key]
    if not lo <= n <= hi:
        raise SceneError(f"{key}: {n} is out of range; allowed: {_range_text(key)}")
    return n


def _nt_from_dt(value, T: float) -> int:
    try:
        dt = float(value) if _is_number(value) else math.nan
    except OverflowError:
        dt = math.inf
    if not math.isfinite(dt) or dt <= 0:
        raise SceneError(f"dt: expected a positive number that divides T, got {_describe(value)}")
    steps = T / dt
    lo, hi = _INT_BOUNDS["nt"]
    if not math.isfinite(steps) or not lo - 0.5 <= steps <= hi + 0.5:
        raise SceneError(f"dt: T/dt = {steps:.6g} steps; allowed: dt dividing T into {lo} to {hi} steps")
    n = round(steps)
    if n < lo or n > hi or abs(n * dt - T) > DT_RELATIVE_TOLERANCE * T:
        raise SceneError(
            f"dt: {_fmt(dt)} does not divide T = {_fmt(T)} (T/dt = {steps:.12g}); "
            f"allowed: T/dt an integer in [{lo}, {hi}] (up to {DT_RELATIVE_TOLERANCE:g} relative), or give nt"
        )
    return n


def _expression_text(key: str, value) -> str:
    # Numbers are accepted as constants: `v0 = -50` reads naturally in TOML.
    if isinstance(value, str):
        return value
    if _is_number(value):
        if isinstance(value, numbers.Integral):
            return str(int(value))
        v = float(value)
        if not math.isfinite(v):
            raise SceneError(f"{key}: {value!r} is not finite; allowed: an expression in x or a finite number")
        return repr(v)
    raise SceneError(f"{key}: expected an expression string or a number, got {_describe(value)}")


def _text(key: str, value) -> str:
    if not isinstance(value, str):
        raise SceneError(f"{key}: expected a string, got {_describe(value)}")
    return value


def _check_name(value) -> str:
    # Names end up in output folders and file names: keep them to one safe line.
    if (
        not isinstance(value, str)
        or not 1 <= len(value) <= _NAME_MAX
        or not value.isprintable()
        or "/" in value
        or "\\" in value
        or value.startswith(".")
    ):
        raise SceneError(
            f"name: invalid name {_describe(value)}; allowed: 1 to {_NAME_MAX} printable characters, "
            "no '/' or '\\', not starting with '.'"
        )
    return value


def _check_model(value) -> str:
    # A scene is data: it names a registered model and never a module (nothing is imported here).
    return names.check_name(value)


def _check_scheme(value) -> str:
    SCHEMES = names.SCHEMES
    if value not in SCHEMES:
        raise SceneError(f"scheme: invalid value {_describe(value)}; allowed: {', '.join(SCHEMES)}")
    return value


def check_petsc_options(value, key: str = "petsc_options") -> tuple:
    """The (name, value) pairs of a petsc_options table, checked against the allow-list; SceneError naming `key`."""
    if not isinstance(value, dict):
        raise SceneError(f"{key}: expected a table of options, got {_describe(value)}; allowed: {_PETSC_ALLOWED}")
    if len(value) > PETSC_MAX_OPTIONS:
        raise SceneError(f"{key}: {len(value)} options; allowed: {_PETSC_ALLOWED}")
    return tuple((_petsc_name(key, name), _petsc_value(key, name, v)) for name, v in value.items())


def _petsc_name(key: str, name) -> str:
    ok = (isinstance(name, str) and _PETSC_NAME.fullmatch(name) and name.startswith(PETSC_PREFIXES)
          and not any(word in name for word in PETSC_REFUSED_WORDS) and name not in PETSC_REFUSED_NAMES)
    if not ok:
        raise SceneError(f"{key}: option {_describe(name)} is not allowed; allowed: {_PETSC_ALLOWED}")
    return name


def _petsc_value(key: str, name: str, value):
    if isinstance(value, bool) or (_is_number(value) and math.isfinite(value)):
        return value
    if isinstance(value, str) and _PETSC_WORD.fullmatch(value) and "python" not in value.lower():
        return value
    raise SceneError(f"{key}: {name} = {_describe(value)} is not allowed; allowed: {_PETSC_ALLOWED}")


def _check_output_times(value, T: float) -> tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise SceneError(f"output_times: expected a list of numbers in [0, T], got {_describe(value)}")
    if len(value) > MAX_OUTPUT_TIMES:
        raise SceneError(f"output_times: {len(value)} times; allowed: at most {MAX_OUTPUT_TIMES} times in [0, T = {_fmt(T)}]")
    times = []
    for t in value:
        if not _is_number(t) or not math.isfinite(float(t)):
            raise SceneError(f"output_times: expected numbers in [0, T = {_fmt(T)}], got {_describe(t)}")
        t = float(t)
        if not 0.0 <= t <= T:
            raise SceneError(f"output_times: {_fmt(t)} is out of range; allowed: numbers in [0, T = {_fmt(T)}]")
        times.append(t)
    if any(b <= a for a, b in zip(times, times[1:])):
        raise SceneError("output_times: must be sorted ascending without duplicates")
    return tuple(times)


def stored_bytes(nx: int, nt: int, n_output_times: int, max_rows: int = STORED_ROWS) -> int:
    """An upper bound on the memory of a run's stored rows: rows × (nx + 1) nodes × BYTES_PER_STORED_NODE."""
    rows = min(nt, max_rows) + 2 + n_output_times  # every k-th step, 0 and T, the output times
    return rows * (nx + 1) * BYTES_PER_STORED_NODE


def _check_storage(nx: int, nt: int, n_output_times: int) -> None:
    """Refuse a scene whose stored rows would not fit, before anything is allocated."""
    need = stored_bytes(nx, nt, n_output_times)
    if need > MAX_STORED_BYTES:
        raise SceneError(
            f"nx, nt, output_times: the stored rows need {need / 1e9:.3g} GB ((min(nt, {STORED_ROWS}) + 2 + "
            f"{n_output_times} output times) rows x (nx + 1) nodes x {BYTES_PER_STORED_NODE} bytes); allowed: at most "
            f"{MAX_STORED_BYTES / 1e9:g} GB; reduce nx or the number of output times"
        )


def _check_membrane_storage(nodes: int, n_output_times: int) -> None:
    need = stored_bytes(nodes - 1, 0, n_output_times)  # no steps besides 0, T and the output times
    if need > MAX_STORED_BYTES:
        raise SceneError(
            f"output_times: the rows at 0, T and the {n_output_times} output times need {need / 1e9:.3g} GB on about "
            f"{nodes} nodes; allowed: at most {MAX_STORED_BYTES / 1e9:g} GB; use fewer output times or a coarser mesh"
        )


def _fmt(v) -> str:
    v = float(v)
    if v.is_integer() and abs(v) < 1e16:
        return str(int(v))
    return repr(v)


def _describe(value) -> str:
    text = repr(value)
    if len(text) > 40:
        text = text[:40] + "..."
    return f"{type(value).__name__} {text}"


# --- files ---------------------------------------------------------------------------------


def _builtin_dir():
    return importlib.resources.files(_BUILTIN_PACKAGE).joinpath(_BUILTIN_FOLDER)


def _builtin_names() -> list[str]:
    try:
        entries = list(_builtin_dir().iterdir())
    except (FileNotFoundError, NotADirectoryError, ModuleNotFoundError):
        return []
    return sorted(e.name[: -len(".toml")] for e in entries if e.name.endswith(".toml"))


def _parse_toml(raw: bytes, label: str) -> dict:
    if len(raw) > MAX_FILE_BYTES:
        raise SceneError(f"scene file {label!r}: larger than {MAX_FILE_BYTES} bytes; scene files are small text files")
    if b"\x00" in raw:
        raise SceneError(f"scene file {label!r}: binary file (contains NUL bytes); expected a UTF-8 TOML text file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise SceneError(
            f"scene file {label!r}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at line {line}); "
            "expected a UTF-8 TOML file"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"scene file {label!r}: invalid TOML: {one_line(exc)}") from None
    except RecursionError:  # tomllib recurses once per level of [[[...]]]; no scene nests at all
        raise SceneError(f"scene file {label!r}: malformed TOML: arrays or tables nested too deeply") from None


def load_scene(name_or_path: str | os.PathLike) -> Scene:
    """Load a built-in scene by name (``"example1"``) or a scene file by path.

    A plain name without ``/`` or ``.toml`` is looked up among the built-in scenes first.
    """
    text = os.fspath(name_or_path)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    builtins = _builtin_names()
    if isinstance(name_or_path, str) and text in builtins:
        raw = _builtin_dir().joinpath(f"{text}.toml").read_bytes()
        return Scene.from_dict(_parse_toml(raw, text), source=text, default_name=text)

    path = Path(text)
    if not path.is_file():
        if path.is_dir():
            raise SceneError(f"scene {text!r}: is a directory; expected a .toml scene file")
        if path.exists():  # a FIFO, a device, a socket: stat only, never open (a FIFO would block)
            raise SceneError(f"scene {text!r}: is not a regular file ({_file_kind(path)}); expected a .toml scene file")
        raise SceneError(
            f"scene {text!r}: no built-in scene of that name and no such file "
            f"(built-in scenes: {', '.join(builtins) or 'none'})"
        )
    try:
        if path.stat().st_size > MAX_FILE_BYTES:
            raise SceneError(
                f"scene file {text!r}: larger than {MAX_FILE_BYTES} bytes; scene files are small text files"
            )
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)  # bounded even if the file grows meanwhile
    except OSError as exc:
        raise SceneError(f"scene file {text!r}: cannot read it ({exc.strerror or exc})") from None
    data = _parse_toml(raw, text)
    if isinstance(data.get("mesh"), str) and not Path(data["mesh"]).is_absolute():
        data["mesh"] = str(path.parent / data["mesh"])  # a mesh file next to its scene file
    return Scene.from_dict(data, source=text, default_name=path.stem)


def _file_kind(path: Path) -> str:
    mode = path.stat().st_mode
    kinds = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
             (stat.S_ISSOCK, "a socket"))
    return next((kind for test, kind in kinds if test(mode)), "not a file")


def list_scenes() -> list[tuple[str, str]]:
    """(name, one-line description) of the built-in scenes, sorted by name."""
    result = []
    for name in _builtin_names():
        try:
            data = _parse_toml(_builtin_dir().joinpath(f"{name}.toml").read_bytes(), name)
            description = str(data.get("description", ""))
        except SceneError:
            description = "(unreadable)"
        first = description.strip().splitlines()[0] if description.strip() else ""
        result.append((name, first))
    return result


# --- writing ----------------------------------------------------------------------------------


def scene_to_toml(scene: Scene) -> str:
    """The scene as a TOML scene file (loadable by :func:`load_scene`), with derived values in a comment."""
    lines = [
        f"# scene {scene.name!r}: dt = {scene.dt:.6g}, dx = {scene.dx:.6g}, r = dt/eps = {scene.r:.6g}",
    ]
    for key, value in scene.as_dict().items():
        lines.append(f"{key} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"


def _toml_value(value) -> str:
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, bool):  # petsc_options only
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)  # shortest round-tripping form; always finite in a valid scene
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):  # petsc_options: names are bare keys (checked)
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")  # pragma: no cover


def _toml_string(s: str) -> str:
    # Multi-line literal strings keep notes readable; anything awkward falls back to escapes.
    if (
        "\n" in s
        and "'''" not in s
        and not s.endswith("'")
        and all(c in "\n\t" or (c.isprintable() and c != "\x7f") for c in s)
    ):
        return "'''\n" + s + "'''"
    # JSON escapes are valid TOML basic-string escapes; DEL must be escaped too in TOML.
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")
