"""Validation of scene data: each function checks one value and raises `SceneError` with one line that names
the key and what is allowed (docs/explanation/reliability.md). Used by `scene.Scene` and `check_petsc_options` by the CLI.
"""

from __future__ import annotations

import errno
import math
import numbers
import os
import re
import stat

import numpy as np

from ..errors import SceneError
from . import names, parameters
from .limits import (
    BOUNDS,
    BYTES_PER_STORED_NODE,
    DOMAIN_KEYS,
    DT_RELATIVE_TOLERANCE,
    FILE_KEYS,
    INT_BOUNDS,
    MAX_CELLS,
    MAX_DISK_RATIO,
    MAX_MAGNITUDE,
    MAX_MEMBRANE_NODES,
    MAX_OUTPUT_TIMES,
    MAX_STORED_BYTES,
    NAME_MAX,
    PETSC_MAX_OPTIONS,
    PETSC_PREFIXES,
    PETSC_REFUSED_NAMES,
    PETSC_REFUSED_WORDS,
    SETUP_BYTES_PER_NODE,
    STORED_ROWS,
    stored_bytes,
)

_PETSC_NAME = re.compile(r"[a-z][a-z0-9_]{0,59}")
_PETSC_WORD = re.compile(r"[A-Za-z][A-Za-z0-9_+\-]{0,31}")
_PETSC_ALLOWED = (f"a table of at most {PETSC_MAX_OPTIONS} PETSc options named {', '.join(p + '*' for p in PETSC_PREFIXES)} in lower case "
                  f"(but not {', '.join(PETSC_REFUSED_NAMES)}: MUMPS' output units and out-of-core files; no viewers, "
                  "monitors, files or debuggers), each a number, a boolean or a word (letters, digits, _ + -)")
_NAME_ALLOWED = f"1 to {NAME_MAX} printable characters, no '/' or '\\', not starting with '.'"
_SIZE_ALLOWED = f"two numbers [Lx, Ly] in [{BOUNDS['length'][0]:g}, {BOUNDS['length'][1]:g}]"
_CELLS_ALLOWED = f"two integers [nx, ny] in [1, {MAX_CELLS}]"
_MESH_SIZE_ALLOWED = f"a number in [radius/{MAX_DISK_RATIO}, radius]"


def allowed(key: str) -> str:
    """What a scene may give for `key` (a key of `FILE_KEYS`), in the words of the key's error messages; the
    scene-keys reference (docs/reference/scene_keys.md) prints it. KeyError for a key without a text."""
    if key == "h":
        return f"{_range_text(key)} (2D: also an expression in x, y)"
    if key in INT_BOUNDS or key in BOUNDS:
        return _range_text(key)
    lo, hi = INT_BOUNDS["nt"]
    values = f"values in [-{MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}]"
    texts = {
        "name": _NAME_ALLOWED,
        "description": "a string",
        "notes": "a string",
        "dt": f"T/dt an integer in [{lo}, {hi}] (up to {DT_RELATIVE_TOLERANCE:g} relative), or give nt",
        "eta0": f"an expression in x (2D: x, y) or a number; 1D: also nx + 1 nodal values; {values}",
        "v0": f"an expression in x (2D: x, y) or a number; 1D: also nx + 1 nodal values; {values}",
        "load": f"an expression in x (2D: x, y) or a number; {values}",
        "obstacle": f"an expression in x (2D: x, y) and t, or a number; {values}",
        "output_times": f"at most {MAX_OUTPUT_TIMES} numbers in [0, T], ascending, no duplicates",
        "model": "a name registered under the entry-point group stringcontact.models (`stringcontact models`)",
        "scheme": ", ".join(names.SCHEMES),
        "domain": ", ".join(DOMAIN_KEYS),
        "size": _SIZE_ALLOWED,
        "cells": _CELLS_ALLOWED,
        "mesh_size": _MESH_SIZE_ALLOWED,
        "mesh": "the path of an XDMF triangle mesh (*.xdmf)",
        "petsc_options": _PETSC_ALLOWED,
        "parameters": f"a table of at most {parameters.PARAMETERS_MAX} constants the model declares, name = number, "
                      "each in its range (the models' constants below)",
    }
    return texts[key]


def check_mesh_path(path: str) -> None:
    """Refuse a mesh path that is not a regular file, saying what it is (missing, a directory, a FIFO, a loop of
    symbolic links); decided from `stat`, nothing is opened (a FIFO would block)."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        if exc.errno == errno.ENOENT:
            raise SceneError(f"mesh: no such file {path!r}; allowed: an XDMF triangle mesh file (*.xdmf)") from None
        what = "is a loop of symbolic links" if exc.errno == errno.ELOOP else f"cannot be read ({exc.strerror})"
        raise SceneError(f"mesh: {path!r} {what}; allowed: an XDMF triangle mesh file (*.xdmf)") from None
    if not stat.S_ISREG(mode):
        kind = "a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "not a regular file"
        raise SceneError(f"mesh: {path!r} is {kind}; allowed: an XDMF triangle mesh file (*.xdmf), a regular file")


def domain_of(data: dict) -> str:
    domain = data.get("domain", "file" if "mesh" in data else "interval")
    if not isinstance(domain, str) or domain not in DOMAIN_KEYS:
        raise SceneError(f"domain: invalid value {describe(domain)}; allowed: {', '.join(DOMAIN_KEYS)}")
    return domain


def check_domain_keys(data: dict, domain: str) -> None:
    """Refuse a geometry key of another domain (and `domain` disagreeing with `mesh`)."""
    if "mesh" in data and domain != "file":
        raise SceneError(f"mesh: a mesh file is its own domain; remove domain = {domain!r} or mesh")
    for other, keys in DOMAIN_KEYS.items():
        for key in keys:
            if other != domain and key in data:
                raise SceneError(f"{key}: only for domain {other!r}, not {domain!r}; domain {domain!r} takes "
                                 f"{', '.join(DOMAIN_KEYS[domain]) or 'no geometry keys'}")


def check_domain(scene, put) -> None:
    """Validate the domain's geometry keys of `scene` (from Scene.__post_init__; `put` sets a normalised value)."""
    domain = scene.domain
    if domain not in DOMAIN_KEYS:
        raise SceneError(f"domain: invalid value {describe(domain)}; allowed: {', '.join(DOMAIN_KEYS)}")
    given = [k for ks in DOMAIN_KEYS.values() for k in ks if k not in DOMAIN_KEYS[domain] and getattr(scene, k) is not None]
    if given:
        raise SceneError(f"{given[0]}: only for domain 'interval', not {domain!r}" if domain != "interval" else
                         f"{given[0]}: not for domain 'interval'; give domain = 'rectangle', 'disk' or a mesh file")
    if domain == "rectangle":
        put("size", _pair("size", scene.size, lambda v: number("length", v), _SIZE_ALLOWED))
        put("cells", _pair("cells", scene.cells, lambda v: _cell_count(v), _CELLS_ALLOWED))
    elif domain == "disk":
        put("radius", number("radius", scene.radius))
        if scene.mesh_size is None:
            raise SceneError(f"mesh_size: domain 'disk' needs mesh_size; allowed: {_MESH_SIZE_ALLOWED}")
        h = float(scene.mesh_size) if is_number(scene.mesh_size) else math.nan
        if not (scene.radius / MAX_DISK_RATIO <= h <= scene.radius):
            raise SceneError(f"mesh_size: {describe(scene.mesh_size)} is out of range; allowed: {_MESH_SIZE_ALLOWED} (radius = {fmt(scene.radius)})")
        put("mesh_size", h)
    if domain in ("rectangle", "disk"):
        check_membrane_nodes(scene.node_estimate, "cells" if domain == "rectangle" else "mesh_size",
                             list(scene.cells) if domain == "rectangle" else scene.mesh_size)
    elif domain == "file":
        if not isinstance(scene.mesh, str) or not scene.mesh.endswith(".xdmf"):
            raise SceneError(f"mesh: expected the path of an XDMF triangle mesh (*.xdmf), got {describe(scene.mesh)}")
        check_mesh_path(scene.mesh)
    if domain != "interval":
        for key in ("length", "nx", "h_left", "h_right"):
            if getattr(scene, key) is not None:
                raise SceneError(f"{key}: only for domain 'interval', not {domain!r}")
        if scene.h is not None and not isinstance(scene.h, str) and not is_number(scene.h):
            raise SceneError(f"h: expected a number or an expression in x, y, got {describe(scene.h)}")


def check_membrane_nodes(nodes: int, key: str, value) -> None:
    """Refuse a membrane of more than MAX_MEMBRANE_NODES nodes from its set-up's memory estimate, before any mesh."""
    if nodes > MAX_MEMBRANE_NODES:
        raise SceneError(
            f"{key}: {value} gives {'about ' if key == 'mesh_size' else ''}{nodes} nodes, about "
            f"{nodes * SETUP_BYTES_PER_NODE / 1e9:.3g} GB to set up ({SETUP_BYTES_PER_NODE / 1e3:g} KB per node, "
            f"measured at 1e6 nodes); allowed: at most {MAX_MEMBRANE_NODES} nodes"
            + (" (e.g. cells = [1000, 1000])" if key == "cells" else
               f" (mesh_size >= radius/{math.sqrt(MAX_MEMBRANE_NODES * math.sqrt(3) / (2 * math.pi)):.0f})"))


def _pair(key: str, value, convert, allowed: str) -> tuple:
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) or len(value) != 2:
        raise SceneError(f"{key}: expected {allowed}, got {describe(value)}")
    try:
        return tuple(convert(v) for v in value)
    except SceneError:
        raise SceneError(f"{key}: {describe(list(value))} is out of range; allowed: {allowed}") from None


def _cell_count(value) -> int:
    if not is_number(value) or not float(value).is_integer() or not 1 <= int(value) <= MAX_CELLS:
        raise SceneError("cells")
    return int(value)


def check_magnitudes(values: dict[str, np.ndarray]) -> None:
    """Refuse values beyond ±MAX_MAGNITUDE: beyond this, energies of order |.|^2/eps overflow or lose all digits."""
    for key, arr in values.items():
        big = np.abs(np.asarray(arr, dtype=float))
        if big.size and big.max() > MAX_MAGNITUDE:
            raise SceneError(f"{key}: |{key}| reaches {big.max():.3g}; allowed: values in [-{MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}]")


def close(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def check_keys(data: dict) -> None:
    unknown = [k for k in data if k not in FILE_KEYS]
    if unknown:
        listed = ", ".join(repr(str(k)) for k in unknown)
        raise SceneError(f"unknown key(s) {listed}; allowed keys are {', '.join(FILE_KEYS)}")


def _range_text(key: str) -> str:
    if key in INT_BOUNDS:
        lo, hi = INT_BOUNDS[key]
        return f"an integer in [{lo}, {hi}]"
    lo, hi, lo_open, hi_open = BOUNDS[key]
    return f"a number in {'(' if lo_open else '['}{fmt(lo)}, {fmt(hi)}{')' if hi_open else ']'}"


def is_number(value) -> bool:
    # bool is an int in Python, but `nx = true` is surely a mistake.
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def number(key: str, value) -> float:
    if not is_number(value):
        raise SceneError(f"{key}: expected a number, got {describe(value)}; allowed: {_range_text(key)}")
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise SceneError(f"{key}: {value!r} is not finite; allowed: {_range_text(key)}")
    lo, hi, lo_open, hi_open = BOUNDS[key]
    if v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
        raise SceneError(f"{key}: {fmt(v)} is out of range; allowed: {_range_text(key)}")
    return v


def integer(key: str, value) -> int:
    if not is_number(value):
        raise SceneError(f"{key}: expected an integer, got {describe(value)}; allowed: {_range_text(key)}")
    if isinstance(value, numbers.Integral):
        n = int(value)
    else:
        v = float(value)
        if not math.isfinite(v) or not v.is_integer():
            raise SceneError(f"{key}: expected an integer, got {value!r}; allowed: {_range_text(key)}")
        n = int(v)
    lo, hi = INT_BOUNDS[key]
    if not lo <= n <= hi:
        raise SceneError(f"{key}: {n} is out of range; allowed: {_range_text(key)}")
    return n


def nt_from_dt(value, T: float) -> int:
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
    if n < lo or n > hi or abs(n * dt - T) > DT_RELATIVE_TOLERANCE * T:
        raise SceneError(
            f"dt: {fmt(dt)} does not divide T = {fmt(T)} (T/dt = {steps:.12g}); "
            f"allowed: T/dt an integer in [{lo}, {hi}] (up to {DT_RELATIVE_TOLERANCE:g} relative), or give nt"
        )
    return n


def expression_text(key: str, value) -> str:
    # Numbers are accepted as constants: `v0 = -50` reads naturally in TOML.
    if isinstance(value, str):
        return value
    if is_number(value):
        if isinstance(value, numbers.Integral):
            return str(int(value))
        v = float(value)
        if not math.isfinite(v):
            raise SceneError(f"{key}: {value!r} is not finite; allowed: an expression in x or a finite number")
        return repr(v)
    raise SceneError(f"{key}: expected an expression string or a number, got {describe(value)}")


def initial_data(key: str, value):
    """`eta0` or `v0`: an expression (as `expression_text`), or a string's nodal values as an array (a NumPy array, a
    list or a tuple of numbers; a restart from a state): a tuple of finite floats within MAX_MAGNITUDE. Whether their
    number fits the mesh is `check_nodal_values`' question."""
    if isinstance(value, str) or is_number(value):
        return expression_text(key, value)
    if isinstance(value, (list, tuple, np.ndarray)):
        try:
            values = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise SceneError(f"{key}: expected numbers in its array, got {describe(value)}") from None
        if values.ndim != 1:
            raise SceneError(f"{key}: an array of nodal values must be a flat list of nx + 1 numbers; got shape "
                             f"{values.shape}")
        bad = np.flatnonzero(~np.isfinite(values) | (np.abs(values) > MAX_MAGNITUDE))
        if bad.size:
            raise SceneError(f"{key}: value {float(values[bad[0]])!r} at node {int(bad[0])} is not finite or too large; "
                             f"allowed: nodal values in [-{MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}]")
        return tuple(values.tolist())
    raise SceneError(f"{key}: expected an expression string, a number or an array of nodal values, got "
                     f"{describe(value)}")


def check_nodal_values(key: str, values: tuple, nx: int | None) -> None:
    """An array of nodal values fits a string of `nx` cells: nx + 1 of them (a membrane takes none)."""
    if nx is None:
        raise SceneError(f"{key}: an array of nodal values is for a string (domain interval); allowed on a membrane: "
                         "an expression in x, y or a number")
    if len(values) != nx + 1:
        raise SceneError(f"{key}: {len(values)} nodal values for nx = {nx} cells; allowed: nx + 1 = {nx + 1} values in "
                         "the order of x")


def text(key: str, value) -> str:
    if not isinstance(value, str):
        raise SceneError(f"{key}: expected a string, got {describe(value)}")
    return value


def check_name(value) -> str:
    # Names end up in output folders and file names: keep them to one safe line.
    if (
        not isinstance(value, str)
        or not 1 <= len(value) <= NAME_MAX
        or not value.isprintable()
        or "/" in value
        or "\\" in value
        or value.startswith(".")
    ):
        raise SceneError(
            f"name: invalid name {describe(value)}; allowed: {_NAME_ALLOWED}"
        )
    return value


def check_model(value) -> str:
    # A scene is data: it names a registered model and never a module (nothing is imported here).
    return names.check_name(value)


def check_parameters(scene, put) -> None:
    """The ``[parameters]`` table: its form always (`parameters.check_table`); against the constants of the model the
    scene names when that model declares some (loading it: `names.declared`). A table under a model without
    constants waits for the run, which checks it against the model it runs (a ``--model`` may bring them)."""
    constants, rule = names.declared(scene.model) if scene.model is not None else ((), None)
    put("parameters", parameters.check_table(scene.parameters, declared=constants))
    if constants:
        parameters.resolve_parameters(scene.model, constants, dict(scene.parameters), rule)


def check_scheme(value) -> str:
    SCHEMES = names.SCHEMES
    if value not in SCHEMES:
        raise SceneError(f"scheme: invalid value {describe(value)}; allowed: {', '.join(SCHEMES)}")
    return value


def check_scheme_options(value) -> tuple:
    """The (name, value) pairs of a ``[scheme]`` table's options (its name and eps, restitution apart): each a name
    and a word, a number or true/false. What a scheme takes is its own to check, when the run is set up."""
    from .limits import SCHEME_OPTIONS_MAX

    pairs = tuple(value.items()) if isinstance(value, dict) else tuple(value)
    if len(pairs) > SCHEME_OPTIONS_MAX:
        raise SceneError(f"scheme: {len(pairs)} options; allowed: at most {SCHEME_OPTIONS_MAX}")
    for name, v in pairs:
        if not (isinstance(name, str) and name.isidentifier()):
            raise SceneError(f"scheme: option name {describe(name)}; allowed: a name (letters, digits, _)")
        if isinstance(v, str):
            text(f"scheme.{name}", v)
        elif not isinstance(v, bool) and not (is_number(v) and math.isfinite(float(v))):
            raise SceneError(f"scheme.{name}: {describe(v)}; allowed: a word, a finite number or true/false")
    return pairs


def check_petsc_options(value, key: str = "petsc_options") -> tuple:
    """The (name, value) pairs of a petsc_options table, checked against the allow-list; SceneError naming `key`."""
    if not isinstance(value, dict):
        raise SceneError(f"{key}: expected a table of options, got {describe(value)}; allowed: {_PETSC_ALLOWED}")
    if len(value) > PETSC_MAX_OPTIONS:
        raise SceneError(f"{key}: {len(value)} options; allowed: {_PETSC_ALLOWED}")
    return tuple((_petsc_name(key, name), _petsc_value(key, name, v)) for name, v in value.items())


def _petsc_name(key: str, name) -> str:
    if isinstance(name, str) and _petsc_name_ok(name):
        return name
    if name in PETSC_REFUSED_NAMES:  # within an allowed prefix: say why this one is not
        raise SceneError(f"{key}: option {name!r} is not allowed (MUMPS ICNTL 1-4 name Fortran output units, files "
                         f"fort.N, and ICNTL 22 writes out-of-core files); allowed: {_PETSC_ALLOWED}")
    if isinstance(name, str) and _petsc_name_ok(name.lower()):
        # PETSc's manual spells a few names with capitals (pc_hypre_boomeramg_P_max); its options are
        # case-insensitive, and one spelling per option keeps a table free of duplicates.
        raise SceneError(f"{key}: option {name!r} is not allowed: write it in lower case, {name.lower()!r} (PETSc's "
                         f"option names are case-insensitive); allowed: {_PETSC_ALLOWED}")
    raise SceneError(f"{key}: option {describe(name)} is not allowed; allowed: {_PETSC_ALLOWED}")


def _petsc_name_ok(name: str) -> bool:
    return bool(_PETSC_NAME.fullmatch(name) and name.startswith(PETSC_PREFIXES)
                and not any(word in name for word in PETSC_REFUSED_WORDS) and name not in PETSC_REFUSED_NAMES)


def _petsc_value(key: str, name: str, value):
    if isinstance(value, bool) or (is_number(value) and math.isfinite(value)):
        return value
    if isinstance(value, str) and _PETSC_WORD.fullmatch(value) and "python" not in value.lower():
        return value
    raise SceneError(f"{key}: {name} = {describe(value)} is not allowed; allowed: {_PETSC_ALLOWED}")


def check_output_times(value, T: float) -> tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise SceneError(f"output_times: expected a list of numbers in [0, T], got {describe(value)}")
    if len(value) > MAX_OUTPUT_TIMES:
        raise SceneError(f"output_times: {len(value)} times; allowed: at most {MAX_OUTPUT_TIMES} times in [0, T = {fmt(T)}]")
    times = []
    for t in value:
        if not is_number(t) or not math.isfinite(float(t)):
            raise SceneError(f"output_times: expected numbers in [0, T = {fmt(T)}], got {describe(t)}")
        t = float(t)
        if not 0.0 <= t <= T:
            raise SceneError(f"output_times: {fmt(t)} is out of range; allowed: numbers in [0, T = {fmt(T)}]")
        times.append(t)
    if any(b <= a for a, b in zip(times, times[1:])):
        raise SceneError("output_times: must be sorted ascending without duplicates")
    return tuple(times)


def check_storage(nx: int, nt: int, n_output_times: int) -> None:
    """Refuse a scene whose stored rows would not fit, before anything is allocated."""
    need = stored_bytes(nx, nt, n_output_times)
    if need > MAX_STORED_BYTES:
        raise SceneError(
            f"nx, nt, output_times: the stored rows need {need / 1e9:.3g} GB ((min(nt, {STORED_ROWS}) + 2 + "
            f"{n_output_times} output times) rows x (nx + 1) nodes x {BYTES_PER_STORED_NODE} bytes); allowed: at most "
            f"{MAX_STORED_BYTES / 1e9:g} GB; reduce nx or the number of output times"
        )


def check_membrane_storage(nodes: int, n_output_times: int) -> None:
    need = stored_bytes(nodes - 1, 0, n_output_times)  # no steps besides 0, T and the output times
    if need > MAX_STORED_BYTES:
        raise SceneError(
            f"output_times: the rows at 0, T and the {n_output_times} output times need {need / 1e9:.3g} GB on about "
            f"{nodes} nodes; allowed: at most {MAX_STORED_BYTES / 1e9:g} GB; use fewer output times or a coarser mesh"
        )


def fmt(v) -> str:
    v = float(v)
    if v.is_integer() and abs(v) < 1e16:
        return str(int(v))
    return repr(v)


def describe(value) -> str:
    text = repr(value)
    if len(text) > 40:
        text = text[:40] + "..."
    return f"{type(value).__name__} {text}"


