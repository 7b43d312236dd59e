"""The ``ros`` backend: ``sensor_msgs/JointState`` messages through a rosbridge server (roslibpy).

For labs that run franka_ros: the arm's joint states arrive on ``/joint_states``; joints
are picked by name (``panda_joint1..7`` or ``fr3_joint1..7`` are found by themselves;
finger joints are left out). Hand-guiding is the operator's job; this backend cannot move.
"""

from __future__ import annotations

import re
import threading

import numpy as np

from lasercal.collector.errors import RobotConnectionError
from lasercal.collector.hardware.base import Clock, JointState, RobotAdapter, import_extra


def arm_joint_names(names: list[str], n: int) -> list[str]:
    """The arm's joints ``<prefix>joint1..n`` among a JointState's names (not the fingers)."""
    for nm in names:
        m = re.fullmatch(r"(.*?)joint1", nm)
        if m and "finger" not in m.group(1):
            return [f"{m.group(1)}joint{i}" for i in range(1, n + 1)]
    raise RobotConnectionError(
        f"ros: no arm joints '...joint1' among the joint names {names}; pass --ros-joints"
    )


class RosRobot(RobotAdapter):
    """Joint states from a rosbridge server.

    Parameters
    ----------
    host, port : the rosbridge websocket server
    n : int, joints of the arm
    joints : list of str or None, the arm's joint names in order (None: found by name)
    topic : str
    stale : float, a reading older than this is a lost connection, s
    """

    name = "ros"
    can_move = False
    guidance = "reading /joint_states through rosbridge: hand-guide the arm, let go, then trigger"
    extra_columns = ("ros_stamp",)

    def __init__(
        self,
        host: str,
        port: int = 9090,
        n: int = 7,
        joints: list | None = None,
        topic: str = "/joint_states",
        stale: float = 1.0,
        clock: Clock | None = None,
    ):
        self.host, self.port, self.n, self.joints, self.topic_name, self.stale = (
            host,
            port,
            n,
            joints,
            topic,
            stale,
        )
        self.roslibpy = import_extra("roslibpy", "the ros backend", "roslibpy", "ros")
        self.clock = clock or Clock()
        self._ros = self._topic = self._msg = None
        self._received = threading.Event()
        self._lock = threading.Lock()

    def connect(self) -> None:
        if self._ros is not None:
            return
        roslibpy = self.roslibpy
        try:
            self._ros = roslibpy.Ros(host=self.host, port=self.port)
            self._ros.run(timeout=5)
        except Exception as e:
            raise RobotConnectionError(
                f"ros: cannot reach rosbridge at {self.host}:{self.port} ({e})"
            ) from None
        self._topic = roslibpy.Topic(self._ros, self.topic_name, "sensor_msgs/JointState")
        self._topic.subscribe(self._on_message)

    def _on_message(self, msg: dict) -> None:
        with self._lock:
            self._msg = (self.clock.now(), msg)
        self._received.set()

    def read(self) -> JointState:
        if not self._received.wait(self.stale * 5) or not self._ros.is_connected:
            raise RobotConnectionError(f"ros: no {self.topic_name} messages from {self.host}:{self.port}")
        with self._lock:
            t, msg = self._msg
        if self.clock.now() - t > self.stale:
            raise RobotConnectionError(
                f"ros: the last {self.topic_name} message is {self.clock.now() - t:.1f} s old"
            )
        names = list(msg["name"])
        self.joints = self.joints or arm_joint_names(names, self.n)
        missing = [j for j in self.joints if j not in names]
        if missing:
            raise RobotConnectionError(f"ros: {self.topic_name} has no joint(s) {missing} (it has {names})")
        idx = [names.index(j) for j in self.joints]
        for key in ("position", "velocity", "effort"):
            if len(msg.get(key) or []) != len(names):
                raise RobotConnectionError(
                    f"ros: {self.topic_name} messages carry no '{key}' (franka_ros publishes it)"
                )
        stamp = msg.get("header", {}).get("stamp", {})
        return JointState(
            np.array(msg["position"])[idx],
            np.array(msg["velocity"])[idx],
            np.array(msg["effort"])[idx],
            t,
            {"ros_stamp": stamp.get("secs", 0) + 1e-9 * stamp.get("nsecs", 0)},
        )

    def close(self) -> None:
        if self._topic is not None:
            self._topic.unsubscribe()
        if self._ros is not None:
            self._ros.close()  # not terminate(): that ends roslibpy's event loop for the whole process
        self._ros = self._topic = None
