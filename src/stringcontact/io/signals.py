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


def _record(into: list) -> dict:
    """Swap the Python handlers of `STOP` for one that appends to `into`; returns the previous ones (a C handler,
    PETSc's, cannot be put back: left in place)."""
    saved = {s: signal.getsignal(s) for s in STOP}
    saved = {s: h for s, h in saved.items() if h is not None}
    for s in saved:
        signal.signal(s, lambda signum, frame: into.append(signum))
    return saved


@contextlib.contextmanager
def signals_held():
    """Hold the stop signals back for a critical section; they take effect right after it (handlers swapped, not
    signals blocked: one that arrived just before would run its handler inside the section)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    saved = _record(received)
    try:
        yield
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)
        for signum in received[:1]:
            if callable(saved[signum]):
                saved[signum](signum, None)
            elif saved[signum] == signal.SIG_DFL:
                os.kill(os.getpid(), signum)


class StopTogether:
    """Under MPI a stop signal that reaches some ranks stops every rank at the same step: recorded, shared by `poll`
    (one allreduce), `Interrupted` raised on all."""

    def __init__(self, comm):
        self.comm = comm if comm is not None and comm.size > 1 else None
        self.received: list[int] = []
        self.saved: dict = {}

    def __enter__(self) -> Self:
        if self.comm is not None and threading.current_thread() is threading.main_thread():
            self.saved = _record(self.received)
        return self

    def poll(self) -> None:
        """Collective: raise `Interrupted` on every rank if a stop signal reached any rank."""
        if self.comm is None:
            return
        from mpi4py import MPI

        from ..errors import Interrupted

        signum = self.comm.allreduce(self.received[0] if self.received else 0, op=MPI.MAX)
        if signum:
            self._restore()
            raise Interrupted(signum)

    def _restore(self) -> None:
        for s, handler in self.saved.items():
            signal.signal(s, handler)
        self.saved = {}

    def __exit__(self, kind, value, tb) -> None:
        self._restore()
        if self.received and kind is None:  # a signal after the last poll: it takes effect now
            os.kill(os.getpid(), self.received[0])
