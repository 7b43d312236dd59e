"""Robot model: joint screws, limits, the laser (or tool point), loaded from YAML and validated.

File format ``lasercal-robot/1`` (mm, rad), see README "Robot model":

.. code-block:: yaml

    format: lasercal-robot/1
    name: panda
    nominal: panda         # optional: the nominal model this one calibrates (built-in name, YAML or URDF)
    units: {length: mm, angle: rad}
    joints:
      - {name: joint1, omega: [0, 0, 1], v: [0, 0, 0], limits: [-2.8973, 2.8973]}
    laser: {omega: [0, 0, 0], v: [0, 0, -1], M: [88, 0, 825]}   # M: aperture at q = 0
    plane: {z: -8}
    home: [...]            # optional: a configuration the aiming IK starts from
    tool: {point: [...]}   # optional: a tool point at q = 0, for point measurements
    ee: {M: [[...], ...]}  # optional: full end-effector frame at q = 0 (4x4, mm), full-pose models
    targets: {T1: [...]}   # optional: targets on the last link at q = 0 (mm, base), position models
    sensor: {T: [[...]]}   # optional: ^S T_base, the base frame in the 3-D sensor's frame (4x4, mm)
    urdf: {file, base_link, tip_link}  # optional: the URDF the model came from (export keeps it)
    links: [...]           # optional: masses (kg) and centres of mass at q = 0 (mm)
    extensions: {}         # optional: non-geometric parameters (see solver.effects)
    prior: {}              # optional: manufacturing tolerances, every fit's prior (solver.identify.prior)
    sheet: {x_mm, y_mm, yaw_deg, scale_x, scale_y}  # `solve`, a sheet session: pose, print scale (S1, S3)
    sheet_std: {x_mm, y_mm, yaw_deg, scale_x, scale_y}  # its standard deviations
    identification: {}     # written by `lasercal solve`: method, statistics, standard errors

A tree (several tips, e.g. a torso with two arms) and coupled joints (solver.kinematics.tree):
each joint may name its ``parent`` joint (default: the one before it; ``base`` for a root) and the
``link`` it moves; ``type: lateral`` joints (``bends: JOINT``) are the two axes across a joint about
which its link bends (value 0 unless bent); ``commanded: [names]`` lists the joints the captures'
q1..qN command and ``coupling: {JOINT: {COMMANDED: c, ..., offset: b}}`` drives a joint that is not
commanded (q_j = sum_k c_jk q_k + b_j); ``target_links: {TARGET: LINK}`` names the link each target
sits on.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lasercal.solver.kinematics.sheet import SheetPose
from lasercal.solver.whole import dump_yaml

FORMAT = "lasercal-robot/1"


def _frozen(a, shape=None) -> np.ndarray:
    a = np.array(a, dtype=float)
    if shape is not None:
        a = a.reshape(shape)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Link:
    """Inertial data of one link for the gravity model: mass (kg), centre of mass at q = 0 (mm, base)."""

    mass: float
    com: np.ndarray


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A serial arm in minimal-POE form with a laser (a prismatic joint) or a tool point.

    Attributes
    ----------
    name : str
    joint_names : tuple of n str
    screws : (n, 6) array, unit-omega joint screws (omega, v) in the base frame at q = 0, mm
    limits : (n, 2) array, joint limits, rad
    laser_dir : (3,) array, unit direction v_p of the laser screw S_p = (0, v_p) at q = 0
    aperture : (3,) array, M: the laser aperture at q = 0, mm
    plane_z : float or None, height of the table plane, mm
    home : (n,) array or None, a configuration the aiming inverse kinematics starts from, rad
    tool_point : (3,) array or None, a tool point at q = 0 (point measurements), mm
    ee_pose : (4, 4) array or None, end-effector frame M at q = 0 (full-pose models), mm
    targets : dict name -> (3,) array, targets on the last link at q = 0 (position models), mm, base frame
    sensor_pose : (4, 4) array or None, ^S T_base: the base frame seen from the 3-D sensor, mm
    urdf : dict, the URDF the model came from ({file, base_link, tip_link, joints}); empty otherwise
    links : tuple of Link, the gravity model (may be empty)
    extensions : dict, non-geometric parameters by effect name
    prior : dict, tolerances overriding the defaults of :mod:`solver.identify.prior` (mm, rad)
    sheet : SheetPose or None, the printed sheet's pose in the base frame, identified by ``solve``
        (:mod:`solver.kinematics.sheet`); the plane's height is ``plane_z``
    sheet_std : dict or None, its standard deviations {x_mm, y_mm, yaw_deg, scale_x, scale_y}
    identification : dict, metadata written by an identification
    notes : tuple of str, what was corrected on load (never silent)
    nominal : str or None, the nominal model this one calibrates: a built-in name, or a YAML or URDF path
        (relative to the model file's folder); what a controller that keeps the nominal model computes
    parents : tuple of n int, each joint's parent joint (-1: the base); empty: a serial chain
    joint_links : tuple of n str, the link each joint moves (empty: unnamed)
    lateral_of : tuple of n int, for a lateral joint (an axis across a joint about which its link bends,
        value 0 unless bent) the joint it bends, else -1; empty: none
    commanded : tuple of str, the commanded joints (the captures' q1..qN) when they differ from the joints
    coupling : (n, len(commanded)) array or None, q_joint = coupling q_commanded + coupling_offset
    coupling_offset : (n,) array or None, rad
    target_links : dict target -> link name it sits on (default: the last joint's link)
    """

    name: str
    joint_names: tuple
    screws: np.ndarray
    limits: np.ndarray
    laser_dir: np.ndarray
    aperture: np.ndarray
    plane_z: float | None = None
    home: np.ndarray | None = None
    tool_point: np.ndarray | None = None
    ee_pose: np.ndarray | None = None
    targets: dict = field(default_factory=dict)
    sensor_pose: np.ndarray | None = None
    urdf: dict = field(default_factory=dict)
    links: tuple = ()
    extensions: dict = field(default_factory=dict)
    prior: dict = field(default_factory=dict)
    sheet: SheetPose | None = None
    sheet_std: dict | None = None
    identification: dict = field(default_factory=dict)
    notes: tuple = ()
    nominal: str | None = None
    parents: tuple = ()
    joint_links: tuple = ()
    lateral_of: tuple = ()
    commanded: tuple = ()
    coupling: np.ndarray | None = None
    coupling_offset: np.ndarray | None = None
    target_links: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.screws.shape[0]

    @property
    def prismatic(self) -> np.ndarray:
        """(n,) bool: joints whose screw has omega = 0 (prismatic; their values in mm)."""
        return np.linalg.norm(self.screws[:, :3], axis=1) < 0.5

    def replace(self, **changes) -> RobotModel:
        """A copy with some fields changed (arrays are frozen again)."""
        for k in (
            "screws",
            "limits",
            "laser_dir",
            "aperture",
            "home",
            "tool_point",
            "ee_pose",
            "sensor_pose",
            "coupling",
            "coupling_offset",
        ):
            if k in changes and changes[k] is not None:
                changes[k] = _frozen(changes[k])
        if "targets" in changes:
            changes["targets"] = {str(k): _frozen(v) for k, v in changes["targets"].items()}
        return dataclasses.replace(self, **changes)

    @property
    def n_commanded(self) -> int:
        """Number of commanded joints: the captures' q1..qN (n without a coupling)."""
        return self.n if self.coupling is None else self.coupling.shape[1]

    @property
    def is_tree(self) -> bool:
        """Whether the joints form a tree (or carry lateral or coupled joints) rather than one plain chain."""
        return bool(self.parents) or self.coupling is not None

    @property
    def real(self) -> np.ndarray:
        """(n,) bool: joints that turn (or slide), as opposed to lateral axes that only bend."""
        return np.array(self.lateral_of, dtype=int) < 0 if self.lateral_of else np.ones(self.n, bool)

    def described(self, q_commanded: np.ndarray) -> np.ndarray:
        """The joints' values (m, n) from the commanded ones (m, n_commanded): q = C q_cmd + b (rad)."""
        q = np.atleast_2d(np.asarray(q_commanded, dtype=float))
        if self.coupling is None:
            return q
        return q @ self.coupling.T + self.coupling_offset

    def within_limits(self, q: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean (m,) mask: every joint of each configuration inside its limits (minus margin, rad)."""
        q = np.atleast_2d(q)
        return np.all((q >= self.limits[:, 0] + margin) & (q <= self.limits[:, 1] - margin), axis=1)

    # ---------------------------------------------------------------- YAML
    def to_dict(self) -> dict:
        """The YAML-ready mapping of this model (format lasercal-robot/1)."""
        r = lambda a: [float(round(x, 12)) for x in np.asarray(a).ravel()]  # noqa: E731
        d: dict[str, Any] = {
            "format": FORMAT,
            "name": self.name,
        }
        if self.nominal is not None:
            d["nominal"] = self.nominal
        d["units"] = {"length": "mm", "angle": "rad", "mass": "kg"}
        d["joints"] = [
            {"name": nm, "omega": r(S[:3]), "v": r(S[3:]), "limits": r(lim)}
            | ({"type": "prismatic"} if pr else {})
            for nm, S, lim, pr in zip(self.joint_names, self.screws, self.limits, self.prismatic)
        ]
        for i, j in enumerate(d["joints"]):  # a tree's structure, when it is one
            if self.parents and self.parents[i] != i - 1:
                j["parent"] = "base" if self.parents[i] < 0 else self.joint_names[self.parents[i]]
            if self.joint_links:
                j["link"] = self.joint_links[i]
            if self.lateral_of and self.lateral_of[i] >= 0:
                j["type"], j["bends"] = "lateral", self.joint_names[self.lateral_of[i]]
        if self.coupling is not None:
            d["commanded"] = list(self.commanded)
            d["coupling"] = {
                nm: {c: float(round(v, 12)) for c, v in zip(self.commanded, row) if v != 0}
                | ({"offset": float(round(b, 12))} if b != 0 else {})
                for nm, row, b in zip(self.joint_names, self.coupling, self.coupling_offset)
                if nm not in self.commanded and (np.any(row != 0) or b != 0)
            }
        d["laser"] = {"omega": [0.0, 0.0, 0.0], "v": r(self.laser_dir), "M": r(self.aperture)}
        if self.plane_z is not None:
            d["plane"] = {"z": float(self.plane_z)}
        if self.home is not None:
            d["home"] = r(self.home)
        if self.tool_point is not None:
            d["tool"] = {"point": r(self.tool_point)}
        if self.ee_pose is not None:
            d["ee"] = {"M": [r(row) for row in self.ee_pose]}
        if self.targets:
            d["targets"] = {k: r(v) for k, v in self.targets.items()}
        if self.sensor_pose is not None:
            d["sensor"] = {"T": [r(row) for row in self.sensor_pose]}
        if self.target_links:
            d["target_links"] = dict(self.target_links)
        if self.urdf:
            d["urdf"] = dict(self.urdf)
        if self.links:
            d["links"] = [{"mass": float(lk.mass), "com": r(lk.com)} for lk in self.links]
        if self.extensions:
            d["extensions"] = self.extensions
        if self.prior:
            d["prior"] = dict(self.prior)
        if self.sheet is not None:
            d["sheet"] = self.sheet.as_dict()
            if self.sheet_std is not None:
                d["sheet_std"] = {k: float(round(v, 9)) for k, v in self.sheet_std.items()}
        if self.identification:
            d["identification"] = self.identification
        if self.notes:
            d["notes"] = list(self.notes)
        return d

    def save(self, path) -> None:
        """Write the model as YAML."""
        Path(path).write_text(dump_yaml(self.to_dict(), sort_keys=False, width=120))
