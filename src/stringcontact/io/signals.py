"""Signals held back during a critical section (a frame written, a folder renamed into place)."""

from __future__ import annotations

import contextlib
import os
import signal
import threading

__all__ = ["signals_held"]


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


