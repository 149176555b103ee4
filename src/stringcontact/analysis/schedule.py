"""`distribute`: a sweep's cases dealt over the ranks of ``mpirun -n K stringcontact study ...``."""

from __future__ import annotations

import time

import numpy as np


def distribute(function, cases: list, comm=None, cost=None, busy: list | None = None) -> list | None:
    """`[function(c) for c in cases]` dealt over `comm`'s ranks, largest `cost` first to the least loaded rank: the
    list on rank 0, None elsewhere; each rank's CPU seconds appended to `busy` on rank 0, if given."""
    t0 = time.process_time()
    if comm is None or comm.size == 1:
        out = [function(c) for c in cases]
        if busy is not None:
            busy.append(time.process_time() - t0)
        return out
    weight = cost or (lambda case: 1.0)
    load, mine = [0.0] * comm.size, []
    for i in sorted(range(len(cases)), key=lambda i: -weight(cases[i])):
        rank = int(np.argmin(load))
        load[rank] += weight(cases[i])
        mine += [i] if rank == comm.rank else []
    done = [(i, function(cases[i])) for i in mine]
    cpu = time.process_time() - t0
    # wait asleep, not in MPI's busy poll, which steals the CPU of the ranks still working
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(0.005)
    gathered = comm.gather((cpu, done), root=0)
    if comm.rank != 0:
        return None
    if busy is not None:
        busy.extend(seconds for seconds, _ in gathered)
    out = dict(pair for _, part in gathered for pair in part)
    return [out[i] for i in range(len(cases))]
