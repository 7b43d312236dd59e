"""One base exception for lasercal, with specific subclasses.

Every error raised on bad user input derives from :class:`LasercalError`; the CLI
turns it into a one-line message and exit code 2, never a traceback. Input that is plausible
but suspicious (a joint angle a hair beyond a rounded limit, a duplicated capture) is kept and
reported through :func:`warn` (a :class:`LasercalWarning`): the CLI prints it as one line
``lasercal: warning: ...`` and goes on.
"""

from __future__ import annotations

import warnings


class LasercalError(Exception):
    """Base class of every error lasercal raises on purpose."""


class FormatError(LasercalError):
    """A file is malformed. The message names the file, and the line and column/field when known."""

    def __init__(self, path, message: str, line: int | None = None, field: str | None = None):
        self.path, self.line, self.field, self.reason = str(path), line, field, message
        where = self.path
        if line is not None:
            where += f", line {line}"
        if field is not None:
            where += f", {'column' if line is not None else 'field'} '{field}'"
        super().__init__(f"{where}: {message}")

    def __reduce__(self):
        # rebuilt from its parts: an error raised in a worker process (``study-mukca --jobs``)
        # crosses back by pickle, which would call __init__ with the full message alone
        return type(self), (self.path, self.reason, self.line, self.field)


class ModelError(LasercalError):
    """A robot model is inconsistent (wrong joint count, bad screw, ...)."""


class IdentificationError(LasercalError):
    """Identification cannot proceed (too few captures, no convergence possible, ...)."""


class AimingError(LasercalError):
    """No in-limit configuration was found that aims the beam at the requested point."""


class CirclePointError(LasercalError):
    """Points that cannot define a rotation plane and circle (too few, coincident, collinear)."""


class LasercalWarning(UserWarning):
    """Input kept but suspicious: the message names the file or option, and what looks wrong."""


def warn(message: str) -> None:
    """Report suspicious input without stopping (the solver never prints: the caller shows it)."""
    warnings.warn(message, LasercalWarning, stacklevel=2)
