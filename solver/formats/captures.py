"""The capture table every kind of session shares: the :class:`Session` record, the format's name and
units, the joint columns, numeric columns read with errors naming line and column, the checks of logged
joint angles (limits, repeated captures), rows written at full precision.

Laser and point sessions are read by :mod:`solver.formats.session`, position sessions by
:mod:`solver.formats.positions`; both build a :class:`Session`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError, warn
from lasercal.solver.formats.checks import degrees_hint
from lasercal.solver.formats.tolerances import Tolerances, robot_tolerances
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.sheet import SheetPose

SESSION_FORMAT = "lasercal-session/1"
UNITS = {"length": "mm", "angle": "rad", "torque": "Nm", "time": "s"}
_LIMIT_TOL = 1e-6  # rad: logged angles are allowed to sit on a limit up to rounding
# A measured angle beyond a (URDF-rounded) limit by at most this much is kept with a warning: measured
# data is the truth. Further out (a column or unit mistake) it is refused. The slack is the smaller of
# LIMIT_SLACK_RAD and LIMIT_SLACK_FRACTION of the joint's range (mm for a prismatic joint).
LIMIT_SLACK_RAD = 0.1
LIMIT_SLACK_FRACTION = 0.05
MIN_PER_POINT = 3  # captures at one point: fewer cannot tell a point's spread from the model's error


@dataclass(frozen=True, eq=False)
class Session:
    """A capture session: where the operator aimed, and the logged joint states.

    Attributes
    ----------
    path : Path, the session folder
    meta : dict, the parsed session.yaml
    robot : RobotModel, the nominal model the session names
    plane_z : float, mm
    aperture_z : float or None, measured p_Mz, mm
    points : dict name -> (3,) array, mm
    point : (m,) array of str, the point each capture aimed at
    target : (m, 3) array, that point's coordinates, mm
    t : (m,) array, s since the session started
    q : (m, n) array, rad
    dq : (m, n) array or None, rad/s
    tau : (m, n) array or None, Nm
    extra : dict column -> (m,) array of str, kept and ignored
    lines : (m,) array of int, the CSV line of each capture
    measurement : str, 'laser' (spot on a plane) or 'point' (a tool point held at a point)
    tool_point : (3,) array or None, nominal tool point at q = 0 (point measurements), mm
    distances : tuple of (A, B, mm), known distances between points (point measurements)
    sigma : (m,) array or None, per-capture sensor noise, mm (position measurements)

    Position measurements (``measurement: position``, :mod:`solver.formats.positions`): ``point``
    is each capture's target on the tool, ``target`` its measured position (mm, sensor frame),
    ``points`` maps each target to None (identified).
    clock : str, 'seconds' (t is a clock) or 'order' (t only orders the rows: no effect in time
        can be tested)
    tolerances : Tolerances or None, the prior of every fit of this session (:mod:`solver.identify.prior`;
        None: plain least squares). Default: the robot's own (:func:`~solver.identify.prior.robot_tolerances`)
    frame : str, 'base' or 'sheet': a sheet session's ``points`` are [x, y, 0] in the sheet's frame, and
        ``target`` holds their x, y there with z the plane's height in the base frame; the sheet's pose
        is identified with the robot (:mod:`solver.kinematics.sheet`)
    sheet : SheetPose or None, a sheet session's stated rough placement (the prior's mean), if any
    spot_sigma : (m,) array or None, a camera session's (``camera_x``.. columns): the measured spot's
        1-sigma uncertainty per axis, mm (RMS of its two axes), NaN for a capture whose spot was not
        measured (an aimed one); a measured capture's ``target`` holds the measured spot, not its cross
    robot_source : (str, Path or None) or None, how the robot was named and the folder a relative path is
        relative to: ``(meta['robot'], path)``, or a ``load_session(robot=...)`` override's ``(robot, None)``
        (relative to the working folder); a calibrated model names its nominal from it
    camera_eye : (m, 3) array or None, a camera session's (``camera_eye_x`` .. columns): where the camera
        stood for each measured photo, mm in the layout's frame (z above the sheet; NaN: not told)
    """

    path: Path
    meta: dict
    robot: RobotModel
    plane_z: float
    aperture_z: float | None
    points: dict
    point: np.ndarray
    target: np.ndarray
    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray | None
    tau: np.ndarray | None
    extra: dict
    lines: np.ndarray
    measurement: str = "laser"
    tool_point: np.ndarray | None = None
    distances: tuple = ()
    sigma: np.ndarray | None = None
    clock: str = "seconds"
    tolerances: Tolerances | None | str = "robot"
    frame: str = "base"
    sheet: SheetPose | None = None
    robot_source: tuple | None = None
    spot_sigma: np.ndarray | None = None
    camera_eye: np.ndarray | None = None

    @property
    def measured(self) -> np.ndarray:
        """(m,) bool: captures whose spot a camera measured (the others were aimed at their cross)."""
        return np.zeros(self.m, bool) if self.spot_sigma is None else np.isfinite(self.spot_sigma)

    def __post_init__(self):
        if isinstance(self.tolerances, str):  # "robot": the nominal's tolerances (a frozen field, set once)
            object.__setattr__(self, "tolerances", robot_tolerances(self.robot))

    @property
    def m(self) -> int:
        """Number of captures."""
        return len(self.point)

    @property
    def positions(self) -> np.ndarray:
        """Tool position of each capture (m,): a point session's point name up to its last '/'
        ('front' for 'front/hole_0'; points of one tool placement share it), else the point."""
        return np.array([nm.rsplit("/", 1)[0] for nm in self.point], dtype=object)

    def subset(self, idx) -> Session:
        """The same session restricted to captures idx (bool mask or indices)."""
        pick = lambda a: None if a is None else a[idx]  # noqa: E731
        seen = set(self.point[idx])
        # an unknown point with no capture left cannot be identified: drop it and its distances
        points = {k: v for k, v in self.points.items() if v is not None or k in seen}
        distances = tuple(d for d in self.distances if d[0] in points and d[1] in points)
        return Session(
            self.path,
            self.meta,
            self.robot,
            self.plane_z,
            self.aperture_z,
            points,
            self.point[idx],
            self.target[idx],
            self.t[idx],
            self.q[idx],
            pick(self.dq),
            pick(self.tau),
            {k: v[idx] for k, v in self.extra.items()},
            self.lines[idx],
            self.measurement,
            self.tool_point,
            distances,
            pick(self.sigma),
            self.clock,
            self.tolerances,
            self.frame,
            self.sheet,
            self.robot_source,
            pick(self.spot_sigma),
            pick(self.camera_eye),
        )


# a camera session's measured spot and its 1-sigma, mm
SPOT_XY = ("camera_x", "camera_y", "camera_sx", "camera_sy")
SPOT_SIGMA_MAX_MM = 50.0  # a stated uncertainty beyond this is no measurement (a unit or column mistake)


def measured_spots(path, rows, header) -> tuple[np.ndarray, np.ndarray] | None:
    """A camera session's measured spots: (m, 2) positions and (m,) 1-sigma (RMS of the axes), mm, NaN
    where a capture's spot was not measured (all four cells empty); None without the columns.

    Raises
    ------
    FormatError
        Naming line and column: some of the four cells empty, a value not a finite number, an
        uncertainty not in (0, 50] mm.
    """
    if "camera_x" not in header:
        return None
    missing = [c for c in SPOT_XY if c not in header]
    if missing:
        raise FormatError(
            path, f"camera_x without {', '.join(missing)} in the header", line=1, field=missing[0]
        )
    idx = [header.index(c) for c in SPOT_XY]
    xy, sig = np.full((len(rows), 2), np.nan), np.full(len(rows), np.nan)
    for r, (ln, row) in enumerate(rows):
        if len(row) != len(header):
            raise FormatError(path, f"expected {len(header)} values, found {len(row)}", line=ln)
        cells = [row[j].strip() for j in idx]
        if not any(cells):
            continue  # not measured: an aimed capture
        v = []
        for c, text in zip(SPOT_XY, cells):
            try:
                x = float(text)
            except ValueError:
                x = math.nan
            if not math.isfinite(x):
                what = (
                    "missing value (a measured spot fills all four of camera_x..camera_sy)"
                    if not text
                    else (f"not a finite number: {text!r}")
                )
                raise FormatError(path, what, line=ln, field=c)
            v.append(x)
        for c, x in zip(SPOT_XY[2:], v[2:]):
            if not 0 < x <= SPOT_SIGMA_MAX_MM:
                raise FormatError(
                    path,
                    f"uncertainty {x:g} (expected a 1-sigma in (0, {SPOT_SIGMA_MAX_MM:g}] mm)",
                    line=ln,
                    field=c,
                )
        xy[r], sig[r] = v[:2], math.sqrt((v[2] ** 2 + v[3] ** 2) / 2)
    return xy, sig


# where a camera session's operator aimed, off the point when its coach planned the spot anywhere, mm
AIM_XY = ("aim_x", "aim_y")
# where the camera stood for each measured photo, from its markers (eq. V2), mm in the layout's frame
EYE_XYZ = ("camera_eye_x", "camera_eye_y", "camera_eye_z")


def optional_columns(path, rows, header, names: tuple, what: str) -> np.ndarray | None:
    """Optional numeric columns that a row fills all or none of: (m, len(names)) floats, NaN where a row
    leaves them all empty; None when the first is not in the header.

    Raises
    ------
    FormatError
        Naming line and column: a later column missing from the header, some of a row's cells empty, a
        value not a finite number (``what`` says what the columns hold).
    """
    if names[0] not in header:
        return None
    missing = [c for c in names[1:] if c not in header]
    if missing:
        raise FormatError(
            path, f"{names[0]} without {', '.join(missing)} in the header", line=1, field=missing[0]
        )
    idx = [header.index(c) for c in names]
    out = np.full((len(rows), len(names)), np.nan)
    for r, (ln, row) in enumerate(rows):
        cells = [row[j].strip() if j < len(row) else "" for j in idx]
        if not any(cells):
            continue
        for k, (c, text) in enumerate(zip(names, cells)):
            try:
                out[r, k] = float(text)
            except ValueError:
                out[r, k] = math.nan
            if not math.isfinite(out[r, k]):
                said = f"missing value ({what} fills all of {', '.join(names)})" if not text else ""
                raise FormatError(path, said or f"not a finite number: {text!r}", line=ln, field=c)
    return out


def aimed_spots(path, rows, header) -> np.ndarray | None:
    """Where a camera session's captures were aimed when the coach planned the spot off its point
    (``--aim anywhere``): (m, 2) mm in the layout's frame, NaN where a row leaves both cells empty (aimed
    at its point); None without the columns (:func:`optional_columns`)."""
    return optional_columns(path, rows, header, AIM_XY, "an aim off the point")


def camera_eyes(path, rows, header) -> np.ndarray | None:
    """Where the camera stood for each measured photo (``camera_eye_x`` .. ``_z``): (m, 3) mm in the layout's
    frame, z above the sheet, NaN where the photo's markers could not tell; None without the columns.

    Raises
    ------
    FormatError
        As :func:`optional_columns`; and a camera not above the sheet (z <= 0).
    """
    eye = optional_columns(path, rows, header, EYE_XYZ, "a camera's position")
    if eye is not None and np.any(eye[:, 2] <= 0):
        r = int(np.flatnonzero(eye[:, 2] <= 0)[0])
        raise FormatError(
            path, f"camera below the sheet: {eye[r, 2]:g} mm", line=rows[r][0], field=EYE_XYZ[2]
        )
    return eye


def _joint_columns(prefix: str, n: int) -> list[str]:
    return [f"{prefix}{i}" for i in range(1, n + 1)]


def captures_repair(folder, meta: dict) -> str:
    """How to mend a captures.csv whose last row a kill tore (:func:`table.check_last_line`)."""
    if meta.get("collector"):  # a capture session: its resume cuts the torn row off and goes on
        return f"`lasercal capture --resume {folder}` cuts the torn row off and goes on"
    return "delete the torn last row, or make the session again"


def _numeric_block(path, rows, header, cols, required=True) -> np.ndarray | None:
    """Columns ``cols`` of the rows as floats, with errors naming line and column."""
    missing = [c for c in cols if c not in header]
    if missing:
        if required or len(missing) < len(cols):
            raise FormatError(
                path, f"missing column(s) {', '.join(missing)} in the header", line=1, field=missing[0]
            )
        return None
    idx = [header.index(c) for c in cols]
    out = np.empty((len(rows), len(cols)))
    for r, (ln, row) in enumerate(rows):
        if len(row) != len(header):
            raise FormatError(path, f"expected {len(header)} values, found {len(row)}", line=ln)
        for k, (c, j) in enumerate(zip(cols, idx)):
            try:
                v = float(row[j])
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                what = "missing value" if not row[j].strip() else f"not a finite number: {row[j]!r}"
                raise FormatError(path, what, line=ln, field=c)
            out[r, k] = v
    return out


def limit_slack(limits: np.ndarray) -> np.ndarray:
    """How far (n,) a measured angle may lie beyond each joint's limit and be kept (with a warning):
    the smaller of :data:`LIMIT_SLACK_RAD` and :data:`LIMIT_SLACK_FRACTION` of the joint's range."""
    return np.minimum(LIMIT_SLACK_RAD, LIMIT_SLACK_FRACTION * (limits[:, 1] - limits[:, 0]))


def check_limits(path, robot: RobotModel, q: np.ndarray, lines) -> None:
    """Measured angles (m, n) against the robot's joint limits: a hair beyond a limit (a rounded limit, a
    FANUC's J4 at -360.000 deg against -6.28 rad) is kept with a warning; beyond :func:`limit_slack` it
    is refused (wrong units or columns).

    Raises
    ------
    FormatError
        At the first angle beyond the slack, naming file, line and column (with a degrees hint).
    """
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    excess = np.maximum(lo - q, q - hi)  # > 0 outside
    out = excess > _LIMIT_TOL
    if not out.any():
        return
    far = excess > _LIMIT_TOL + limit_slack(robot.limits)
    r, j = np.argwhere(far if far.any() else out)[0]
    where = f"joint {j + 1} = {q[r, j]:.6g} rad is outside its limits [{lo[j]:.4f}, {hi[j]:.4f}]"
    if far.any():
        hint = degrees_hint(q, robot.limits)
        raise FormatError(
            path,
            where
            + (
                f": {hint}"
                if hint
                else f" by {excess[r, j]:.3g} (more than {limit_slack(robot.limits)[j]:.3g})"
            ),
            line=int(lines[r]),
            field=f"q{j + 1}",
        )
    warn(
        f"{path}, line {int(lines[r])}, column 'q{j + 1}': {where} by {excess[r, j]:.3g} "
        f"({int(out.sum())} angle(s) beyond a limit by at most {excess[out].max():.3g}): kept as measured "
        "(a rounded limit in the robot file?)"
    )


def repeated_captures(point, q: np.ndarray) -> tuple[dict, np.ndarray]:
    """Captures that repeat an earlier one: the same point and the same joint angles (to 1e-9 rad), as a
    capture saved twice or a copied row would.

    Parameters
    ----------
    point : (m,) point (or target) of each capture
    q : (m, n) joint angles, rad

    Returns
    -------
    distinct : dict point -> number of distinct configurations captured there
    repeats : (k,) int array, the indices of the captures that repeat an earlier one
    """
    point = np.asarray(point, dtype=str)
    qr = np.round(np.asarray(q, dtype=float), 9)
    distinct, repeats = {}, []
    for nm in dict.fromkeys(point):
        idx = np.flatnonzero(point == nm)
        _, first = np.unique(qr[idx], axis=0, return_index=True)
        distinct[str(nm)] = len(first)
        repeats.extend(np.setdiff1d(idx, idx[first]))
    return distinct, np.sort(np.array(repeats, dtype=int))


def check_repeats(path, point, q: np.ndarray, lines) -> None:
    """Captures that repeat earlier ones (:func:`repeated_captures`): a point left with fewer than
    :data:`MIN_PER_POINT` distinct configurations among at least as many rows is refused (copies of one
    capture are not data, and would be reported as an unidentifiable model); other repeats are kept with
    a warning.

    Raises
    ------
    FormatError
        Naming the file, the point and the lines that repeat earlier ones.
    """
    distinct, rep = repeated_captures(point, q)
    if not len(rep):
        return
    point = np.asarray(point, dtype=str)
    counts = {nm: int(np.sum(point == nm)) for nm in distinct}

    def shown(idx) -> str:
        return ", ".join(str(int(lines[i])) for i in idx[:5]) + (", ..." if len(idx) > 5 else "")

    for nm, k in distinct.items():
        if counts[nm] >= MIN_PER_POINT > k:
            idx = [i for i in rep if point[i] == nm]
            raise FormatError(
                path,
                f"the {counts[nm]} captures at {nm} are only {k} distinct configuration(s): line(s) "
                f"{shown(idx)} repeat earlier rows (one capture saved many times?); capture at least "
                f"{MIN_PER_POINT} different configurations there",
                line=int(lines[idx[0]]),
                field="point",
            )
    warn(
        f"{path}: {len(rep)} capture(s) repeat an earlier one exactly (same point and joint angles; "
        f"line(s) {shown(rep)}): kept, but a capture saved twice counts twice"
    )


def format_row(values) -> list[str]:
    """CSV cells with full float precision (repr round-trips exactly)."""
    return [v if isinstance(v, str) else repr(float(v)) for v in values]
