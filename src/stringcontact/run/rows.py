"""The stored rows of a run (`RowObserver`): which steps are kept within a memory budget, gathered in x order, and
the per-time series every rank sums."""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI

from ..fem import domains
from ..io.result import ENERGY_KEYS, canonical_cells, node_sort_key
from ..io.xdmf import global_cells
from ..scene import BYTES_PER_STORED_NODE

if TYPE_CHECKING:
    from .options import Storage

__all__ = ["SERIES_KEYS", "RowObserver", "StorageWarning", "budget_steps", "output_steps", "step_times", "stored_steps"]


def output_steps(nt: int, dt: float, output_times) -> set[int]:
    """The steps nearest to the scene's output times."""
    return {min(nt, max(0, round(t / dt))) for t in output_times}


def step_times(steps, dt: float, output_times=()) -> np.ndarray:
    """The times of `steps`: n·Δt to 12 significant digits (0.04, not 0.039999999999999994), an output time as given."""
    steps = np.asarray(steps, dtype=np.int64)
    times = np.array([float(f"{n * dt:.12g}") for n in steps.tolist()], dtype=float)
    for t in output_times:
        hit = np.flatnonzero(np.abs(steps * dt - float(t)) <= 1e-9 * max(dt, abs(float(t))))
        times[hit] = float(t)
    return times


def stored_steps(nt: int, dt: float, output_times, max_rows: int) -> np.ndarray:
    """Every k-th step so that about `max_rows` rows are kept, plus 0, nt and the scene's output times."""
    stride = max(1, math.ceil(nt / max(1, max_rows)))
    steps = set(range(0, nt + 1, stride)) | {0, nt} | output_steps(nt, dt, output_times)
    return np.array(sorted(steps), dtype=np.int64)


class StorageWarning(UserWarning):
    """The stored rows were thinned to fit the row budget."""


def budget_steps(nt: int, dt: float, output_times, max_rows: int, nodes: int, budget: int):
    """`stored_steps` thinned to every k-th step, the smallest k whose rows fit `budget` bytes, always with 0, T and
    the output times (ValueError if they alone do not fit): (steps, a line saying so, or None)."""
    steps = stored_steps(nt, dt, output_times, max_rows)
    row = max(1, nodes) * BYTES_PER_STORED_NODE
    allowed = budget // row
    if len(steps) <= allowed:
        return steps, None
    fixed = {0, nt} | output_steps(nt, dt, output_times)
    if allowed < len(fixed):
        raise ValueError(
            f"output_times: 0, T and the output times are {len(fixed)} stored rows of {nodes} nodes "
            f"({len(fixed) * row / 1e9:.3g} GB); allowed: at most {allowed} rows (row budget {budget / 1e9:.3g} GB); "
            "give fewer output times or a coarser mesh")
    lo, hi = 1, nt + 1  # stride nt + 1 keeps the fixed steps only, which fit
    while lo < hi:  # the smallest stride that fits (a bisection: the count falls with the stride, nearly monotone)
        mid = (lo + hi) // 2
        if nt // mid + 1 + sum(1 for f in fixed if f % mid) <= allowed:
            hi = mid
        else:
            lo = mid + 1
    kept = np.array(sorted(set(range(0, nt + 1, hi)) | fixed), dtype=np.int64)
    note = (f"max_rows = {max_rows}: {len(steps)} stored rows of {nodes} nodes would take {len(steps) * row / 1e9:.3g} GB, "
            f"over the row budget of {budget / 1e9:.3g} GB; keeping {len(kept)} rows (every {hi}-th step, with 0, T "
            "and the output times)")
    return kept, note


class _Gather:
    """Gathers owned dof arrays (concatenated: the global dof numbering) in x order (2D: by x, then y) to rank 0, or
    with `to_all` to every rank; where they are not gathered, `holds` is False and `x` None."""

    def __init__(self, comm, x_owned: np.ndarray, to_all: bool = False):
        self.comm, self.to_all = comm, to_all
        self.counts = comm.allgather(len(x_owned)) if comm.size > 1 else [len(x_owned)]
        self.nodes = int(sum(self.counts))
        self.holds = to_all or comm.rank == 0
        xs = _collect(comm, x_owned, to_all)
        self.order = self.x = None
        self.identity, self._buffers = False, {}
        if self.holds:
            x = np.concatenate(xs)
            self.order = np.argsort(node_sort_key(x), kind="stable")
            self.x = x[self.order]
            self.identity = bool(np.array_equal(self.order, np.arange(self.order.size)))

    def __call__(self, a: np.ndarray, out: np.ndarray | None = None) -> np.ndarray | None:
        """The gathered array in x order (into `out`) where held; None elsewhere. Collective."""
        a = np.ascontiguousarray(a, dtype=out.dtype if out is not None else None)
        if self.comm.size == 1 and self.identity:  # serial, dofs already in x order: one copy
            if out is None:
                return a.copy()
            out[...] = a
            return out
        send = a.view(np.uint8) if a.dtype == bool else a  # MPI has no NumPy bool: its bytes
        buf = self._buffer(send.dtype) if self.holds else None
        if self.comm.size == 1:
            buf[...] = send
        elif self.to_all:
            self.comm.Allgatherv(send, [buf, self.counts])
        else:
            self.comm.Gatherv(send, [buf, self.counts] if self.holds else None, root=0)
        if not self.holds:
            return None
        return np.take(buf.view(a.dtype), self.order, out=out)

    def _buffer(self, dtype) -> np.ndarray:
        if dtype not in self._buffers:
            self._buffers[dtype] = np.empty(self.nodes, dtype=dtype)
        return self._buffers[dtype]


def _collect(comm, a: np.ndarray, to_all: bool) -> list | None:
    """The ranks' arrays, in rank order: on rank 0 (every rank with `to_all`); None elsewhere."""
    if comm.size == 1:
        return [a]
    return comm.allgather(a) if to_all else comm.gather(a, root=0)


SERIES_KEYS = ("contact_measure", "max_speed", "depth")


def _row_series(comm, fields: dict, weights: np.ndarray, obstacle: np.ndarray) -> tuple[float, float, float]:
    """One stored time's contact measure Σ weights·contact, max |v| and max (ψ − η) over all ranks. Collective."""
    measure = float(np.dot(weights, np.asarray(fields["contact"], dtype=float)))
    highs = np.array([np.max(np.abs(fields["velocity"]), initial=-np.inf),
                      np.max(obstacle - fields["eta"], initial=-np.inf)])
    if comm.size > 1:
        measure = comm.allreduce(measure, op=MPI.SUM)
        mine, highs = highs, np.empty(2)
        comm.Allreduce(mine, highs, op=MPI.MAX)
    return measure, float(highs[0]), float(highs[1])


def _mesh_rows(V, gather: _Gather, weights: np.ndarray) -> dict:
    """2D: the owned nodal areas `weights` and the triangles (sent in global dof numbers), gathered in node order where
    the rows are; 1D: none. Collective."""
    if V.mesh.topology.dim == 1:
        return {}
    parts = _collect(gather.comm, global_cells(V), gather.to_all)
    weights = gather(weights)
    if not gather.holds:
        return {}
    position = np.empty_like(gather.order)
    position[gather.order] = np.arange(gather.order.size)  # global dof -> place in x order
    return {"weights": weights, "cells": canonical_cells(position[np.concatenate(parts)])}


class RowObserver:
    """An observer of a `TimeStepper` (`core.observers.Observer`) that keeps the rows of a run of `nt` steps of `dt`:
    about ``storage.max_rows`` of them within ``storage.row_budget`` bytes, always with 0, the last step and the
    `output_times` (`budget_steps`), gathered in x order on rank 0 (every rank with ``storage.gather == "all"``); on
    every rank the energies, the per-time series and the lowest η and gap. `sink(t, fields)`, if set, gets each
    stored row too (the output folder's XDMF frames). `geometry`: a membrane's nodal areas and triangles. Collective."""

    def __init__(self, stepper, nt: int, dt: float, output_times, storage: Storage):
        p = stepper.problem
        self.problem, self.comm, self.dt, self.output_times = p, stepper.comm, dt, tuple(output_times)
        self.gather = gather = _Gather(self.comm, p.x, to_all=storage.gather == "all")
        self.steps, note = budget_steps(nt, dt, output_times, storage.max_rows, gather.nodes, storage.row_budget)
        if note is not None and self.comm.rank == 0:
            warnings.warn(note, StorageWarning, stacklevel=3)
        k, self.n, self.fields = len(self.steps), 0, {}
        if gather.holds:  # with the model's output fields (`Model.outputs`)
            names = ("eta", "velocity", "contact_force", *(f.name for f in p.outputs.fields))
            self.fields = {name: np.empty((k, gather.nodes)) for name in names}
            self.fields["contact"] = np.empty((k, gather.nodes), dtype=bool)
        self.energy = {key: np.empty(k) for key in ENERGY_KEYS}
        self.series = {key: np.empty(k) for key in SERIES_KEYS}
        self.weights = domains.nodal_areas(p.V)[: p.n_owned]  # ∫φ_i: the trapezoid's weights in 1D, the areas in 2D
        self.geometry = _mesh_rows(p.V, gather, self.weights)  # the same owned weights, gathered
        self.has_obstacle = p.obstacle is not None or "obstacle" in p.params.extra
        self.psi = None if p.obstacle is not None else p.obstacle_values(0.0)[: p.n_owned]
        self.min_eta = self.min_gap = math.inf
        self.sink = None

    def _gap(self, stepper, eta: np.ndarray, n: int) -> float:
        """min (η − ψ) over this rank's nodes at step n (inf without nodes); a moving ψ as the scheme set it."""
        if not eta.size:
            return math.inf
        if not self.has_obstacle:
            return float(eta.min())
        psi = self.psi if self.psi is not None else stepper.discrete.obstacle.owned_at_run_time(n * self.dt)
        return float(np.min(eta - psi))

    def started(self, stepper) -> None:
        """The initial state: the lowest η over the free nodes, the gap, the row at t = 0."""
        eta, interior = stepper.scheme.eta, self.problem.interior
        self.min_eta = float(np.min(eta[interior])) if interior.any() else math.inf
        self.min_gap = self._gap(stepper, eta, 0)
        if self._next_step == 0:
            self._store(stepper, 0)

    def stepped(self, stepper) -> None:
        """After a step: the lowest η and gap so far, and the row if this step is a stored one."""
        eta = stepper.scheme.eta
        if eta.size:
            low = float(eta.min())
            self.min_eta = min(self.min_eta, low)
            self.min_gap = min(self.min_gap, self._gap(stepper, eta, stepper.step) if self.has_obstacle else low)
        if stepper.step == self._next_step:
            self._store(stepper, stepper.step)

    @property
    def _next_step(self) -> int:
        return self.steps[self.n] if self.n < len(self.steps) else -1

    def _store(self, stepper, n: int) -> None:
        scheme, p = stepper.scheme, self.problem
        fields = {"eta": scheme.eta, "velocity": scheme.velocity, "contact": scheme.contact(),
                  "contact_force": scheme.contact_force}
        fields.update(p.outputs(scheme.eta, scheme.fields))
        t = float(step_times([n], self.dt, self.output_times)[0])
        psi = stepper.discrete.obstacle.owned_at_run_time(t) if p.obstacle is not None else self.psi
        series = _row_series(self.comm, fields, self.weights, psi)
        for name, arr in fields.items():
            arr = np.asarray(arr, dtype=bool if name == "contact" else float)  # the same bytes from every rank
            self.gather(arr, out=self.fields[name][self.n] if self.fields else None)
        for key, value in zip(ENERGY_KEYS, stepper.ledger.cumulative):
            self.energy[key][self.n] = value
        for key, value in zip(SERIES_KEYS, series):
            self.series[key][self.n] = value
        self.n += 1
        if self.sink is not None:
            self.sink(t, {k: np.asarray(a, dtype=float) for k, a in fields.items()})
