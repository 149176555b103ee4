"""Sweeps are embarrassingly parallel: :func:`distribute` deals the cases over the ranks of a communicator
(each rank runs its cases on ``MPI.COMM_SELF``) and gathers the results on rank 0. ``mpirun -n K stringcontact
study ...`` uses it; serial is the default."""

from __future__ import annotations

import time

import numpy as np


def distribute(function, cases: list, comm=None, cost=None, busy: list | None = None) -> list | None:
    """`[function(c) for c in cases]`, the cases dealt over `comm`'s ranks; the list on rank 0, None elsewhere.

    Cases are dealt largest `cost` first, each to the least loaded rank, so the ranks finish together. Each
    rank runs its cases itself (on COMM_SELF); only the results travel, by one gather. If `busy` is a list,
    rank 0 appends each rank's CPU seconds for its cases to it: on idle cores the sweep takes about their
    maximum, so sum/max is the speed-up that the dealing allows (the wall clock of a shared machine is noisier).
    """
    t0 = time.process_time()
    if comm is None or comm.size == 1:
        out = [function(c) for c in cases]
        if busy is not None:
            busy.append(time.process_time() - t0)
        return out
    # Longest processing time first: each case, largest first, goes to the least loaded rank so far.
    order = sorted(range(len(cases)), key=lambda i: -(cost(cases[i]) if cost else 1.0))
    load = [0.0] * comm.size
    mine = []
    for i in order:
        rank = int(np.argmin(load))
        load[rank] += cost(cases[i]) if cost else 1.0
        if rank == comm.rank:
            mine.append(i)
    done = [(i, function(cases[i])) for i in mine]
    cpu = time.process_time() - t0
    # Wait for the other ranks asleep, not in MPI's busy poll: on a shared machine the poll steals the CPU
    # that the ranks still working need.
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(0.005)
    gathered = comm.gather((cpu, done), root=0)
    if comm.rank != 0:
        return None
    out = [None] * len(cases)
    for seconds, part in gathered:
        for i, value in part:
            out[i] = value
    if busy is not None:
        busy.extend(seconds for seconds, _ in gathered)
    return out
