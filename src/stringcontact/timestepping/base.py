"""What every scheme is given (`Setting`), what it must provide (`Scheme`), and the parts they share.

A scheme advances the nodal state (η, v) one step and reports the terms of its own discrete energy
identity, so that the driver's ledger E(0) + W_ext = E(t) + D_visc + D_con + D_num closes to round-off
whatever the scheme. Energy that the contact law (or a projection) removes is always D_con, booked the
same way by every scheme: the work of the nodal contact force f with the step's mean velocity,
−(Δt/2) f·(v^n + v^{n+1}). It is ½ m V² for a node that lands at speed V and stops, whatever ε, and
about 0 for a node held at rest on the obstacle; what a scheme's identity puts elsewhere is D_num.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..fem import nodal
from ..errors import InstabilityError, InstabilityWarning
from ..fem.operators import Operators

#: (kinetic, elastic, viscous, contact, numerical, external, stored): the state energies after a step, then
#: the step's increments of the cumulative terms, then the energy held by a conservative contact law.
StepEnergy = tuple


class NodalLaws:
    """The model's pointwise laws compiled to NumPy at the nodes, in placeholders η, η_old and v.

    ``quotient`` is the paper's v^n = (η^n − η^{n−1})/Δt as UFL; a scheme with a nodal velocity passes
    ``v`` instead. ``set(...)`` points the placeholders at arrays (no copy); ``compile(expr)`` returns a
    `nodal.NodalExpression` whose ``evaluate_env(self.env)`` reads them.
    """

    def __init__(self, model, V, params, dt: float, fields: dict, x: np.ndarray):
        self.model, self.params = model, params
        self.eta, self.eta_old, self.v = fem.Function(V), fem.Function(V), fem.Function(V)
        self.quotient = (self.eta - self.eta_old) / fem.Constant(V.mesh, PETSc.ScalarType(dt))
        self.env = nodal.environment(fields, x)
        self._keys = {"eta": id(self.eta), "eta_old": id(self.eta_old), "v": id(self.v)}

    def compile(self, expr) -> nodal.NodalExpression:
        return nodal.NodalExpression(expr)

    def set(self, **arrays) -> None:
        for name, a in arrays.items():
            self.env[self._keys[name]] = a


@dataclass
class Setting:
    """What a scheme is given: the model's operators on one mesh, Δt, the options, the ends and the laws."""

    ops: Operators
    dt: float
    mass: str
    penalty: str | None
    bc: np.ndarray  # owned dof indices of the fixed ends
    g: np.ndarray  # their heights
    laws: NodalLaws
    comm: MPI.Comm
    eps: float
    x: np.ndarray  # coordinates of the owned dofs
    nt: int
    petsc_options: dict | None = None  # on top of the size rule's (`solver_options`), validated by the scene

    @property
    def n_owned(self) -> int:
        return self.ops.m.size

    @cached_property
    def interior(self) -> np.ndarray:  # read every step: computed once
        mask = np.ones(self.n_owned, dtype=bool)
        mask[self.bc] = False
        return mask


class Scheme:
    """The contract. A scheme module defines ``class Scheme(base.Scheme)`` with:

    * ``PENALTIES``: the penalties it accepts, its default first; ``()`` when it uses no penalty (and no ε);
    * ``MASSES``: the mass matrices it accepts, its default first;
    * ``__init__(setting)``: assemble and factorise (set-up time);
    * ``start(eta0, v0) -> StepEnergy``: the initial state (ends already at their heights, v0 = 0 there);
    * ``step() -> StepEnergy``: one step;
    * ``eta``, ``velocity``, ``contact_force``: this rank's nodal arrays of the current state (the force
      density applied in the last step), read by the driver when it stores a row;
    * ``timings``: extra counters for the summary (e.g. refactorisations).
    """

    PENALTIES: tuple = ()
    MASSES: tuple = ("lumped", "consistent")
    situation = ""  # for the instability message: e.g. "r = dt/eps = 4, penalty explicit"
    remedy = "use a smaller dt"

    def __init__(self, setting: Setting):
        self.s = setting

    @property
    def timings(self) -> dict:
        """Extra counters for the summary (e.g. refactorisations)."""
        return {}

    @staticmethod
    def requires(model) -> str | None:
        """Why this scheme cannot run `model` (one clause), or None."""
        return None

    @classmethod
    def check_options(cls, name: str, penalty, mass) -> tuple:
        """(penalty, mass) with the scheme's defaults; ValueError naming the scheme and what it accepts."""
        if penalty is None:
            penalty = cls.PENALTIES[0] if cls.PENALTIES else None
        elif penalty not in cls.PENALTIES:
            accepts = f"penalty {' or '.join(cls.PENALTIES)}" if cls.PENALTIES else "no penalty (and no eps)"
            raise ValueError(f"scheme {name!r} accepts {accepts}, not penalty {penalty!r}")
        if mass is None:
            mass = cls.MASSES[0]
        elif mass not in cls.MASSES:
            raise ValueError(f"scheme {name!r} accepts mass {' or '.join(cls.MASSES)}, not {mass!r}")
        return penalty, mass

    def contact(self) -> np.ndarray:
        """The model's contact set at the current η (bool per node)."""
        laws = self.s.laws
        if not hasattr(self, "_contact_law"):
            self._contact_law = laws.compile(laws.model.contact_set(laws.eta, laws.params))
        laws.set(eta=self.eta)
        return self._contact_law.evaluate_env(laws.env)


# --- shared parts -------------------------------------------------------------------------------------


def check_law_stability(model, dt: float, eps: float, penalty: str) -> None:
    """Apply the contact law's own bound on Δt and ε (`Model.stability`): refuse or warn before the run."""
    r = dt / eps
    verdict = model.stability(dt, eps, penalty) if model.stability is not None else None
    if verdict is None:
        return
    kind, why = verdict
    if kind == "refuse":
        raise InstabilityError(f"{why} (model '{model.name}', at step 0, t = 0)", step=0, time=0.0, r=r)
    warnings.warn(why, InstabilityWarning, stacklevel=4)


def wrap(a: np.ndarray, comm) -> PETSc.Vec:
    """A PETSc vector over `a`'s memory (this rank's part of the vector is all of `a`)."""
    return PETSc.Vec().createWithArray(a.reshape(-1), size=(a.size, PETSc.DECIDE), comm=comm)


#: Global unknowns up to which the step's constant system is LU-factorised once, in serial; above, CG.
#: Measured (docs/linear_solvers.md, square membranes 1e4 to 1e6 nodes): in serial the back-substitution beat
#: CG per step at every size (1e6 nodes, quiet: LU 0.22 s, CG + Jacobi 0.89 s, CG + AMG 1.08 s); CG only saves
#: set-up (12 s against 46 s) and memory (1.8 GB against 3.1 GB). So LU up to the largest size measured; above it
#: the factor (growing faster than the mesh) outgrows memory first.
LU_MAX_NODES = 1_000_000
#: The same on several ranks (MUMPS): its distributed back-substitution was slower on 2 ranks than on 1 at
#: every size, while CG's step halved (1e6 nodes: MUMPS 1.0 s, CG + Jacobi 0.43 s; 2.5e5: 126 ms against 72 ms).
#: CG + Jacobi was level with MUMPS at 4e4 nodes and ahead above. A string (1D) keeps its LU on any number of
#: ranks: a tridiagonal factor has no fill.
LU_MAX_NODES_PARALLEL = 40_000

#: CG stops when the true residual is below CG_RTOL ‖b‖, from the scheme's predictor as the first guess. The
#: ledger books the step's work with the computed η, so a residual r leaks (η^{n+1} − η^n)·r per step: at
#: 1e-14 ‖b‖ that is the LU back-substitution's own round-off, and the 2D ledgers close to 1e-10 E(0).
CG_RTOL = 1e-14

#: CG's preconditioner: Jacobi while Gershgorin's bound of the Jacobi-scaled matrix's condition number is at
#: most this (A nearly diagonal: projection's M/Δt² + C/Δt at its stable Δt; diagonal, one iteration, when
#: α = 0), else BoomerAMG, whose iteration count does not grow with the mesh (3 to 7 here). Measured
#: (docs/linear_solvers.md): on a quiet machine Jacobi won projection at 1e6 nodes (bound 41: 0.89 s against
#: 1.08 s per step serial, 0.43 s against 0.69 s on 2 ranks) and newmark at bounds 65 and 193 (4e4 nodes);
#: AMG won newmark at bound 640. (A loaded first pass had AMG ahead at bound 41: that one was noise.)
JACOBI_MAX_CONDITION = 100.0

#: The options of each path; a scene's or the command line's `petsc_options` go on top, key by key.
DIRECT = {"ksp_type": "preonly", "pc_type": "lu"}
ITERATIVE = {"ksp_type": "cg", "ksp_rtol": CG_RTOL, "ksp_atol": 0.0, "ksp_norm_type": "unpreconditioned",
             "ksp_initial_guess_nonzero": True, "ksp_max_it": 1000}
JACOBI = {"pc_type": "jacobi"}
AMG = {"pc_type": "hypre", "pc_hypre_type": "boomeramg"}

#: Every KSP takes its options under this prefix, set just before its setFromOptions and removed just after.
PREFIX = "stringcontact_"


def solver_options(n_global: int, ranks: int, options: dict | None = None, condition: float = math.inf,
                   dim: int = 2) -> dict:
    """The PETSc options for `n_global` unknowns: LU up to LU_MAX_NODES (LU_MAX_NODES_PARALLEL on several
    ranks, none for a string, `dim` 1), else CG; then `options`.

    A user's ksp_type (or, without one, pc_type) picks the path whose defaults the rest goes on top of. CG's
    preconditioner, unless the user names one: Jacobi if `condition` (`jacobi_condition_bound`) is at most
    JACOBI_MAX_CONDITION, else AMG.
    """
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
    return chosen


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


def configured_ksp(A: PETSc.Mat, comm, options: dict) -> PETSc.KSP:
    """A KSP for A set from `options` under its own prefix; the options leave PETSc's database right after."""
    ksp = PETSc.KSP().create(comm)
    ksp.setOptionsPrefix(PREFIX)
    ksp.setOperators(A)
    db = PETSc.Options()
    try:
        for name, value in options.items():
            db.setValue(PREFIX + name, _option_text(value))
        ksp.setFromOptions()
    finally:
        for name in options:
            db.delValue(PREFIX + name)
    ksp.setUp()
    return ksp


class Linear:
    """A x = b for a matrix that stays (or changes now and then, `reset`): LU or CG by size and options.

    A has identity rows at the fixed dofs `bc` (`dirichlet_rows`) and every b holds their heights `g` there.
    ``solve(b, x)``: LU is the factor's back-substitution, without KSPSolve's bookkeeping. CG needs a
    symmetric matrix, so it zeroes A's fixed columns too and moves their (constant) part to b, the lift;
    it starts from the x it is given (the scheme's predictor: ``iterative`` says whether to give one).
    `dim` is the mesh's (`solver_options`: a string keeps its LU on any number of ranks).
    """

    def __init__(self, A: PETSc.Mat, comm, options: dict | None, bc: np.ndarray, g: np.ndarray, dim: int):
        self.A, self.bc = A, bc
        self.options = solver_options(A.getSize()[0], comm.size, options, dim=dim)
        kind = self.options["ksp_type"], self.options.get("pc_type")
        self.iterative = not (kind[0] == "preonly" and kind[1] in ("lu", "cholesky"))
        if self.iterative:
            self.lift, self.b = _symmetric_rows(A, bc, g), A.createVecLeft()
            if "pc_type" not in (options or {}):
                self.condition = jacobi_condition_bound(A)
                self.options = solver_options(A.getSize()[0], comm.size, options, self.condition, dim)
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

    def describe(self) -> str:
        """One line: e.g. "LU (mumps)" or "cg + hypre boomeramg, mean 7.2 iterations per solve"."""
        pc = self.ksp.getPC()
        if not self.iterative:
            return f"{pc.getType().upper()} ({pc.getFactorSolverType()})"
        kind = pc.getType() + (f" {pc.getHYPREType()}" if pc.getType() == "hypre" else "")
        mean = self.iterations / self.solves if self.solves else 0.0
        return f"{self.ksp.getType()} + {kind}, mean {mean:.1f} iterations per solve"


class DampedLU:
    """A constant matrix plus a diagonal that changes now and then (a damping on the active set).

    ``update(extra)`` puts ``extra`` on top of the constant diagonal and, only if it changed, refactorises
    (LU: PETSc keeps the symbolic factorisation) or sets the preconditioner up again (CG): counted in
    ``refactorisations``. Every rank must take part, so under MPI the ranks agree first. ``solve(b, x)`` and
    ``iterative`` are the `Linear`'s; the other arguments are passed to it.
    """

    def __init__(self, A: PETSc.Mat, comm, options: dict | None, bc: np.ndarray, g: np.ndarray, dim: int):
        self.A, self.comm = A, comm
        self.base = A.getDiagonal().array.copy()
        self.diag = A.createVecLeft()
        self.current = np.zeros_like(self.base)  # what is on top of the constant diagonal now
        self.linear = Linear(A, comm, options, bc, g, dim)
        self.solve, self.iterative = self.linear.solve, self.linear.iterative
        self.refactorisations = 0
        self.anywhere = any_rank(comm)

    def update(self, extra: np.ndarray) -> None:
        if self.anywhere(not np.array_equal(extra, self.current)):
            np.add(self.base, extra, out=self.diag.array)
            self.A.setDiagonal(self.diag)
            self.linear.reset()
            self.solve = self.linear.solve
            self.current[:] = extra
            self.refactorisations += 1


def any_rank(comm):
    """anyrank(flag): whether the flag is set on any rank (one allreduce), or the flag itself in serial."""
    if comm.size == 1:
        return lambda flag: flag
    return lambda flag: comm.allreduce(flag, op=MPI.LOR)


def summer(comm):
    """allsum(*values): the sums over the ranks (one allreduce), or the values themselves in serial."""
    if comm.size == 1:
        return lambda *vals: vals
    return lambda *vals: comm.allreduce(np.array(vals), op=MPI.SUM).tolist()


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
