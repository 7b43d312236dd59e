"""Robot model files: ``lasercal-robot/1`` YAML (mm, rad) parsed and validated into a RobotModel.

Built-in robots live in the package's data (``lasercal.data``, found with importlib.resources),
so an installed wheel finds them from any folder.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError, warn
from lasercal.solver.formats.checks import (
    Range,
    load_yaml,
    metres_hint,
    radians_hint,
    sheet_pose_problem,
)
from lasercal.solver.formats.data import resolve
from lasercal.solver.formats.tolerances import DEFAULTS
from lasercal.solver.kinematics.effects import extension_from_model
from lasercal.solver.kinematics.minimal import normalise_screw
from lasercal.solver.kinematics.model import FORMAT, Link, RobotModel, _frozen
from lasercal.solver.kinematics.sheet import KEYS as SHEET_KEYS
from lasercal.solver.kinematics.sheet import SCALE_KEYS, SHAPE_KEYS, TILT_KEYS, SheetPose

PLANE_Z = Range(-5000.0, 5000.0, "mm")
MASS = Range(0.0, 1000.0, "kg")
_TOL_UNIT = 1e-6  # a printed axis further than this from unit length is reported
MAX_ABS = 1e6  # no number of a robot file (mm, rad, kg) is this large: 1e308 is a typing accident


def _vec(d: dict, key: str, n: int, path, where: str) -> np.ndarray:
    if key not in d:
        raise FormatError(path, f"missing '{key}' in {where}", field=f"{where}.{key}")
    try:
        a = np.array(d[key], dtype=float).ravel()
    except (TypeError, ValueError):
        raise FormatError(path, f"'{key}' in {where} must be {n} numbers", field=f"{where}.{key}") from None
    if a.size != n or not np.all(np.abs(a) <= MAX_ABS):  # NaN fails the test too
        raise FormatError(
            path,
            f"'{key}' in {where} must be {n} finite numbers within +-{MAX_ABS:g}, got {d[key]!r}",
            field=f"{where}.{key}",
        )
    return a


def _checked_screw(w, v, path, where: str, notes: list) -> np.ndarray:
    S, norm_err, pitch = normalise_screw(np.concatenate([w, v]))
    if norm_err > _TOL_UNIT or abs(pitch) > 1e-6:
        notes.append(
            f"{where}: printed axis has |axis| off unit by {norm_err:.3g} and pitch {pitch:.3g} mm; "
            "normalised on load"
        )
    return S


def sheet_values(d: dict, key: str, path, partial: bool = False, scale: float = 1.0) -> list | None:
    """A mapping ``d[key]`` {x_mm, y_mm, yaw_deg[, scale_x, scale_y, tilt_x_rad, tilt_y_rad, shear,
    curl_xx_per_mm, curl_xy_per_mm, curl_yy_per_mm]} (a sheet's pose or its standard deviations) as eleven
    finite numbers (None if absent; a pose key left out is 0 when ``partial``, a scale left out is
    ``scale``: 1 for a pose, an exact print; 0 for its standard deviation; a tilt or shape key left out 0:
    level, square and flat, as files written before the shape was modelled say)."""
    m = d.get(key)
    if m is None:
        return None
    keys = SHEET_KEYS + SCALE_KEYS + TILT_KEYS + SHAPE_KEYS
    if not isinstance(m, dict) or set(m) - set(keys) or (not partial and set(SHEET_KEYS) - set(m)):
        raise FormatError(
            path,
            f"'{key}' must be a mapping {{x_mm, y_mm, yaw_deg[, scale_x, scale_y, tilt_x_rad, tilt_y_rad, "
            "shear, curl_xx_per_mm, curl_xy_per_mm, curl_yy_per_mm]}",
            field=key,
        )
    vals = []
    for k in keys:
        try:
            v = (
                float(m.get(k, scale if k in SCALE_KEYS else 0.0))
                if not isinstance(m.get(k), bool)
                else math.nan
            )
        except (TypeError, ValueError):
            v = math.nan
        if not math.isfinite(v):
            raise FormatError(path, f"{m.get(k)!r} (expected a finite number)", field=f"{key}.{k}")
        vals.append(v)
    return vals


def sheet_pose(d: dict, key: str, path, placement: bool = False) -> SheetPose | None:
    """A sheet's pose ``d[key]`` (None if absent), checked by :func:`~checks.sheet_pose_problem`.

    ``placement``: a person's rough placement in the base frame (a layout's or session's ``sheet``; keys
    may be left out): metres refused, a yaw in radians warned about. Else an identified pose (a model's).
    """
    vals = sheet_values(d, key, path, partial=placement)
    if vals is None:
        return None
    bad = sheet_pose_problem(vals[:3], absolute=placement)
    if bad:
        raise FormatError(path, bad[1], field=key if bad[0] is None else f"{key}.{SHEET_KEYS[bad[0]]}")
    for k, v in zip(TILT_KEYS, vals[5:]):
        if not abs(v) < 0.1:  # a table a few mrad off level: degrees or a slope in percent written here
            raise FormatError(path, f"{v:g} (expected a tilt in rad, a few 0.001)", field=f"{key}.{k}")
    for k, v in zip(SHAPE_KEYS, vals[7:]):
        if not abs(v) < (0.1 if k == "shear" else 0.01):  # a shear in mm per m or a curvature in 1/m here
            raise FormatError(
                path,
                f"{v:g} (expected a print's shear in mm per mm, a few 0.001)"
                if k == "shear"
                else f"{v:g} (expected a sheet's curvature in 1/mm, a few 1e-5)",
                field=f"{key}.{k}",
            )
    for k, v in zip(SCALE_KEYS, vals[3:5]):
        if not 0.9 < v < 1.1:  # a printer scales by a few 0.1 %: a percentage or a ppm figure written here
            raise FormatError(
                path, f"{v:g} (expected a printer's scale factor, 1 for an exact print)", field=f"{key}.{k}"
            )
    hint = radians_hint(vals[2]) if placement else None
    if hint:
        warn(f"{path}, field '{key}.yaw_deg': {hint}")
    return SheetPose(*vals)


def model_from_dict(d: dict, path="<model>") -> RobotModel:
    """Build and validate a :class:`RobotModel` from a parsed YAML mapping."""
    if not isinstance(d, dict):
        raise FormatError(
            path, "not a robot model: expected a lasercal-robot/1 YAML mapping (or a URDF file, *.urdf)"
        )
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
        prismatic = j.get("type", "revolute") == "prismatic"
        if prismatic and np.linalg.norm(w) > 0:
            raise FormatError(path, "a prismatic joint's omega must be [0, 0, 0]", field=f"{where}.omega")
        if not prismatic and np.linalg.norm(w) < 0.5:
            raise FormatError(
                path,
                "joint axis omega must be (close to) a unit vector (or give type: prismatic)",
                field=f"{where}.omega",
            )
        screws.append(
            _checked_screw(w, _vec(j, "v", 3, path, where), path, f"{where} ({j.get('name', i + 1)})", notes)
        )
        lim = _vec(j, "limits", 2, path, where)
        if not lim[0] < lim[1]:
            raise FormatError(
                path, "limits must be [lower, upper] with lower < upper", field=f"{where}.limits"
            )
        if not prismatic and np.abs(lim).max() > 4 * np.pi:  # a prismatic joint's limits are mm
            raise FormatError(
                path,
                f"limits {lim.tolist()} look like degrees (expected rad, within +-4 pi)",
                field=f"{where}.limits",
            )
        limits.append(lim)
        names.append(str(j.get("name", f"joint{i + 1}")))
    n = len(screws)
    tree = tree_structure(d, joints, names, path)
    laser = d.get("laser")
    if laser is None and isinstance(d.get("targets"), dict) and d["targets"]:
        # a position robot (targets measured by a 3-D sensor) has no laser: a stand-in, never used
        laser = {"v": [0, 0, 1], "M": np.mean([np.ravel(v) for v in d["targets"].values()], axis=0).tolist()}
    if not isinstance(laser, dict):
        raise FormatError(path, "missing 'laser' mapping (omega, v, M)", field="laser")
    lw = _vec(laser, "omega", 3, path, "laser") if "omega" in laser else np.zeros(3)
    if np.linalg.norm(lw) > 0:
        raise FormatError(
            path, "the laser is a prismatic joint: its omega must be [0, 0, 0]", field="laser.omega"
        )
    lv = _vec(laser, "v", 3, path, "laser")
    if np.linalg.norm(lv) < 0.5:
        raise FormatError(path, "laser direction v must be (close to) a unit vector", field="laser.v")
    laser_S = _checked_screw(np.zeros(3), lv, path, "laser", notes)
    aperture = _vec(laser, "M", 3, path, "laser")
    hint = metres_hint(aperture)
    if hint:
        raise FormatError(path, f"aperture {aperture.tolist()}: {hint}", field="laser.M")
    plane = d.get("plane")
    plane_z = None
    if isinstance(plane, dict) and "z" in plane:
        msg = PLANE_Z.problem(plane["z"])
        if msg:
            raise FormatError(path, f"plane z {msg}", field="plane.z")
        plane_z = float(plane["z"])
    home = _vec(d, "home", n, path, "model") if d.get("home") is not None else None
    lim = np.array(limits)
    if home is not None and np.any((home < lim[:, 0]) | (home > lim[:, 1])):
        j = int(np.argmax((home < lim[:, 0]) | (home > lim[:, 1])))
        raise FormatError(
            path,
            f"home joint {j + 1} = {home[j]:g} rad is outside its limits [{lim[j, 0]:g}, {lim[j, 1]:g}] rad",
            field="home",
        )
    tool = d.get("tool")
    tool_point = (
        _vec(tool, "point", 3, path, "tool")
        if isinstance(tool, dict) and tool.get("point") is not None
        else None
    )
    if tool_point is not None and metres_hint(tool_point):
        raise FormatError(
            path, f"tool point {tool_point.tolist()}: {metres_hint(tool_point)}", field="tool.point"
        )
    ee = d.get("ee")
    ee_pose = None
    if isinstance(ee, dict) and ee.get("M") is not None:
        ee_pose = _vec(ee, "M", 16, path, "ee").reshape(4, 4)
        R = ee_pose[:3, :3]
        if (
            np.abs(R.T @ R - np.eye(3)).max() > 1e-6
            or np.linalg.det(R) < 0
            or np.abs(ee_pose[3] - [0, 0, 0, 1]).max() > 0
        ):
            raise FormatError(
                path, "ee.M must be a rigid transform (orthonormal rotation, last row 0 0 0 1)", field="ee.M"
            )
    targets = {}
    if d.get("targets") is not None:
        if not isinstance(d["targets"], dict):
            raise FormatError(path, "'targets' must be a mapping NAME: [x, y, z] (mm)", field="targets")
        targets = {str(k): _frozen(_vec(d["targets"], k, 3, path, "targets")) for k in d["targets"]}
        hint = metres_hint(np.array(list(targets.values()))) if targets else None
        if hint:
            raise FormatError(path, f"targets: {hint}", field="targets")
    sensor_pose = None
    if isinstance(d.get("sensor"), dict) and d["sensor"].get("T") is not None:
        sensor_pose = _vec(d["sensor"], "T", 16, path, "sensor").reshape(4, 4)
        R = sensor_pose[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise FormatError(path, "sensor.T must be a rigid transform", field="sensor.T")
    links = []
    for i, lk in enumerate(d.get("links", []) or []):
        mass = lk.get("mass") if isinstance(lk, dict) else None
        msg = MASS.problem(mass)
        if msg:
            raise FormatError(path, f"mass {msg}", field=f"links[{i}].mass")
        links.append(Link(float(mass), _frozen(_vec(lk, "com", 3, path, f"links[{i}]"))))
    links = tuple(links)
    if links and len(links) != n:
        raise FormatError(path, f"'links' must have one entry per joint ({n})", field="links")
    extension_from_model(d.get("extensions", {}) or {}, path, n)  # validated here: a NaN never reaches a fit
    prior = d.get("prior") or {}
    DEFAULTS.updated(prior, path)  # validated here too
    sheet, sheet_std = sheet_pose(d, "sheet", path), sheet_values(d, "sheet_std", path, scale=0.0)
    if sheet_std is not None and sheet is None:
        raise FormatError(
            path, "'sheet_std' needs 'sheet' (the pose it is the uncertainty of)", field="sheet_std"
        )
    if sheet_std is not None and min(sheet_std) < 0:
        k = (SHEET_KEYS + SCALE_KEYS + TILT_KEYS + SHAPE_KEYS)[int(np.argmin(sheet_std))]
        raise FormatError(
            path, f"{min(sheet_std):g} (expected a standard deviation >= 0)", field=f"sheet_std.{k}"
        )
    nominal = d.get("nominal")
    if nominal is not None and (not isinstance(nominal, str) or not nominal.strip()):
        raise FormatError(
            path, "'nominal' must name a robot: a built-in name, a model YAML or a URDF", field="nominal"
        )
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
        targets=targets,
        sensor_pose=None if sensor_pose is None else _frozen(sensor_pose),
        urdf=dict(d.get("urdf", {}) or {}),
        links=links,
        extensions=dict(d.get("extensions", {}) or {}),
        prior=dict(prior),
        sheet=sheet,
        sheet_std=None
        if sheet_std is None
        else {
            k: v
            for k, v in zip(SHEET_KEYS + SCALE_KEYS + TILT_KEYS + SHAPE_KEYS, sheet_std)
            if k in d["sheet_std"]
        },
        identification=dict(d.get("identification", {}) or {}),
        notes=tuple(notes),
        nominal=nominal,
        **tree,
    )


def tree_structure(d: dict, joints: list, names: list, path) -> dict:
    """The tree, lateral axes and coupling of a robot file (:mod:`solver.kinematics.model`), validated:
    the RobotModel fields ``parents``, ``joint_links``, ``lateral_of``, ``commanded``, ``coupling``,
    ``coupling_offset`` and ``target_links`` (empty for a plain serial chain)."""
    n = len(names)
    index = {nm: i for i, nm in enumerate(names)}
    if len(index) != n:
        raise FormatError(path, "joint names must be distinct", field="joints")
    keys = ("parent", "link", "bends")
    if not any(k in j for j in joints for k in keys) and not any(
        k in d for k in ("commanded", "coupling", "target_links")
    ):
        return {}
    parents, links, lateral = [], [], []
    for i, j in enumerate(joints):
        where = f"joints[{i}]"
        p = j.get("parent", names[i - 1] if i else "base")
        if p != "base" and (p not in index or index[p] >= i):
            raise FormatError(
                path,
                f"parent {p!r} is not a joint listed before {names[i]!r} (or 'base')",
                field=f"{where}.parent",
            )
        parents.append(-1 if p == "base" else index[p])
        links.append(str(j.get("link", names[i])))
        lateral_joint = j.get("type") == "lateral"
        if lateral_joint != ("bends" in j) or (lateral_joint and j["bends"] not in index):
            raise FormatError(
                path,
                "a lateral joint names the joint it bends ('type: lateral' with 'bends: JOINT')",
                field=where,
            )
        lateral.append(index[j["bends"]] if lateral_joint else -1)
    commanded = d.get("commanded")
    if commanded is None:
        commanded = [nm for nm, lat in zip(names, lateral) if lat < 0]
    if not isinstance(commanded, list) or not all(isinstance(c, str) for c in commanded) or not commanded:
        raise FormatError(path, "'commanded' must list joint names (the captures' q1..qN)", field="commanded")
    cidx = {c: k for k, c in enumerate(commanded)}
    C, b = np.zeros((n, len(commanded))), np.zeros(n)
    for nm in names:
        if nm in cidx:
            C[index[nm], cidx[nm]] = 1.0
    coupling = d.get("coupling") or {}
    if not isinstance(coupling, dict):
        raise FormatError(
            path, "'coupling' must map JOINT: {COMMANDED: coefficient, offset: rad}", field="coupling"
        )
    for nm, terms in coupling.items():
        if nm not in index or nm in cidx or not isinstance(terms, dict):
            raise FormatError(
                path,
                f"coupling {nm!r}: a joint that is not commanded, mapped to its terms",
                field=f"coupling.{nm}",
            )
        for k, v in terms.items():
            if (k != "offset" and k not in cidx) or isinstance(v, bool) or not isinstance(v, (int, float)):
                raise FormatError(
                    path, f"{k}: {v!r} (expected a commanded joint and a number)", field=f"coupling.{nm}.{k}"
                )
            if k == "offset":
                b[index[nm]] = float(v)
            else:
                C[index[nm], cidx[k]] = float(v)
    tl = d.get("target_links") or {}
    if not isinstance(tl, dict) or not all(str(v) in links for v in tl.values()):
        raise FormatError(
            path,
            f"'target_links' must map targets to links ({', '.join(dict.fromkeys(links))})",
            field="target_links",
        )
    return {
        "parents": tuple(parents),
        "joint_links": tuple(links),
        "lateral_of": tuple(lateral),
        "commanded": tuple(commanded),
        "coupling": _frozen(C),
        "coupling_offset": _frozen(b),
        "target_links": {str(k): str(v) for k, v in tl.items()},
    }


def resolve_robot_path(name_or_path, base: Path | None = None) -> Path:
    """A robot file from a built-in name ('panda') or a path (relative to ``base`` first)."""
    return resolve("robots", name_or_path, base)


def load_model(
    name_or_path, base: Path | None = None, base_link: str | None = None, tip_link: str | None = None
) -> RobotModel:
    """Load and validate a robot model by name ('panda', 'puma560', ...) or path.

    Parameters
    ----------
    name_or_path : str or Path, a built-in name, a ``lasercal-robot/1`` YAML or a ``.urdf``
        (:func:`solver.formats.urdf.load_urdf`, the chain from ``base_link`` to ``tip_link``)
    base : Path, optional, the folder a relative path is tried in first (e.g. the session's)
    base_link, tip_link : str, optional, the URDF chain's ends (only for a URDF)

    Returns
    -------
    RobotModel
    """
    ref = str(name_or_path)
    if ref.lower().endswith(".xacro"):
        raise FormatError(ref, "a xacro file: expand it to a URDF first (xacro FILE.urdf.xacro > FILE.urdf)")
    if ref.lower().endswith(".urdf"):
        from lasercal.solver.formats.urdf import load_urdf

        p = Path(ref)
        if not p.is_absolute() and base is not None and ((Path(base) / p).exists() or not p.exists()):
            p = Path(base) / p  # relative to the file that names it (a missing one is reported there)
        return load_urdf(p, base_link, tip_link)
    path = resolve_robot_path(name_or_path, base)
    model = model_from_dict(load_yaml(path), path)
    for key, link in (("base_link", base_link), ("tip_link", tip_link)):
        if link is not None:
            raise FormatError(
                path, f"{key} {link!r} names a URDF link, but this robot is not a URDF", field=key
            )
    return model
