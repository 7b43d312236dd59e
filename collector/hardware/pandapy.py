"""The ``panda-py`` backend: panda-python (libfranka 0.9, Panda arms on older system versions).

Switches the arm into teaching mode (gravity-compensated hand-guiding) for capture
sessions; commanded moves (validation) leave it. Desk credentials enable the pilot's
check/cross/circle buttons as a trigger.
"""

from __future__ import annotations

import queue

import numpy as np

from lasercal.collector.errors import RobotConnectionError
from lasercal.collector.hardware.base import JointState, PilotButtons, RobotAdapter, import_extra


class PandaPyPilot(PilotButtons):
    """Pilot buttons through panda-py's Desk listener (a thread feeding a queue)."""

    def __init__(self, desk):
        self.desk = desk
        self._events: queue.Queue = queue.Queue()
        desk.listen(self._on_event)

    def _on_event(self, event: dict) -> None:
        for button, pressed in event.items():
            if pressed and button in self.MAP:
                self._events.put(self.MAP[button])

    def poll(self, timeout: float) -> list[str]:
        try:
            first = self._events.get(timeout=timeout)
        except queue.Empty:
            return []
        out = [first]
        while not self._events.empty():
            out.append(self._events.get_nowait())
        return out

    def close(self) -> None:
        self.desk.stop_listen()


class PandaPyRobot(RobotAdapter):
    """A Panda through panda-python.

    Parameters
    ----------
    host : str, the robot's FCI address
    speed : float, speed factor of commanded moves, (0, 1]
    desk : (user, password) or None, Desk credentials for the pilot buttons
    """

    name = "panda-py"
    can_move = True
    guidance = "teaching mode is on: hand-guide the arm, let go, then trigger"
    extra_columns = ("robot_mode",)

    def __init__(self, host: str, speed: float = 0.1, desk: tuple | None = None):
        self.panda_py = import_extra("panda_py", "the panda-py backend", "panda-python", "panda")
        self.host, self.speed, self.desk = host, speed, desk
        self._panda = None

    def connect(self) -> None:
        if self._panda is not None:
            return
        try:
            self._panda = self.panda_py.Panda(self.host)
            self._panda.teaching_mode(True)
        except Exception as e:
            raise RobotConnectionError(
                f"panda-py: cannot connect to the robot at {self.host} ({e})"
            ) from None

    def read(self) -> JointState:
        try:
            s = self._panda.get_state()
        except Exception as e:
            raise RobotConnectionError(
                f"panda-py: the robot at {self.host} stopped answering ({e})"
            ) from None
        mode = str(s.robot_mode).rsplit(".", 1)[-1]  # 'RobotMode.kIdle' -> 'kIdle'
        return JointState(
            np.array(s.q), np.array(s.dq), np.array(s.tau_J), self.clock.now(), {"robot_mode": mode}
        )

    def move_to(self, q: np.ndarray) -> None:
        try:
            self._panda.teaching_mode(False)
            ok = self._panda.move_to_joint_position(np.asarray(q, dtype=float), speed_factor=self.speed)
        except Exception as e:
            raise RobotConnectionError(
                f"panda-py: the move to {np.round(q, 4).tolist()} failed ({e})"
            ) from None
        if not ok:
            raise RobotConnectionError(
                f"panda-py: the move to {np.round(q, 4).tolist()} did not reach its target"
            )

    def stop(self) -> None:
        if self._panda is not None:
            try:
                self._panda.stop_controller()
            except Exception:  # the link may be gone already: the robot then stops by itself (reflex)
                pass

    def pilot_buttons(self) -> PilotButtons | None:
        if self.desk is None:
            return None
        try:
            return PandaPyPilot(self.panda_py.Desk(self.host, *self.desk))
        except Exception as e:
            raise RobotConnectionError(
                f"panda-py: cannot open the Desk session at {self.host} ({e})"
            ) from None

    def close(self) -> None:
        if self._panda is not None:
            try:
                self._panda.teaching_mode(False)
            except Exception:  # the link may already be gone; closing must not mask the real error
                pass
            self._panda = None
