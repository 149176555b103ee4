"""BLAS held to one thread while a run steps.

The schemes' energy terms are dot products of nodal vectors (``np.dot``). OpenBLAS (PyPI's NumPy, which the
dolfinx wheel's stack uses) computes a dot product of more than 10,000 entries on all its threads; on a loaded
2-core machine the stiff string's Example 1 (10,002 unknowns) stepped 5 to 14 times slower for it: 6.1-11.4 s
against 0.81-1.16 s held to one thread (`benchmarks/bench_blas_threads.py`, dolfinx 0.11 wheel, OpenBLAS 0.3.34). A dot product of nodal vectors gains nothing from threads: so while a
run steps a vector this long, BLAS has one thread (threadpoolctl), and the caller's setting comes back after.
Debian's NumPy links a single-threaded BLAS, where nothing changes.
"""

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
