"""Signals held back during a critical section (a frame written, a folder renamed into place)."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from typing import Self

__all__ = ["StopTogether", "signals_held"]


@contextlib.contextmanager
def signals_held():
    """Hold SIGINT, SIGTERM and SIGHUP back for a short critical section; they take effect right after it.

    The Python handlers are swapped for a recorder (blocking the signals in the OS would not do: a signal
    that arrived just before still runs its Python handler at the next bytecode, inside the section).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    saved = {s: h for s, h in saved.items() if h is not None}  # a C handler (PETSc's) cannot be put back: leave it
    for s in saved:
        signal.signal(s, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)
        for signum in received[:1]:
            handler = saved[signum]
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), signum)




class StopTogether:
    """Under MPI: a stop signal (SIGINT, SIGTERM, SIGHUP) that reaches some ranks stops every rank at the same step.

    While the context is open the signals are recorded, not raised; `poll`, called by every rank at the same
    steps, shares them (one allreduce of a number) and raises `Interrupted` on every rank if any rank received
    one, so that all of them leave the time loop together and mark the folder interrupted (a rank stopping
    alone would leave the others waiting in the next step's collective calls). With one process nothing changes:
    the signals raise at once.
    """

    def __init__(self, comm):
        self.comm = comm if comm is not None and comm.size > 1 else None
        self.received: list[int] = []
        self.saved: dict = {}

    def __enter__(self) -> Self:
        if self.comm is not None and threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
                handler = signal.getsignal(s)
                if handler is not None:  # a C handler (PETSc's) cannot be put back: leave it
                    self.saved[s] = signal.signal(s, lambda signum, frame: self.received.append(signum))
        return self

    def poll(self) -> None:
        """Collective: raise `Interrupted` on every rank if a stop signal reached any rank."""
        if self.comm is None:
            return
        from mpi4py import MPI

        signum = self.comm.allreduce(self.received[0] if self.received else 0, op=MPI.MAX)
        if signum:
            self._restore()
            from ..errors import Interrupted

            raise Interrupted(signum)

    def _restore(self) -> None:
        for s, handler in self.saved.items():
            signal.signal(s, handler)
        self.saved = {}

    def __exit__(self, kind, value, tb) -> None:
        self._restore()
        if self.received and kind is None:  # a signal after the last poll: it takes effect now
            os.kill(os.getpid(), self.received[0])
