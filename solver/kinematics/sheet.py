"""A printed sheet of reference points lying on the table: its pose in the robot's base frame.

The sheet's own frame has its points at [x, y, 0] mm. Laid flat on the table at height Z
(base frame), perpendicular to joint 1's axis (the robot stands on the table), the sheet's
in-plane pose is three numbers, (x, y, yaw):

    p_base = Rz(yaw) p_sheet + [x, y, Z]                                   (eq. S1)

``solve`` identifies (x, y, yaw) with the robot when a layout says ``frame: sheet``.

With the sheet's pose unknown, the base frame is the robot's own (eq. S2): joint 1's axis is the
nominal's (direction and position), the rotation about it puts joint 2's axis at q = 0 in the
nominal's direction, the height is the plane's. :func:`own_frame` expresses any robot model in it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from lasercal.solver.kinematics.poe import adjoint, inv_T

if TYPE_CHECKING:  # annotations only: the model module imports this one
    from lasercal.solver.kinematics.model import RobotModel

KEYS = ("x_mm", "y_mm", "yaw_deg")


@dataclass(frozen=True)
class SheetPose:
    """The sheet frame's pose in the base frame (eq. S1).

    Attributes
    ----------
    x_mm, y_mm : float, the sheet origin's position in the base frame, mm
    yaw_deg : float, the sheet's x axis from the base x axis, about +z, deg
    """

    x_mm: float = 0.0
    y_mm: float = 0.0
    yaw_deg: float = 0.0

    @property
    def vector(self) -> np.ndarray:
        """(3,) array [x mm, y mm, yaw rad]: the parameters an identification moves."""
        return np.array([self.x_mm, self.y_mm, math.radians(self.yaw_deg)])

    @classmethod
    def from_vector(cls, v) -> SheetPose:
        """The pose of a parameter vector [x mm, y mm, yaw rad]."""
        return cls(float(v[0]), float(v[1]), math.degrees(float(v[2])))

    def as_dict(self) -> dict:
        """``{x_mm, y_mm, yaw_deg}``, the model and layout files' ``sheet`` mapping."""
        return {k: float(round(getattr(self, k), 9)) for k in KEYS}

    def to_base(self, p_sheet: np.ndarray, z: float) -> np.ndarray:
        """Sheet points (k, 2) or (k, 3) (z ignored) to the base frame (k, 3), mm (eq. S1)."""
        return sheet_to_base(self.vector, np.asarray(p_sheet, dtype=float), z)[0]

    def from_base(self, p_base: np.ndarray) -> np.ndarray:
        """Base-frame points (k, 2) or (k, 3) to sheet coordinates (k, 2), mm (eq. S1 inverted)."""
        p = np.atleast_2d(np.asarray(p_base, dtype=float))[:, :2] - [self.x_mm, self.y_mm]
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        return p @ np.array([[c, -s], [s, c]])


def sheet_to_base(v: np.ndarray, p_sheet: np.ndarray, z) -> tuple[np.ndarray, np.ndarray]:
    """Eq. S1 and its Jacobian with respect to v = [x mm, y mm, yaw rad].

    Parameters
    ----------
    v : (3,) array
    p_sheet : (k, 2) or (k, 3) array, sheet coordinates, mm (a third column is ignored)
    z : float or (k,) array, the sheet's height in the base frame, mm

    Returns
    -------
    p : (k, 3) array, base frame, mm
    J : (k, 3, 3) array, dp/dv (the z row is zero)
    """
    p = np.atleast_2d(p_sheet)[:, :2]
    c, s = math.cos(v[2]), math.sin(v[2])
    R = np.array([[c, -s], [s, c]])
    out = np.empty((len(p), 3))
    out[:, :2] = p @ R.T + v[:2]
    out[:, 2] = z
    J = np.zeros((len(p), 3, 3))
    J[:, 0, 0] = J[:, 1, 1] = 1.0
    J[:, :2, 2] = p @ np.array([[-s, -c], [c, -s]]).T  # dR/dyaw p
    return out, J


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

