"""The one interface every robot backend implements, and the clocks sessions run on.

A backend reads the arm's joint state; the session flow (``collector.capture``,
``collector.validate``) decides when to capture. Backends that can move the arm say so
(``can_move``) and implement :meth:`RobotAdapter.move_to`; the others leave motion to
the operator. Each backend imports its robot SDK when it is constructed, through
:func:`import_extra`, so a missing SDK costs nothing until that backend is chosen, and
is reported before a session folder is made.
"""

from __future__ import annotations

import importlib
import time
from dataclasses import dataclass, field

import numpy as np

from lasercal.collector.errors import MissingExtraError


@dataclass(frozen=True)
class JointState:
    """One reading of the arm.

    Attributes
    ----------
    q : (n,) array, joint positions, rad
    dq : (n,) array, joint velocities, rad/s
    tau : (n,) array, measured joint torques, Nm
    t : float, time of the reading on the backend's clock, s
    extra : dict column -> value, whatever else the backend offers (e.g. ``robot_mode``)
    """

    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    t: float
    extra: dict = field(default_factory=dict)


class Clock:
    """Wall time for real robots: monotonic seconds, real sleeps."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        time.sleep(seconds)


class FakeClock(Clock):
    """Simulated time: ``sleep`` advances it at once, so simulated sessions never wait."""

    def __init__(self, start: float = 0.0):
        self.t = float(start)

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += seconds


class PilotButtons:
    """Button events of the robot's own pilot (wrist) buttons: check = capture, cross = discard, circle =
    quit."""

    MAP = {"check": "capture", "cross": "discard", "circle": "quit"}

    def poll(self, timeout: float) -> list[str]:
        """Commands ('capture', 'discard', 'quit') from buttons pressed since the last poll."""
        raise NotImplementedError

    def close(self) -> None:
        """Stop listening."""


class RobotAdapter:
    """A robot backend. Subclasses implement connect, read and close; the rest is optional.

    Attributes
    ----------
    name : str, the ``--backend`` name
    can_move : bool, :meth:`move_to` moves the arm (validation runs unattended)
    guidance : str, what the operator must know, shown when a session starts
    extra_columns : tuple of str, keys of ``JointState.extra`` (captures.csv extra columns)
    clock : Clock, the time base of ``JointState.t``
    """

    name = "robot"
    can_move = False
    guidance = ""
    extra_columns: tuple = ()
    clock: Clock = Clock()

    def connect(self) -> None:
        """Open the connection (a no-op when open). Raises RobotConnectionError when the robot cannot be
        reached."""
        raise NotImplementedError

    def read(self) -> JointState:
        """The current joint state. Raises RobotConnectionError when the robot stopped answering."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the robot (idempotent)."""
        raise NotImplementedError

    def move_to(self, q: np.ndarray) -> None:
        """Move the arm to configuration q (rad) and return when it got there (``can_move`` backends)."""
        raise NotImplementedError(f"the {self.name} backend cannot move the arm")

    def stop(self) -> None:
        """Stop any commanded motion now (Ctrl-C, lost link); never raises. No-op where nothing moves."""

    def pilot_buttons(self) -> PilotButtons | None:
        """The robot's pilot buttons as a trigger, or None when the backend offers none."""
        return None

    def prompt_point(self, name: str, xyz: np.ndarray, index: int, spot: np.ndarray | None = None) -> None:
        """The operator is asked to aim at point ``name`` for its capture ``index`` (0-based): at ``xyz``
        (base frame, mm), or with ``spot`` (2,) at that spot of the layout's frame, off the point, that the
        coach planned in its cell (``--aim anywhere``).

        Real robots ignore it (the operator reads the screen); the simulated operator acts on it.
        """

    def prompt_configuration(self, q: np.ndarray) -> None:
        """The operator is asked to guide the arm to configuration q (validation without motion)."""

    def resume_at(self, q: np.ndarray, t: float) -> None:
        """A resumed capture session starts: its last capture was at configuration q (rad), session time t
        (s). A real arm is wherever it is (no-op); a simulated one is put back there, so that the resumed
        session repeats the unbroken one."""

    def suggest_pose(self, q: np.ndarray) -> None:
        """The capture coach suggests configuration q (rad) for the next capture.

        Real robots ignore it (the operator reads the joint changes on screen; the arm is not moved);
        the simulated operator starts hand-guiding from it.
        """


def import_extra(module: str, what: str, package: str, extra: str | None = None):
    """Import an optional dependency, or raise MissingExtraError with the pip command."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(what, package, extra) from None
