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
    sheet: {x_mm, y_mm, yaw_deg}      # written by `solve` for a sheet session: the sheet's pose (eq. S1)
    sheet_std: {x_mm, y_mm, yaw_deg}  # its standard deviations
    identification: {}     # written by `lasercal solve`: method, statistics, standard errors
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lasercal.solver.kinematics.sheet import SheetPose

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
    sheet_std : dict or None, its standard deviations {x_mm, y_mm, yaw_deg}
    identification : dict, metadata written by an identification
    notes : tuple of str, what was corrected on load (never silent)
    nominal : str or None, the nominal model this one calibrates: a built-in name, or a YAML or URDF path
        (relative to the model file's folder); what a controller that keeps the nominal model computes
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
        ):
            if k in changes and changes[k] is not None:
                changes[k] = _frozen(changes[k])
        if "targets" in changes:
            changes["targets"] = {str(k): _frozen(v) for k, v in changes["targets"].items()}
        return dataclasses.replace(self, **changes)

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
        Path(path).write_text(yaml.safe_dump(self.to_dict(), sort_keys=False, width=120))
