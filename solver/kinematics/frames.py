"""A robot model's base frame, moved: by a rigid motion, and into the robot's own frame (eq. S2).

With a printed sheet's pose unknown (:mod:`solver.kinematics.sheet`), the base frame is the robot's own:
joint 1's axis is the nominal's (direction and position), the rotation about it puts joint 2's axis at
q = 0 in the nominal's direction, the height is the plane's. :func:`own_frame` expresses any robot model
in it, :func:`moved` moves a model's base frame.
"""

from __future__ import annotations

import math

import numpy as np

from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import adjoint, inv_T


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation (3, 3) about a unit axis by angle (rad)."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def own_frame(model: RobotModel, nominal: RobotModel) -> np.ndarray:
    """The rigid motion G (4, 4) taking ``model``'s base frame to its own (eq. S2).

    G rotates joint 1's axis onto the nominal's direction (the smallest rotation), moves it across onto the
    nominal's line (not along it: the height stays), then turns about that line until joint 2's axis at
    q = 0, seen along joint 1, points as the nominal's. Apply it with :func:`moved`.

    Parameters
    ----------
    model, nominal : RobotModel, two models of one arm (revolute joints 1 and 2)

    Returns
    -------
    (4, 4) array, mm
    """
    w1, wn = model.screws[0, :3], nominal.screws[0, :3]
    axis = np.cross(w1, wn)
    s = np.linalg.norm(axis)
    R = _rotation(axis / s, math.atan2(s, float(w1 @ wn))) if s > 1e-15 else np.eye(3)
    c, cn = R @ np.cross(w1, model.screws[0, 3:]), np.cross(wn, nominal.screws[0, 3:])  # points on the axes
    G = np.eye(4)
    G[:3, :3], G[:3, 3] = R, (cn - c) - ((cn - c) @ wn) * wn
    w2 = G[:3, :3] @ model.screws[1, :3]
    a, b = w2 - (w2 @ wn) * wn, nominal.screws[1, :3] - (nominal.screws[1, :3] @ wn) * nominal.screws[0, :3]
    phi = math.atan2(float(wn @ np.cross(a, b)), float(a @ b))
    T = np.eye(4)
    T[:3, :3] = _rotation(wn, phi)
    T[:3, 3] = cn - T[:3, :3] @ cn  # about joint 1's (nominal) line
    return T @ G


def moved(model: RobotModel, G: np.ndarray) -> RobotModel:
    """The model with its base frame moved by G (4, 4): screws Ad_G S, points and frames G p, a sensor's
    view X G^-1 (every prediction unchanged in the moved frame)."""
    R, t = G[:3, :3], G[:3, 3]
    changes = {
        "screws": (adjoint(G) @ model.screws.T).T,
        "laser_dir": R @ model.laser_dir,
        "aperture": R @ model.aperture + t,
        "targets": {k: R @ v + t for k, v in model.targets.items()},
    }
    if model.tool_point is not None:
        changes["tool_point"] = R @ model.tool_point + t
    if model.ee_pose is not None:
        changes["ee_pose"] = G @ model.ee_pose
    if model.sensor_pose is not None:
        changes["sensor_pose"] = model.sensor_pose @ inv_T(G)
    return model.replace(**changes)
