"""The output folder of `study` and `check`, taken before they compute: its lock and its hidden partial folder."""

from __future__ import annotations

import contextlib

__all__ = ["staged_output"]


@contextlib.contextmanager
def staged_output(out, force: bool, command: str, comm, root: int = 0):
    """``with staged_output(out, force, command, comm) as partial:`` compute, then write into `partial`.

    The folder is taken (`io.publish.staged_folder`: checked, locked, a hidden partial folder beside it) before
    the body runs, by rank `root` alone, with one outcome on every rank (`fem.agree.agreed`): a folder another
    study writes to, or one that cannot be made, is refused before minutes of computing, not after them. Yields
    the partial folder on `root`, None on the other ranks and when `out` is None; it is published when the body
    ends without an error, removed otherwise.
    """
    from ..fem.agree import agreed
    from ..io.publish import staged_folder

    with contextlib.ExitStack() as stack:
        partial = None
        if out is not None:
            partial = agreed(comm, lambda: stack.enter_context(staged_folder(out, force, command=command)), root=root)
        yield partial
