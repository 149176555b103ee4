"""Stop signals (SIGINT, SIGTERM, SIGHUP) held back during a critical section (`signals_held`), or under MPI
shared so that every rank stops at the same step (`StopTogether`)."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from typing import Self

__all__ = ["StopTogether", "signals_held"]

STOP = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class _Held:
    """In the main thread (and if `active`), the Python handlers of `STOP` swapped for one that appends the signal to
    `received`, until `restore` (a C handler, PETSc's, cannot be put back: left in place)."""

    def __init__(self, active: bool = True):
        self.received: list[int] = []
        active = active and threading.current_thread() is threading.main_thread()
        self.saved = {s: h for s in STOP if active and (h := signal.getsignal(s)) is not None}
        for s in self.saved:
            signal.signal(s, lambda signum, frame: self.received.append(signum))

    def restore(self) -> dict:
        saved, self.saved = self.saved, {}
        for s, handler in saved.items():
            signal.signal(s, handler)
        return saved


@contextlib.contextmanager
def signals_held():
    """Hold the stop signals back for a critical section; they take effect right after it (handlers swapped, not
    signals blocked: one that arrived just before would run its handler inside the section)."""
    held = _Held()
    try:
        yield
    finally:
        saved = held.restore()
        for signum in held.received[:1]:
            if callable(saved[signum]):
                saved[signum](signum, None)
            elif saved[signum] == signal.SIG_DFL:
                os.kill(os.getpid(), signum)


class StopTogether:
    """Under MPI a stop signal that reaches some ranks stops every rank at the same step: recorded, shared by `poll`
    (one allreduce), `Interrupted` raised on all."""

    def __init__(self, comm):
        self.comm = comm if comm is not None and comm.size > 1 else None

    def __enter__(self) -> Self:
        self.held = _Held(active=self.comm is not None)
        return self

    def poll(self) -> None:
        """Collective: raise `Interrupted` on every rank if a stop signal reached any rank."""
        if self.comm is None:
            return
        from mpi4py import MPI

        from ..errors import Interrupted

        signum = self.comm.allreduce(self.held.received[0] if self.held.received else 0, op=MPI.MAX)
        if signum:
            self.held.restore()
            raise Interrupted(signum)

    def __exit__(self, kind, value, tb) -> None:
        self.held.restore()
        if self.held.received and kind is None:  # a signal after the last poll: it takes effect now
            os.kill(os.getpid(), self.held.received[0])
