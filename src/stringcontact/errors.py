"""The two errors a user can meet, each with a message that names the cause and the remedy."""


class SceneError(ValueError):
    """A scene (file, key or expression) is invalid. The message names the key and what is allowed."""


class InstabilityError(RuntimeError):
    """The time stepping is, or became, unstable. The message names the step, the time, r and a remedy."""

    def __init__(self, message, *, step=None, time=None, r=None):
        super().__init__(message)
        self.step = step
        self.time = time
        self.r = r
