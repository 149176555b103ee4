"""What a simulation returns (`Result`): per-node arrays at the stored times and the per-time series."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

#: The energy terms of `Result.energy` (the dissipations and the external work cumulative from t = 0).
ENERGY_KEYS = ("kinetic", "elastic", "viscous_dissipation", "contact_dissipation", "numerical_dissipation",
               "external_work", "internal_dissipation")
#: The fields stored at each node and stored time (the XDMF's attributes, in this order).
FIELDS = ("eta", "velocity", "contact", "contact_force")
#: The XDMF field written after `FIELDS` when the scene's obstacle moves: ψ at the nodes at each frame's time (an
#: obstacle at rest is not written: view.py draws it).
OBSTACLE_FIELD = "obstacle"
#: The per-node arrays: held where the rows were gathered (rank 0 by default), absent on the other ranks.
PER_NODE = ("x", *FIELDS, "fields", "weights", "cells")
CHUNK_VALUES = 2**24  # contact_measure converts at most this many contact values to float at once (128 MB)


def contact_runs(contact: np.ndarray) -> np.ndarray:
    """The runs of at least two contact nodes in each row of a 1D contact array (an isolated node is a component of
    zero length: Example 2's left end, pinned at η = 0)."""
    contact = np.asarray(contact, dtype=bool)
    counts = np.zeros(len(contact), dtype=np.int64)
    chunk = max(1, CHUNK_VALUES // max(1, contact.shape[1]))  # a few rows' temporaries at a time, not all rows'
    for i in range(0, len(contact), chunk):
        pairs = contact[i:i + chunk, :-1] & contact[i:i + chunk, 1:]  # edges with both ends in contact
        counts[i:i + chunk] = pairs[:, :1].sum(axis=1) + np.count_nonzero(pairs[:, 1:] & ~pairs[:, :-1], axis=1)
    return counts


def node_sort_key(x: np.ndarray) -> np.ndarray:
    """The key of the nodes' order, the same for any number of ranks: x in 1D; x + iy in 2D (by x, then y)."""
    return x if x.ndim == 1 else x[:, 0] + 1j * x[:, 1]


def canonical_cells(cells: np.ndarray) -> np.ndarray:
    """Triangles (indices into the sorted nodes) in a fixed order whatever the ranks: each starting at its smallest
    node (orientation kept), then sorted."""
    turn = (np.argmin(cells, axis=1)[:, None] + np.arange(3)) % 3
    cells = np.take_along_axis(cells, turn, axis=1)
    return cells[np.lexsort(cells.T[::-1])]


class RowsElsewhere(AttributeError):
    """A per-node array read on a rank that does not hold the rows (`Storage(gather="root")`, rank > 0)."""


@dataclass(eq=False, repr=False)
class Result:
    """The stored rows of one run, ordered by x (2D: by x, then y), and its per-time series.

    Under MPI the per-node arrays (`PER_NODE`) are gathered to rank 0 only (`Storage(gather="root")`): elsewhere
    `has_rows` is False and reading one raises `RowsElsewhere`. The per-time series are the same on every rank: t,
    steps, energy, min_eta, min_gap, status, message, and `series` ("contact_measure", "max_speed", "depth").

    `min_gap` is the least gap η − ψ over every node and step (ψ at each step's time when the obstacle moves; below 0
    the string is −min_gap below it); `min_eta` the least height η over the same (at t = 0 the interior nodes):
    one number under the flat obstacle ψ = 0. `contact` is η ≤ ψ; `contact_force` is the contact force density at
    t_n, ≥ 0 and 0 off the contact set under every scheme (which step's force: docs/explanation/schemes.md).

    `energy` holds (k,) arrays, the dissipations and the external work cumulative from t = 0, so that
    E(0) + W_ext = E(t) + D_visc + D_con + D_num closes to round-off; every scheme books D_con as the applied force's
    work with the step's mean velocity, and D_num is what its own discrete energy identity holds besides the
    physical terms (docs/explanation/reliability.md). For `paper`, per step,

        ΔD_num = ½|v^{n+1} − v^n|²_M + ½|η^{n+1} − η^n|²_K − (Δt/2) f·(v^{n+1} − v^n),

    whose force term is negative where the explicit penalty brakes a node, so D_num can be negative (Example 1:
    −4.1 of E(0) = 1311): the scheme's time error in energy terms, O(Δt).

    `fields` holds the model's output fields by name, (k, nodes) like `eta`, and `field_info` how each is shown
    (`OutputField.metadata`); `parameters` the model's constants as used; `timings` seconds ("setup", "solve",
    "output", "pictures"), `counters` the schemes' counts, `solver` what solved the steps, in words.
    """

    scene: object
    x: np.ndarray
    t: np.ndarray
    steps: np.ndarray
    eta: np.ndarray
    velocity: np.ndarray
    contact: np.ndarray
    contact_force: np.ndarray
    energy: dict
    min_eta: float
    penalty: str
    mass: str
    model: str
    status: str = "complete"
    timings: dict = field(default_factory=dict)
    message: str = ""
    scheme: str = "paper"
    weights: np.ndarray | None = None  # 2D: the lumped nodal areas ∫φ_i dx, in the order of x
    cells: np.ndarray | None = None  # 2D: the triangles, (k, 3) indices into x
    series: dict = field(default_factory=dict)
    has_rows: bool = True
    checks: dict = field(default_factory=dict)  # "energy_balance", "penetration": run.checks.checks_of
    model_origin: dict = field(default_factory=dict)  # model.registry.model_origin
    penetration_bound: str | None = "velocity"  # the contact law's bound: model.interface.penetration_bound_of
    law_reads_eps: bool = True  # whether the contact law reads ε (model.interface.reads_eps)
    energy_label: str | None = None  # the legend of the model's stored energy (None: the paper's ½∫|∇η|²)
    fields: dict = field(default_factory=dict)
    field_info: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)
    counters: dict = field(default_factory=dict)
    solver: dict = field(default_factory=dict)
    petsc_options: dict = field(default_factory=dict)  # the options the solver was given: the model's, then the user's
    min_gap: float = math.nan  # nan: not known

    def __getattribute__(self, name):
        if name in PER_NODE and not object.__getattribute__(self, "has_rows"):
            raise RowsElsewhere(
                f"Result.{name}: the per-node rows are on rank 0 only (Storage(gather='root')); this rank holds the "
                "series (t, energy, min_eta, min_gap, contact_measure); use Storage(gather='all') for rows on every rank")
        return object.__getattribute__(self, name)

    def __repr__(self) -> str:
        rows = f"{len(self.t)} rows" + (f" of {len(self.x)} nodes" if self.has_rows else " (per-node arrays on rank 0)")
        return f"Result({getattr(self.scene, 'name', self.scene)!r}, scheme {self.scheme!r}, {self.status}, {rows})"

    @property
    def total_energy(self) -> np.ndarray:
        """E(t) = kinetic + elastic energy at each stored time."""
        return self.energy["kinetic"] + self.energy["elastic"]

    @property
    def balance_residual(self) -> np.ndarray:
        """E(0) + W_ext − [E(t) + D_visc + D_int + D_con + D_num] at each stored time; round-off for this scheme."""
        e = self.energy
        spent = e["viscous_dissipation"] + e["contact_dissipation"] + e["numerical_dissipation"]
        spent = spent + e.get("internal_dissipation", 0.0)
        return self.total_energy[0] + e["external_work"] - (self.total_energy + spent)

    @cached_property
    def stored_min_gap(self) -> np.ndarray:
        """min over the nodes of η − ψ at each stored time (diagnostics.csv's ``min_gap``): −``series["depth"]``
        where the run summed it over the ranks, else from the rows."""
        depth = (self.series or {}).get("depth")
        if depth is not None and len(depth) == len(self.t):
            return -np.asarray(depth, dtype=float)
        scene, x = self.scene, np.asarray(self.x, dtype=float)
        if getattr(scene, "obstacle", None) is None:
            return np.min(self.eta, axis=1, initial=np.inf)
        moves = getattr(scene, "obstacle_moves", False)
        psi = None if moves else scene.obstacle_values(x)
        return np.array([np.min(row - (scene.obstacle_values(x, float(t)) if moves else psi), initial=np.inf)
                         for t, row in zip(self.t, self.eta)])

    @property
    def dim(self) -> int:
        """1 for a string (the interval), 2 for a membrane."""
        return (1 if np.ndim(self.x) == 1 else 2) if self.has_rows else self.scene.dim

    @cached_property
    def contact_measure(self) -> np.ndarray:
        """Measure of the contact set at each stored time: its length in 1D (trapezoidal in x), its area in 2D (the
        lumped nodal areas of the nodes in contact); where the rows are absent, the series the solver summed over
        the ranks. Computed once: the tables, the report and the pictures read it."""
        if not self.has_rows:
            return self.series["contact_measure"]
        from scipy.integrate import trapezoid  # here: NumPy names it trapz before 2.0 and trapezoid after

        k, nodes = self.contact.shape
        out = np.empty(k)
        chunk = max(1, CHUNK_VALUES // max(1, nodes))  # a float copy of a few rows at a time, not of all of them
        for i in range(0, k, chunk):
            c = self.contact[i:i + chunk].astype(float)
            if self.dim == 2:
                out[i:i + chunk] = c @ self.weights
            else:
                out[i:i + chunk] = trapezoid(c, self.x, axis=1) if nodes > 1 else c[:, 0]
        return out

    @property
    def contact_length(self) -> np.ndarray:
        """`contact_measure` (diagnostics.csv's ``contact_length`` of a string, ``contact_area`` of a membrane)."""
        return self.contact_measure

    @cached_property
    def contact_components(self) -> np.ndarray:
        """The number of components of the contact set at each stored row (`contact_runs` in 1D,
        `contact_patches` in 2D), computed once."""
        return contact_runs(self.contact) if self.dim == 1 else self.contact_patches()

    def contact_patches(self) -> np.ndarray:
        """2D: the number of contact patches (connected sets of contact nodes along mesh edges) at each stored time."""
        if self.dim == 1:
            raise ValueError("contact_patches: 2D only (in 1D, count the runs of Result.contact)")
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        edges = np.concatenate([self.cells[:, [0, 1]], self.cells[:, [1, 2]], self.cells[:, [2, 0]]])
        counts = []
        for row in self.contact:
            keep = row[edges[:, 0]] & row[edges[:, 1]]
            graph = coo_matrix((np.ones(int(keep.sum())), tuple(edges[keep].T)), shape=(row.size, row.size))
            _n, labels = connected_components(graph, directed=False)
            counts.append(np.unique(labels[row]).size)
        return np.array(counts)
