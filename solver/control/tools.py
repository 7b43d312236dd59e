"""The flange and the tools on it: which frame a goal is for, under the calibrated and the nominal model.

The flange. Laser spots, targets and tool points never show where the flange itself is on the last link,
so the flange is the nominal one carried by the calibrated last joint: a URDF robot's tip link where the
calibrated URDF puts it (:func:`solver.formats.urdf.tip_frame`), Franka's flange ``panda_link8`` (107 mm
along joint 7's axis) for a Panda or an FR3 (:func:`solver.formats.export.flange_frame`), the last joint's
frame at the foot of the aperture for other robots. Both exports (URDF, DH) carry this same flange, so
MoveIt with the calibrated URDF and ``lasercal correct`` agree on it. A zero offset of the last joint
(the flange turned about its own axis) is invisible to such data: it is the nominal's.

A tool is a fixed frame in the flange frame (its ``offset``): the flange itself, a TCP given in the
flange frame, or a point the calibration identified -- a position session's target, a point session's
tool point, a full-pose session's end-effector frame ``ee``. An identified point is taken into the
flange frame of the calibrated model; the nominal model carries the same offset on its own flange
(what a controller with that TCP computes). A point's frame keeps the flange's orientation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.errors import FormatError
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import inv_T

FLANGE = "flange"


@dataclass(frozen=True, eq=False)
class Tool:
    """A tool: its name and its frame in the flange frame.

    Attributes
    ----------
    name : str, 'flange', 'tcp', a target's name, 'tool' or 'ee'
    offset : (4, 4) array, the tool frame in the flange frame, mm
    """

    name: str
    offset: np.ndarray


def flange(model: RobotModel) -> np.ndarray:
    """The model's flange frame at q = 0 (4, 4) mm, base frame (module docstring)."""
    from lasercal.solver.formats.export import model_flange

    return model_flange(model)


def identified_points(model: RobotModel) -> dict:
    """The tools a calibration identified, name -> (4, 4) frame at q = 0 in the base frame (mm): targets,
    a point session's tool point ('tool'), a full-pose model's end-effector frame ('ee')."""
    out = {}
    for name, p in model.targets.items():
        out[name] = _at(p)
    if model.tool_point is not None:
        out["tool"] = _at(model.tool_point)
    fullpose = str(model.identification.get("method", "")).startswith("fullpose")
    if model.ee_pose is not None and (fullpose or not model.urdf):  # a URDF's ee_pose is its tip, not a tool
        out["ee"] = np.asarray(model.ee_pose, dtype=float)
    return out


def _at(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def make_tool(model: RobotModel, flange_T: np.ndarray, tool=None) -> Tool:
    """The tool ``tool`` names on the model whose flange is ``flange_T``.

    Parameters
    ----------
    model : RobotModel
    flange_T : (4, 4) array, the model's flange at q = 0 (:func:`flange`)
    tool : None or 'flange' (the flange), a name of :func:`identified_points` (its point, with the
        flange's orientation unless it is a frame), a TCP (3,) mm in the flange frame, or a Tool

    Returns
    -------
    Tool
    """
    if isinstance(tool, Tool):
        return tool
    if tool is None or (isinstance(tool, str) and tool == FLANGE):
        return Tool(FLANGE, np.eye(4))
    if isinstance(tool, str):
        points = identified_points(model)
        if tool not in points:
            known = ", ".join([FLANGE] + list(points))
            raise FormatError("tool", f"{model.name!r} has no tool {tool!r} (it has: {known})")
        T = inv_T(flange_T) @ points[tool]
        if tool != "ee":
            T[:3, :3] = np.eye(3)  # a point: the flange's orientation
        return Tool(tool, T)
    tcp = np.asarray(tool, dtype=float).ravel()
    if tcp.shape != (3,) or not np.all(np.isfinite(tcp)):
        raise FormatError("tool", f"a TCP is 3 finite numbers x y z (mm, flange frame), got {tool!r}")
    return Tool("tcp", _at(tcp))
