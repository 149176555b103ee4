"""The output folder of `study` and `check`, taken before they compute: its lock and its hidden partial folder."""

from __future__ import annotations

import contextlib

__all__ = ["staged_output"]


@contextlib.contextmanager
def staged_output(out, force: bool, command: str, comm, root: int = 0):
    """``with staged_output(out, force, command, comm) as partial:`` compute, then write into `partial`.

    The folder is taken (`io.target.check_target`, then `io.publish.staged_folder`: locked, a hidden partial
    folder beside it) before the body runs, by rank `root` alone (another rank probing it would find it locked),
    with one outcome on every rank (`fem.agree.one_outcome`): a folder another study writes to, or one that cannot be
    made, is refused before minutes of computing, not after them. Yields
    the partial folder on `root`, None on the other ranks and when `out` is None; it is published when the body
    ends without an error, removed otherwise.
    """
    from ..fem.agree import one_outcome
    from ..io.publish import staged_folder
    from ..io.target import check_target

    def take(stack):
        check_target(out, force, command=command)  # the command line's rules (no missing parents outside .)
        return stack.enter_context(staged_folder(out, force, command=command))

    with contextlib.ExitStack() as stack:
        partial = None if out is None else one_outcome(comm, take, stack, root=root)
        yield partial
