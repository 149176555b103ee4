"""One outcome on every rank for work that runs on each rank alone, or on one rank only: a check that fails on one
rank must not leave the others waiting in the next collective call. Every rank raises the first failing rank's error."""

from __future__ import annotations

import pickle

__all__ = ["one_outcome", "same_on_every_rank"]


def one_outcome(comm, work, *args, root: int | None = None):
    """`work(*args)` on every rank (on `root` only, if given; the others return None), with one outcome. Collective;
    the work itself must not make a collective call before it can fail."""
    value, error = None, None
    if root is None or comm.rank == root:
        try:
            value = work(*args)
        except Exception as exc:  # noqa: BLE001 - any failure, an input error or a bug, must reach every rank
            error = exc
    if comm.size > 1:
        failed = [e for e in comm.allgather(_portable(error)) if e is not None]
        if failed and error is None:
            raise failed[0]
        if failed and str(failed[0]) != str(error):
            raise failed[0] from error  # the first failing rank's line, on every rank
    if error is not None:
        raise error
    return value


def _portable(error: Exception | None):
    """The error as it can travel to the other ranks: itself if it pickles, else a RuntimeError with its text."""
    if error is None:
        return None
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:  # noqa: BLE001 - an exception with unpicklable state
        return RuntimeError(f"{type(error).__name__}: {error}")


def same_on_every_rank(comm, what: str, value) -> None:
    """A one-line `SceneError` on every rank unless `value` (plain data) is the same on every rank (one allgather of
    its digest). Collective; free in serial."""
    if comm.size == 1:
        return
    import hashlib
    import json

    def plain(o):  # an array (a restart's eta0) by its bytes; anything else by its repr
        return hashlib.sha256(o.tobytes()).hexdigest() if hasattr(o, "tobytes") else repr(o)

    digest = hashlib.sha256(json.dumps(value, sort_keys=True, default=plain).encode()).hexdigest()[:16]
    digests = comm.allgather(digest)
    if len(set(digests)) > 1:
        from ..errors import SceneError

        differ = [rank for rank, d in enumerate(digests) if d != digests[0]]
        raise SceneError(f"{what}: rank {differ[0]} was given other values than rank 0 ({value!r:.120} on rank "
                         f"{comm.rank}); allowed: the same {what} on every rank of the MPI job")
