"""A printed sheet of reference points lying on the table: its pose in the robot's base frame.

The sheet's own frame has its points at [x, y, 0] mm. Laid flat on the table at height Z
(base frame), perpendicular to joint 1's axis (the robot stands on the table), the sheet's
in-plane pose is three numbers, (x, y, yaw):

    p_base = Rz(yaw) p_sheet + [x, y, Z]                                   (eq. S1)

A printer scales the page a little along each of its axes (a few 0.1 %, docs/sheet.md), and a table is
flat but not quite perpendicular to joint 1's axis (a robot bolted down tilted by a few mrad: the
thesis's Panda's joint 1 leans 4.8 mrad from its table's normal). The sheet's coordinates as printed are
then s = diag(1 + ex, 1 + ey) p_sheet, and its surface rises by tx, ty per mm along them:

    p_base = [Rz(yaw) s + [x, y],  Z + tx s_x + ty s_y]                   (eq. S3)

``solve`` identifies (x, y, yaw, ex, ey, tx, ty) with the robot when a layout says ``frame: sheet``: on
a camera session, where spots are measured to a few hundredths of a mm, an unmodelled 0.2 % print or a
4.8 mrad tilt leaves about 0.1 mm of misfit. With the sheet's pose unknown, the base frame is the robot's
own (eq. S2, :mod:`solver.kinematics.frames`).

The sheet's shape (issue 52), beside eq. S3: a printer that feeds the paper askew leans the print's y
axis along its x by g mm per mm (a rectangle printed as a parallelogram), and a taped sheet is not flat
(it curls, it domes). The printed coordinates of a layout point (u, v) are then

    s = (s_x, s_y) = ((1 + ex) u + g v,  (1 + ey) v)                       (eq. S5)

and the paper's surface rises over the tilt plane by a low-order height field in them,

    z = Z + tx s_x + ty s_y + h(s),  h = 1/2 (kxx s_x^2 + 2 kxy s_x s_y + kyy s_y^2)     (eq. S6)

(k in 1/mm: a curl along the sheet's y axis is a cylinder, kyy alone; a dome a paraboloid, kxx = kyy;
h(0) = 0 and dh(0) = 0, so the origin's height and the tilt stay eq. S3's). In the table's plane the
point is eq. S3's, Rz(yaw) s + [x, y]: bending the paper by a mm over 150 mm shortens its span by
(h / L)^2 L, micrometres, which the model leaves out. With g = k = 0, eqs. S5, S6 are eq. S3. ``solve``
fits (g, kxx, kxy, kyy) only when the data ask for them (:mod:`solver.identify.sheetshape`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

KEYS = ("x_mm", "y_mm", "yaw_deg")
SCALE_KEYS = ("scale_x", "scale_y")  # the printer's scale along the sheet's axes (1: exact), eq. S3
TILT_KEYS = ("tilt_x_rad", "tilt_y_rad")  # the surface's rise along the sheet's axes (0: level), eq. S3
# the print's shear g (mm per mm, eq. S5), the paper's height field's curvatures kxx, kxy, kyy (1/mm, eq. S6)
SHAPE_KEYS = ("shear", "curl_xx_per_mm", "curl_xy_per_mm", "curl_yy_per_mm")
NPOSE, NFULL = 7, 11  # a sheet's parameters: eq. S3's (pose, print scale, tilt); with eqs. S5, S6's shape


@dataclass(frozen=True)
class SheetPose:
    """The sheet frame's pose in the base frame (eqs. S1, S3).

    Attributes
    ----------
    x_mm, y_mm : float, the sheet origin's position in the base frame, mm
    yaw_deg : float, the sheet's x axis from the base x axis, about +z, deg
    scale_x, scale_y : float, the printer's scale along the sheet's x and y axes (1: exact)
    tilt_x_rad, tilt_y_rad : float, the sheet's rise per mm along its x and y axes, rad (0: level)
    shear : float, the print's shear g (eq. S5), mm per mm (0: square)
    curl_xx_per_mm, curl_xy_per_mm, curl_yy_per_mm : float, the height field's curvatures (eq. S6), 1/mm
        (0: flat)
    """

    x_mm: float = 0.0
    y_mm: float = 0.0
    yaw_deg: float = 0.0
    scale_x: float = 1.0
    scale_y: float = 1.0
    tilt_x_rad: float = 0.0
    tilt_y_rad: float = 0.0
    shear: float = 0.0
    curl_xx_per_mm: float = 0.0
    curl_xy_per_mm: float = 0.0
    curl_yy_per_mm: float = 0.0

    @property
    def shaped(self) -> bool:
        """True when the print is sheared or the paper not flat (eqs. S5, S6 beyond eq. S3)."""
        return any(getattr(self, k) != 0.0 for k in SHAPE_KEYS)

    @property
    def curl(self) -> np.ndarray:
        """(3,) array [kxx, kxy, kyy] 1/mm: the height field's curvatures (eq. S6)."""
        return np.array([self.curl_xx_per_mm, self.curl_xy_per_mm, self.curl_yy_per_mm])

    @property
    def full_vector(self) -> np.ndarray:
        """(11,) array: :attr:`vector` then [g, kxx 1/mm, kxy 1/mm, kyy 1/mm] (eqs. S5, S6)."""
        return np.r_[self.vector, [getattr(self, k) for k in SHAPE_KEYS]]

    @property
    def vector(self) -> np.ndarray:
        """(7,) array [x mm, y mm, yaw rad, ex, ey, tx rad, ty rad] (e = scale - 1): what a fit moves."""
        return np.array(
            [self.x_mm, self.y_mm, math.radians(self.yaw_deg), self.scale_x - 1, self.scale_y - 1]
            + [self.tilt_x_rad, self.tilt_y_rad]
        )

    @classmethod
    def from_vector(cls, v) -> SheetPose:
        """The pose of a parameter vector [x mm, y mm, yaw rad], [x, y, yaw, ex, ey, tx, ty] or that and
        [g, kxx, kxy, kyy] (eqs. S5, S6)."""
        x, y, yaw, ex, ey, tx, ty, g, kxx, kxy, kyy = (list(map(float, v)) + [0.0] * 8)[:NFULL]
        return cls(x, y, math.degrees(yaw), 1.0 + ex, 1.0 + ey, tx, ty, g, kxx, kxy, kyy)

    def as_dict(self) -> dict:
        """``{x_mm, y_mm, yaw_deg}``, with ``{scale_x, scale_y, tilt_x_rad, tilt_y_rad}`` when the print is
        not exact or the sheet not level, and {shear, curl_xx_per_mm, curl_xy_per_mm, curl_yy_per_mm} when
        the sheet has a shape (eqs. S5, S6): the model and layout files' ``sheet`` mapping."""
        exact = (self.scale_x, self.scale_y, self.tilt_x_rad, self.tilt_y_rad) == (1.0, 1.0, 0.0, 0.0)
        keys = KEYS + (() if exact and not self.shaped else SCALE_KEYS + TILT_KEYS)
        keys += SHAPE_KEYS if self.shaped else ()
        return {k: float(round(getattr(self, k), 9 if k in KEYS else 12)) for k in keys}

    def to_base(self, p_sheet: np.ndarray, z: float) -> np.ndarray:
        """Sheet points (k, 2) or (k, 3) (their z ignored) to the base frame (k, 3), mm, on a sheet whose
        origin lies at height z (eqs. S1, S3; S5, S6 when the sheet has a shape)."""
        v = self.full_vector if self.shaped else self.vector
        return sheet_to_base(v, np.asarray(p_sheet, dtype=float), z)[0]

    def from_base(self, p_base: np.ndarray) -> np.ndarray:
        """Base-frame points (k, 2) or (k, 3) to sheet coordinates (k, 2), mm (eqs. S1, S3 inverted in the
        table's plane, eq. S5's shear with them: a point's height is the sheet's there)."""
        p = np.atleast_2d(np.asarray(p_base, dtype=float))[:, :2] - [self.x_mm, self.y_mm]
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        printed = p @ np.array([[c, -s], [s, c]])  # s of eq. S5
        v = printed[:, 1] / self.scale_y
        return np.column_stack([(printed[:, 0] - self.shear * v) / self.scale_x, v])

    def height(self, p_sheet: np.ndarray) -> np.ndarray:
        """Eq. S6's height field h (k,) mm over the tilt plane at layout points (k, 2) mm."""
        v = self.full_vector
        s = sheet_print(v, np.atleast_2d(np.asarray(p_sheet, dtype=float))[:, :2])
        return 0.5 * (v[8] * s[:, 0] ** 2 + 2 * v[9] * s[:, 0] * s[:, 1] + v[10] * s[:, 1] ** 2)


def sheet_print(v: np.ndarray, raw: np.ndarray) -> np.ndarray:
    """Eq. S5: layout points (k, 2) mm as printed (k, 2) mm, under v's scale (and shear, an 11-vector)."""
    e = np.asarray(v[3:5], dtype=float) if len(v) > 3 else np.zeros(2)
    p = raw * (1.0 + e)
    if len(v) > NPOSE:
        p[:, 0] += v[7] * raw[:, 1]
    return p


def sheet_to_base(v: np.ndarray, p_sheet: np.ndarray, z) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. S1, S3 (S5, S6) and the Jacobian with respect to v = [x mm, y mm, yaw rad, ex, ey, tx rad, ty rad
    (, g, kxx 1/mm, kxy 1/mm, kyy 1/mm)]. Vectorised over the points (captures).

    Parameters
    ----------
    v : (7,) array (or (3,): an exact print on a level sheet; (11,): with the print's shear and the paper's
        height field, eqs. S5, S6)
    p_sheet : (k, 2) or (k, 3) array, sheet coordinates, mm (a third column is ignored)
    z : float or (k,) array, the sheet's height in the base frame at its origin, mm

    Returns
    -------
    p : (k, 3) array, base frame, mm
    J : (k, 3, len(v)) array, dp/dv
    """
    raw = np.atleast_2d(p_sheet)[:, :2]
    tilt = np.asarray(v[5:7], dtype=float) if len(v) > 3 else np.zeros(2)
    p = sheet_print(v, raw)  # as printed (eq. S5)
    c, s = math.cos(v[2]), math.sin(v[2])
    R = np.array([[c, -s], [s, c]])
    out = np.empty((len(p), 3))
    out[:, :2] = p @ R.T + v[:2]
    out[:, 2] = z + p @ tilt
    slope = np.broadcast_to(tilt, p.shape).copy()  # dz/ds (eq. S6: tilt + K s)
    if len(v) > NPOSE:
        kxx, kxy, kyy = v[8:11]
        out[:, 2] += 0.5 * (kxx * p[:, 0] ** 2 + 2 * kxy * p[:, 0] * p[:, 1] + kyy * p[:, 1] ** 2)
        slope += p @ np.array([[kxx, kxy], [kxy, kyy]])
    J = np.zeros((len(p), 3, len(v)))
    J[:, 0, 0] = J[:, 1, 1] = 1.0
    J[:, :2, 2] = p @ np.array([[-s, -c], [c, -s]]).T  # dR/dyaw p
    if len(v) > 3:
        J[:, :2, 3] = raw[:, :1] * R[:, 0]  # d/d e_i: R's column i times the layout's coordinate
        J[:, :2, 4] = raw[:, 1:2] * R[:, 1]
        J[:, 2, 3], J[:, 2, 4] = raw[:, 0] * slope[:, 0], raw[:, 1] * slope[:, 1]
        J[:, 2, 5], J[:, 2, 6] = p[:, 0], p[:, 1]  # d/d t_i: the printed coordinate
    if len(v) > NPOSE:
        J[:, :2, 7] = raw[:, 1:2] * R[:, 0]  # d/d g: s_x grows by v
        J[:, 2, 7] = raw[:, 1] * slope[:, 0]
        J[:, 2, 8], J[:, 2, 9], J[:, 2, 10] = 0.5 * p[:, 0] ** 2, p[:, 0] * p[:, 1], 0.5 * p[:, 1] ** 2
    return out, J


def sheet_residual(v: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. S4: an in-plane residual measured in the base frame, in the printed sheet's own units.

        r_s = diag(1 + e)^-1 Rz(yaw)^T r

    where r = spot - point (base frame, on the sheet's surface): r_s is where the spot lies on the paper
    minus where the point is printed, in the units a camera or an operator measures on the paper. Unlike
    |r|, |r_s| does not shrink when robot and sheet shrink together about the base origin: a fit in base
    frame mm is paid for a common scale of robot and sheet (about -m sigma_e^2 for m captures), one in
    sheet units is not (the scale is then fixed by the robot's lengths, as it physically is).

    Parameters
    ----------
    v : (3,), (7,) or (11,) array, the sheet's parameters [x mm, y mm, yaw rad(, ex, ey, tx rad, ty rad(, g,
        kxx, kxy, kyy))]: the shear g would add g r_y to r_s's x, under 1e-5 mm for the residuals a fit
        meets (g ~ 1e-3, |r| ~ 0.01 mm), which eq. S4 leaves out
    r : (k, 2) array, base-frame in-plane residuals, mm

    Returns
    -------
    r_s : (k, 2) array, sheet units (printed mm)
    M : (2, 2) array, the map diag(1 + e)^-1 Rz(yaw)^T
    dM : (k, 2, len(v)) array, d(M)/dv r at fixed r (non-zero in the yaw and scale columns only)
    """
    r = np.atleast_2d(np.asarray(r, dtype=float))[:, :2]
    e = np.asarray(v[3:5], dtype=float) if len(v) > 3 else np.zeros(2)
    c, s = math.cos(v[2]), math.sin(v[2])
    Rt = np.array([[c, s], [-s, c]])
    inv = 1.0 / (1.0 + e)
    M = inv[:, None] * Rt
    rot = r @ Rt.T  # Rz(yaw)^T r
    dM = np.zeros((len(r), 2, len(v)))
    dM[:, :, 2] = inv * (r @ np.array([[-s, c], [-c, -s]]).T)  # d Rz(yaw)^T / d yaw r
    if len(v) > 3:
        dM[:, 0, 3] = -rot[:, 0] * inv[0] ** 2
        dM[:, 1, 4] = -rot[:, 1] * inv[1] ** 2
    return rot * inv, M, dM
