"""Robot model: joint screws, limits, the laser (or tool point), loaded from YAML and validated.

File format ``lasercal-robot/1`` (mm, rad), see README "Robot model":

.. code-block:: yaml

    format: lasercal-robot/1
    name: panda
    units: {length: mm, angle: rad}
    joints:
      - {name: joint1, omega: [0, 0, 1], v: [0, 0, 0], limits: [-2.8973, 2.8973]}
    laser: {omega: [0, 0, 0], v: [0, 0, -1], M: [88, 0, 825]}   # M: aperture at q = 0
    plane: {z: -8}
    home: [...]            # optional: a configuration the aiming IK starts from
    tool: {point: [...]}   # optional: a tool point at q = 0, for point measurements
    ee: {M: [[...], ...]}  # optional: full end-effector frame at q = 0 (4x4, mm), full-pose models
    links: [...]           # optional: masses (kg) and centres of mass at q = 0 (mm)
    extensions: {}         # optional: non-geometric parameters (see solver.effects)
    identification: {}     # written by `lasercal solve`: method, statistics, standard errors
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .errors import FormatError
from .minimal import normalise_screw

FORMAT = "lasercal-robot/1"
DATA_DIR = Path(__file__).resolve().parent.parent / "data"
_TOL_UNIT = 1e-6  # a printed axis further than this from unit length is reported


def _frozen(a, shape=None) -> np.ndarray:
    a = np.array(a, dtype=float)
    if shape is not None:
        a = a.reshape(shape)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Link:
    """Inertial data of one link for the gravity model: mass (kg), centre of mass at q = 0 (mm, base frame)."""

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
    links : tuple of Link, the gravity model (may be empty)
    extensions : dict, non-geometric parameters by effect name
    identification : dict, metadata written by an identification
    notes : tuple of str, what was corrected on load (never silent)
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
    links: tuple = ()
    extensions: dict = field(default_factory=dict)
    identification: dict = field(default_factory=dict)
    notes: tuple = ()

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.screws.shape[0]

    def replace(self, **changes) -> "RobotModel":
        """A copy with some fields changed (arrays are frozen again)."""
        for k in ("screws", "limits", "laser_dir", "aperture", "home", "tool_point", "ee_pose"):
            if k in changes and changes[k] is not None:
                changes[k] = _frozen(changes[k])
        return dataclasses.replace(self, **changes)

    def within_limits(self, q: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean (m,) mask: every joint of each configuration inside its limits (minus margin, rad)."""
        q = np.atleast_2d(q)
        return np.all((q >= self.limits[:, 0] + margin) & (q <= self.limits[:, 1] - margin), axis=1)

    # ---------------------------------------------------------------- YAML
    def to_dict(self) -> dict:
        """The YAML-ready mapping of this model (format lasercal-robot/1)."""
        r = lambda a: [float(round(x, 12)) for x in np.asarray(a).ravel()]  # noqa: E731
        d: dict[str, Any] = {"format": FORMAT, "name": self.name, "units": {"length": "mm", "angle": "rad", "mass": "kg"}}
        d["joints"] = [
            {"name": nm, "omega": r(S[:3]), "v": r(S[3:]), "limits": r(lim)}
            for nm, S, lim in zip(self.joint_names, self.screws, self.limits)
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
        if self.links:
            d["links"] = [{"mass": float(lk.mass), "com": r(lk.com)} for lk in self.links]
        if self.extensions:
            d["extensions"] = self.extensions
        if self.identification:
            d["identification"] = self.identification
        if self.notes:
            d["notes"] = list(self.notes)
        return d

    def save(self, path) -> None:
        """Write the model as YAML."""
        Path(path).write_text(yaml.safe_dump(self.to_dict(), sort_keys=False, width=120))


def _vec(d: dict, key: str, n: int, path, where: str) -> np.ndarray:
    if key not in d:
        raise FormatError(path, f"missing '{key}' in {where}", field=f"{where}.{key}")
    try:
        a = np.array(d[key], dtype=float).ravel()
    except (TypeError, ValueError):
        raise FormatError(path, f"'{key}' in {where} must be {n} numbers", field=f"{where}.{key}") from None
    if a.size != n or not np.all(np.isfinite(a)):
        raise FormatError(path, f"'{key}' in {where} must be {n} finite numbers, got {d[key]!r}", field=f"{where}.{key}")
    return a


def _checked_screw(w, v, path, where: str, notes: list) -> np.ndarray:
    S, norm_err, pitch = normalise_screw(np.concatenate([w, v]))
    if norm_err > _TOL_UNIT or abs(pitch) > 1e-6:
        notes.append(f"{where}: printed axis has |axis| off unit by {norm_err:.3g} and pitch {pitch:.3g} mm; normalised on load")
    return S


def model_from_dict(d: dict, path="<model>") -> RobotModel:
    """Build and validate a :class:`RobotModel` from a parsed YAML mapping."""
    if not isinstance(d, dict):
        raise FormatError(path, "a robot model must be a YAML mapping")
    fmt = d.get("format", FORMAT)
    if fmt != FORMAT:
        raise FormatError(path, f"unsupported format {fmt!r} (expected {FORMAT})", field="format")
    units = d.get("units", {}) or {}
    if units.get("length", "mm") != "mm" or units.get("angle", "rad") != "rad":
        raise FormatError(path, "only length: mm and angle: rad are supported", field="units")
    joints = d.get("joints")
    if not isinstance(joints, list) or not joints:
        raise FormatError(path, "'joints' must be a non-empty list", field="joints")
    notes: list[str] = list(d.get("notes", []) or [])
    names, screws, limits = [], [], []
    for i, j in enumerate(joints):
        where = f"joints[{i}]"
        if not isinstance(j, dict):
            raise FormatError(path, "each joint must be a mapping", field=where)
        w = _vec(j, "omega", 3, path, where)
        if np.linalg.norm(w) < 0.5:
            raise FormatError(path, "joint axis omega must be (close to) a unit vector; only revolute arm joints are supported", field=f"{where}.omega")
        screws.append(_checked_screw(w, _vec(j, "v", 3, path, where), path, f"{where} ({j.get('name', i + 1)})", notes))
        lim = _vec(j, "limits", 2, path, where)
        if not lim[0] < lim[1]:
            raise FormatError(path, "limits must be [lower, upper] with lower < upper", field=f"{where}.limits")
        limits.append(lim)
        names.append(str(j.get("name", f"joint{i + 1}")))
    n = len(screws)
    laser = d.get("laser")
    if not isinstance(laser, dict):
        raise FormatError(path, "missing 'laser' mapping (omega, v, M)", field="laser")
    lw = np.array(laser.get("omega", [0, 0, 0]), dtype=float)
    if np.linalg.norm(lw) > 0:
        raise FormatError(path, "the laser is a prismatic joint: its omega must be [0, 0, 0]", field="laser.omega")
    lv = _vec(laser, "v", 3, path, "laser")
    if np.linalg.norm(lv) < 0.5:
        raise FormatError(path, "laser direction v must be (close to) a unit vector", field="laser.v")
    laser_S = _checked_screw(np.zeros(3), lv, path, "laser", notes)
    aperture = _vec(laser, "M", 3, path, "laser")
    plane = d.get("plane")
    plane_z = float(plane["z"]) if isinstance(plane, dict) and "z" in plane else None
    home = _vec(d, "home", n, path, "model") if d.get("home") is not None else None
    tool = d.get("tool")
    tool_point = _vec(tool, "point", 3, path, "tool") if isinstance(tool, dict) and tool.get("point") is not None else None
    ee = d.get("ee")
    ee_pose = None
    if isinstance(ee, dict) and ee.get("M") is not None:
        ee_pose = _vec(ee, "M", 16, path, "ee").reshape(4, 4)
        R = ee_pose[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0 or np.abs(ee_pose[3] - [0, 0, 0, 1]).max() > 0:
            raise FormatError(path, "ee.M must be a rigid transform (orthonormal rotation, last row 0 0 0 1)", field="ee.M")
    links = tuple(
        Link(float(lk["mass"]), _frozen(_vec(lk, "com", 3, path, f"links[{i}]"))) for i, lk in enumerate(d.get("links", []) or [])
    )
    if links and len(links) != n:
        raise FormatError(path, f"'links' must have one entry per joint ({n})", field="links")
    return RobotModel(
        name=str(d.get("name", Path(str(path)).stem)),
        joint_names=tuple(names),
        screws=_frozen(screws),
        limits=_frozen(limits),
        laser_dir=_frozen(laser_S[3:]),
        aperture=_frozen(aperture),
        plane_z=plane_z,
        home=None if home is None else _frozen(home),
        tool_point=None if tool_point is None else _frozen(tool_point),
        ee_pose=None if ee_pose is None else _frozen(ee_pose),
        links=links,
        extensions=dict(d.get("extensions", {}) or {}),
        identification=dict(d.get("identification", {}) or {}),
        notes=tuple(notes),
    )


def resolve_robot_path(name_or_path, base: Path | None = None) -> Path:
    """A robot file from a name under data/robots/ ('panda') or a path (relative to base)."""
    p = Path(str(name_or_path))
    candidates = [p] if p.is_absolute() else ([base / p] if base else []) + [p, DATA_DIR / "robots" / p, DATA_DIR / "robots" / f"{p}.yaml"]
    for c in candidates:
        if c.is_file():
            return c
    known = ", ".join(sorted(f.stem for f in (DATA_DIR / "robots").glob("*.yaml")))
    raise FormatError(name_or_path, f"no such robot file or name (built-in robots: {known})")


def load_yaml(path) -> Any:
    """Parse a YAML file, turning I/O and syntax errors into a FormatError with the line."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise FormatError(path, f"cannot read file ({e.strerror})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        raise FormatError(path, f"invalid YAML: {getattr(e, 'problem', e)}", line=None if mark is None else mark.line + 1) from None


def load_model(name_or_path, base: Path | None = None) -> RobotModel:
    """Load and validate a robot model by name ('panda', 'puma560', ...) or path."""
    path = resolve_robot_path(name_or_path, base)
    return model_from_dict(load_yaml(path), path)
