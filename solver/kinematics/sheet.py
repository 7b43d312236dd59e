"""A printed sheet of reference points lying on the table: its pose in the robot's base frame.

The sheet's own frame has its points at [x, y, 0] mm. Laid flat on the table at height Z
(base frame), perpendicular to joint 1's axis (the robot stands on the table), the sheet's
in-plane pose is three numbers, (x, y, yaw):

    p_base = Rz(yaw) p_sheet + [x, y, Z]                                   (eq. S1)

``solve`` identifies (x, y, yaw) with the robot when a layout says ``frame: sheet``. With the sheet's
pose unknown, the base frame is the robot's own (eq. S2, :mod:`solver.kinematics.frames`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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
