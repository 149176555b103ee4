"""The step's linear solve (docs/explanation/linear_solvers.md): LU or CG chosen by the system's size, PETSc options.

`check_option_values` refuses what PETSc (a KSP or a Newton step) would reject, crash or loop on, before the mesh;
`solver_options` is the size rule with a scene's or the command line's options on top; `configured_ksp` builds a
KSP from them under its own prefix; `Linear` solves A x = b for a matrix that stays, or changes now and then (a
damping on its diagonal); `dirichlet_rows` puts identity rows at the fixed ends.
"""

from __future__ import annotations

import contextlib
import functools
import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SceneError
from ..scene.limits import MAX_MEMBRANE_NODES
from .base import Ranks

#: Global unknowns up to which the step's constant system is LU-factorised once in serial, else CG: every membrane
#: a scene allows (1001²). Measured (docs/explanation/linear_solvers.md): the LU's step was the cheapest in flight up
#: to 1e6 nodes (154-158 ms against CG's 748-889) and grew like N; only its set-up and memory grow faster.
LU_MAX_NODES = MAX_MEMBRANE_NODES
#: The same on several ranks (MUMPS): on 2 ranks CG + Jacobi was the cheaper step from 1e3 to 1e6 nodes, with a third
#: of MUMPS' set-up and less memory (docs/explanation/linear_solvers.md). A string keeps its LU (no fill) on any number.
LU_MAX_NODES_PARALLEL = 1_000
#: CG stops at a true residual of CG_RTOL ‖b‖: the ledger books the step's work with the computed η, so a residual
#: leaks into it; at 1e-14 it is the LU's own round-off, and the 2D ledgers close to 1e-10 E(0).
CG_RTOL = 1e-14
#: CG's preconditioner: Jacobi while Gershgorin's bound of the Jacobi-scaled matrix's condition number is at most this,
#: else BoomerAMG (3 to 7 iterations whatever the mesh). Measured: Jacobi won at bounds 41 to 193, AMG at 640
#: (docs/explanation/linear_solvers.md).
JACOBI_MAX_CONDITION = 100.0

#: The options of each path; a scene's or the command line's `petsc_options` go on top, key by key.
DIRECT = {"ksp_type": "preonly", "pc_type": "lu"}
ITERATIVE = {"ksp_type": "cg", "ksp_rtol": CG_RTOL, "ksp_atol": 0.0, "ksp_norm_type": "unpreconditioned",
             "ksp_initial_guess_nonzero": True, "ksp_max_it": 1000}
JACOBI = {"pc_type": "jacobi"}
AMG = {"pc_type": "hypre", "pc_hypre_type": "boomeramg"}

#: Every KSP takes its options under this prefix, set just before its setFromOptions and removed just after.
PREFIX = "stringcontact_"

#: Options that take a number, an integer or a boolean; every name ending in "_type" takes a word.
NUMBER_OPTIONS = ("ksp_rtol", "ksp_atol", "ksp_divtol", "mat_mumps_cntl_", "snes_rtol", "snes_atol", "snes_stol")
INTEGER_OPTIONS = ("ksp_max_it", "ksp_gmres_restart", "mat_mumps_icntl_", "snes_max_it")
BOOLEAN_OPTIONS = ("ksp_initial_guess_nonzero",)

#: The ranges of integer options PETSc allocates or loops over unchecked (pc_mg_levels = 100 and ksp_gmres_restart =
#: 1e8 crash it, pc_hypre_boomeramg_max_iter = 2**31 - 1 runs for hours); any other takes [0, INTEGER_MAX], MUMPS'
#: ICNTL (negative codes, sizes in MB) 32 bits.
INTEGER_RANGES = {
    "ksp_max_it": (0, 100_000),
    "ksp_gmres_restart": (1, 1000),
    "ksp_lgmres_augment": (0, 100),
    "ksp_bcgsl_ell": (1, 20),
    "pc_factor_levels": (0, 20),
    "pc_asm_overlap": (0, 20),
    "pc_hypre_boomeramg_max_iter": (1, 100),
    "pc_hypre_boomeramg_max_levels": (2, 50),
    "pc_gamg_levels": (1, 30),
    "pc_mg_levels": (1, 30),
}
INTEGER_MAX = 1000
MUMPS_ICNTL_RANGE = (-(2**31), 2**31 - 1)

#: Preconditioners and Krylov methods that need code or data the solver does not give (a shell's function,
#: fieldsplit's index sets, multigrid's interpolations) or a matrix type it does not make: PETSc stops or crashes.
NEEDS_CODE = {
    "pc_type": ("shell", "python", "fieldsplit", "mg", "composite", "ksp", "redistribute", "patch", "deflation",
                "lmvm", "bddc", "nn", "is", "telescope", "lsc", "galerkin", "cp", "hmg", "exotic", "tfs", "h2opus",
                "hpddm", "pfmg", "syspfmg"),
    "ksp_type": ("python", "fetidp", "hpddm"),
}
#: Factorisations of PETSc's own, which work on one rank only (MatGetFactor fails on an MPI matrix).
SERIAL_FACTORS = ("lu", "ilu", "icc", "cholesky")


def check_option_values(options: dict, key: str = "petsc_options", ranks: int = 1) -> None:
    """Refuse (SceneError, one line naming the option and what is allowed) a value PETSc would reject at set-up,
    crash or loop on: a word, number, integer or boolean where one is read, integers in their ranges
    (`INTEGER_RANGES`), a KSP, PC, factor solver or ordering type this PETSc build lacks or that needs code
    (`NEEDS_CODE`), PETSc's own factorisations on more than one of `ranks`, Newton's tolerances and line searches
    (`_check_newton`). Milliseconds: run before the mesh."""
    for name, value in options.items():
        kind = _wrong_kind(name, value)
        if kind is not None:
            raise SceneError(f"{key}: {name} = {_option_text(value)} is not {kind}; allowed: {kind}")
        _check_range(key, name, value)
        if not isinstance(value, str):
            continue
        choices = _type_choices(name)
        if value in NEEDS_CODE.get(name, ()):
            usable = [t for t in choices or () if t not in NEEDS_CODE[name]]
            raise SceneError(f"{key}: {name} = {value!r} needs code or data that this solver does not give (PETSc "
                             f"stops at set-up); allowed: {', '.join(usable)}")
        if name.endswith("pc_type") and value == "hypre":  # `without_hypre` replaces it where PETSc has none
            continue
        if choices is not None and value not in choices:
            raise SceneError(f"{key}: {name} = {value!r} is not a choice of this PETSc build; allowed: "
                             f"{', '.join(choices)}")
    _check_parallel(options, key, ranks)
    _check_newton(options, key)


#: The largest tolerances Newton's stopping test may be given: above them it passes at once (snes_atol = 1e300
#: took the guess as the step's solution after 0 iterations: η = −2, the energy up 30 %, the run "complete").
SNES_TOLERANCE_MAX = {"snes_atol": 1e-6, "snes_rtol": 1e-2, "snes_stol": 1e-2}
#: The line searches a Newton step may take: "shell" needs a function of the caller's (PETSc stops with error 83),
#: and the error-oriented "nleqerr" does not take the bounds of a variational inequality (`VI_LINESEARCHES`).
LINESEARCHES = ("bt", "basic", "l2", "cp", "nleqerr")
VI_LINESEARCHES = ("bt", "basic", "l2", "cp")


def _check_newton(options: dict, key: str) -> None:
    """SceneError for a Newton tolerance that makes its stopping test vacuous (`SNES_TOLERANCE_MAX`), < 1 iteration, or a line search it cannot run."""
    for name, high in SNES_TOLERANCE_MAX.items():
        value = options.get(name)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and not 0 <= value <= high:
            raise SceneError(f"{key}: {name} = {value:g} is out of range; allowed: a number in [0, {high:g}] (a "
                             "larger one passes Newton's stopping test without solving the step)")
    iterations = options.get("snes_max_it")
    if isinstance(iterations, int) and not isinstance(iterations, bool) and iterations < 1:
        raise SceneError(f"{key}: snes_max_it = {iterations} is out of range; allowed: an integer in [1, 1000]")
    search = options.get("snes_linesearch_type")
    if search is not None and search not in LINESEARCHES:
        raise SceneError(f"{key}: snes_linesearch_type = {search!r} is not a line search a Newton step can take "
                         f"(it needs code or is unknown); allowed: {', '.join(LINESEARCHES)}")


def check_vi_linesearch(options: dict) -> None:
    """SceneError for a line search without bounds in a VI's step (a field bounded below, `Model.field_lower`)."""
    search = options.get("snes_linesearch_type")
    if search is not None and search not in VI_LINESEARCHES:
        raise SceneError(f"petsc_options: snes_linesearch_type = {search!r} does not take the bounds of this model's "
                         f"step (a variational inequality: a field bounded below); allowed: {', '.join(VI_LINESEARCHES)}")


def _check_range(key: str, name: str, value) -> None:
    """Integers in their range: `INTEGER_RANGES`, MUMPS' ICNTL in 32 bits, any other in [0, INTEGER_MAX]."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or name.startswith(NUMBER_OPTIONS):
        return
    if not (name.startswith(INTEGER_OPTIONS) or name in INTEGER_RANGES or isinstance(value, int)):
        return  # a float where PETSc reads a real (pc_hypre_boomeramg_strong_threshold = 0.5)
    low, high = (MUMPS_ICNTL_RANGE if name.startswith("mat_mumps_icntl_")
                 else INTEGER_RANGES.get(name, (0, INTEGER_MAX)))
    if not low <= value <= high:
        raise SceneError(f"{key}: {name} = {_option_text(value)} is out of range; allowed: an integer in [{low}, {high}]")


def _check_parallel(options: dict, key: str, ranks: int) -> None:
    """PETSc's own LU, ILU, ICC and Cholesky on one rank only."""
    pc = options.get("pc_type")
    package = options.get("pc_factor_mat_solver_type", "mumps" if pc in ("lu", "cholesky") else "petsc")
    if ranks > 1 and pc in SERIAL_FACTORS and package == "petsc":  # LU and Cholesky default to MUMPS there
        if pc in ("lu", "cholesky"):
            fix = f"pc_factor_mat_solver_type = 'mumps' with pc_type = {pc!r}, or one rank"
        else:
            fix = "pc_type = 'hypre', 'gamg', 'bjacobi' or 'jacobi', or one rank"
        raise SceneError(f"{key}: pc_type = {pc!r} with PETSc's own factorisation runs on one rank only, not on "
                         f"{ranks}; allowed: {fix}")


def _wrong_kind(name: str, value) -> str | None:
    """The kind of value option `name` takes, in words, if `value` is not of it; else None."""
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if name.endswith("_type"):
        kind, ok = "a word (a PETSc type name)", isinstance(value, str)
    elif name.startswith(NUMBER_OPTIONS):
        kind, ok = "a number >= 0", number and value >= 0
    elif name.startswith(INTEGER_OPTIONS):
        kind, ok = "an integer", number and float(value).is_integer()
    elif name in BOOLEAN_OPTIONS:
        kind, ok = "true or false", isinstance(value, bool)
    else:
        return None
    return None if ok else kind


def _type_choices(name: str) -> tuple[str, ...] | None:
    """The values PETSc accepts for `name` here, or None when they are not asked (left to PETSc)."""
    if name in ("ksp_type", "pc_type"):
        return _installed(name)
    if name == "pc_factor_mat_solver_type":  # the built-in factorisation and the external packages built in
        return tuple(t for t in _names(PETSc.Mat.SolverType) if t == "petsc" or PETSc.Sys.hasExternalPackage(t))
    if name == "pc_factor_mat_ordering_type":
        return _names(PETSc.Mat.OrderingType)
    return None


def _names(types) -> tuple[str, ...]:
    return tuple(sorted(v for k, v in vars(types).items() if not k.startswith("_") and isinstance(v, str)))


@functools.cache
def _installed(name: str) -> tuple[str, ...]:
    """petsc4py's KSP (`name` "ksp_type") or PC types this build can make, each tried on a fresh object on
    PETSC_COMM_SELF; never "python" (a scene is data)."""
    make = PETSc.KSP if name == "ksp_type" else PETSc.PC
    ok = []
    for t in _names(make.Type):
        obj = make().create(PETSc.COMM_SELF)
        try:
            obj.setType(t)
            ok.append(t)
        except PETSc.Error:
            pass
        with contextlib.suppress(PETSc.Error):  # a type never set up may fail its own reset (pipelcg): harmless
            obj.destroy()
    return tuple(t for t in ok if t != "python")


def solver_options(n_global: int, ranks: int, options: dict | None = None, condition: float = math.inf,
                   dim: int = 2, notes: list | None = None) -> dict:
    """The PETSc options for `n_global` unknowns: LU up to LU_MAX_NODES (LU_MAX_NODES_PARALLEL on several ranks, but
    a string's, `dim` 1), else CG; then `options`. A user's ksp_type (or pc_type) picks the path. CG's preconditioner,
    unless named: Jacobi if `condition` (`jacobi_condition_bound`) is at most JACOBI_MAX_CONDITION, else AMG (gamg
    without hypre, `without_hypre`, with a line in `notes`)."""
    options = dict(options or {})
    kind = options.get("ksp_type") or ({"lu": "preonly", "cholesky": "preonly"}.get(options.get("pc_type"), "cg")
                                       if "pc_type" in options else None)
    limit = LU_MAX_NODES if ranks == 1 or dim == 1 else LU_MAX_NODES_PARALLEL
    direct = kind == "preonly" if kind is not None else n_global <= limit
    if direct:
        chosen = dict(DIRECT, **({"pc_factor_mat_solver_type": "mumps"} if ranks > 1 else {}))
    else:
        chosen = ITERATIVE | (JACOBI if condition <= JACOBI_MAX_CONDITION else AMG)
    if "pc_type" in options and not direct:  # the user's preconditioner replaces the chosen one, sub-options too
        chosen = dict(ITERATIVE)
    chosen.update(options)
    chosen, note = without_hypre(chosen)
    if note and notes is not None:
        notes.append(note)
    return chosen


#: The preconditioner that takes BoomerAMG's place where PETSc has no hypre (the dolfinx wheel's): PETSc's own AMG.
HYPRE_STAND_IN = "gamg"


@functools.cache
def has_hypre() -> bool:
    """Whether this PETSc build has hypre (Debian's has; the dolfinx 0.11 wheel's has not)."""
    return bool(PETSc.Sys.hasExternalPackage("hypre"))


def without_hypre(options: dict) -> tuple[dict, str | None]:
    """`options` with every ``*pc_type = 'hypre'`` (a fieldsplit's sub-solvers' too) as `HYPRE_STAND_IN` and
    hypre's own options left out, where this PETSc has no hypre; and a line saying so (None: nothing replaced)."""
    if has_hypre() or not any(k.endswith("pc_type") and v == "hypre" for k, v in options.items()):
        return options, None
    kept = {k: (HYPRE_STAND_IN if k.endswith("pc_type") and v == "hypre" else v) for k, v in options.items()
            if "pc_hypre_" not in k}
    return kept, f"{HYPRE_STAND_IN} in place of hypre, which this PETSc build does not have"


def jacobi_condition_bound(A: PETSc.Mat) -> float:
    """Gershgorin's bound of κ(D⁻¹A) for a symmetric A with a positive diagonal D: (1 + ρ)/(1 − ρ) with
    ρ = max_i Σ_{j≠i} |a_ij| / a_ii, or inf when ρ ≥ 1 (A not diagonally dominant). One pass over A's rows."""
    ia, _, a = A.getValuesCSR()
    d = A.getDiagonal().array
    row_sums = np.bincount(np.repeat(np.arange(d.size), np.diff(ia)), weights=np.abs(a), minlength=d.size)
    rho = np.max((row_sums - np.abs(d)) / np.where(d > 0, d, np.nan), initial=0.0)
    rho = A.getComm().tompi4py().allreduce(float(rho) if np.isfinite(rho) else math.inf, op=MPI.MAX)
    return (1.0 + rho) / (1.0 - rho) if rho < 1.0 else math.inf


def _option_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


@contextlib.contextmanager
def options_held(prefix: str, options: dict):
    """`options` in PETSc's database under `prefix` for the block, removed after (nothing leaks into another solver);
    some are read only at set-up (MUMPS' ICNTL, fieldsplit's sub-solvers): hold them there too."""
    db = PETSc.Options()
    try:
        for name, value in options.items():
            db.setValue(prefix + name, _option_text(value))
        yield
    finally:
        for name in options:
            db.delValue(prefix + name)


def set_from_options(solver, prefix: str, options: dict) -> None:
    """`solver.setFromOptions()` (a KSP, a SNES) with `options` under `prefix` (`options_held`)."""
    solver.setOptionsPrefix(prefix)
    try:
        with options_held(prefix, options):
            solver.setFromOptions()
    except PETSc.Error as exc:  # a value `check_option_values` cannot ask about (pc_hypre_type = 'bogus'): one line
        reason = str(exc).strip().splitlines()[-1].split("] ", 1)[-1].replace("-" + prefix, "")
        raise SceneError(f"petsc_options: PETSc refused a value ({reason}); allowed: the values PETSc lists") from None


def configured_ksp(A: PETSc.Mat, comm, options: dict) -> PETSc.KSP:
    """A KSP for A set from `options` under its own prefix; the options leave PETSc's database right after."""
    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    set_from_options(ksp, PREFIX, options)
    try:
        with options_held(PREFIX, options):  # MUMPS reads its ICNTL at the factorisation
            ksp.setUp()
    except PETSc.Error as exc:  # a combination the checks cannot foresee: the options' fault, one line
        chosen = ", ".join(f"{k} = {_option_text(v)}" for k, v in options.items() if k.endswith("_type"))
        raise SceneError(f"petsc_options: PETSc cannot set up the linear solver ({chosen}): {_petsc_reason(exc)}; "
                         "allowed: options that PETSc can set up for an assembled matrix") from None
    return ksp


def _petsc_reason(exc: Exception) -> str:
    """PETSc's own one-line reason from a petsc4py error (its message, else its error code)."""
    lines = [line.split("] ", 1)[-1].strip() for line in str(exc).strip().splitlines()]
    lines = [line for line in lines if line and not line.startswith(("See ", "Petsc ", "Configure", "#"))]
    return (lines[0] if lines and lines[0] != "error code" else f"error code {getattr(exc, 'ierr', '?')}")[:200]


class Linear:
    """A x = b for a matrix that stays, or changes now and then (`reset`) or on its diagonal (`update`): LU or CG by
    size and options.

    A has identity rows at the fixed dofs `bc` and every b their heights `g`. ``solve(b, x)``: LU is the factor's
    back-substitution, without KSPSolve's bookkeeping; CG zeroes A's fixed columns too (symmetric) and moves their
    part to b, and starts from the x it is given (``iterative``: give a predictor). `dim`: the mesh's.
    """

    def __init__(self, A: PETSc.Mat, comm, options: dict | None, bc: np.ndarray, g: np.ndarray, dim: int):
        self.A, self.bc, self.notes = A, bc, []
        self.base, self.diagonal = A.getDiagonal().array.copy(), A.createVecLeft()  # A's own diagonal, `update`'s
        self.extra, self.refactorisations, self.anywhere = np.zeros_like(self.base), 0, Ranks(comm).any
        self.options = solver_options(A.getSize()[0], comm.size, options, dim=dim, notes=self.notes)
        kind = self.options["ksp_type"], self.options.get("pc_type")
        self.iterative = not (kind[0] == "preonly" and kind[1] in ("lu", "cholesky"))
        if self.iterative:
            self.lift, self.b = _symmetric_rows(A, bc, g), A.createVecLeft()
            if "pc_type" not in (options or {}):
                self.condition = jacobi_condition_bound(A)
                self.notes.clear()
                self.options = solver_options(A.getSize()[0], comm.size, options, self.condition, dim, self.notes)
        self.ksp = configured_ksp(A, comm, self.options)
        self.iterations = self.solves = 0
        self._bind()

    def _bind(self) -> None:
        self.solve = self._iterate if self.iterative else self.ksp.getPC().getFactorMatrix().solve

    def _iterate(self, b: PETSc.Vec, x: PETSc.Vec) -> None:
        self.b.waxpy(-1.0, self.lift, b)
        self.ksp.solve(self.b, x)
        x.array[self.bc] = b.array[self.bc]  # decoupled rows: exact, whatever the preconditioner did there
        self.iterations += self.ksp.getIterationNumber()
        self.solves += 1
        if self.ksp.getConvergedReason() < 0:
            raise ValueError(f"the linear solver ({self.describe()}) did not converge: PETSc reason "
                             f"{self.ksp.getConvergedReason()} after {self.ksp.getIterationNumber()} iterations; set "
                             "petsc_options (e.g. ksp_rtol, pc_type) or use an LU (ksp_type = 'preonly', pc_type = 'lu')")

    def reset(self) -> None:
        """A's values changed: refactorise (LU) or set the preconditioner up again (CG)."""
        self.ksp.setOperators(self.A)
        self.ksp.setUp()
        self._bind()

    def update(self, extra: np.ndarray) -> None:
        """`extra` on top of A's own diagonal (a damping on the active set): refactorised (LU keeps the symbolic
        factorisation) or CG's preconditioner set up again only if it changed on any rank."""
        if self.anywhere(not np.array_equal(extra, self.extra)):
            np.add(self.base, extra, out=self.diagonal.array)
            self.A.setDiagonal(self.diagonal)
            self.reset()
            self.extra[:] = extra
            self.refactorisations += 1

    def describe(self, *others: Linear) -> str:
        """One line: e.g. "LU (mumps)" or "cg + hypre boomeramg, mean 7.2 iterations per solve", the mean over
        this solver's solves and those of `others` (the contact step's free-step solver, with the same options)."""
        pc = self.ksp.getPC()
        if not self.iterative:
            return f"{pc.getType().upper()} ({pc.getFactorSolverType()})"
        kind = pc.getType() + (f" {pc.getHYPREType()}" if pc.getType() == "hypre" else "")
        solves = self.solves + sum(o.solves for o in others)
        mean = (self.iterations + sum(o.iterations for o in others)) / solves if solves else 0.0
        return f"{self.ksp.getType()} + {kind}, mean {mean:.1f} iterations per solve" + "".join(
            f" ({note})" for note in self.notes)


def dirichlet_rows(A: PETSc.Mat, bc: np.ndarray) -> None:
    """Identity rows at the fixed ends (their values are set in the right-hand side)."""
    rstart = A.getOwnershipRange()[0]
    A.zeroRows((bc + rstart).astype(np.int32), diag=1.0)


def _symmetric_rows(A: PETSc.Mat, bc: np.ndarray, g: np.ndarray) -> PETSc.Vec:
    """Zero A's fixed columns too (A has identity rows there); the lift A_{free,fixed} g that b must lose."""
    fixed = A.createVecRight()
    fixed.array[bc] = g
    lift = A.createVecLeft()
    A.mult(fixed, lift)
    lift.array[bc] = 0.0
    rstart = A.getOwnershipRange()[0]
    A.zeroRowsColumns((bc + rstart).astype(np.int32), diag=1.0)
    return lift
