"""The stop signals (SIGINT, SIGTERM, SIGHUP): raising `Interrupted` while a command runs (`stop_signals`), held back
during a critical section (`signals_held`), or under MPI shared so that every rank stops at the same step
(`StopTogether`). Each swaps the Python handlers, in the main thread only (the only one that may set them)."""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Self

from .errors import Interrupted

__all__ = ["STOP_SIGNALS", "StopTogether", "signals_held", "stop_signals"]

#: Signals that stop a run cleanly (its output kept, marked "interrupted"); exit code 128 + the signal number.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class _Swapped:
    """In the main thread (and if `active`), the handlers of `STOP_SIGNALS` swapped for `handler` (default: the signal
    appended to `received`) until `restore`. A C handler (PETSc's) cannot be put back: left in place, or with `over_c`
    replaced and the default put back."""

    def __init__(self, handler=None, active: bool = True, over_c: bool = False):
        self.received: list[int] = []
        active = active and threading.current_thread() is threading.main_thread()
        saved = {s: signal.getsignal(s) for s in STOP_SIGNALS} if active else {}
        self.saved = {s: signal.SIG_DFL if h is None else h for s, h in saved.items() if h is not None or over_c}
        for s in self.saved:
            signal.signal(s, handler or (lambda signum, frame: self.received.append(signum)))

    def restore(self) -> None:
        saved, self.saved = self.saved, {}
        for s, handler in saved.items():
            signal.signal(s, handler)


@contextlib.contextmanager
def stop_signals(on_signal=None):
    """The stop signals raise `Interrupted` (the run stops, its output kept) until the block ends, over any handler
    (PETSc's too); `on_signal(signum)` is called first."""

    def handler(signum, frame):
        if on_signal is not None:
            on_signal(signum)
        raise Interrupted(signum)

    swapped = _Swapped(handler, over_c=True)
    try:
        yield
    finally:
        swapped.restore()


@contextlib.contextmanager
def signals_held():
    """Hold the stop signals back for a critical section; they take effect right after it (handlers swapped, not
    signals blocked: one that arrived just before would run its handler inside the section)."""
    held = _Swapped()
    try:
        yield
    finally:
        held.restore()
        if held.received:  # the first one, to its own handler now (`raise_signal` runs a Python one before it returns)
            signal.raise_signal(held.received[0])


class StopTogether:
    """Under MPI a stop signal that reaches some ranks stops every rank at the same step: recorded, shared by `poll`
    (one allreduce), `Interrupted` raised on all."""

    def __init__(self, comm):
        self.comm = comm if comm is not None and comm.size > 1 else None

    def __enter__(self) -> Self:
        self.held = _Swapped(active=self.comm is not None)
        return self

    def poll(self) -> None:
        """Collective: raise `Interrupted` on every rank if a stop signal reached any rank."""
        if self.comm is None:
            return
        from mpi4py import MPI

        signum = self.comm.allreduce(self.held.received[0] if self.held.received else 0, op=MPI.MAX)
        if signum:
            self.held.restore()
            raise Interrupted(signum)

    def __exit__(self, kind, value, tb) -> None:
        self.held.restore()
        if self.held.received and kind is None:  # a signal after the last poll: it takes effect now
            signal.raise_signal(self.held.received[0])
