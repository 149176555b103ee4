"""The keys a scene file may hold and the limits on their values (ranges, sizes, the stored rows' memory)."""

from __future__ import annotations

#: The domains and the geometry keys each one takes, with their defaults (None: required, or for the end heights
#: eta0's values there; docs/howto/membranes.md). A `mesh` key alone means "file".
DOMAIN_KEYS = {
    "interval": {"length": 1.0, "nx": None, "h_left": None, "h_right": None},
    "rectangle": {"size": (1.0, 1.0), "cells": None},
    "disk": {"radius": 1.0, "mesh_size": None},
    "file": {"mesh": None},
}
#: Optional expression fields in x that reach the model as P1 functions (`Parameters.extra`).
FIELD_KEYS = ("load", "obstacle")
#: Required keys; besides these, exactly one of nt or dt (a scheme requires its own options, such as eps).
REQUIRED_KEYS = ("T", "alpha", "nx", "eta0", "v0")
#: The scheme's options that also work at the top level of a file, with a warning (else: the ``[scheme]`` table).
SCHEME_KEYS_AT_TOP = ("eps", "restitution")
#: The most options a ``[scheme]`` table may hold.
SCHEME_OPTIONS_MAX = 32
#: The largest scene file read, in bytes.
MAX_FILE_BYTES = 1_000_000
DT_RELATIVE_TOLERANCE = 1e-9  # dt must divide T up to this relative error

#: The range [low, high] of each number: wide enough for any sensible run, tight enough to catch typos. length,
#: radius and T at least 1e-6 (1e-300 made a zero-length interval); eps: docs/explanation/reliability.md.
BOUNDS = {"length": (1e-6, 1e4), "radius": (1e-6, 1e4), "T": (1e-6, 1e4), "alpha": (0.0, 1e4), "eps": (1e-12, 1e6),
          "h": (-1e6, 1e6), "h_left": (-1e6, 1e6), "h_right": (-1e6, 1e6), "restitution": (0.0, 1.0)}
# nx: dolfinx's mesh set-up is deaf to Ctrl-C: 0.5 s at 1e5 cells, minutes at 1e6 (benchmarks/bench_mesh_size.py).
INT_BOUNDS = {"nx": (2, 100_000), "nt": (1, 100_000_000), "cells": (1, 2000)}
#: At most this many output times: each is a stored row (and an XDMF frame, within --frames).
MAX_OUTPUT_TIMES = 1000
#: The stored rows may take at most this many bytes.
MAX_STORED_BYTES = 2_000_000_000
#: The bytes of one node in one stored row: eta, velocity, contact force (float64) and contact (bool).
BYTES_PER_STORED_NODE = 3 * 8 + 1
#: The solver's default number of stored rows (`Storage(max_rows=400)`), besides 0, T and the output times.
STORED_ROWS = 400
NAME_MAX = 100
#: petsc_options: a scene is data, so only solver settings, never an option that opens, writes or runs anything.
PETSC_PREFIXES = ("ksp_", "pc_", "mat_mumps_icntl_", "mat_mumps_cntl_", "mat_superlu_dist_",
                  # a nonlinear model's Newton step (timestepping/newton.py): its tolerances and line search only
                  "snes_rtol", "snes_atol", "snes_stol", "snes_max_it", "snes_linesearch_type")
#: Refused inside a name: viewers, monitors, reasons (a file, a window), debuggers, logs, Python classes. Refused
#: names: MUMPS' ICNTL 1-4 (Fortran output units, files fort.N) and 22 (out-of-core files).
PETSC_REFUSED_WORDS = ("view", "monitor", "draw", "debugger", "log", "print", "python", "file", "dump", "save",
                       "history", "reason")
PETSC_REFUSED_NAMES = tuple(f"mat_mumps_icntl_{i}" for i in (1, 2, 3, 4, 22))
PETSC_MAX_OPTIONS = 32
#: A rectangle's cells per direction and a disk's radius / mesh_size (gmsh takes minutes beyond).
MAX_CELLS = INT_BOUNDS["cells"][1]
MAX_DISK_RATIO = 1000
#: A membrane's nodes: the largest measured, 1001 x 1001, whose serial set-up peaked at 3096 MB RSS, 3.1 KB per
#: node (benchmarks/bench_memory.py); cells = [2000, 2000] took 7 GB and more before a MemoryError.
MAX_MEMBRANE_NODES = 1001 * 1001
SETUP_BYTES_PER_NODE = 3100
#: The largest |eta0|, |v0|, load or obstacle value a scene may give.
MAX_MAGNITUDE = 1e6


def stored_bytes(nx: int, nt: int, n_output_times: int, max_rows: int = STORED_ROWS) -> int:
    """An upper bound on the memory of a run's stored rows: rows × (nx + 1) nodes × BYTES_PER_STORED_NODE."""
    rows = min(nt, max_rows) + 2 + n_output_times  # every k-th step, 0 and T, the output times
    return rows * (nx + 1) * BYTES_PER_STORED_NODE


#: The keys a scene file (or `Scene.replace`) accepts, in order: key -> (type, unit, default, meaning); the
#: scene-keys reference is generated from it. Units: wave speed 1, so x and t share a unit; η is a height.
KEY_DOCS = {
    "name": ("string", "", "the file's name without .toml", "the scene's name (titles, output file names)"),
    "description": ("string", "", '""', "one line shown by `stringcontact list`"),
    "notes": ("string", "", '""', "how the source data were read (free text)"),
    "domain": ("string", "", '"interval" ("file" with mesh)', "the domain: interval (string), rectangle, disk, file"),
    "length": ("number", "x", "1", "the string's length l: the interval (0, l)"),
    "size": ("list of 2 numbers", "x", "[1, 1]", "the rectangle [0, Lx] × [0, Ly]"),
    "cells": ("list of 2 integers", "", "required (rectangle)", "the rectangle's cells per direction [nx, ny]"),
    "radius": ("number", "x", "1", "the disk's radius (centre 0)"),
    "mesh_size": ("number", "x", "required (disk)", "gmsh's largest element size on the disk"),
    "mesh": ("string", "", "required (file)", "the path of an XDMF triangle mesh (the domain 'file')"),
    "T": ("number", "t", "required", "the final time"),
    "alpha": ("number", "t", "required", "viscosity α (the damping term α η_txx)"),
    "nx": ("integer", "", "required (1D)", "number of cells of the interval"),
    "nt": ("integer", "", "one of nt, dt", "number of time steps"),
    "dt": ("number", "t", "one of nt, dt", "time step; T/dt must be an integer (stored as nt)"),
    "eta0": ("expression or number", "η", "required", "initial displacement η(0, x), an expression in x (2D: x, y)"),
    "v0": ("expression or number", "η/t", "required", "initial velocity η_t(0, x)"),
    "fields0": ("table", "", "not given: each field's rule (docs/howto/nonlinear_models.md)", ("the initial values of "
                "the model's further unknowns (`Model.fields`), name = an expression in x (2D: x, y), a number, or (1D) "
                "nx + 1 nodal values")),
    "h": ("number (2D: or expression)", "η", "eta0 at the ends (2D: on the boundary)", ("the height at which both ends "
           "(2D: the boundary) are held")),
    "h_left": ("number", "η", "eta0(0)", "the height of the left end"),
    "h_right": ("number", "η", "eta0(l)", "the height of the right end"),
    "load": ("expression or number", "η/t²", "not given: no load", ("external force density f(x), for a model that "
              "reads it (`loaded_obstacle`)")),
    "obstacle": ("expression or number", "η", "not given: ψ = 0", ("obstacle profile ψ(x) (2D: ψ(x, y)), for a model "
                  "that reads it; with t in it the obstacle moves")),
    "output_times": ("list of numbers", "t", "[]", "times stored exactly (snapshots, XDMF frames)"),
    "model": ("string", "", '"inelastic"', "a registered model (`stringcontact models`), never a module path"),
    "scheme": ("string or table", "", '"paper"', ("the time scheme (`stringcontact.SCHEMES`): its name, or a [scheme] "
                "table of its `name` and its options (eps, penalty, mass, restitution, ...: `stringcontact.SCHEMES`' "
                "own declarations)")),
    "eps": ("number", "t", "required by the penalty schemes (paper, newmark)", ("[scheme] table: the penalty ε, the "
             "contact force (1/ε) χ{η < ψ} (η_t)⁻; scheme projection (no penalty) does not read it (at the top level "
             "of a file too, with a warning)")),
    "restitution": ("number", "", "0 (inelastic)", ("[scheme] table: scheme projection's restitution coefficient e "
                     "(Paoli-Schatzman); at the top level of a file too, with a warning")),
    "parameters": ("table", "", "the model's defaults", ("the model's constants, name = number (each model's in the "
                    "table below; `stringcontact show`)")),
    "petsc_options": ("table", "", "not given: the scheme's solver", "PETSc options for the linear solver"),
}
#: The keys a scene file (or `Scene.replace`) accepts, in the order they are written.
FILE_KEYS = tuple(KEY_DOCS)
