"""The calibrated model in the forms controllers load: a URDF, a DH-style table, the YAML.

Every form is built from one set of frames at the zero configuration, one per joint:
z along the identified axis, origin on the identified line, x along the common normal
to the next axis (the modified-DH construction, Craig), its sign -- and, where the
construction leaves a choice (parallel axes, the last joint), its position -- taken from
a reference frame. For the Panda and the FR3 the reference is Franka's own description
(``franka_description``), so that the nominal model reproduces Franka's joint origins
and DH table exactly and a calibrated one moves each frame only by the identified
correction: meshes, inertias and controllers written for Franka's link frames still fit.
Other robots use the minimal-POE link frames of :func:`solver.minimal.link_frame`.

Since each frame's z is the joint's axis through its line, chaining the frames with
rotations about z reproduces the product of exponentials exactly:
``F_1 Rz(q_1) F_1^-1 F_2 Rz(q_2) ... = e^[S_1]q_1 e^[S_2]q_2 ... F_n``.

Rotations are written as URDF roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import yaml

from lasercal.solver.kinematics.minimal import link_frame
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import inv_T
from lasercal.solver.whole import dump_yaml

# franka_description (panda_arm.xacro): joint origins relative to the previous link, xyz (m) and rpy (rad).
FRANKA_ORIGINS = (
    ((0.0, 0.0, 0.333), (0.0, 0.0, 0.0)),
    ((0.0, 0.0, 0.0), (-np.pi / 2, 0.0, 0.0)),
    ((0.0, -0.316, 0.0), (np.pi / 2, 0.0, 0.0)),
    ((0.0825, 0.0, 0.0), (np.pi / 2, 0.0, 0.0)),
    ((-0.0825, 0.384, 0.0), (-np.pi / 2, 0.0, 0.0)),
    ((0.0, 0.0, 0.0), (np.pi / 2, 0.0, 0.0)),
    ((0.088, 0.0, 0.0), (np.pi / 2, 0.0, 0.0)),
)
FRANKA_FLANGE_MM = 107.0  # panda_joint8: the flange, along joint 7's axis
# Joint torque (Nm) and speed (rad/s) limits of the URDF <limit> tags, from Franka's datasheets.
FRANKA_EFFORT = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
FRANKA_VELOCITY = {
    "panda": (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),
    "fr3": (2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26),
}
_FRANKA_MATCH = (0.1, 30.0)  # rad, mm: a model whose axes are this close to Franka's is a Panda or an FR3
_PARALLEL = 1e-9  # |z_i x z_j| below this: parallel axes, the common normal is anywhere along them
FORMATS = ("urdf", "dh", "yaml")  # and franka_description's kinematics.yaml: solver.formats.franka


def transform(xyz, rpy) -> np.ndarray:
    """Homogeneous transform (4, 4) from a translation and URDF roll-pitch-yaw angles (rad)."""
    T = np.eye(4)
    from scipy.spatial.transform import Rotation  # loaded on use: slow to import for `lasercal --help`

    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # extrinsic x, y, z: Rz(yaw) Ry(pitch) Rx(roll)
    T[:3, 3] = xyz
    return T


def xyz_rpy(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation and URDF roll-pitch-yaw (rad) of a homogeneous transform."""
    from scipy.spatial.transform import Rotation

    return T[:3, 3].copy(), Rotation.from_matrix(T[:3, :3]).as_euler("xyz")


def franka_frames() -> np.ndarray:
    """Franka's joint frames at the zero configuration in the base frame, (7, 4, 4), mm."""
    T, out = np.eye(4), []
    for xyz, rpy in FRANKA_ORIGINS:
        T = T @ transform(1000.0 * np.array(xyz), rpy)
        out.append(T)
    return np.array(out)


def _axis(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The point nearest the base origin and the unit direction of a revolute joint's axis."""
    return np.cross(S[:3], S[3:]), S[:3]


def _foot(p: np.ndarray, w: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The point of the line p + s w (unit w) nearest to x."""
    return p + w * ((x - p) @ w)


def _unit_normal(v: np.ndarray, w: np.ndarray) -> np.ndarray | None:
    """v made orthogonal to the unit w and normalised; None when nothing is left of it."""
    u = v - w * (v @ w)
    n = np.linalg.norm(u)
    return u / n if n > _PARALLEL else None


def _common_normal(p1, w1, p2, w2, near) -> tuple[np.ndarray, np.ndarray | None]:
    """Foot on line 1 of the common normal with line 2, and its direction (None when the lines coincide).

    For parallel lines the common normal can sit anywhere: the foot nearest to ``near`` is taken.
    """
    n = np.cross(w1, w2)
    if np.linalg.norm(n) < _PARALLEL:
        f = _foot(p1, w1, near)
        return f, _unit_normal(p2 - f, w1)
    f = p1 + w1 * (np.cross(p2 - p1, w2) @ n) / (n @ n)
    return f, n / np.linalg.norm(n)


def _x_axis(ref: np.ndarray, z: np.ndarray) -> np.ndarray:
    """A frame's x for the unit z: the reference frame's x made normal to z, or its y when x is along z.

    The reference's x and y are orthogonal, so they cannot both lie along z: any z gets an x.
    """
    x = _unit_normal(ref[:3, 0], z)
    return x if x is not None else _unit_normal(ref[:3, 1], z)


def _frame(x: np.ndarray, z: np.ndarray, origin: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, origin
    return T


@dataclass(frozen=True, eq=False)
class Frames:
    """The frames every export is written from (base frame, zero configuration, mm).

    Attributes
    ----------
    prefix : str or None, 'panda' or 'fr3' when the reference is Franka's description
    base : (4, 4) array, DH frame 0: z along joint 1's axis, origin at the foot of the base origin on it
    joints : (n, 4, 4) array, joint frames: z along the identified axis, origin on its line
    flange : (4, 4) array or None, Franka's flange (panda_link8): joint 7's frame 107 mm along its axis
    laser : (4, 4) array, origin at the laser aperture, z along the beam
    """

    prefix: str | None
    base: np.ndarray
    joints: np.ndarray
    flange: np.ndarray | None
    laser: np.ndarray


def _franka_prefix(model: RobotModel) -> str | None:
    """'fr3' or 'panda' when every axis of the model lies near Franka's, else None."""
    if model.n != len(FRANKA_ORIGINS):
        return None
    for S, F in zip(model.screws, franka_frames()):
        p, w = _axis(S)
        off = np.linalg.norm(F[:3, 3] - _foot(p, w, F[:3, 3]))
        if np.arccos(np.clip(w @ F[:3, 2], -1.0, 1.0)) > _FRANKA_MATCH[0] or off > _FRANKA_MATCH[1]:
            return None
    return "fr3" if model.name.lower().startswith("fr3") else "panda"


def kinematic_frames(model: RobotModel) -> Frames:
    """Joint frames of the model at the zero configuration, closest to the reference frames.

    Parameters
    ----------
    model : RobotModel (revolute joints and a laser)

    Returns
    -------
    Frames
    """
    prefix = _franka_prefix(model)
    ref = franka_frames() if prefix else np.array([link_frame(S) for S in model.screws])
    axes = [_axis(S) for S in model.screws]
    n = model.n
    frames = []
    for i, (p, w) in enumerate(axes):
        r = ref[i]
        if i < n - 1:
            origin, x = _common_normal(p, w, *axes[i + 1], near=r[:3, 3])
        else:  # the last joint: where the previous common normal meets its axis; x from the reference
            origin = _common_normal(p, w, *axes[i - 1], near=r[:3, 3])[0] if n > 1 else _foot(p, w, r[:3, 3])
            x = None
        if x is None:
            x = _x_axis(r, w)
        frames.append(_frame(x if x @ r[:3, 0] >= 0 else -x, w, origin))
    frames = np.array(frames)
    p1, w1 = axes[0]
    base = _frame(frames[0][:3, 0], w1, _foot(p1, w1, np.zeros(3)))
    flange = None
    if prefix:
        flange = frames[-1].copy()
        flange[:3, 3] += FRANKA_FLANGE_MM * frames[-1][:3, 2]
    last = flange if flange is not None else frames[-1]
    vp = model.laser_dir
    laser = _frame(_x_axis(last, vp), vp, model.aperture)
    return Frames(prefix, base, frames, flange, laser)


def flange_frame(model: RobotModel, frames: Frames | None = None) -> np.ndarray:
    """The flange frame at q = 0 (4, 4) mm, carried by the model's last joint (:func:`kinematic_frames`).

    Franka's flange (``panda_link8``, 107 mm along joint 7's axis) for a Panda or an FR3; for other robots
    no flange is of record, and the last joint's frame slid along its axis to the foot of the laser
    aperture (or tool point) stands in.
    """
    F = kinematic_frames(model) if frames is None else frames
    if F.flange is not None:
        return F.flange
    last = F.joints[-1]
    flange = last.copy()
    flange[:3, 3] = _foot(last[:3, 3], last[:3, 2], model.aperture)
    return flange


def model_flange(model: RobotModel) -> np.ndarray:
    """The model's flange at q = 0 (4, 4) mm, base frame, as every export and ``lasercal correct`` carry it:
    a URDF model's tip link where the calibrated URDF puts it (:func:`solver.formats.urdf.tip_frame`), else
    :func:`flange_frame`."""
    if model.urdf:
        from lasercal.solver.formats.urdf import tip_frame

        return tip_frame(model)
    return flange_frame(model)


def _num(v: float) -> str:
    """A float that round-trips exactly (repr), without a trailing '.0' noise for integers."""
    v = float(v)
    return repr(v) if v != int(v) else str(int(v))


def _origin(T: np.ndarray) -> str:
    xyz, rpy = xyz_rpy(T)
    return f'<origin xyz="{" ".join(_num(c / 1000.0) for c in xyz)}" rpy="{" ".join(_num(a) for a in rpy)}"/>'


def _extension_note(model: RobotModel) -> str:
    if not model.extensions:
        return ""
    return (
        "non-geometric corrections a URDF cannot carry (apply them in the controller): "
        + yaml.safe_dump(model.extensions, default_flow_style=True, width=10**6).strip()
    )


def to_urdf(model: RobotModel) -> str:
    """A kinematic URDF (no meshes or inertias): joint origins from the identified screws, metres.

    For the Panda and the FR3 the names are Franka's (``panda_link0..8``, ``panda_joint1..7``,
    the fixed ``panda_joint8`` to the flange) and a fixed ``panda_laser_joint`` puts the
    ``panda_laser`` frame at the aperture with z along the beam; other robots get
    ``link0..n``, the model's joint names and ``laser``. A full-pose model's end-effector frame
    {E} (``ee``) is the fixed link ``lasercal_ee`` (joint ``lasercal_ee_joint``) on the same parent.
    """
    from lasercal.solver.formats.urdf import EE_LINK  # (here: the URDF module loads scipy's rotations)

    F = kinematic_frames(model)
    pre = f"{F.prefix}_" if F.prefix else ""
    links = [f"{pre}link{i}" for i in range(model.n + 1)]
    joints = [f"{pre}joint{i + 1}" for i in range(model.n)] if F.prefix else list(model.joint_names)
    effort = FRANKA_EFFORT if F.prefix else (0.0,) * model.n
    velocity = FRANKA_VELOCITY[F.prefix] if F.prefix else (0.0,) * model.n
    out = [
        '<?xml version="1.0"?>',
        (
            f"<!-- lasercal export of {model.name}: joint frames at q = 0 with z along the identified axes "
            f"(written by {__name__}); kinematics only -->"
        ),
    ]
    note = _extension_note(model)
    if note:
        out.append(f"<!-- {note} -->")
    out.append(f'<robot name="{F.prefix or model.name}">')
    out += [f'  <link name="{nm}"/>' for nm in links]
    prev = np.eye(4)
    for i, T in enumerate(F.joints):
        lo, hi = model.limits[i]
        out += [
            f'  <joint name="{joints[i]}" type="revolute">',
            f'    <parent link="{links[i]}"/>',
            f'    <child link="{links[i + 1]}"/>',
            f"    {_origin(inv_T(prev) @ T)}",
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{_num(lo)}" upper="{_num(hi)}" effort="{_num(effort[i])}" '
            f'velocity="{_num(velocity[i])}"/>',
            "  </joint>",
        ]
        prev = T
    parent = links[-1]
    if F.flange is not None:
        flange = f"{pre}link{model.n + 1}"
        out += [
            f'  <link name="{flange}"/>',
            f'  <joint name="{pre}joint{model.n + 1}" type="fixed">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{flange}"/>',
            f"    {_origin(inv_T(prev) @ F.flange)}",
            "  </joint>",
        ]
        parent, prev = flange, F.flange
    fixed = {f"{pre}laser": (f"{pre}laser_joint", F.laser)}
    if model.ee_pose is not None:
        fixed[EE_LINK] = (f"{EE_LINK}_joint", np.asarray(model.ee_pose))
    for name, (joint, T) in fixed.items():
        out += [
            f'  <link name="{name}"/>',
            f'  <joint name="{joint}" type="fixed">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{name}"/>',
            f"    {_origin(inv_T(prev) @ T)}",
            "  </joint>",
        ]
    return "\n".join(out + ["</robot>", ""])


def dh_parameters(frames: np.ndarray, base: np.ndarray) -> np.ndarray:
    """Modified DH (Craig) parameters (n, 4) ``alpha, a, theta, d`` of consecutive frames (rad, mm).

    Row i relates frame i-1 (``base`` for the first) to frame i:
    T = Rx(alpha) Tx(a) Rz(theta) Tz(d). Exact because each x lies along the common normal
    of its axis and the next one.
    """
    out, prev = [], base
    for T in frames:
        x0, z0, o0 = prev[:3, 0], prev[:3, 2], prev[:3, 3]
        x1, z1, o1 = T[:3, 0], T[:3, 2], T[:3, 3]
        alpha = np.arctan2(np.cross(z0, z1) @ x0, z0 @ z1)
        theta = np.arctan2(np.cross(x0, x1) @ z1, x0 @ x1)
        out.append((alpha, (o1 - o0) @ x0, theta, (o1 - o0) @ z1))
        prev = T
    return np.array(out)


def to_dh(model: RobotModel) -> str:
    """The DH-style table (YAML ``lasercal-dh/1``): per joint its screw and modified DH parameters.

    T(q) = base * prod_i Rx(alpha_i) Tx(a_i) Rz(theta_i + q_i) Tz(d_i) * flange * tool gives the
    laser frame (origin the aperture, z along the beam), mm and rad. ``flange`` is a fixed DH row
    from the last joint's frame along its axis: Franka's flange (d = 107 mm) for the Panda and the
    FR3, else the foot of the aperture on the last axis; ``tool`` is the laser frame in the flange's.
    """
    F = kinematic_frames(model)
    dh = dh_parameters(F.joints, F.base)
    last = F.joints[-1]
    flange = flange_frame(model, F)
    fl = dh_parameters(flange[None], last)[0]
    r = lambda a: [float(round(float(x), 12)) for x in np.ravel(a)]  # noqa: E731

    def pose(T):
        xyz, rpy = xyz_rpy(T)
        return {"xyz": r(xyz), "rpy": r(rpy)}

    d = {
        "format": "lasercal-dh/1",
        "robot": model.name,
        "units": {"length": "mm", "angle": "rad"},
        "convention": "T(q) = base * prod_i Rx(alpha_i) Tx(a_i) Rz(theta_i + q_i) Tz(d_i) * flange * tool "
        "(modified DH, Craig; flange: the fixed row Rx(alpha) Tx(a) Rz(theta) Tz(d) from the last joint "
        "to the flange); "
        "rpy: R = Rz(yaw) Ry(pitch) Rx(roll); omega, v: the joint screw in the base frame at q = 0",
        "base": pose(F.base),
        "joints": [
            {
                "name": nm,
                "alpha": float(round(al, 12)),
                "a": float(round(a, 12)),
                "theta": float(round(th, 12)),
                "d": float(round(dd, 12)),
                "omega": r(S[:3]),
                "v": r(S[3:]),
            }
            for nm, (al, a, th, dd), S in zip(model.joint_names, dh, model.screws)
        ],
        "flange": {
            "name": f"{F.prefix}_joint{model.n + 1}" if F.prefix else "flange",
            **{k: float(round(v, 12)) for k, v in zip(("alpha", "a", "theta", "d"), fl)},
        },
        "tool": pose(inv_T(flange) @ F.laser),
    }
    if model.extensions:
        d["extensions"] = model.extensions
    head = (
        f"# lasercal export of {model.name}: modified DH parameters and joint screws "
        "(see solver/formats/export.py)\n"
    )
    return head + yaml.safe_dump(d, sort_keys=False, width=10**6, default_flow_style=None)


def to_yaml(model: RobotModel) -> str:
    """The model as lasercal writes it (format lasercal-robot/1, normalised screws)."""
    return dump_yaml(model.to_dict(), sort_keys=False, width=120)


def export(model: RobotModel, fmt: str) -> str:
    """The model as text in ``fmt``: 'urdf', 'dh' or 'yaml'. A model from a URDF exports as that URDF with
    calibrated joints (:func:`solver.formats.urdf.calibrated_urdf`). franka_description's kinematics.yaml is
    :func:`solver.formats.franka.to_franka`."""
    if fmt == "urdf" and model.urdf:
        from lasercal.solver.formats.urdf import calibrated_urdf

        return calibrated_urdf(model)
    return {"urdf": to_urdf, "dh": to_dh, "yaml": to_yaml}[fmt](model)
