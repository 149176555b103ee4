"""The JIT compiler's log stays at WARNING: a first run on a fresh machine prints no compiler command lines.

ffcx calls ``logging.basicConfig()`` on import and cffi raises the root logger to INFO while it compiles, so the gcc
command lines reach the output (4 lines per form). A root-logger filter drops exactly those records below WARNING.
"""

from __future__ import annotations

import logging

#: Where the JIT's records come from: distutils (as setuptools ships it, or the stdlib's) and cffi/ffcx.
JIT_SOURCES = ("distutils", "cffi", "ffcx")


class QuietCompiler(logging.Filter):
    """Drops the JIT compiler's records below WARNING."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.WARNING:
            return True
        path = record.pathname.replace("\\", "/")
        return not any(f"/{name}/" in path or f"/_{name}/" in path for name in JIT_SOURCES)


def quiet_compiler() -> None:
    """Install `QuietCompiler` on the root logger (idempotent) and keep ffcx's own logger at WARNING."""
    root = logging.getLogger()
    if not any(isinstance(f, QuietCompiler) for f in root.filters):
        root.addFilter(QuietCompiler())
    ffcx = logging.getLogger("ffcx")
    if ffcx.level == logging.NOTSET:  # a level the user chose is kept
        ffcx.setLevel(logging.WARNING)
