"""The output folder of `study` and `check`, taken before they compute: its lock and its hidden partial folder."""

from __future__ import annotations

import contextlib


@contextlib.contextmanager
def staged_output(out, force: bool, command: str, comm, root: int = 0):
    """``with staged_output(out, force, command, comm) as partial:`` compute, then write into `partial` (None on the
    other ranks and without `out`): published if the body ends without an error, else removed. Rank `root` takes the
    folder before the body runs, one outcome on every rank: a refusal comes before minutes of computing."""
    from ..fem.agree import one_outcome
    from ..io.publish import check_target, staged_folder

    def take(stack):
        check_target(out, force, command=command)  # the command line's rules (no missing parents outside .)
        return stack.enter_context(staged_folder(out, force, command=command))

    with contextlib.ExitStack() as stack:
        yield None if out is None else one_outcome(comm, take, stack, root=root)
