"""A printable reference sheet for a robot: the drawing (``vision.sheet``), and with a robot and a rough
placement, a check that the arm can aim at every point where the sheet will lie (``solver``'s aiming IK).

Units: mm, and degrees for the placement's yaw (as in the layout's ``sheet`` mapping).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.solver.errors import AimingError, LasercalError
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.sheet import SheetPose
from lasercal.vision.sheet import SheetDesign, write_sheet

DEFAULT_PLANE_Z = -8.0  # mm: the thesis's Panda table (data/robots/panda.yaml), without a robot's own
REACH_CONFIGS = 15  # configurations the reach check asks for per point: a capture's usual per-point count


@dataclass(frozen=True)
class Reach:
    """Whether the arm can aim at one point of the sheet where it is placed.

    Attributes
    ----------
    name : str
    base : (3,) array, the point in the robot base frame, mm
    reachable : bool, ``n`` diverse in-limit configurations aim the beam through it
    """

    name: str
    base: np.ndarray
    reachable: bool


def check_reach(
    model: RobotModel,
    design: SheetDesign,
    pose: SheetPose,
    plane_z: float,
    n: int = REACH_CONFIGS,
    seed: int = 0,
) -> list[Reach]:
    """Each point of the sheet placed at ``pose`` (eq. S1): can the aiming IK find ``n`` configurations?

    Parameters
    ----------
    model : RobotModel, the nominal robot
    design : SheetDesign
    pose : SheetPose, the sheet frame's rough pose in the base frame
    plane_z : float, the sheet's height in the base frame, mm
    n : int, configurations needed per point (a capture's per-point count)
    seed : int, of the aiming IK's random draws

    Returns
    -------
    list of Reach, in the design's point order
    """
    names = list(design.points)
    xyz = pose.to_base(np.array([design.points[k] for k in names]), plane_z)
    rng = np.random.default_rng(seed)
    out = []
    for name, p in zip(names, xyz):
        try:
            aim(model, p, n, rng)
            ok = True
        except AimingError:
            ok = False
        out.append(Reach(name, p, ok))
    return out


def make_sheet(
    out,
    design: SheetDesign,
    plane_z: float,
    model: RobotModel | None = None,
    pose: SheetPose | None = None,
    per_point: int = REACH_CONFIGS,
) -> tuple[dict, list[Reach]]:
    """Check the reach (with a model and a pose), then write the sheet's PDF, SVG and layout.yaml.

    Parameters
    ----------
    out : str or Path, an existing folder to write into
    design : SheetDesign
    plane_z : float, mm, base frame
    model : RobotModel or None, checks every point can be aimed at (needs ``pose``)
    pose : SheetPose or None, the rough placement written as the layout's ``sheet``
    per_point : int, configurations the reach check asks for per point

    Returns
    -------
    (dict kind -> Path of the files written, list of Reach; empty without a model)

    Raises
    ------
    LasercalError
        A model without a pose, or a point the arm cannot aim at (nothing is written).
    """
    reach = []
    if model is not None:
        if pose is None:
            raise LasercalError("the reach check needs where the sheet will lie: give --place X Y YAW")
        reach = check_reach(model, design, pose, plane_z, per_point)
        bad = [r for r in reach if not r.reachable]
        if bad:
            where = ", ".join(f"{r.name} at ({r.base[0]:.0f}, {r.base[1]:.0f}) mm" for r in bad)
            raise LasercalError(
                f"{model.name} cannot aim its beam at {where} (base frame) in {per_point} in-limit "
                "configurations: place the sheet nearer the robot (--place) or choose a smaller paper"
            )
    files = write_sheet(Path(out), design, plane_z, None if pose is None else pose.as_dict())
    return files, reach
