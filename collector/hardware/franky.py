"""The ``franky`` backend: franky-control (libfranka for FR3 / system >= 5) over the FCI.

Reads the measured joint positions, velocities, torques (``tau_J``) and robot mode.
franky cannot switch hand-guiding on: the operator holds the pilot's guiding buttons.
Moves (validation) use a joint motion scaled by ``dynamics`` (fraction of the limits).
With Desk credentials the pilot's check/cross/circle buttons can trigger captures.
"""

from __future__ import annotations

import numpy as np

from lasercal.collector.errors import MissingExtraError, RobotConnectionError
from lasercal.collector.hardware.base import JointState, PilotButtons, RobotAdapter, import_extra


class FrankyPilot(PilotButtons):
    """Pilot buttons through franky's Desk session (HTTPS + websocket to the robot's Desk)."""

    def __init__(self, desk):
        self.desk = desk

    def poll(self, timeout: float) -> list[str]:
        events = self.desk.poll_buttons(timeout)
        return [self.MAP[e.button.value] for e in events if e.pressed and e.button.value in self.MAP]

    def close(self) -> None:
        self.desk.close()


class FrankyRobot(RobotAdapter):
    """A Franka arm through franky-control.

    Parameters
    ----------
    host : str, the robot's FCI address
    dynamics : float, relative dynamics factor of commanded moves, (0, 1]
    desk : (user, password) or None, Desk credentials for the pilot buttons
    """

    name = "franky"
    can_move = True
    guidance = (
        "hand-guiding is your job: hold the pilot's guiding buttons, bring the spot onto the point, "
        "let go, then trigger (franky cannot switch guiding on)"
    )
    extra_columns = ("robot_mode",)

    def __init__(self, host: str, dynamics: float = 0.1, desk: tuple | None = None):
        self.franky = import_extra("franky", "the franky backend", "franky-control", "franky")
        self.host, self.dynamics, self.desk = host, dynamics, desk
        self._robot = None

    def connect(self) -> None:
        if self._robot is not None:
            return
        franky = self.franky
        try:
            self._robot = franky.Robot(self.host, realtime_config=franky.RealtimeConfig.Ignore)
            self._robot.relative_dynamics_factor = self.dynamics
        except Exception as e:  # franky.NetworkException and friends: one line, no traceback
            raise RobotConnectionError(f"franky: cannot connect to the robot at {self.host} ({e})") from None

    def read(self) -> JointState:
        try:
            s = self._robot.state
        except Exception as e:  # NetworkException (UDP timeout) or RuntimeError once the link is gone
            raise RobotConnectionError(f"franky: the robot at {self.host} stopped answering ({e})") from None
        return JointState(
            np.array(s.q),
            np.array(s.dq),
            np.array(s.tau_J),
            self.clock.now(),
            {"robot_mode": s.robot_mode.name},
        )

    def move_to(self, q: np.ndarray) -> None:
        try:
            self._robot.move(self.franky.JointMotion([float(v) for v in q]))
        except Exception as e:
            raise RobotConnectionError(
                f"franky: the move to {np.round(q, 4).tolist()} failed ({e})"
            ) from None

    def stop(self) -> None:
        if self._robot is not None:
            try:
                self._robot.stop()
            except Exception:  # the link may be gone already: the robot then stops by itself (reflex)
                pass

    def pilot_buttons(self) -> PilotButtons | None:
        if self.desk is None:
            return None
        if not hasattr(self.franky, "Desk"):
            raise MissingExtraError("the pilot-button trigger", "franky-control>=2.0", "franky")
        desk = self.franky.Desk(self.host, *self.desk)
        try:
            desk.open()
        except Exception as e:
            raise RobotConnectionError(f"franky: cannot open the Desk session at {self.host} ({e})") from None
        return FrankyPilot(desk)

    def close(self) -> None:
        self._robot = None  # franky disconnects when the Robot is released
