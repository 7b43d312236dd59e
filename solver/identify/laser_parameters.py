"""What a laser fit moves, and the one count of it that every command prints.

A laser fit's parameters (``solve``, the report, ``plan`` and the capture coach all count these, through
:func:`counted_parameters` and :func:`counted_rank`):

* the robot's: per joint its axis direction (wx, wy) and position across it (qx, qy), eq. M1 of
  :mod:`solver.kinematics.minimal`; the beam's direction (laser.vx, vy) and where it starts (M.x, y, z);
* on a sheet session (``frame: sheet``), the sheet's pose on the table (sheet.x, sheet.y, sheet.yaw, eq. S1),
  the printer's scale along its axes (sheet.ex, sheet.ey) and its tilt from joint 1's normal plane
  (sheet.tx, sheet.ty, eq. S3), less the parameters held to fix the robot's own base frame
  (:func:`sheet_gauge`): spots on a sheet cannot tell a motion of the base in the table's plane from the
  sheet's;
* an extension's (``--extend``), when one is fitted.

Of these, spots never see where the beam starts along itself (one combination of M.x, y, z: the height
``aperture_z`` fixes it), and on a sheet they never see a common scale of the robot and the print (a
world grown about the base origin, the robot raised with the sheet's height: where the spot lies on the
paper, in the paper's units, is unchanged, eq. S4), so rank = parameters - 1 (a sheet's: - 2) is a fully
identified fit (:func:`unseen_by_spots`); the robot's tolerances (the prior) fix what spots cannot. The
rank is the SVD rank of the captures' Jacobian over the counted parameters, without the prior
(:func:`solver.identify.lsq.identifiability`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.identify.lsq import identifiability
from lasercal.solver.kinematics.laser import LaserParams
from lasercal.solver.kinematics.minimal import screw_from_eta
from lasercal.solver.kinematics.poe import ad

# mm, mm, rad, 1, 1, rad, rad: eq. S1's pose and eq. S3's print scale (e = scale - 1) and tilt, identified
# with the robot
SHEET_NAMES = ["sheet.x", "sheet.y", "sheet.yaw", "sheet.ex", "sheet.ey", "sheet.tx", "sheet.ty"]
SHEET_KINDS = [
    "sheet_pos",
    "sheet_pos",
    "sheet_yaw",
    "sheet_scale",
    "sheet_scale",
    "sheet_tilt",
    "sheet_tilt",
]
NSHEET = len(SHEET_NAMES)
# 1, 1/mm x 3: the print's shear and the paper's height field (eqs. S5, S6), fitted only when tested
# (solver.identify.sheetshape); their priors are wide on purpose (the print scale's for the shear, the table
# tilt's per mm for the curvatures: a 10 m radius is no constraint), so the data decide them
SHAPE_NAMES = ["sheet.g", "sheet.kxx", "sheet.kxy", "sheet.kyy"]
SHAPE_KINDS = ["sheet_shear", "sheet_curl", "sheet_curl", "sheet_curl"]
# 1/mm x 6: a camera's view of a paper that is not flat (eq. S7 of solver.identify.spot), with the shape on a
# session the camera measured
WARP_NAMES = ["camera.axx", "camera.axy", "camera.ayy", "camera.bxx", "camera.bxy", "camera.byy"]
WARP_KINDS = ["sheet_curl"] * 6
NWARP = len(WARP_NAMES)


def unseen_by_spots(sheet: bool) -> int:
    """Combinations of the counted parameters that no spot data can see (module docstring): the beam's start
    along itself, and on a sheet (``sheet``) the common scale of robot and print."""
    return 2 if sheet else 1


def sheet_gauge(P: LaserParams) -> list[int]:
    """Parameters held to fix the robot's own base frame when the points lie on a sheet of unknown pose.

    Spots on a sheet cannot tell a rigid motion of the base in the table's plane (x, y, and a rotation
    about the plane's normal) from the sheet's own: the base frame is then the robot's (docs/formats.md,
    "The robot's own base frame"). Held at nominal: joint 1's four parameters (its axis, direction and
    position, is the nominal's: the table is normal to it) and the direction component of joint 2 that a
    rotation about joint 1 moves most (joint 2's axis at q = 0 keeps the nominal's direction: a Panda's
    has no x component). The height is the plane's (the session's ``plane.z``).

    Returns
    -------
    list of indices into P's parameters
    """
    S1, S2 = P.model.screws[0], P.model.screws[1]
    _, dS2 = screw_from_eta(P.frames[1], np.zeros(4))
    d_eta = np.linalg.lstsq(dS2, ad(S1) @ S2, rcond=None)[0]  # joint 2's eta under a rotation about joint 1
    return [0, 1, 2, 3, 4 + int(np.argmax(np.abs(d_eta[:2])))]


@dataclass(frozen=True)
class CountedParameters:
    """The parameters a laser fit moves (module docstring).

    Attributes
    ----------
    names : tuple of str, every parameter: the robot's, then the sheet's pose (a sheet session), then the
        extension's
    free : (k,) int array, indices into ``names`` of the parameters the fit moves (the count)
    robot : int, how many of ``names`` are the robot's
    sheet : bool, a sheet session (its pose among the parameters, the gauge held)
    shape : bool, the sheet's shape too (eqs. S5, S6: shear and height field)
    warp : bool, with it the camera's view of the raised paper (eq. S7)
    """

    names: tuple
    free: np.ndarray
    robot: int
    sheet: bool
    shape: bool = False
    warp: bool = False

    @property
    def held(self) -> list[str]:
        """The parameters held at nominal to fix the base frame (none off a sheet)."""
        return [nm for i, nm in enumerate(self.names) if i not in set(self.free.tolist())]

    @property
    def count(self) -> int:
        return len(self.free)

    def describe(self) -> str:
        """What the count is, e.g. '31 = 7 joints x 4 (axis direction, position) + beam direction 2 + beam
        start 3 + sheet pose 3 - 5 held for the base frame (joint1.wx, ...)'."""
        joints = (self.robot - 5) // 4
        parts = [f"{joints} joints x 4 (axis direction, position)", "beam direction 2", "beam start 3"]
        if self.sheet:
            parts.append("sheet pose 3, print scale 2 and tilt 2")
        if self.shape:
            parts.append("sheet shear 1 and curl 3")
        if self.warp:
            parts.append("the camera's view of the raised paper 6")
        extra = len(self.names) - self.robot - NSHEET * self.sheet - len(SHAPE_NAMES) * self.shape
        extra -= NWARP * self.warp
        if extra:
            parts.append(f"extension {extra}")
        text = f"{self.count} = " + " + ".join(parts)
        if self.held:
            text += f" - {len(self.held)} held for the robot's own base frame ({', '.join(self.held)})"
        return text


def counted_parameters(
    P: LaserParams, sheet: bool, extension_names=(), shape: bool = False, warp: bool = False
) -> CountedParameters:
    """The parameters a laser fit of this robot moves (module docstring): the one definition of the count.

    Parameters
    ----------
    P : LaserParams
    sheet : bool, the session's points lie on a sheet of unknown pose (``frame: sheet``)
    extension_names : parameter names of a fitted extension, if any
    shape : bool, the sheet's shear and height field too (eqs. S5, S6; a sheet session)
    warp : bool, with the shape, the camera's view of the raised paper (eq. S7; a camera session)
    """
    shape = shape and sheet
    warp = warp and shape
    sheet_names = SHEET_NAMES + (SHAPE_NAMES if shape else []) + (WARP_NAMES if warp else []) if sheet else []
    names = tuple(P.names) + tuple(sheet_names) + tuple(extension_names)
    held = sheet_gauge(P) if sheet else []
    return CountedParameters(names, np.setdiff1d(np.arange(len(names)), held), P.size, sheet, shape, warp)


def counted_rank(
    J: np.ndarray, target_xy: np.ndarray, counted: CountedParameters, slope: np.ndarray | None = None
) -> int:
    """The SVD rank of the captures' spot Jacobian over the counted parameters (no prior).

    Parameters
    ----------
    J : (m, 2, p) array, d spot / d robot parameters (P's order)
    target_xy : (m, 2) array, the captures' points in the base frame, mm (a sheet's pose moves them:
        d point / d(x, y, yaw, ex, ey) = [e_x, e_y, e_z x point, x e_x, y e_y], eqs. S1, S3; where the turn
        and the scale are about, and the sheet's small yaw, do not change the rank)
    slope : (m, 2) array, d spot / d plane height of each capture's beam (d_xy / d_z): a sheet's tilt moves
        the plane under the spot by point . (tx, ty) (eq. S3), points about their mean
    counted : CountedParameters of the robot (and sheet), without an extension

    Returns
    -------
    int, 0 without captures
    """
    if not len(J):
        return 0
    cols = [J]
    if counted.sheet:
        S = np.zeros((len(J), 2, NSHEET))
        S[:, 0, 0] = S[:, 1, 1] = -1.0  # residual = spot - point
        S[:, 0, 2], S[:, 1, 2] = target_xy[:, 1], -target_xy[:, 0]
        S[:, 0, 3], S[:, 1, 4] = -target_xy[:, 0], -target_xy[:, 1]
        S[:, :, 5:] = slope[:, :, None] * (target_xy - target_xy.mean(axis=0))[:, None, :]
        cols.append(S)
    A = np.concatenate(cols, axis=2)[:, :, counted.free]
    return identifiability(A.reshape(-1, counted.count), [counted.names[i] for i in counted.free])[0].rank
