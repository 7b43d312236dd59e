"""Robot adapters against stand-in SDK modules (the franky adapter meets a real simulator in
test_collector_franky_sim)."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from lasercal.collector.errors import RobotConnectionError
from lasercal.collector.hardware.base import FakeClock
from lasercal.collector.hardware.pandapy import PandaPyRobot
from lasercal.collector.hardware.ros import RosRobot, arm_joint_names
from lasercal.collector.worlds.fake import FakeRobot, perturbed_model
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import aim

NAMES = ["panda_finger_joint1"] + [f"panda_joint{i}" for i in (3, 1, 2, 7, 4, 5, 6)] + ["panda_finger_joint2"]


@pytest.fixture
def roslibpy(monkeypatch):
    """A stand-in for roslibpy: one Ros connection and a topic the test publishes on."""
    mod = types.ModuleType("roslibpy")

    class Ros:
        def __init__(self, host, port):
            self.is_connected = False

        def run(self, timeout):
            self.is_connected = True

        def close(self):
            self.is_connected = False

    class Topic:
        def __init__(self, ros, name, msg_type):
            assert msg_type == "sensor_msgs/JointState"
            mod.topic = self

        def subscribe(self, cb):
            self.cb = cb

        def unsubscribe(self):
            self.cb = None

    mod.Ros, mod.Topic = Ros, Topic
    monkeypatch.setitem(sys.modules, "roslibpy", mod)
    return mod


def _msg(values, velocity=True):
    v = list(values)
    return {
        "name": NAMES,
        "position": v,
        "velocity": [0.01 * x for x in v] if velocity else [],
        "effort": [10 * x for x in v],
        "header": {"stamp": {"secs": 12, "nsecs": 500_000_000}},
    }


def test_ros_joint_states_are_mapped_by_name_and_fingers_left_out(roslibpy):
    clock = FakeClock()
    robot = RosRobot("127.0.0.1", clock=clock, stale=1.0)
    robot.connect()
    values = np.arange(len(NAMES), dtype=float)  # value i sits at name i
    roslibpy.topic.cb(_msg(values))
    s = robot.read()
    expect = [values[NAMES.index(f"panda_joint{i}")] for i in range(1, 8)]
    np.testing.assert_array_equal(s.q, expect)
    np.testing.assert_array_equal(s.tau, 10 * np.array(expect))
    assert s.extra["ros_stamp"] == 12.5
    clock.sleep(1.5)
    with pytest.raises(RobotConnectionError, match="1.5 s old"):
        robot.read()
    roslibpy.topic.cb(_msg(values, velocity=False))
    with pytest.raises(RobotConnectionError, match="no 'velocity'"):
        robot.read()
    robot.close()


def test_arm_joint_names():
    assert arm_joint_names(["fr3_finger_joint1", "fr3_joint2", "fr3_joint1"], 7)[6] == "fr3_joint7"
    with pytest.raises(RobotConnectionError, match="--ros-joints"):
        arm_joint_names(["finger_joint1", "wheel"], 7)


@pytest.fixture
def panda_py(monkeypatch):
    """A stand-in for panda_py recording what the adapter asks of the arm."""
    mod = types.ModuleType("panda_py")
    calls = mod.calls = []

    class Panda:
        def __init__(self, host):
            calls.append(("connect", host))

        def teaching_mode(self, on):
            calls.append(("teaching", on))

        def get_state(self):
            return types.SimpleNamespace(
                q=[0.1] * 7, dq=[0.0] * 7, tau_J=[1.0] * 7, robot_mode="RobotMode.kGuiding"
            )

        def move_to_joint_position(self, q, speed_factor):
            calls.append(("move", speed_factor))
            return bool(q[0] < 1)

    mod.Panda = Panda
    monkeypatch.setitem(sys.modules, "panda_py", mod)
    return mod


def test_panda_py_guides_in_teaching_mode_and_leaves_it_to_move(panda_py):
    robot = PandaPyRobot("127.0.0.1", speed=0.2)
    robot.connect()
    s = robot.read()
    assert s.extra["robot_mode"] == "kGuiding" and s.tau[0] == 1.0
    robot.move_to(np.zeros(7))
    with pytest.raises(RobotConnectionError, match="did not reach"):
        robot.move_to(np.full(7, 2.0))
    robot.close()
    assert panda_py.calls == [
        ("connect", "127.0.0.1"),
        ("teaching", True),
        ("teaching", False),
        ("move", 0.2),
        ("teaching", False),
        ("move", 0.2),
        ("teaching", False),
    ]


def test_perturbed_truth_is_seeded_and_millimetres_off():
    nominal = load_model("panda")
    a, b, c = perturbed_model(nominal, 5), perturbed_model(nominal, 5), perturbed_model(nominal, 6)
    np.testing.assert_array_equal(a.screws, b.screws)
    assert not np.array_equal(a.screws, c.screws)
    layout = load_layout(builtin_dir("layouts") / "thesis.yaml")
    q = aim(nominal, layout.points["P4"], 10, np.random.default_rng(0), **layout.aim_kwargs())
    err = np.linalg.norm(predict_spots(a, q, -8.0)[0][:, :2] - layout.points["P4"][:2], axis=1)
    assert 1 < err.mean() < 30  # like a real uncalibrated Panda (~10 mm)


def test_fake_robot_moves_like_a_position_controlled_arm():
    truth = load_model("panda_thesis_identified")
    robot = FakeRobot(truth, FakeClock())
    robot.connect()
    target = truth.home + 0.5
    robot.move_to(target)  # returns on arrival: the clock has run for the move
    assert robot.clock.now() >= 1.875 * 0.5 / robot.motion.speed
    s = robot.read()
    assert s.extra["robot_mode"] == "Move" and np.abs(s.q - target).max() < 0.05
    robot.clock.sleep(5.0)  # the release jiggle has died away
    assert np.abs(robot.read().q - target).max() < 1e-8
    robot.close()
    with pytest.raises(RobotConnectionError):
        robot.read()
