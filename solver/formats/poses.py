"""Pose sessions: the full pose of a frame on the tool measured by a 6-DoF sensor (tracker + probe, camera).

``session.yaml``: ``format: lasercal-session/1``, ``units`` (mm, rad), ``measurement: pose``, ``robot``
(a name, a model YAML or a URDF); optional ``sensor`` and ``source`` (free text), ``clock: order``.

``captures.csv``: ``q1..qN,x,y,z,rx,ry,rz`` -- the joint angles (rad) and the measured frame in the sensor's
frame: origin x, y, z (mm) and orientation rx, ry, rz (rad, a rotation vector: axis times angle, as
``correct`` reads goals); optional ``sx,sy,sz`` (mm) and ``srx,sry,srz`` (rad), the stated standard
deviations, ``t`` (the row order or s), ``temperature`` (deg C); other columns pass through.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.captures import (
    SESSION_FORMAT,
    UNITS,
    _joint_columns,
    _numeric_block,
    check_limits,
)
from lasercal.solver.formats.checks import metres_hint
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.table import read_csv
from lasercal.solver.formats.tolerances import Tolerances, robot_tolerances
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.whole import dump_yaml

POSE = ("x", "y", "z", "rx", "ry", "rz")
STD = ("sx", "sy", "sz", "srx", "sry", "srz")
MAX_ROTVEC = np.pi + 1e-6  # a rotation vector longer than pi rad: degrees, or not a rotation vector


@dataclass(frozen=True, eq=False)
class PoseSession:
    """Measured full poses of one session (one sensor placement, one tool mounting).

    Attributes
    ----------
    path : Path, the session folder
    meta : dict, the parsed session.yaml
    robot : RobotModel, the nominal
    q : (m, n) array, rad
    T : (m, 4, 4) array, the measured frames in the sensor frame, mm
    std : (m, 6) array or None, stated standard deviations (x, y, z mm; rx, ry, rz rad)
    t : (m,) array, the row order (or s)
    temperature : (m,) array or None, deg C
    lines : (m,) int array, the CSV line of each capture
    header, rows : the CSV's columns and cells (``predict`` passes them through)
    tolerances : Tolerances or None, the prior (default the robot's own)
    """

    path: Path
    meta: dict
    robot: RobotModel
    q: np.ndarray
    T: np.ndarray
    std: np.ndarray | None
    t: np.ndarray
    temperature: np.ndarray | None
    lines: np.ndarray
    header: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    tolerances: Tolerances | None = None

    @property
    def m(self) -> int:
        """Number of captures."""
        return len(self.q)

    @property
    def name(self) -> str:
        """The session's name: its folder's."""
        return self.path.name

    def subset(self, rows: np.ndarray) -> PoseSession:
        """The session restricted to some captures (index or mask)."""
        idx = np.arange(self.m)[rows]
        pick = lambda a: None if a is None else a[idx]  # noqa: E731
        return PoseSession(
            self.path,
            self.meta,
            self.robot,
            self.q[idx],
            self.T[idx],
            pick(self.std),
            self.t[idx],
            pick(self.temperature),
            self.lines[idx],
            self.header,
            [self.rows[i] for i in idx] if self.rows else [],
            self.tolerances,
        )


def frames_from_pose(pose: np.ndarray) -> np.ndarray:
    """(m, 4, 4) frames from (m, 6) rows x, y, z (mm), rx, ry, rz (rad, rotation vector)."""
    T = np.tile(np.eye(4), (len(pose), 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(pose[:, 3:]).as_matrix()
    T[:, :3, 3] = pose[:, :3]
    return T


def pose_from_frames(T: np.ndarray) -> np.ndarray:
    """(m, 6) rows x, y, z (mm), rx, ry, rz (rad, rotation vector) of (m, 4, 4) frames."""
    return np.hstack([T[:, :3, 3], Rotation.from_matrix(T[:, :3, :3]).as_rotvec()])


def is_pose_session(folder) -> bool:
    """Whether a folder's session.yaml says ``measurement: pose`` (False when it cannot be read)."""
    try:
        meta = yaml.safe_load((Path(folder) / "session.yaml").read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        return False
    return isinstance(meta, dict) and meta.get("measurement") == "pose"


def load_pose_session(folder, robot=None) -> PoseSession:
    """Load and validate a pose session folder (module docstring).

    Parameters
    ----------
    folder : str or Path
    robot : str or Path, optional, a robot in place of the session's ``robot``

    Raises
    ------
    FormatError
        Naming file, line and column of the first problem.
    """
    from lasercal.solver.formats.session import session_yaml

    folder = Path(folder)
    meta, ypath, cpath = session_yaml(folder)
    if meta.get("measurement") != "pose":
        raise FormatError(
            ypath, f"expected 'measurement: pose', got {meta.get('measurement')!r}", field="measurement"
        )
    if robot is not None:
        model = load_model(robot)
    elif "robot" not in meta:
        raise FormatError(ypath, "missing 'robot' (a name under data/robots/ or a path)", field="robot")
    else:
        model = load_model(meta["robot"], base=folder)
    header, rows = read_csv(cpath)
    if not rows:
        raise FormatError(cpath, "no captures", line=2)
    q = _numeric_block(cpath, rows, header, _joint_columns("q", model.n))
    pose = _numeric_block(cpath, rows, header, list(POSE))
    lines = np.array([ln for ln, _ in rows], dtype=int)
    hint = metres_hint(pose[:, :3])
    if hint:
        raise FormatError(cpath, f"measured positions: {hint}", field="x")
    far = np.linalg.norm(pose[:, 3:], axis=1) > MAX_ROTVEC
    if far.any():
        i = int(np.argmax(far))
        raise FormatError(
            cpath,
            f"rotation vector of length {np.linalg.norm(pose[i, 3:]):.4g} rad > pi: rx, ry, rz must be a "
            "rotation "
            "vector in rad (not Euler angles in degrees)",
            line=int(lines[i]),
            field="rx",
        )
    std = _numeric_block(cpath, rows, header, list(STD), required=False)
    if std is not None and np.any(std < 0):
        r, c = np.argwhere(std < 0)[0]
        raise FormatError(cpath, "a standard deviation must be >= 0", line=int(lines[r]), field=STD[c])
    t = _numeric_block(cpath, rows, header, ["t"], required=False)
    temp = _numeric_block(cpath, rows, header, ["temperature"], required=False)
    check_limits(cpath, model, q, lines)
    return PoseSession(
        folder,
        meta,
        model,
        q,
        frames_from_pose(pose),
        std,
        np.arange(len(q), dtype=float) if t is None else t[:, 0],
        None if temp is None else temp[:, 0],
        lines,
        header,
        [r for _, r in rows],
        robot_tolerances(model),
    )


def pose_meta(robot_ref: str, **extra) -> dict:
    """The session.yaml mapping of a pose session."""
    meta = {
        "format": SESSION_FORMAT,
        "robot": str(robot_ref),
        "units": dict(UNITS) | {"temperature": "degC"},
        "measurement": "pose",
        "clock": "order",
    }
    meta.update(extra)
    return meta


def write_pose_session(folder, meta: dict, q, T, std=None, t=None, temperature=None) -> Path:
    """Write a pose session folder (captures.csv: q1..qN,t[,temperature],x,y,z,rx,ry,rz[,sx..srz])."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "session.yaml").write_text(dump_yaml(meta, sort_keys=False, width=120))  # whole: a cut shows
    q = np.atleast_2d(q)
    t = np.arange(len(q), dtype=float) if t is None else np.asarray(t, float)
    cols = [q, t[:, None]]
    header = _joint_columns("q", q.shape[1]) + ["t"]
    if temperature is not None:
        cols.append(np.asarray(temperature, float)[:, None])
        header.append("temperature")
    cols.append(pose_from_frames(T))
    header += list(POSE)
    if std is not None:
        cols.append(np.asarray(std, float))
        header += list(STD)
    data = np.hstack(cols)
    with open(folder / "captures.csv", "w", newline="") as f:
        f.write(",".join(header) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.17g")
    return folder


def write_pose_rows(out, header: list, rows: list, T: np.ndarray) -> None:
    """``predict``'s output: each input row followed by x, y, z (mm), rx, ry, rz (rad) of its frame."""
    w = csv.writer(out, lineterminator="\n")
    w.writerow(list(header) + list(POSE))
    for row, p in zip(rows, pose_from_frames(T)):
        w.writerow(list(row) + [f"{c:.6f}" if k < 3 else f"{c:.9f}" for k, c in enumerate(p)])
