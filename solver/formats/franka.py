"""The calibrated model as franka_description's ``kinematics.yaml``: what franka_ros2 and MoveIt 2 load.

franka_description (Franka Robotics, Apache-2.0) builds a Franka robot's URDF from xacro; the macro
``franka-kinematics`` of ``robots/common/utils.xacro`` writes each joint's ``<origin>`` from
``robots/<id>/kinematics.yaml``: per joint ``joint1`` .. ``joint8`` a mapping ``kinematic: {x, y, z,
roll, pitch, yaw}`` (m, rad; R = Rz(yaw) Ry(pitch) Rx(roll)), the origin of ``<id>_joint<i>`` in its
parent link ``<id>_link<i-1>``. Joints 1-7 turn about z of their frame (``<axis xyz="0 0 1"/>``, fixed in
franka_arm.xacro); ``joint8`` is the fixed flange joint to ``<id>_link8``. Robot ids: ``fer`` (the Panda),
``fr3``, ``fr3v2``, ``fp3`` (one nominal geometry).

The origins (exact for any calibrated model). A URDF whose joint i turns about z of the frame G_i
(its pose at q = 0 in the base frame ``<id>_link0``) computes

    T(q) = O_1 Rz(q_1) O_2 Rz(q_2) ... O_7 Rz(q_7) O_8,   O_i = G_(i-1)^-1 G_i  (G_0 = I),  O_8 = G_7^-1 F

with F the flange at q = 0. When G_i has z along the joint's identified axis omega_i and its origin on the
axis line, G_i Rz(q) G_i^-1 = e^[S_i] q (Modern Robotics eq. 3.51 and 3.88: the screw motion about that
line), so T(q) = e^[S_1]q_1 ... e^[S_7]q_7 F, the model's product of exponentials (eq. 4.14), for every
q: a tilted or shifted axis becomes a rotated and displaced origin O_i, with the next origin O_(i+1)
re-expressed in the tilted frame by the same product. The G_i are
:func:`solver.formats.export.kinematic_frames` (x along the common normal to the next axis, its sign
Franka's) and F its flange (Franka's ``link8``, 107 mm along joint 7's calibrated axis; a URDF model's tip
link): the frames of ``lasercal export --format urdf`` and ``lasercal correct``, which agree on the flange.

A joint's zero offset d_i (the link is at q_i + d_i when the joint reads q_i) is a turn Rz(d_i) about the
joint's own axis. The minimal-POE screws carry it in the axes after joint i, so the common normal to the
next axis -- frame i's x -- turns by d_i: O_i becomes O_i Rz(d_i), and O_(i+1) stays. Since Rz(d_i)
Rz(q_i) = Rz(q_i) Rz(d_i), that is the same as Rz(d_i) at the head of the next origin O_(i+1) for every
frame after link i, and it turns link i's own frame (its meshes and collision shapes) with the link, as
the real link turns. The flange's turn about its own axis is invisible to a laser's or a tool's data: it
stays the nominal's (joint 7's frame takes its x from Franka's), so a zero offset of joint 7 -- or the part
of another joint's that turns the flange about its axis -- is not in the file (as in every export).

What ``kinematics.yaml`` cannot carry is said (:func:`not_carried`), never dropped in silence: the laser
(lasercal's measuring tool, a prismatic joint), identified tool points and end-effector frames, robot
effects (a compliance, an eccentricity), the sensor's transform to the base.
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.errors import ModelError
from lasercal.solver.formats.export import FRANKA_ORIGINS, kinematic_frames, model_flange, xyz_rpy
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import inv_T

ROBOT_IDS = ("fer", "fr3", "fr3v2", "fp3")
FAMILY = {"panda": "fer", "fr3": "fr3"}  # kinematic_frames' prefix -> the default robot id
_DECIMALS = 15  # m and rad: round-off below 1e-12 mm; Franka's nominal values read as Franka writes them
_SAMPLES = 500  # configurations over which an effect's size is measured


def franka_origins(model: RobotModel) -> np.ndarray:
    """The origins O_1 .. O_8 (8, 4, 4) of ``joint1`` .. ``joint8`` in their parent links, mm (module
    docstring).

    Parameters
    ----------
    model : RobotModel, a Franka arm (7 revolute joints near Franka's axes)

    Returns
    -------
    (8, 4, 4) array, homogeneous transforms, mm

    Raises
    ------
    ModelError
        The model is no Franka arm.
    """
    _check_franka(model)
    G = kinematic_frames(model).joints
    frames = np.concatenate([np.eye(4)[None], G, model_flange(model)[None]])
    return np.array([inv_T(frames[i]) @ frames[i + 1] for i in range(8)])


def _check_franka(model: RobotModel) -> None:
    """Refuse a model that is no Franka arm (ModelError naming what differs)."""
    n = len(FRANKA_ORIGINS)
    if model.is_tree or model.n != n or model.prismatic.any():
        what = ", a tree or coupled joints" if model.is_tree else ""
        what += ", prismatic joints" if model.prismatic.any() else ""
        raise ModelError(
            f"{model.name!r} is not a Franka arm ({n} revolute joints in a chain): it has {model.n} "
            f"joints{what}"
        )
    if kinematic_frames(model).prefix is None:
        raise ModelError(
            f"{model.name!r} is not a Franka arm: its axes are not within 0.1 rad and 30 mm of Franka's "
            "(Panda, FR3, FP3)"
        )


def default_robot_id(model: RobotModel) -> str:
    """'fer' for a Panda, 'fr3' for an FR3 (by the model's name), as :func:`export.kinematic_frames` tells."""
    _check_franka(model)
    return FAMILY[kinematic_frames(model).prefix]


def _num(v: float) -> str:
    """A number PyYAML (and so xacro's ``load_yaml``) reads back as this float: rounded to 1e-15, and a
    mantissa with a point (PyYAML reads '1e-05' as a string)."""
    v = round(float(v), _DECIMALS) + 0.0  # + 0.0: no '-0'
    if v == int(v) and abs(v) < 1e15:
        return str(int(v))
    s = repr(v)
    if "e" in s and "." not in s.split("e")[0]:
        m, e = s.split("e")
        s = f"{m}.0e{e}"
    return s


def to_franka(model: RobotModel, robot_id: str | None = None) -> str:
    """The ``kinematics.yaml`` of franka_description for the model (module docstring), m and rad.

    Parameters
    ----------
    model : RobotModel, a Franka arm
    robot_id : 'fer', 'fr3', 'fr3v2' or 'fp3'; default the model's family (:func:`default_robot_id`)

    Returns
    -------
    str, the YAML text (a comment header naming the model, the units and where it goes)
    """
    rid = robot_id or default_robot_id(model)
    if rid not in ROBOT_IDS:
        raise ModelError(f"robot id {rid!r} is not a franka_description robot ({', '.join(ROBOT_IDS)})")
    origins = franka_origins(model)
    out = [
        f"# lasercal export of {model.name}: franka_description robots/{rid}/kinematics.yaml",
        f"# (written by {__name__}). Units: x, y, z in m; roll, pitch, yaw in rad (R = Rz(yaw) Ry(pitch)",
        f"# Rx(roll)). Each jointN's origin in its parent link {rid}_link(N-1); joints 1-7 turn about z of",
        f"# their frame; joint8 is the fixed flange ({rid}_link8). {rid}_link0 is the model's base frame.",
        "",
    ]
    for i, origin in enumerate(origins):
        xyz, rpy = xyz_rpy(origin)
        vals = dict(zip(("x", "y", "z"), xyz / 1000.0)) | dict(zip(("roll", "pitch", "yaw"), rpy))
        if i == 7:
            out.append("# Joint to tool origin (the flange)")
        out += [f"joint{i + 1}:", "  kinematic:"] + [f"    {k}: {_num(v)}" for k, v in vals.items()] + [""]
    return "\n".join(out)


def _in_flange(model: RobotModel, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A frame at q = 0 (4, 4) mm in the flange's frame: its position mm and its rotation matrix."""
    L = inv_T(model_flange(model)) @ T
    return L[:3, 3], L[:3, :3]


def _mm(p) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in p) + ") mm"


def _angle(R: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


def _effect_size(model: RobotModel) -> tuple[float, float] | None:
    """The largest joint correction (rad) and flange displacement (mm) of the model's robot effects over
    configurations drawn within the limits (seeded), or None when they cannot be evaluated from q alone."""
    from lasercal.solver.errors import LasercalError
    from lasercal.solver.kinematics.effects import extension_from_model
    from lasercal.solver.kinematics.gravity import model_torques
    from lasercal.solver.kinematics.ik import tool_frames
    from lasercal.solver.streams import stream

    try:
        ext = extension_from_model(model.extensions, model.name, model.n)
    except LasercalError:
        return None
    if ext is None or "t" in ext.needs():  # a drift needs a session's clock: no size from q alone
        return None
    q = stream(0, "franka-export", "effects").uniform(
        model.limits[:, 0], model.limits[:, 1], (_SAMPLES, model.n)
    )
    tau = model_torques(model, q)[0] if "tau" in ext.needs() else None
    qt = ext.true_q(q, None, tau)  # q_true = q + dq(q, tau(q)), as lasercal correct applies it
    F = model_flange(model)
    d = tool_frames(model.screws, F, qt)[0][:, :3, 3] - tool_frames(model.screws, F, q)[0][:, :3, 3]
    return float(np.abs(qt - q).max()), float(np.linalg.norm(d, axis=1).max())


def effect_notes(model: RobotModel) -> list[str]:
    """The model's robot effects (``extensions``), one sentence each with its size: what no kinematic file
    (kinematics.yaml, a URDF, a DH table) carries, and lasercal's corrector applies.

    Parameters
    ----------
    model : RobotModel

    Returns
    -------
    list of str (empty without effects)
    """
    out = []
    for effect, entry in (model.extensions or {}).items():
        joints = entry.get("joints") if isinstance(entry, dict) else None
        where = f" of joint(s) {', '.join(map(str, joints))}" if joints else ""
        out.append(f"the {effect}{where} (a correction of the joint angles, not a geometry){{size}}")
    if out:
        size = _effect_size(model)
        text = (
            f": up to {size[0] * 1000:.3f} mrad of joint angle, {size[1]:.3f} mm at the flange over "
            f"{_SAMPLES} configurations within the limits -- lasercal's corrector applies it"
            if size
            else " -- lasercal's corrector applies it"
        )
        out = [s.replace("{size}", text) for s in out]
    return out


def not_carried(model: RobotModel) -> list[str]:
    """What the model holds that ``kinematics.yaml`` cannot carry, one sentence each with its size.

    Parameters
    ----------
    model : RobotModel, a Franka arm

    Returns
    -------
    list of str (empty when the file carries the whole model)
    """
    out = []
    link8 = "the flange (link8)"
    if not model.urdf:  # a URDF model has no laser: its laser fields stand in for the tip
        p, R = _in_flange(model, _laser_frame(model))
        tilt = np.degrees(np.arccos(np.clip(R[:, 2] @ np.array([0.0, 0.0, 1.0]), -1.0, 1.0)))
        out.append(
            f"the laser (lasercal's measuring tool, a prismatic joint): aperture at {_mm(p)} in {link8}, "
            f"beam {tilt:.3f} deg from its z axis -- no link of franka_description"
        )
    for name, point in dict(model.targets).items():
        p = _in_flange(model, _at(point))[0]
        out.append(f"target {name!r} at {_mm(p)} in {link8} (a TCP, not a joint)")
    if model.tool_point is not None:
        p = _in_flange(model, _at(model.tool_point))[0]
        out.append(f"the tool point at {_mm(p)} in {link8} (a TCP, not a joint)")
    fullpose = str(model.identification.get("method", "")).startswith("fullpose")
    ee = model.ee_pose is not None and (fullpose or not model.urdf)
    p, R = _in_flange(model, np.asarray(model.ee_pose)) if ee else (np.zeros(3), np.eye(3))
    if ee and (np.abs(p).max() > 1e-9 or np.abs(R - np.eye(3)).max() > 1e-12):  # the flange itself: carried
        rpy = xyz_rpy(_pose(R, p))[1]
        out.append(
            f"the end-effector frame 'ee' at {_mm(p)}, rpy ({', '.join(f'{a:.6f}' for a in rpy)}) rad in "
            f"{link8} (a TCP, not a joint)"
        )
    out += effect_notes(model)
    if model.sensor_pose is not None:
        S = np.asarray(model.sensor_pose)
        out.append(
            f"the sensor's transform to the base (^S T_base: {np.linalg.norm(S[:3, 3]):.3f} mm, "
            f"{np.degrees(_angle(S[:3, :3])):.3f} deg): where the robot stands, for the world-to-base joint"
        )
    return out


def _laser_frame(model: RobotModel) -> np.ndarray:
    return kinematic_frames(model).laser


def _at(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _pose(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def robot_id_note(model: RobotModel, robot_id: str) -> str | None:
    """A sentence when the robot id is of another family than the model (a Panda written for an FR3)."""
    own = default_robot_id(model)
    if (own == "fer") != (robot_id == "fer"):
        return (
            f"--robot-id {robot_id}: the model {model.name!r} is of the {own} family; the file is written "
            f"for robots/{robot_id}/ all the same (one nominal geometry)"
        )
    return None
