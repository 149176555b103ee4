"""BLAS held to one thread (threadpoolctl) while a run steps long nodal vectors: OpenBLAS threads a dot product of
over 10,000 entries, and the stiff string's Example 1 stepped 5 to 14 times slower for it on a loaded 2-core machine
(`benchmarks/bench_blas_threads.py`). The caller's setting comes back after."""

from __future__ import annotations

import contextlib
import functools

#: Nodal vectors up to this length: no BLAS (OpenBLAS's dot product is single-threaded up to 10,000 entries), and
#: no limit to set (setting one costs about 11 µs, a tenth of a small string's step).
THREADED_LENGTH = 8192


@functools.cache
def _controller():
    """threadpoolctl's view of the BLAS libraries loaded now (made once: it scans the process's libraries)."""
    from threadpoolctl import ThreadpoolController

    controller = ThreadpoolController().select(user_api="blas")
    return controller if any(lib.num_threads > 1 for lib in controller.lib_controllers) else None


def one_thread(length: int):
    """A context in which BLAS runs on one thread, for a run whose nodal vectors have `length` entries (nothing to
    do below `THREADED_LENGTH`, or where BLAS has one thread already)."""
    controller = _controller() if length > THREADED_LENGTH else None
    return controller.limit(limits=1) if controller is not None else contextlib.nullcontext()


__all__ = ["THREADED_LENGTH", "one_thread"]
