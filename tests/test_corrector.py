"""lasercal.Corrector: one goal at a time, warm-started from the previous command, it gives ``correct``'s
command (the same goal, the same seed) along a continuous path -- with a TCP and the model's effects -- and
hands what it cannot do to ``correct``'s solver, saying so. Its latency is benchmarks/bench_corrector.py's."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import lasercal
from lasercal.solver.control.corrector import Corrector
from lasercal.solver.control.robot import Robot, load_model
from lasercal.solver.errors import FormatError, ModelError
from lasercal.solver.formats.robots import load_model as load_robot_model

TCP = (0.0, 0.0, 103.4)


@pytest.fixture(scope="module")
def robot():
    model = load_robot_model("panda_thesis_identified").replace(
        extensions={
            "joint_compliance": {"joints": [2], "c": [1.2e-4]},
            "encoder_eccentricity": {"joints": [4], "a": [2e-4], "b": [-1e-4]},
        }
    )
    return Robot(model, load_robot_model("panda"))


def path(robot, m: int, tool=TCP) -> np.ndarray:
    """m full-pose goals (m, 4, 4) 1 ms apart from the ready pose: a circle, a wave, the tool rocking."""
    start = robot.fk(robot.model.home, tool=tool)[0]
    t, w = np.arange(m) * 1e-3, 2 * np.pi / 0.5  # a fast path: 1.3 m/s, so that two steps are needed
    goals = np.tile(start, (m, 1, 1))
    goals[:, :3, 3] += np.stack([100 * (np.cos(w * t) - 1), 100 * np.sin(w * t), 50 * np.sin(2 * w * t)], 1)
    rock = Rotation.from_rotvec(np.stack([0.2 * np.sin(w * t), 0.2 * np.sin(1.3 * w * t), 0 * t], 1))
    goals[:, :3, :3] = rock.as_matrix() @ start[:3, :3]
    return goals


def run(corrector, goals) -> tuple[np.ndarray, list]:
    out, steps = [], []
    for g in goals:
        out.append(corrector(g))
        steps.append((corrector.last.steps, corrector.last.fallback))
    return np.array(out), steps


def test_along_a_path_the_commands_are_corrects(robot):
    goals = path(robot, 300)
    c = lasercal.Corrector(robot, tool=TCP, q0=robot.model.home)
    q, steps = run(c, goals)
    # started where the last tick's motion carries the joints, one step reaches the goal at 1.3 m/s and a
    # second confirms it (from the last command itself, as the second goal starts from rest: three)
    assert not any(fb for _, fb in steps) and max(s for s, _ in steps[2:]) == 2
    ref = robot.correct(goals, seed=np.vstack([robot.model.home, q[:-1]]), tool=TCP)
    assert ref.ok.all()
    assert np.abs(q - ref.q).max() < 1e-8  # rad: the same solution, nearest the previous command
    T = robot.fk(q, tool=TCP)  # lasercal's own kinematics, with the effects
    assert np.linalg.norm(T[:, :3, 3] - goals[:, :3, 3], axis=1).max() < 1e-6  # mm
    assert np.abs(T[:, :3, :3] - goals[:, :3, :3]).max() < 1e-8


def test_a_joint_on_its_limit_is_held_there_as_correct_holds_it(robot):
    """Six laps of the fast path carry joint 2 onto its limit margin (from goal ~2880 on): the corrector holds
    it there and moves the others, as correct's active set does -- no goal goes to the full solver."""
    goals = path(robot, 3000)
    c = Corrector(robot, tool=TCP, q0=robot.model.home)
    q, steps = run(c, goals)
    lo = robot.model.limits[:, 0] + robot.options.margin
    on_limit = q[:, 1] - lo[1] < 1e-4  # its true angle on the margin, the command off it by the compliance's
    assert on_limit.sum() > 50  # the case is exercised: joint 2 sits on its margin for tens of goals
    assert not any(fb for _, fb in steps)
    ref = robot.correct(goals, seed=np.vstack([robot.model.home, q[:-1]]), tool=TCP)
    assert ref.ok.all() and np.abs(q - ref.q).max() < 1e-6  # rad


def test_positions_and_rotation_vectors_are_the_same_goals(robot):
    goals = path(robot, 40)
    poses = np.hstack([goals[:, :3, 3], Rotation.from_matrix(goals[:, :3, :3]).as_rotvec()])
    a = run(Corrector(robot, tool=TCP, q0=robot.model.home), goals)[0]
    b = run(Corrector(robot, tool=TCP, q0=robot.model.home), poses)[0]
    assert np.abs(a - b).max() < 1e-9
    p = run(Corrector(robot, tool=TCP, q0=robot.model.home), goals[:, :3, 3])[0]  # positions: the nearest
    ref = robot.correct(goals[:, :3, 3], seed=np.vstack([robot.model.home, p[:-1]]), tool=TCP)
    assert np.abs(p - ref.q).max() < 1e-8


def test_the_nominal_pose_is_the_nominal_models_view_of_the_command(robot):
    c = Corrector(robot, tool=TCP, q0=robot.model.home)
    q = c(path(robot, 2)[1])
    assert np.abs(c.nominal_pose() - robot.fk(q, tool=TCP, nominal=True)[0]).max() < 1e-9


def test_a_goal_it_cannot_take_goes_to_the_full_solver_and_says_so(robot):
    c = Corrector(robot, q0=robot.model.home)
    far = robot.fk(robot.model.home)[0]
    far[:3, 3] = [3000.0, 0.0, 0.0]  # out of reach
    q = c(far)
    assert c.last.fallback and not c.last.ok and "unreachable" in c.last.reason
    assert q.shape == (7,) and robot.model.within_limits(q[None])[0]
    jump = robot.fk(np.array([0.5, 0.3, -0.2, -1.5, 0.1, 2.0, 0.3]))[0]  # 1 rad away from home: a restart
    c.reset(robot.model.home)
    q = c(jump)
    assert c.last.ok and np.linalg.norm(robot.fk(q)[0][:3, 3] - jump[:3, 3]) < 1e-6


def test_bad_goals_and_warm_starts_are_refused(robot):
    c = Corrector(robot)
    with pytest.raises(FormatError, match="goal"):
        c(np.zeros(5))
    with pytest.raises(FormatError, match="q0"):
        Corrector(robot, q0=[0.0] * 6)
    with pytest.raises(ModelError, match="serial chain"):
        Corrector(load_model("justin"))


def test_a_model_file_or_name_is_loaded():
    c = Corrector("panda")
    goal = c.robot.fk(c.robot.model.home)[0]
    assert np.abs(c(goal) - c.robot.model.home).max() < 1e-9
