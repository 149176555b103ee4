"""The errors a user can meet, each with a message that names the cause and the remedy.

The command line maps them to exit codes (see `stringcontact.cli.main`): `SceneError`, `OutputError` and
`StackError` to 2, `InstabilityError` to 3 (2 if it is found before the first step), `Interrupted` to 128 + the signal number.
:func:`one_line` puts a message (or the text of an exception) on the one line those errors are shown on.
"""

import contextlib
import signal


class SceneError(ValueError):
    """A scene (file, key or expression) is invalid. The message names the key and what is allowed."""


class ModelError(ValueError):
    """The model's UFL does not fit the scheme (for example it is not linear in η, η_t, η_tt)."""


class InstabilityError(RuntimeError):
    """The time stepping is, or became, unstable. The message names the step, the time, r and a remedy."""

    def __init__(self, message, *, step=None, time=None, r=None):
        super().__init__(message)
        self.step, self.time, self.r = step, time, r


class SolverError(RuntimeError):
    """A numerical step failed after the input was accepted (a linear solve that does not converge): exit code 1,
    not 2 "bad input" (docs/explanation/reliability.md)."""


class OutputError(RuntimeError):
    """The output folder cannot be used: not empty, locked by another run, not writable, or the disk is full."""


class StackError(ImportError):
    """The installed FEniCS stack is not one this package runs on (a dolfinx too old or too new): exit code 2."""


class Interrupted(KeyboardInterrupt):
    """SIGINT (Ctrl-C) or SIGTERM during a run: a KeyboardInterrupt, so that SIGTERM is cleaned up after as Ctrl-C."""

    def __init__(self, signum: int = signal.SIGINT):
        self.signum = int(signum)
        name = signal.Signals(self.signum).name
        super().__init__(f"interrupted by {name}" + (" (Ctrl-C)" if self.signum == signal.SIGINT else ""))

    @property
    def exit_code(self) -> int:
        """The shell's convention: 128 + the signal number (130 for SIGINT, 143 for SIGTERM)."""
        return 128 + self.signum


class InstabilityWarning(UserWarning):
    """Stable, but not as intended: e.g. the explicit velocity penalty with 1 < Δt/ε < 2 rebounds with restitution r − 1."""


class PenetrationWarning(UserWarning):
    """The string went further below the obstacle than the velocity penalty should allow (see docs/explanation/reliability.md)."""


def one_line(text, limit: int | None = None) -> str:
    """`text` (a message or an exception) on one line, each run of whitespace one space; at most `limit` characters."""
    line = " ".join(str(text).split())
    return line if limit is None else line[:limit]


#: What a plugin's own code raises when it breaks its contract (a wrong type returned, a key it does not have): one
#: line naming the plugin (exit 2), not an internal error.
PLUGIN_FAULTS = (TypeError, KeyError, AttributeError, IndexError, NotImplementedError, ZeroDivisionError)


def plugin_failure(what: str, exc: BaseException) -> BaseException:
    """The one-line `SceneError` naming `what` (a model, a scheme) for ``sys.exit``, a `KeyboardInterrupt` or a
    `PLUGIN_FAULTS` error its code raised; any other exception is returned as it is."""
    if isinstance(exc, Interrupted) or not isinstance(exc, (SystemExit, KeyboardInterrupt, *PLUGIN_FAULTS)):
        return exc
    if isinstance(exc, SystemExit):
        why = f"called sys.exit({exc.code!r}); a plugin's code must return its value or raise an exception, never end the process"
    elif isinstance(exc, KeyboardInterrupt):
        why = "raised KeyboardInterrupt itself (no Ctrl-C was pressed); a plugin's code must return its value or raise an exception"
    else:
        why = f"failed with {type(exc).__name__}: {one_line(exc, 200)}; see its declaration and docs/howto/models.md or schemes.md"
    return SceneError(f"{what} {why}")


@contextlib.contextmanager
def plugin_code(what: str):
    """Run a plugin's own code: what `plugin_failure` names becomes a one-line `SceneError` naming `what` (not an
    exit 0 with nothing said); a signal's `Interrupted` and this package's own errors pass."""
    try:
        yield
    except BaseException as exc:
        failure = plugin_failure(what, exc)
        if failure is exc:
            raise
        raise failure from None
