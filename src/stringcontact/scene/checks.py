"""Validation of scene data: each function checks one value and raises `SceneError` with one line that names
the key and what is allowed (docs/explanation/reliability.md)."""

from __future__ import annotations

import errno
import itertools
import math
import numbers
import os
import re
import stat

import numpy as np

from ..errors import SceneError
from . import limits, names, parameters
from .limits import BOUNDS, DOMAIN_KEYS, INT_BOUNDS, MAX_MAGNITUDE, MAX_MEMBRANE_NODES
from .parameters import describe, fmt, is_number

_PETSC_NAME = re.compile(r"[a-z][a-z0-9_]{0,59}")
_PETSC_WORD = re.compile(r"[A-Za-z][A-Za-z0-9_+\-]{0,31}")
_VALUES = f"values in [-{MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}]"
#: What a scene may give for each key that has no range of numbers: the words of its error messages.
_ALLOWED = {
    "name": f"1 to {limits.NAME_MAX} printable characters, no '/' or '\\', not starting with '.'",
    **dict.fromkeys(("description", "notes"), "a string"),
    "dt": (f"T/dt an integer in [{INT_BOUNDS['nt'][0]}, {INT_BOUNDS['nt'][1]}] (up to {limits.DT_RELATIVE_TOLERANCE:g} "
           "relative), or give nt"),
    **dict.fromkeys(("eta0", "v0"), f"an expression in x (2D: x, y) or a number; 1D: also nx + 1 nodal values; "
                                    f"{_VALUES}"),
    "load": f"an expression in x (2D: x, y) or a number; {_VALUES}",
    "obstacle": f"an expression in x (2D: x, y) and t, or a number; {_VALUES}",
    "output_times": f"at most {limits.MAX_OUTPUT_TIMES} numbers in [0, T], ascending, no duplicates",
    "model": "a name registered under the entry-point group stringcontact.models (`stringcontact models`)",
    "domain": ", ".join(DOMAIN_KEYS),
    "size": f"two numbers [Lx, Ly] in [{BOUNDS['length'][0]:g}, {BOUNDS['length'][1]:g}]",
    "cells": f"two integers [nx, ny] in [1, {limits.MAX_CELLS}]",
    "mesh_size": f"a number in [radius/{limits.MAX_DISK_RATIO}, radius]",
    "mesh": "the path of an XDMF triangle mesh (*.xdmf)",
    "petsc_options": (f"a table of at most {limits.PETSC_MAX_OPTIONS} PETSc options named "
                      f"{', '.join(p + '*' for p in limits.PETSC_PREFIXES)} in lower case (but not "
                      f"{', '.join(limits.PETSC_REFUSED_NAMES)}: MUMPS' output units and out-of-core files; no "
                      "viewers, monitors, files or debuggers), each a number, a boolean or a word (letters, digits, "
                      "_ + -)"),
    "fields0": f"a table of the model's fields, name = an expression in x (2D: x, y), a number or (1D) nx + 1 nodal "
               f"values; {_VALUES}",
    "parameters": (f"a table of at most {parameters.PARAMETERS_MAX} constants the model declares, name = number, "
                   "each in its range (the models' constants below)"),
}


def _range_text(key: str) -> str:
    if key in INT_BOUNDS:
        return f"an integer in [{INT_BOUNDS[key][0]}, {INT_BOUNDS[key][1]}]"
    return f"a number in [{fmt(BOUNDS[key][0])}, {fmt(BOUNDS[key][1])}]"


def allowed(key: str) -> str:
    """What a scene may give for `key` (in `limits.FILE_KEYS`), in the words of its error messages."""
    if key == "scheme":
        return ", ".join(names.SCHEMES)
    if key in _ALLOWED:
        return _ALLOWED[key]
    return _range_text(key) + (" (2D: also an expression in x, y)" if key == "h" else "")


def file_kind(mode: int) -> str:
    """'a FIFO', 'a directory', ... for a `stat` mode that is not a regular file's."""
    kinds = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
             (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    return next((kind for test, kind in kinds if test(mode)), "not a regular file")


def os_reason(exc: OSError) -> str:
    """Why a path could not be opened or stat'ed, as the rest of a sentence: 'does not exist', 'is a directory', ..."""
    return {errno.ENOENT: "does not exist", errno.ELOOP: "is a loop of symbolic links",
            errno.EISDIR: "is a directory"}.get(exc.errno, f"cannot be opened ({exc.strerror or exc})")


def check_mesh_path(path: str) -> None:
    """Refuse a mesh path that is not a regular file, saying what it is; from `stat` (opening a FIFO would block)."""
    allowed = "allowed: an XDMF triangle mesh file (*.xdmf)"
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        what = f"no such file {path!r}" if exc.errno == errno.ENOENT else f"{path!r} {os_reason(exc)}"
        raise SceneError(f"mesh: {what}; {allowed}") from None
    if not stat.S_ISREG(mode):
        raise SceneError(f"mesh: {path!r} is {file_kind(mode)}; {allowed}, a regular file")


def domain_of(data: dict) -> str:
    """The domain a scene's keys name: `domain`, else "file" with a `mesh`, else "interval"."""
    domain = data.get("domain", "file" if "mesh" in data else "interval")
    if not isinstance(domain, str) or domain not in DOMAIN_KEYS:
        raise SceneError(f"domain: invalid value {describe(domain)}; allowed: {', '.join(DOMAIN_KEYS)}")
    return domain


def check_domain(scene, put) -> None:
    """Validate `scene`'s geometry keys (`put` sets a normalised value): none of another domain, its own in range."""
    domain = domain_of({"domain": scene.domain})
    if scene.mesh is not None and domain != "file":
        raise SceneError(f"mesh: a mesh file is its own domain; remove domain = {domain!r} or mesh")
    for other, keys in DOMAIN_KEYS.items():
        for key in keys:
            if other != domain and getattr(scene, key) is not None:
                raise SceneError(f"{key}: only for domain {other!r}, not {domain!r}; domain {domain!r} takes "
                                 f"{', '.join(DOMAIN_KEYS[domain])}")
    if domain == "rectangle":
        put("size", _pair("size", scene.size, lambda v: number("length", v)))
        put("cells", _pair("cells", scene.cells, lambda v: integer("cells", v)))
        check_membrane_nodes(scene.node_estimate, "cells", list(scene.cells))
    elif domain == "disk":
        put("radius", number("radius", scene.radius))
        if scene.mesh_size is None:
            raise SceneError(f"mesh_size: domain 'disk' needs mesh_size; allowed: {_ALLOWED['mesh_size']}")
        h = float(scene.mesh_size) if is_number(scene.mesh_size) else math.nan
        if not (scene.radius / limits.MAX_DISK_RATIO <= h <= scene.radius):
            raise SceneError(f"mesh_size: {describe(scene.mesh_size)} is out of range; allowed: "
                             f"{_ALLOWED['mesh_size']} (radius = {fmt(scene.radius)})")
        put("mesh_size", h)
        check_membrane_nodes(scene.node_estimate, "mesh_size", scene.mesh_size)
    elif domain == "file":
        if not isinstance(scene.mesh, str) or not scene.mesh.endswith(".xdmf"):
            raise SceneError(f"mesh: expected the path of an XDMF triangle mesh (*.xdmf), got {describe(scene.mesh)}")
        check_mesh_path(scene.mesh)
    if domain != "interval" and scene.h is not None and not isinstance(scene.h, str) and not is_number(scene.h):
        raise SceneError(f"h: expected a number or an expression in x, y, got {describe(scene.h)}")


def check_membrane_nodes(nodes: int, key: str, value) -> None:
    """Refuse a membrane of more than MAX_MEMBRANE_NODES nodes, before any mesh."""
    if nodes > MAX_MEMBRANE_NODES:
        raise SceneError(
            f"{key}: {value} gives {'about ' if key == 'mesh_size' else ''}{nodes} nodes, about "
            f"{nodes * limits.SETUP_BYTES_PER_NODE / 1e9:.3g} GB to set up ({limits.SETUP_BYTES_PER_NODE / 1e3:g} KB "
            f"per node, measured at 1e6 nodes); allowed: at most {MAX_MEMBRANE_NODES} nodes"
            + (" (e.g. cells = [1000, 1000])" if key == "cells" else
               f" (mesh_size >= radius/{math.sqrt(MAX_MEMBRANE_NODES * math.sqrt(3) / (2 * math.pi)):.0f})"))


def _pair(key: str, value, convert) -> tuple:
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) or len(value) != 2:
        raise SceneError(f"{key}: expected {_ALLOWED[key]}, got {describe(value)}")
    try:
        return tuple(convert(v) for v in value)
    except SceneError:
        raise SceneError(f"{key}: {describe(list(value))} is out of range; allowed: {_ALLOWED[key]}") from None


def check_magnitude(key: str, values) -> None:
    """Refuse values beyond ±MAX_MAGNITUDE (energies of order |.|^2/eps would overflow or lose all digits)."""
    big = np.abs(np.asarray(values, dtype=float))
    if big.size and big.max() > MAX_MAGNITUDE:
        raise SceneError(f"{key}: |{key}| reaches {big.max():.3g}; allowed: {_VALUES}")


def close(a: float, b: float) -> bool:
    """Whether a and b agree to 1e-9 relative (absolute below 1)."""
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def check_keys(data: dict) -> None:
    """Refuse a key that is not in `limits.FILE_KEYS`, listing the allowed ones."""
    unknown = [k for k in data if k not in limits.FILE_KEYS]
    if unknown:
        listed = ", ".join(repr(str(k)) for k in unknown)
        raise SceneError(f"unknown key(s) {listed}; allowed keys are {', '.join(limits.FILE_KEYS)}")


def number(key: str, value) -> float:
    """`value`, a finite number within `BOUNDS[key]`, as a float."""
    return parameters.check_number(key, value, _range_text(key), lambda v: BOUNDS[key][0] <= v <= BOUNDS[key][1])


def integer(key: str, value) -> int:
    """`value`, an integer (or a float without a fraction) within `INT_BOUNDS[key]`, as an int."""
    if is_number(value) and not isinstance(value, numbers.Integral):
        v = float(value)
        value = int(v) if math.isfinite(v) and v.is_integer() else value
    if not isinstance(value, numbers.Integral) or isinstance(value, (bool, np.bool_)):
        got = describe(value) if not is_number(value) else repr(value)
        raise SceneError(f"{key}: expected an integer, got {got}; allowed: {_range_text(key)}")
    if not INT_BOUNDS[key][0] <= int(value) <= INT_BOUNDS[key][1]:
        raise SceneError(f"{key}: {int(value)} is out of range; allowed: {_range_text(key)}")
    return int(value)


def nt_from_dt(value, T: float) -> int:
    """The number of steps a time step `value` divides T into."""
    try:
        dt = float(value) if is_number(value) else math.nan
    except OverflowError:
        dt = math.inf
    if not math.isfinite(dt) or dt <= 0:
        raise SceneError(f"dt: expected a positive number that divides T, got {describe(value)}")
    steps = T / dt
    lo, hi = INT_BOUNDS["nt"]
    if not math.isfinite(steps) or not lo - 0.5 <= steps <= hi + 0.5:
        raise SceneError(f"dt: T/dt = {steps:.6g} steps; allowed: dt dividing T into {lo} to {hi} steps")
    n = round(steps)
    if n < lo or n > hi or abs(n * dt - T) > limits.DT_RELATIVE_TOLERANCE * T:
        raise SceneError(f"dt: {fmt(dt)} does not divide T = {fmt(T)} (T/dt = {steps:.12g}); allowed: {_ALLOWED['dt']}")
    return n


def expression_text(key: str, value) -> str:
    """An expression's text: a string as it is, a number (`v0 = -50` reads naturally in TOML) as its text."""
    if isinstance(value, str):
        return value
    if is_number(value):
        if isinstance(value, numbers.Integral):
            return str(int(value))
        if not math.isfinite(float(value)):
            raise SceneError(f"{key}: {value!r} is not finite; allowed: an expression in x or a finite number")
        return repr(float(value))
    raise SceneError(f"{key}: expected an expression string or a number, got {describe(value)}")


def initial_data(key: str, value):
    """`eta0` or `v0`: an expression (`expression_text`), or nodal values as a tuple of finite floats."""
    if isinstance(value, str) or is_number(value):
        return expression_text(key, value)
    if not isinstance(value, (list, tuple, np.ndarray)):
        raise SceneError(f"{key}: expected an expression string, a number or an array of nodal values, got "
                         f"{describe(value)}")
    kind = np.asarray(value).dtype.kind if not np.ma.isMaskedArray(value) else "masked"
    if kind not in "biuf" or len(value) == 0:  # complex parts and masks would be dropped silently
        raise SceneError(f"{key}: expected numbers in its array (real, none masked), got {describe(value)}; allowed: "
                         f"nodal {_VALUES}")
    values = np.asarray(value, dtype=float)
    if values.ndim != 1:
        raise SceneError(f"{key}: an array of nodal values must be a flat list of nx + 1 numbers; got shape "
                         f"{values.shape}")
    bad = np.flatnonzero(~np.isfinite(values) | (np.abs(values) > MAX_MAGNITUDE))
    if bad.size:
        raise SceneError(f"{key}: value {float(values[bad[0]])!r} at node {int(bad[0])} is not finite or too large; "
                         f"allowed: nodal {_VALUES}")
    return tuple(values.tolist())


def initial_fields(value, nx: int | None) -> tuple:
    """The ``fields0`` table as (name, value) pairs, each value as `initial_values`'."""
    pairs = tuple(value.items()) if isinstance(value, dict) else tuple(value)
    return tuple((name, initial_values(f"fields0.{name}", v, nx)) for name, v in pairs)


def initial_values(key: str, value, nx: int | None):
    """`initial_data`, its nodal values (if any) checked to fit a string of `nx` cells (a membrane takes none)."""
    values = initial_data(key, value)
    if not isinstance(values, tuple):
        return values
    if nx is None:
        raise SceneError(f"{key}: an array of nodal values is for a string (domain interval); allowed on a membrane: "
                         "an expression in x, y or a number")
    if len(values) != nx + 1:
        raise SceneError(f"{key}: {len(values)} nodal values for nx = {nx} cells; allowed: nx + 1 = {nx + 1} values in "
                         "the order of x")
    return values


def text(key: str, value) -> str:
    """`value`, a string."""
    if not isinstance(value, str):
        raise SceneError(f"{key}: expected a string, got {describe(value)}")
    return value


def check_name(value) -> str:
    """A scene's name: it ends up in output folders and file names, so one safe line."""
    if (not isinstance(value, str) or not 1 <= len(value) <= limits.NAME_MAX or not value.isprintable() or "/" in value
            or "\\" in value or value.startswith(".")):
        raise SceneError(f"name: invalid name {describe(value)}; allowed: {_ALLOWED['name']}")
    return value


def check_parameters(scene, put) -> None:
    """The ``[parameters]`` table: its form, and its values against the named model's constants, if it has some."""
    constants, rule = names.declared(scene.model) if scene.model is not None else ((), None)
    put("parameters", parameters.check_table(scene.parameters, declared=constants))
    if constants:
        parameters.resolve_parameters(scene.model, constants, dict(scene.parameters), rule)


def check_scheme(key: str, value) -> str:
    """A registered time scheme's name."""
    if value not in names.SCHEMES:
        raise SceneError(f"scheme: invalid value {describe(value)}; allowed: {', '.join(names.SCHEMES)}")
    return value


def check_scheme_options(key: str, value) -> tuple:
    """A ``[scheme]`` table's other options as (name, value) pairs: a word, a number or true/false each."""
    pairs = tuple(value.items()) if isinstance(value, dict) else tuple(value)
    if len(pairs) > limits.SCHEME_OPTIONS_MAX:
        raise SceneError(f"scheme: {len(pairs)} options; allowed: at most {limits.SCHEME_OPTIONS_MAX}")
    for name, v in pairs:
        if not (isinstance(name, str) and name.isidentifier()):
            raise SceneError(f"scheme: option name {describe(name)}; allowed: a name (letters, digits, _)")
        if not isinstance(v, (str, bool)) and not (is_number(v) and math.isfinite(float(v))):
            raise SceneError(f"scheme.{name}: {describe(v)}; allowed: a word, a finite number or true/false")
    return pairs


def check_petsc_options(value, key: str = "petsc_options") -> tuple:
    """The (name, value) pairs of a petsc_options table, checked against the allow-list; SceneError naming `key`."""
    allow = _ALLOWED["petsc_options"]
    if not isinstance(value, dict):
        raise SceneError(f"{key}: expected a table of options, got {describe(value)}; allowed: {allow}")
    if len(value) > limits.PETSC_MAX_OPTIONS:
        raise SceneError(f"{key}: {len(value)} options; allowed: {allow}")
    pairs = []
    for name, v in value.items():
        if not (isinstance(name, str) and _petsc_name_ok(name)):
            if name in limits.PETSC_REFUSED_NAMES:  # within an allowed prefix: say why this one is not
                raise SceneError(f"{key}: option {name!r} is not allowed (MUMPS ICNTL 1-4 name Fortran output units, "
                                 f"files fort.N, and ICNTL 22 writes out-of-core files); allowed: {allow}")
            if isinstance(name, str) and _petsc_name_ok(name.lower()):  # PETSc's manual writes pc_hypre_boomeramg_P_max
                raise SceneError(f"{key}: option {name!r} is not allowed: write it in lower case, {name.lower()!r} "
                                 f"(PETSc's option names are case-insensitive); allowed: {allow}")
            raise SceneError(f"{key}: option {describe(name)} is not allowed; allowed: {allow}")
        word = isinstance(v, str) and _PETSC_WORD.fullmatch(v) and "python" not in v.lower()
        if not (word or isinstance(v, bool) or (is_number(v) and math.isfinite(v))):
            raise SceneError(f"{key}: {name} = {describe(v)} is not allowed; allowed: {allow}")
        pairs.append((name, v))
    return tuple(pairs)


def _petsc_name_ok(name: str) -> bool:
    return bool(_PETSC_NAME.fullmatch(name) and name.startswith(limits.PETSC_PREFIXES) and name not in
                limits.PETSC_REFUSED_NAMES and not any(word in name for word in limits.PETSC_REFUSED_WORDS))


def check_output_times(value, T: float) -> tuple[float, ...]:
    """At most limits.MAX_OUTPUT_TIMES numbers in [0, T], ascending, as a tuple of floats."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise SceneError(f"output_times: expected a list of numbers in [0, T], got {describe(value)}")
    if len(value) > limits.MAX_OUTPUT_TIMES:
        raise SceneError(f"output_times: {len(value)} times; allowed: at most {limits.MAX_OUTPUT_TIMES} times in "
                         f"[0, T = {fmt(T)}]")
    for t in value:
        if not is_number(t) or not math.isfinite(float(t)):
            raise SceneError(f"output_times: expected numbers in [0, T = {fmt(T)}], got {describe(t)}")
        if not 0.0 <= float(t) <= T:
            raise SceneError(f"output_times: {fmt(t)} is out of range; allowed: numbers in [0, T = {fmt(T)}]")
    times = tuple(float(t) for t in value)
    if any(b <= a for a, b in itertools.pairwise(times)):
        raise SceneError("output_times: must be sorted ascending without duplicates")
    return times


def check_storage(scene) -> None:
    """Refuse a scene whose stored rows would not fit (a membrane's: 0, T and the output times), before allocating."""
    n, most = len(scene.output_times), f"allowed: at most {limits.MAX_STORED_BYTES / 1e9:g} GB"
    if scene.dim == 1 and (need := limits.stored_bytes(scene.nx, scene.nt, n)) > limits.MAX_STORED_BYTES:
        raise SceneError(f"nx, nt, output_times: the stored rows need {need / 1e9:.3g} GB ((min(nt, "
                         f"{limits.STORED_ROWS}) + 2 + {n} output times) rows x (nx + 1) nodes x "
                         f"{limits.BYTES_PER_STORED_NODE} bytes); {most}; reduce nx or the number of output times")
    if scene.dim == 2 and (need := limits.stored_bytes(scene.node_estimate - 1, 0, n)) > limits.MAX_STORED_BYTES:
        raise SceneError(f"output_times: the rows at 0, T and the {n} output times need {need / 1e9:.3g} GB on about "
                         f"{scene.node_estimate} nodes; {most}; use fewer output times or a coarser mesh")
