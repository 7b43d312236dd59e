"""Inverse kinematics and the pieces of a corrected command, against analytic truth: goals made by forward
kinematics of known configurations, Franka's published DH table, the fixed point of a joint effect."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lasercal.solver.analysis.simulate import random_configs
from lasercal.solver.control.correct import command_angles, true_angles
from lasercal.solver.control.robot import Robot, load_model
from lasercal.solver.formats.robots import load_model as load_robot_model
from lasercal.solver.formats.urdf import load_urdf
from lasercal.solver.kinematics.effects import Combination, Extension
from lasercal.solver.kinematics.ik import IKOptions, solve_ik, tool_frames
from lasercal.solver.kinematics.poe import fk, poe_chain, space_jacobian
from tests.conftest import franka_flange

DATA = Path(__file__).parent / "data"


def test_tool_frames_are_the_poe_chain():
    """The IK's specialised forward kinematics equals the general POE chain (exp6), revolute and prismatic."""
    rng = np.random.default_rng(0)
    M = np.eye(4)
    M[:3, 3] = [10.0, 20.0, 900.0]
    for model in (load_robot_model("panda_thesis_identified"), load_urdf(DATA / "rail_ur5.urdf")):
        q = random_configs(model, 40, rng)
        T, J = tool_frames(model.screws, M, q)
        chain = poe_chain(model.screws, q)
        assert np.abs(T - fk(model.screws, M, q)).max() < 1e-9
        assert np.abs(J - space_jacobian(model.screws, chain)).max() < 1e-9


def test_the_panda_flange_is_frankas():
    """lasercal's nominal Panda flange at any q is the flange of Franka's DH table (z down at q = 0)."""
    robot = load_model("panda")
    q = random_configs(robot.model, 30, np.random.default_rng(1))
    assert np.abs(robot.fk(q) - franka_flange(q)).max() < 1e-9
    assert np.allclose(
        robot.flange, [[1, 0, 0, 88], [0, -1, 0, 0], [0, 0, -1, 926], [0, 0, 0, 1]], atol=1e-12
    )


@pytest.mark.parametrize("oriented", [False, True])
def test_goals_made_from_known_configurations_are_reached_inside_the_limits(oriented):
    """Goals = the flange at random in-limit configurations (away from the stretched arm, q4 < -0.8): each is
    reached to 1e-7 mm (1e-9 rad) from the ready pose, every joint inside its limits less the margin."""
    robot = load_model("panda_thesis_identified")
    q = random_configs(robot.model, 300, np.random.default_rng(2), margin=0.1)
    q[:, 3] = np.minimum(q[:, 3], -0.8)
    T = robot.fk(q)
    seed = np.broadcast_to(robot.model.home, q.shape)
    o = IKOptions()
    sol = solve_ik(
        robot.model.screws,
        robot.flange,
        robot.model.limits,
        seed,
        T[:, :3, 3],
        T[:, :3, :3] if oriented else None,
        o,
        pull=False,
    )
    assert sol.reached.all() and sol.error_mm.max() < 1e-7 and sol.error_rad.max() < 1e-9
    assert robot.model.within_limits(sol.q, margin=o.margin - 1e-12).all()
    got = robot.fk(sol.q)
    assert np.abs(got[:, :3, 3] - T[:, :3, 3]).max() < 1e-7
    if oriented:
        assert np.abs(got[:, :3, :3] - T[:, :3, :3]).max() < 1e-9


@pytest.mark.parametrize("oriented", [False, True])
def test_a_redundant_arm_goes_to_the_solution_nearest_the_seed(oriented):
    """7 joints, a 3- or 6-task: the known configuration q0 is one solution, so the one nearest a seed near it
    is no farther from the seed, and it is stationary: the seed's pull has nothing left in the null space."""
    robot = load_model("panda_thesis_identified")
    rng = np.random.default_rng(3)
    q0 = random_configs(robot.model, 200, rng, margin=0.3)
    q0[:, 3] = np.minimum(q0[:, 3], -0.8)
    seed = q0 + rng.normal(0, 0.05, q0.shape)
    T = robot.fk(q0)
    goal = np.hstack([T[:, :3, 3], rotation_vectors(T)]) if oriented else T[:, :3, 3]
    sol = robot.ik(goal, seed=seed)
    assert sol.ok.all()
    d, d0 = np.linalg.norm(sol.q - seed, axis=1), np.linalg.norm(q0 - seed, axis=1)
    assert (
        np.all(d <= d0 + 1e-9) and np.mean(d < d0 - 1e-6) > 0.8
    )  # nearer than q0, but for seeds off its row space
    _, J = tool_frames(robot.model.screws, robot.flange, sol.q)
    p = robot.fk(sol.q)[:, :3, 3]
    Jt = np.concatenate(
        [np.cross(J[:, :3], p[:, :, None], axis=1) + J[:, 3:]] + ([J[:, :3]] if oriented else []), axis=1
    )
    null = np.eye(7) - np.linalg.pinv(Jt) @ Jt
    assert np.abs(np.einsum("mij,mj->mi", null, seed - sol.q)).max() < 1e-6


def rotation_vectors(T: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(T[:, :3, :3]).as_rotvec()


def test_an_unreachable_goal_is_flagged_with_its_reason():
    robot = load_model("panda")
    c = robot.ik([[3000.0, 0.0, 0.0], [400.0, 0.0, 500.0]])
    assert not c.ok[0] and c.ok[1]
    assert c.reason[0].startswith("unreachable: the best of 9 starts misses by") and c.residual_mm[0] > 1500
    assert c.reason[1] == "" and c.residual_mm[1] < 1e-6


def test_a_goal_beyond_the_limit_margin_is_refused_not_clipped_silently():
    """A 3-joint arm (the Puma's first three joints, limits +-1 rad): a goal made at q2 = 0.98 rad lies inside
    the limits but outside a 0.05 rad margin, and the other branch needs q2 < -1: refused with joint 2 held
    at the margin; without the margin it is reached."""
    puma = load_robot_model("puma560")
    screws, limits = puma.screws[:3], np.tile([-1.0, 1.0], (3, 1))
    M = np.eye(4)
    M[:3, 3] = puma.aperture
    goal = fk(screws, M, np.array([[0.3, 0.98, 0.5]]))[:, :3, 3]
    sol = solve_ik(screws, M, limits, np.zeros((1, 3)), goal, None, IKOptions(margin=0.05), pull=False)
    assert not sol.reached[0] and sol.error_mm[0] > 0.5
    assert sol.at_bound[0].tolist() == [False, True, False] and sol.q[0, 1] == pytest.approx(0.95)
    free = solve_ik(screws, M, limits, np.zeros((1, 3)), goal, None, IKOptions(margin=0.0), pull=False)
    assert free.reached[0] and np.abs(free.q[0] - [0.3, 0.98, 0.5]).max() < 1e-6


def test_a_joint_effect_is_inverted_by_its_fixed_point():
    """q_cmd = q_true - dq(q_cmd, tau(q_cmd)): the model's effect at the command gives back q_true."""
    model = load_robot_model("panda")
    ext = Combination(
        (
            Extension("joint_compliance", (2, 4), None, np.array([-1.5e-4, -1e-4])),
            Extension("encoder_eccentricity", (1, 6), None, np.array([2e-3, -1e-3, 5e-4, 1.5e-3])),
        )
    )
    q_true = random_configs(model, 50, np.random.default_rng(4))
    q_cmd = command_angles(model, ext, q_true)
    assert np.abs(true_angles(model, ext, q_cmd) - q_true).max() < 1e-12
    assert np.abs(q_cmd - q_true).max() > 1e-3


def test_ik_with_an_effect_reaches_the_goal_at_the_true_angles():
    """A model with a compliance: the commands, bent by the compliance under gravity, put the flange at the
    goal; the same commands on a rigid arm miss by the sag."""
    base = load_robot_model("panda")
    model = base.replace(extensions={"joint_compliance": {"joints": [2], "c": [-2e-4]}})
    robot = Robot(model, base)
    q0 = random_configs(base, 100, np.random.default_rng(5), margin=0.3)
    q0[:, 3] = np.minimum(q0[:, 3], -0.8)
    goal = Robot(base, base).fk(q0)[:, :3, 3]
    c = robot.ik(goal, seed=q0)
    assert c.ok.all() and c.residual_mm.max() < 1e-6
    assert np.abs(robot.fk(c.q)[:, :3, 3] - goal).max() < 1e-6
    assert np.median(np.linalg.norm(Robot(base, base).fk(c.q)[:, :3, 3] - goal, axis=1)) > 1.0
    # a configuration planned on the rigid calibrated geometry (MoveIt with the URDF), as commands
    assert np.abs(robot.fk(robot.command(q0)) - Robot(base, base).fk(q0)).max() < 1e-9
