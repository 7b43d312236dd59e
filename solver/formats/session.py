"""Session, layout and configuration files: read, validate, write (formats in README).

* Layout ``lasercal-layout/1`` (YAML): ``plane: {z}``, ``points: {NAME: [x, y, z]}`` (mm, base
  frame), optional ``calibration``/``validation`` name lists, ``aiming`` hints and ``markers``
  (read by ``vision``). ``frame: sheet`` puts ``points`` (and ``markers``) in a printed sheet's own
  frame, [x, y, 0] mm, whose in-plane pose on the table is unknown (identified by ``solve``);
  ``sheet: {x_mm, y_mm, yaw_deg}`` is then an optional rough placement (eq. S1 of
  :mod:`solver.kinematics.sheet`). No ``frame`` is ``frame: base``.
* Session: a folder with ``session.yaml`` (``format: lasercal-session/1``; ``clock: seconds``, the
  default, or ``order`` when ``t`` is only the recording order) and ``captures.csv``
  (``point,t,q1..qN[,dq1..dqN][,tau1..tauN][,extra...]``; mm, rad, Nm, s).
* Configurations CSV: ``q1..qN`` with optional ``t`` and ``tau1..tauN``; other columns pass through
  (renamed ``measured_NAME`` where an output column takes their name: :func:`header_beside`).

Every malformed input raises :class:`~solver.errors.FormatError` naming file, line and column.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from lasercal.solver.errors import AimingError, FormatError
from lasercal.solver.formats.captures import (
    EYE_XYZ,
    SESSION_FORMAT,
    SPOT_XY,
    UNITS,
    Session,
    _joint_columns,
    _numeric_block,
    aimed_spots,
    camera_eyes,
    captures_repair,
    check_limits,
    check_repeats,
    format_row,
    measured_spots,
)
from lasercal.solver.formats.checks import METRES_BELOW_MM, Range, metres_hint
from lasercal.solver.formats.data import resolve
from lasercal.solver.formats.positions import load_position_session
from lasercal.solver.formats.robots import load_model, load_yaml, sheet_pose
from lasercal.solver.formats.table import read_csv
from lasercal.solver.formats.tolerances import load_tolerances
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.sheet import SheetPose
from lasercal.solver.whole import dump_yaml

LAYOUT_FORMAT = "lasercal-layout/1"
CLOCKS = ("seconds", "order")  # what the t column is: a real clock (s), or the recording order (a count)
DISTANCE = Range(0.0, 1e5, "mm", lo_open=True)  # a known distance between two points
SAME_POINT_MM = 1.0  # reference points closer than this are one point
APERTURE_TOL_MM = 100.0  # a measured aperture height further than this from the nominal model's is a mistake
FRAMES = ("base", "sheet")  # the frame of a layout's points: the robot's base, or a printed sheet's own
SPOT_FAR_MM = 60.0  # a measured spot farther than this from its point is a unit or column mistake
AIM_FAR_MM = 150.0  # an aim off its point farther than this is out of its cell on any printed sheet
AIMING = {"tilt_deg": Range(0.0, 90.0, "deg"), "length": Range(0.0, 5000.0, "mm", lo_open=True)}


@dataclass(frozen=True)
class Layout:
    """Reference points on the table.

    Attributes
    ----------
    path : str
    plane_z : float, mm
    points : dict name -> (3,) array, mm, base frame
    calibration, validation : tuple of point names
    aiming : dict, hints for the aiming IK (``tilt_deg``, ``length``)
    raw : dict, the whole mapping (other packages read their own sections, e.g. ``markers``)
    frame : str, 'base' (points in the robot's base frame) or 'sheet' (points [x, y, 0] in the sheet's
        own frame, the plane at z = plane_z in the base frame)
    sheet : SheetPose or None, a sheet layout's rough placement on the table (None: not given)
    """

    path: str
    plane_z: float
    points: dict
    calibration: tuple
    validation: tuple
    aiming: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict)
    frame: str = "base"
    sheet: SheetPose | None = None

    def in_base(self, pose: SheetPose | None = None) -> Layout:
        """This layout with its points in the base frame: a sheet layout through ``pose`` (default its
        placement ``sheet``), eq. S1; a base layout unchanged.

        Raises
        ------
        FormatError
            A sheet layout with neither a pose nor a placement.
        """
        if self.frame == "base":
            return self
        pose = pose or self.sheet
        if pose is None:
            raise FormatError(
                self.path,
                "the points are in the sheet's frame and the sheet's placement is unknown: add "
                "'sheet: {x_mm, y_mm, yaw_deg}' (where the sheet's origin roughly lies, base frame) or give "
                "an identified model",
                field="sheet",
            )
        names = list(self.points)
        xyz = pose.to_base(np.array([self.points[k] for k in names]), self.plane_z)
        return replace(self, points=dict(zip(names, xyz)), frame="base", sheet=None)

    def unreachable(self, name: str) -> str:
        """The message for a point no configuration can aim at, naming the layout file and the point."""
        return (
            f"{self.path}, point {name} {np.round(self.points[name], 1).tolist()} mm: out of reach (no "
            "configuration within the joint limits, the aiming range and the table clearance aims at it)"
        )

    def aim_at(self, model: RobotModel, name: str, n: int, rng: np.random.Generator) -> np.ndarray:
        """Configurations (n, N) of ``model`` aiming at point ``name`` under the layout's hints
        (:func:`solver.kinematics.aim.aim`).

        Raises
        ------
        AimingError
            Naming the layout file and the point: the aiming IK knows only coordinates.
        """
        from lasercal.solver.kinematics.aim import aim

        try:
            return aim(model, self.points[name], n, rng, **self.aim_kwargs())
        except AimingError as e:
            raise AimingError(f"{self.path}, point {name}: {e}") from None

    def aim_kwargs(self) -> dict:
        """Keyword arguments for :func:`solver.aim.aim` from the ``aiming`` hints."""
        kw = {}
        if "tilt_deg" in self.aiming:
            kw["tilt"] = tuple(math.radians(float(a)) for a in self.aiming["tilt_deg"])
        if "length" in self.aiming:
            kw["length"] = tuple(float(a) for a in self.aiming["length"])
        return kw


def _points(d, path, key="points", allow_unknown: bool = False) -> dict:
    pts = d.get(key)
    if not isinstance(pts, dict) or not pts:
        raise FormatError(path, f"'{key}' must be a mapping NAME: [x, y, z] (mm)", field=key)
    out = {}
    for name, xyz in pts.items():
        if xyz is None and allow_unknown:  # point measurements: identified with the robot
            out[str(name)] = None
            continue
        try:
            a = np.array(xyz, dtype=float).ravel()
        except (TypeError, ValueError):
            a = np.array([])
        if a.size != 3 or not np.all(np.isfinite(a)):
            raise FormatError(
                path, f"point {name!r} must be [x, y, z] in mm, got {xyz!r}", field=f"{key}.{name}"
            )
        out[str(name)] = a
    known = [a for a in out.values() if a is not None]
    hint = metres_hint(np.array(known)) if known else None
    if hint:
        raise FormatError(path, hint, field=key)
    return out


def _plane_z(d, path) -> float:
    plane = d.get("plane")
    try:
        z = float(plane["z"])
    except (TypeError, KeyError, ValueError):
        raise FormatError(path, "'plane' must be a mapping {z: <mm>}", field="plane") from None
    if not math.isfinite(z):
        raise FormatError(path, f"plane z = {z} (expected a finite height, mm)", field="plane.z")
    return z


def _frame(d, path) -> tuple[str, SheetPose | None]:
    """``frame`` (base or sheet) and a sheet layout's optional placement ``sheet: {x_mm, y_mm, yaw_deg}``."""
    frame = d.get("frame", "base") or "base"
    if frame not in FRAMES:
        raise FormatError(path, f"frame {frame!r} (expected 'base' or 'sheet')", field="frame")
    if d.get("sheet") is not None and frame != "sheet":
        raise FormatError(path, "'sheet' (a placement) needs 'frame: sheet'", field="sheet")
    return frame, sheet_pose(d, "sheet", path, placement=True)


def _names(d, key, points, path) -> tuple:
    names = d.get(key)
    if names is None:
        return ()
    if not isinstance(names, list):
        raise FormatError(path, f"'{key}' must be a list of point names", field=key)
    for nm in names:
        if str(nm) not in points:
            raise FormatError(path, f"'{key}' names unknown point {nm!r}", field=key)
    return tuple(str(n) for n in names)


def session_layout(meta: dict, path) -> Layout:
    """The layout a capture session was started with, from its session.yaml mapping (the folder is
    self-contained: points, requested and validation points, plane, aiming hints). A session not
    made by ``capture`` (simulated, imported) names no requested points: all its points are."""
    c = meta.get("collector") or {}
    pts = {k: np.asarray(v, dtype=float) for k, v in meta["points"].items()}
    frame, sheet = _frame(meta, path)
    return Layout(
        str(path),
        float(meta["plane"]["z"]),
        pts,
        tuple(meta.get("requested") or pts),
        tuple(meta.get("validation") or ()),
        dict(c.get("aiming") or {}),
        frame=frame,
        sheet=sheet,
    )


def load_layout(path) -> Layout:
    """Load and validate a layout YAML, given by path or built-in name ('thesis', 'puma')."""
    path = resolve("layouts", path)
    d = load_yaml(path)
    if not isinstance(d, dict):
        raise FormatError(path, "a layout must be a YAML mapping")
    if d.get("format", LAYOUT_FORMAT) != LAYOUT_FORMAT:
        raise FormatError(
            path, f"unsupported format {d.get('format')!r} (expected {LAYOUT_FORMAT})", field="format"
        )
    units = d.get("units") or {}
    if not isinstance(units, dict) or units.get("length", "mm") != "mm":
        raise FormatError(path, f"units {units!r} (expected length: mm)", field="units")
    points = _points(d, path)
    calib = _names(d, "calibration", points, path)
    valid = _names(d, "validation", points, path)
    both = [p for p in calib if p in valid]
    if both:
        raise FormatError(
            path,
            f"point {both[0]} is listed both as calibration and as validation (expected a validation point "
            "the model is not fitted to)",
            field="validation",
        )
    if not calib:
        calib = tuple(p for p in points if p not in valid)
    plane_z = _plane_z(d, path)
    frame, sheet = _frame(d, path)
    check_layout_geometry(path, points, 0.0 if frame == "sheet" else plane_z, calib, frame)
    aiming = dict(d.get("aiming", {}) or {}) if isinstance(d.get("aiming", {}) or {}, dict) else None
    if aiming is None:
        raise FormatError(path, "'aiming' must be a mapping (tilt_deg, length)", field="aiming")
    for key, rng in AIMING.items():
        if key in aiming:
            v = aiming[key]
            bad = not isinstance(v, list) or len(v) != 2 or any(rng.problem(x) for x in v) or v[0] > v[1]
            if not bad and rng.unit == "mm" and max(v) < METRES_BELOW_MM:
                raise FormatError(
                    path, f"aiming {key} = {v!r}: these look like metres (expected mm)", field=f"aiming.{key}"
                )
            if bad:
                raise FormatError(
                    path,
                    f"aiming {key} = {v!r} (expected [low, high], each {rng.expected()})",
                    field=f"aiming.{key}",
                )
    return Layout(str(path), plane_z, points, calib, valid, aiming, d, frame, sheet)


def check_layout_geometry(
    path, points: dict, plane_z: float, calibration: tuple, frame: str = "base"
) -> None:
    """Points lie on the plane (z = 0 on a sheet), no two coincide, and the calibration points are not
    collinear.

    Raises
    ------
    FormatError
        Naming the layout and the point(s) at fault, and what would fix it.
    """
    names = list(points)
    xyz = np.array([points[n] for n in names])
    for n, p in zip(names, xyz):
        if abs(p[2] - plane_z) > SAME_POINT_MM:
            raise FormatError(
                path,
                f"point {n} z = {p[2]:g} mm is off the plane z = {plane_z:g} mm (expected on it)"
                if frame == "base"
                else f"point {n} z = {p[2]:g} mm: on a sheet (frame: sheet) points are [x, y, 0] mm",
                field=f"points.{n}",
            )
    check_distinct(path, points)
    c = np.array([points[n][:2] for n in calibration])
    if len(c) >= 3 and np.linalg.svd(c - c.mean(axis=0), compute_uv=False)[1] < SAME_POINT_MM:
        raise FormatError(
            path,
            f"calibration points {', '.join(calibration)} are collinear: the direction along their line is "
            "unidentifiable (expected at least three points not on one line)",
            field="points",
        )


def check_distinct(path, points: dict, key: str = "points") -> None:
    """No two reference points (those with coordinates) coincide.

    Raises
    ------
    FormatError
        Naming the file and every point at the first place where points coincide (three coincident
        points are not 'collinear': they are one point).
    """
    names = [n for n, p in points.items() if p is not None]
    if len(names) < 2:
        return
    xyz = np.array([points[n] for n in names], dtype=float)
    d = np.linalg.norm(xyz[:, None] - xyz[None], axis=2) + np.eye(len(xyz)) * 1e9
    if d.min() < SAME_POINT_MM:
        i = int(np.unravel_index(np.argmin(d), d.shape)[0])
        same = [names[i]] + [names[j] for j in np.flatnonzero(d[i] < SAME_POINT_MM)]
        raise FormatError(
            path,
            f"points {', '.join(same[:-1])} and {same[-1]} are the same point "
            f"{np.round(xyz[i], 3).tolist()} mm (expected distinct points, > {SAME_POINT_MM:g} mm apart)",
            field=key,
        )


def captures_header(n: int, dq: bool = False, tau: bool = False, extra=()) -> list[str]:
    """The captures.csv header for an n-joint robot."""
    return (
        ["point", "t"]
        + _joint_columns("q", n)
        + (_joint_columns("dq", n) if dq else [])
        + (_joint_columns("tau", n) if tau else [])
        + list(extra)
    )


def check_aperture(where, aperture_z: float, robot: RobotModel, field: str | None = None) -> None:
    """A measured aperture height p_Mz (mm) within :data:`APERTURE_TOL_MM` of the nominal model's.

    Raises
    ------
    FormatError
        Naming ``where`` (a file and ``field``, or an option such as ``--aperture-z``).
    """
    if not abs(aperture_z - robot.aperture[2]) <= APERTURE_TOL_MM:
        raise FormatError(
            where,
            f"aperture_z = {aperture_z:g} mm is not within {APERTURE_TOL_MM:g} mm of the {robot.name} "
            f"model's {robot.aperture[2]:g} mm (expected its height at q = 0, mm: sign, metres?)",
            field=field,
        )


def session_clock(meta: dict, path) -> str:
    """What the session's ``t`` column is: ``seconds`` (a clock, the default) or ``order`` (row order)."""
    clock = meta.get("clock", "seconds")
    if clock not in CLOCKS:
        raise FormatError(
            path,
            f"clock must be 'seconds' (t in s) or 'order' (t is the row order), got {clock!r}",
            field="clock",
        )
    return clock


def load_session(
    folder, robot=None, base_link: str | None = None, tip_link: str | None = None, prior=None
) -> Session:
    """Load and validate a session folder (session.yaml + captures.csv), with the prior of its fits.

    Parameters
    ----------
    folder : str or Path, the session folder
    robot : str or Path, optional, a robot (name, YAML or ``.urdf``; a relative path from the working
        folder) in place of the session's ``robot``; the session's ``base_link`` and ``tip_link``
        then do not apply
    base_link, tip_link : str, optional, the URDF chain's ends, in place of the session's keys
    prior : str or Path, optional, 'none' (plain least squares) or a ``lasercal-prior/1`` file over the
        robot's tolerances (default: the robot's own, :func:`~solver.identify.prior.load_tolerances`)

    Returns
    -------
    Session
    """
    session = _load_session(Path(folder), robot, base_link, tip_link)
    source = (str(robot), None) if robot else (str(session.meta.get("robot")), session.path)
    if prior is None:
        return replace(session, robot_source=source)
    return replace(session, tolerances=load_tolerances(prior, session.robot), robot_source=source)


def session_yaml(folder: Path) -> tuple[dict, Path, Path]:
    """A session folder's checked ``session.yaml`` mapping (format, units), its path and the captures' path.

    Raises
    ------
    FormatError
        Not a folder, not a mapping, another format, other units (naming the file and field).
    """
    ypath, cpath = folder / "session.yaml", folder / "captures.csv"
    if not folder.is_dir():
        raise FormatError(
            folder, "not a session folder (expected a folder with session.yaml and captures.csv)"
        )
    meta = load_yaml(ypath)
    if not isinstance(meta, dict):
        raise FormatError(ypath, "session.yaml must be a YAML mapping")
    if meta.get("format") != SESSION_FORMAT:
        raise FormatError(
            ypath, f"expected 'format: {SESSION_FORMAT}', got {meta.get('format')!r}", field="format"
        )
    units = meta.get("units") or {}
    for k, v in UNITS.items():
        if units.get(k, v) != v:
            raise FormatError(ypath, f"units.{k} must be {v!r}", field=f"units.{k}")
    return meta, ypath, cpath


def session_robot(folder: Path, meta: dict, ypath, robot, base_link, tip_link) -> RobotModel:
    """The session's robot: ``robot`` when given (a name or a path), else the one session.yaml names."""
    if robot is not None:
        return load_model(robot, base_link=base_link, tip_link=tip_link)
    if "robot" not in meta:
        raise FormatError(ypath, "missing 'robot' (a name under data/robots/ or a path)", field="robot")
    return load_model(
        meta["robot"],
        base=folder,
        base_link=base_link or meta.get("base_link"),
        tip_link=tip_link or meta.get("tip_link"),
    )


def point_tool(meta: dict, points: dict, ypath) -> tuple[np.ndarray, tuple]:
    """A point session's tool point (3,) mm (at q = 0) and its known distances between points."""
    tool = meta.get("tool")
    if not isinstance(tool, dict):
        raise FormatError(
            ypath, "a point session needs 'tool: {point: [x, y, z]}' (mm, at q = 0)", field="tool"
        )
    tool_point = np.array(_points({"tool": {"point": tool.get("point")}}, ypath, "tool")["point"])
    return tool_point, _distances(meta, points, ypath)


def laser_heights(meta: dict, ypath, robot: RobotModel, measurement: str) -> tuple[float, float | None]:
    """The plane's height z (mm; NaN for a point session without a plane) and the laser aperture's
    measured height p_Mz (mm, or None)."""
    plane_z = (
        _plane_z(meta, ypath) if measurement == "laser" or meta.get("plane") is not None else float("nan")
    )
    laser = meta.get("laser") or {}
    aperture_z = None
    if laser.get("aperture_z") is not None:
        try:
            aperture_z = float(laser["aperture_z"])
        except (TypeError, ValueError):
            raise FormatError(
                ypath, "laser.aperture_z must be a number (mm)", field="laser.aperture_z"
            ) from None
        check_aperture(ypath, aperture_z, robot, "laser.aperture_z")
    return plane_z, aperture_z


@dataclass(frozen=True)
class CaptureRows:
    """The columns of captures.csv, checked.

    Attributes
    ----------
    q : (m, n) array, rad; t : (m,) array (s or order); dq, tau : (m, n) arrays or None (rad/s, Nm)
    names : (m,) object array, the points aimed at
    lines : (m,) int array, each capture's line in the file
    spots : ((m, 2), (m, 2)) arrays or None, measured spots and their sigma (mm, layout frame; NaN: aimed)
    aims : (m, 2) array or None, where the spot was aimed off its point (mm, layout frame; NaN: at it)
    eyes : (m, 3) array or None, where the camera stood for each measured photo (mm, layout frame; NaN: not
        told)
    extra : dict column -> (m,) object array, the columns lasercal does not read
    """

    q: np.ndarray
    t: np.ndarray
    dq: np.ndarray | None
    tau: np.ndarray | None
    names: np.ndarray
    lines: np.ndarray
    spots: tuple | None
    aims: np.ndarray | None
    eyes: np.ndarray | None
    extra: dict


def capture_rows(folder: Path, meta: dict, cpath, robot: RobotModel, points: dict) -> CaptureRows:
    """captures.csv's columns for ``robot``'s n joints, each capture at one of ``points``."""
    header, rows = read_csv(cpath, captures_repair(folder, meta))
    n = robot.n
    if header[:2] != ["point", "t"]:
        raise FormatError(
            cpath,
            f"header must start with 'point,t,q1..q{n}', got {','.join(header[:3])}...",
            line=1,
            field=header[0],
        )
    qcols = _joint_columns("q", n)
    q = _numeric_block(cpath, rows, header, qcols)
    t = _numeric_block(cpath, rows, header, ["t"])[:, 0]
    dq = _numeric_block(cpath, rows, header, _joint_columns("dq", n), required=False)
    tau = _numeric_block(cpath, rows, header, _joint_columns("tau", n), required=False)
    names = []
    for ln, row in rows:
        nm = row[0].strip()
        if nm not in points:
            raise FormatError(
                cpath,
                f"unknown point {nm!r} (session.yaml defines {', '.join(points)})",
                line=ln,
                field="point",
            )
        names.append(nm)
    lines = np.array([ln for ln, _ in rows], dtype=int)
    check_limits(cpath, robot, q, lines)
    check_repeats(cpath, names, q, lines)
    spots = measured_spots(cpath, rows, header)
    aims = aimed_spots(cpath, rows, header)
    eyes = camera_eyes(cpath, rows, header) if spots is not None else None
    if eyes is not None:
        eyes[~np.isfinite(spots[1])] = np.nan  # an eye without a measured spot says nothing a fit uses
    known = set(["point", "t"] + qcols + _joint_columns("dq", n) + _joint_columns("tau", n))
    known |= set(SPOT_XY) if spots is not None else set()
    known |= set(EYE_XYZ) if eyes is not None else set()
    extra = {
        h: np.array([row[j] for _, row in rows], dtype=object) for j, h in enumerate(header) if h not in known
    }
    return CaptureRows(q, t, dq, tau, np.array(names, dtype=object), lines, spots, aims, eyes, extra)


def aim_offset(meta: dict, ypath) -> np.ndarray | None:
    """A camera session's offset [dx, dy] (mm) of where the operator aims from each cross, or None."""
    offset = meta.get("aim_offset")
    if offset is None:
        return None
    try:
        offset = np.array(offset, dtype=float).reshape(2)
    except (TypeError, ValueError):
        offset = np.full(2, np.nan)
    if not np.all(np.abs(offset) <= SPOT_FAR_MM):
        raise FormatError(ypath, f"aim_offset must be [dx, dy] within {SPOT_FAR_MM:g} mm", field="aim_offset")
    return offset


def beam_targets(target: np.ndarray, c: CaptureRows, offset, cpath) -> np.ndarray | None:
    """Move each capture's target (m, 3) mm, in place, to where the beam was aimed or measured: beside the
    cross by the session's aim ``offset``; at the coach's planned aim (``--aim anywhere``); at the camera's
    measured spot. Returns the measured spots' sigma (m, 2) mm (None without a camera)."""
    if offset is not None:  # a camera session: the operator aims beside each cross, on white paper
        target[:, :2] += offset
    if c.aims is not None:  # the coach planned the spot off the point: aimed there (--aim anywhere)
        off = np.isfinite(c.aims[:, 0])
        far = off & (np.linalg.norm(c.aims - target[:, :2], axis=1) > AIM_FAR_MM)
        if far.any():
            i = int(np.flatnonzero(far)[0])
            raise FormatError(
                cpath,
                f"the aim lies {np.linalg.norm(c.aims[i] - target[i, :2]):.0f} mm from {c.names[i]} "
                f"(expected within {AIM_FAR_MM:g} mm, its cell on the sheet; mm in the layout's frame)",
                line=int(c.lines[i]),
                field="aim_x",
            )
        target[off, :2] = c.aims[off]
    if c.spots is None:
        return None
    # a measured spot is where the beam was: the fit's target, with its uncertainty
    ok = np.isfinite(c.spots[1])
    far = ok & (np.linalg.norm(c.spots[0] - target[:, :2], axis=1) > SPOT_FAR_MM)
    if far.any():
        i = int(np.flatnonzero(far)[0])
        raise FormatError(
            cpath,
            f"the measured spot lies {np.linalg.norm(c.spots[0][i] - target[i, :2]):.0f} mm from where "
            f"{c.names[i]}'s capture was aimed (expected within {SPOT_FAR_MM:g} mm; mm, the layout's "
            "frame)",
            line=int(c.lines[i]),
            field="camera_x",
        )
    target[ok, :2] = c.spots[0][ok]
    return c.spots[1]


def _load_session(folder: Path, robot, base_link, tip_link) -> Session:
    """:func:`load_session` without the prior (the session's robot's own), section by section."""
    meta, ypath, cpath = session_yaml(folder)
    robot = session_robot(folder, meta, ypath, robot, base_link, tip_link)
    measurement = meta.get("measurement", "laser")
    if measurement not in ("laser", "point", "position"):
        raise FormatError(
            ypath,
            f"measurement must be 'laser', 'point' or 'position', got {measurement!r}",
            field="measurement",
        )
    clock = session_clock(meta, ypath)
    if measurement == "position":
        return load_position_session(folder, meta, robot, clock)
    points = _points(meta, ypath, allow_unknown=measurement == "point")
    check_distinct(ypath, points)
    tool_point, distances = point_tool(meta, points, ypath) if measurement == "point" else (None, ())
    plane_z, aperture_z = laser_heights(meta, ypath, robot, measurement)
    c = capture_rows(folder, meta, cpath, robot, points)
    target = np.array([np.full(3, np.nan) if points[nm] is None else points[nm] for nm in c.names]).reshape(
        -1, 3
    )
    frame, sheet = _frame(meta, ypath) if measurement == "laser" else ("base", None)
    check_consistent(
        ypath, meta, points, cpath, c.names, c.lines, frame, plane_z if measurement == "laser" else None
    )
    if frame == "sheet":
        check_layout_geometry(ypath, points, 0.0, tuple(points), frame)
        target[:, 2] = plane_z  # x, y on the sheet; z the plane's height in the base frame
    spot_sigma = beam_targets(target, c, aim_offset(meta, ypath), cpath)
    return Session(
        folder,
        meta,
        robot,
        plane_z,
        aperture_z,
        points,
        c.names,
        target,
        c.t,
        c.q,
        c.dq,
        c.tau,
        c.extra,
        c.lines,
        measurement,
        tool_point,
        distances,
        clock=clock,
        frame=frame,
        sheet=sheet,
        spot_sigma=spot_sigma,
        camera_eye=c.eyes,
    )


def check_consistent(ypath, meta: dict, points: dict, cpath, names, lines, frame: str, plane_z) -> None:
    """session.yaml agrees with itself and with captures.csv, as a whole file does: its ``requested`` and
    ``validation`` lists name its points, every capture is at a requested point, and a laser session's
    base-frame points lie on its plane (a sheet's [x, y, 0] points whose ``frame: sheet`` was lost do
    not). A file cut short (by hand, or written before files said where they end, solver/whole.py)
    fails one of these where its lost keys would otherwise take their defaults.

    Raises
    ------
    FormatError
        Naming the file, the field or line, and what a cut would explain.
    """
    requested = _names(meta, "requested", points, ypath)
    _names(meta, "validation", points, ypath)
    if requested:
        for nm, ln in zip(names, lines):
            if nm not in requested:
                raise FormatError(
                    cpath,
                    f"a capture at {nm}, which {ypath}'s 'requested' ({', '.join(requested)}) does not list "
                    "(expected a requested point: session.yaml cut short?)",
                    line=int(ln),
                    field="point",
                )
    if frame == "base" and plane_z is not None:
        for nm, p in points.items():
            if p is not None and abs(p[2] - plane_z) > SAME_POINT_MM:
                raise FormatError(
                    ypath,
                    f"point {nm} z = {p[2]:g} mm is off the plane z = {plane_z:g} mm (expected base-frame "
                    "points on the plane, or 'frame: sheet' for a sheet's [x, y, 0]: cut short?)",
                    field=f"points.{nm}",
                )


def _distances(meta: dict, points: dict, path) -> tuple:
    """``constraints: {distances: [[A, B, mm], ...]}``, validated."""
    cons = meta.get("constraints") or {}
    out = []
    for i, row in enumerate(cons.get("distances", []) or []):
        field = f"constraints.distances[{i}]"
        if not isinstance(row, (list, tuple)) or len(row) != 3:
            raise FormatError(path, "each distance is [A, B, mm]", field=field)
        a, b, dist = row
        if str(a) not in points or str(b) not in points:
            raise FormatError(path, f"distance names unknown point(s) {a!r}, {b!r}", field=field)
        msg = DISTANCE.problem(dist)
        if msg:
            raise FormatError(path, f"distance {a}-{b}: {msg}", field=field)
        if str(a) == str(b):
            raise FormatError(path, f"a distance from {a!r} to itself (expected two points)", field=field)
        out.append((str(a), str(b), float(dist)))
    return tuple(out)


def session_meta(robot_ref: str, layout: Layout, aperture_z: float | None, **extra) -> dict:
    """The session.yaml mapping for a new session: the layout is copied in (a self-contained folder)."""
    meta = {
        "format": SESSION_FORMAT,
        "robot": str(robot_ref),
        "units": dict(UNITS),
        "clock": "seconds",
        "plane": {"z": float(layout.plane_z)},
        "laser": {"aperture_z": None if aperture_z is None else float(aperture_z)},
        "points": {k: [float(x) for x in v] for k, v in layout.points.items()},
        "requested": list(layout.calibration),
        "validation": list(layout.validation),
    }
    if layout.frame == "sheet":
        meta["frame"] = "sheet"
        if layout.sheet is not None:
            meta["sheet"] = layout.sheet.as_dict()
    meta.update(extra)
    return meta


def write_session(folder, meta: dict, point, t, q, dq=None, tau=None, extra: dict | None = None) -> Path:
    """Write a complete session folder (simulations and imports; the collector appends instead)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "session.yaml").write_text(dump_yaml(meta, sort_keys=False, width=120))
    q = np.atleast_2d(q)
    extra = extra or {}
    header = captures_header(q.shape[1], dq is not None, tau is not None, extra)
    with open(folder / "captures.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for i in range(len(point)):
            vals = (
                [point[i], t[i], *q[i]]
                + ([] if dq is None else list(dq[i]))
                + ([] if tau is None else list(tau[i]))
            )
            w.writerow(format_row(vals) + [str(extra[k][i]) for k in extra])
    return folder


@dataclass(frozen=True)
class Configs:
    """A configurations CSV: q (m, n) rad, optional t (m,) s and tau (m, n) Nm, and all columns as text."""

    header: list
    rows: list
    q: np.ndarray
    t: np.ndarray | None
    tau: np.ndarray | None


def header_beside(header: list, added: list, prefix: str = "measured_") -> list:
    """The columns of an output: the input's passed through, then ``added``; a passed-through name an
    added column takes (a position session's measured ``x,y,z`` beside the predicted ones) gets
    ``prefix``, so that no name is written twice and the added columns keep their documented names."""
    taken = set(added)
    out = []
    for h in header:
        while h in taken:
            h = prefix + h
        taken.add(h)
        out.append(h)
    return out + list(added)


def load_configs(path, robot: RobotModel) -> Configs:
    """Load a configurations CSV (columns q1..qN, optional t and tau1..tauN; others passed through)."""
    header, rows = read_csv(path)
    if not rows:
        raise FormatError(path, "no configurations (a header and no rows)", line=2)
    # a coupled robot's columns are its commanded joints; q holds the joints they drive (q = C q_cmd + b)
    q = robot.described(_numeric_block(path, rows, header, _joint_columns("q", robot.n_commanded)))
    t = _numeric_block(path, rows, header, ["t"], required=False)
    tau = _numeric_block(path, rows, header, _joint_columns("tau", robot.n), required=False)
    check_limits(path, robot, q, [ln for ln, _ in rows])
    return Configs(header, [r for _, r in rows], q, None if t is None else t[:, 0], tau)
