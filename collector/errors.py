"""Errors of the collector, all derived from :class:`~solver.errors.LasercalError`.

The ``lasercal`` command turns each into one line ``lasercal: error: <message>`` and exit
code 2. A message says what to do next where there is something to do (the pip command
of a missing extra, the command that resumes an interrupted session).
"""

from __future__ import annotations

from lasercal.solver.errors import LasercalError


class MissingExtraError(LasercalError):
    """An optional dependency (robot SDK, serial library) is not installed."""

    def __init__(self, what: str, package: str, extra: str | None = None):
        pip = (
            f"pip install 'lasercal[{extra}]' (or pip install {package})"
            if extra
            else f"pip install {package}"
        )
        super().__init__(f"{what} needs the Python package {package}, which is not installed: {pip}")


class RobotConnectionError(LasercalError):
    """The robot cannot be reached, or stopped answering during a session."""


class SessionError(LasercalError):
    """A session folder cannot be started or resumed as asked (exists, mismatching options, ...)."""


class DeviceError(LasercalError):
    """A trigger device, rangefinder or camera cannot be opened or read."""


class InputEnded(LasercalError):
    """The trigger's input ended (standard input at its end: no one at the keyboard). Not a
    :class:`DeviceError`: the command that ran the session says what was kept and how to resume it."""
