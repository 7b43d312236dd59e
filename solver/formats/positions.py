"""Position sessions: targets on the tool measured by a 3-D point sensor (laser tracker, mocap, CMM arm).

``session.yaml`` needs ``format: lasercal-session/1``, ``units`` (mm, rad), ``measurement:
position`` and ``robot`` (a name, a model YAML or a ``.urdf`` with optional ``base_link`` and
``tip_link``). Optional: ``targets: [names]`` (the targets the CSV may name), ``sensor`` (a
name, free text), ``noise_mm``, ``positions: FILE.csv`` (the sensor's rows in a file of their
own, row i measured at captures.csv's row i).

``captures.csv``: ``q1..qN,x,y,z`` (rad, or mm for prismatic joints; x, y, z in mm in the
sensor's frame), optional ``target`` (default: one target ``T1``), ``sigma`` (mm, the row's
noise std per axis), ``t`` (s) and ``tau1..tauN`` (Nm); other columns pass through.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.captures import (
    SESSION_FORMAT,
    UNITS,
    Session,
    _joint_columns,
    _numeric_block,
    captures_repair,
    check_limits,
    check_repeats,
    format_row,
)
from lasercal.solver.formats.checks import metres_hint
from lasercal.solver.formats.table import read_csv
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.whole import dump_yaml

DEFAULT_TARGET = "T1"


def load_position_session(folder: Path, meta: dict, robot: RobotModel, clock: str = "seconds") -> Session:
    """Read a position session's captures (module docstring) into a :class:`Session`.

    Parameters
    ----------
    folder : Path, the session folder
    meta : dict, its parsed session.yaml
    robot : RobotModel, the nominal robot
    clock : str, what ``t`` is (see :func:`session_clock`); without a ``t`` column it is ``order``

    Returns
    -------
    Session with ``measurement='position'``, ``target`` the measured positions (m, 3) mm
    """
    cpath = folder / "captures.csv"
    header, rows = read_csv(cpath, captures_repair(folder, meta))
    n = robot.n
    qcols = _joint_columns("q", robot.n_commanded)  # a coupled robot's commanded joints
    q = robot.described(_numeric_block(cpath, rows, header, qcols))  # the joints they drive
    robot = with_target_links(robot, meta, folder / "session.yaml")
    spath, sheader, srows = cpath, header, rows
    if meta.get("positions") is not None:
        spath = folder / str(meta["positions"])
        sheader, srows = read_csv(spath)
        if len(srows) != len(rows):
            raise FormatError(
                spath,
                f"{len(srows)} sensor rows but {cpath.name} has {len(rows)} captures: the rows must pair up",
                field="rows",
            )
    y = _numeric_block(spath, srows, sheader, ["x", "y", "z"])
    hint = metres_hint(y)
    if hint:
        raise FormatError(spath, f"sensor positions: {hint}", field="x")
    sig = _numeric_block(spath, srows, sheader, ["sigma"], required=False)
    if sig is not None and np.any(sig <= 0):
        r = int(np.argmax(sig[:, 0] <= 0))
        raise FormatError(spath, "sigma must be positive (mm)", line=srows[r][0], field="sigma")
    if "target" in sheader:
        j = sheader.index("target")
        names = np.array([row[j].strip() or DEFAULT_TARGET for _, row in srows], dtype=object)
    else:
        names = np.full(len(srows), DEFAULT_TARGET, dtype=object)
    allowed = meta.get("targets")
    if allowed is not None:
        allowed = [str(a) for a in allowed]
        bad = [i for i, nm in enumerate(names) if nm not in allowed]
        if bad:
            raise FormatError(
                spath,
                f"unknown target {names[bad[0]]!r} (session.yaml names {', '.join(allowed)})",
                line=srows[bad[0]][0],
                field="target",
            )
    t = _numeric_block(cpath, rows, header, ["t"], required=False)
    if t is None:  # no clock: the rows' order is all there is
        t, clock = np.arange(len(rows), dtype=float), "order"
    else:
        t = t[:, 0]
    tau = _numeric_block(cpath, rows, header, _joint_columns("tau", n), required=False)
    lines = np.array([ln for ln, _ in rows], dtype=int)
    check_limits(cpath, robot, q, lines)
    check_repeats(cpath, names, q, lines)
    known = set(qcols + _joint_columns("tau", n) + ["t", "x", "y", "z", "target", "sigma"])
    extra = {
        h: np.array([row[j] for _, row in rows], dtype=object) for j, h in enumerate(header) if h not in known
    }
    if len(rows) < 1:
        raise FormatError(cpath, "no captures", line=2)
    return position_session(
        robot, q, y, names, None if sig is None else sig[:, 0], folder, meta, t, tau, extra, lines, clock
    )


def with_target_links(robot: RobotModel, meta: dict, path) -> RobotModel:
    """The robot with the links its targets sit on: session.yaml's ``targets`` as a mapping TARGET: LINK
    (a list of names keeps the robot's own, by default the last joint's link)."""
    tl = meta.get("targets")
    if not isinstance(tl, dict):
        return robot
    links = set(robot.joint_links)
    bad = [f"{k}: {v}" for k, v in tl.items() if str(v) not in links]
    if bad:
        raise FormatError(
            path,
            f"target {bad[0]!r} names no link of {robot.name} ({', '.join(dict.fromkeys(robot.joint_links))})"
            if links
            else f"{robot.name} is one chain: its targets name no link (give 'targets' as a list)",
            field="targets",
        )
    return robot.replace(target_links={str(k): str(v) for k, v in tl.items()})


def position_session(
    robot: RobotModel,
    q: np.ndarray,
    y: np.ndarray,
    names: np.ndarray,
    sigma: np.ndarray | None = None,
    folder: Path | str = "<memory>",
    meta: dict | None = None,
    t: np.ndarray | None = None,
    tau: np.ndarray | None = None,
    extra: dict | None = None,
    lines: np.ndarray | None = None,
    clock: str = "order",
) -> Session:
    """A position :class:`Session` from arrays (e.g. circle points expanded into positions).

    Parameters
    ----------
    robot : RobotModel, the nominal
    q : (m, n) array, rad
    y : (m, 3) array, measured positions, mm, sensor frame
    names : (m,) array of str, the target of each row
    sigma : (m,) array, optional, per-row noise, mm
    folder, meta : the session's folder (names files in errors) and session.yaml mapping
    t : (m,) array, optional, s (default: the row order, ``clock='order'``)
    tau : (m, n) array, optional, Nm
    extra : dict column -> (m,) array, passed through
    lines : (m,) int array, optional, file line of each row (default 2, 3, ...)
    clock : str, what ``t`` is

    Returns
    -------
    Session with ``measurement='position'``
    """
    names = np.asarray(names, dtype=object)
    m = len(names)
    return Session(
        Path(folder),
        meta if meta is not None else position_meta(robot.name, dict.fromkeys(names)),
        robot,
        float("nan"),
        None,
        {nm: None for nm in dict.fromkeys(names)},
        names,
        np.asarray(y, dtype=float),
        np.arange(m, dtype=float) if t is None else t,
        np.asarray(q, dtype=float),
        None,
        tau,
        extra or {},
        np.arange(2, m + 2) if lines is None else lines,
        "position",
        None,
        (),
        None if sigma is None else np.asarray(sigma, dtype=float),
        clock,
    )


def position_meta(robot_ref: str, targets, **extra) -> dict:
    """The session.yaml mapping of a position session."""
    meta = {
        "format": SESSION_FORMAT,
        "robot": str(robot_ref),
        "units": dict(UNITS),
        "measurement": "position",
        # a mapping TARGET: LINK names the link each target sits on (a tree); else the names
        "targets": dict(targets)
        if isinstance(targets, dict) and all(isinstance(v, str) for v in targets.values())
        else [str(t) for t in targets],
    }
    meta.update(extra)
    return meta


def write_position_session(
    folder, meta: dict, q: np.ndarray, y: np.ndarray, names, sigma=None, tau=None, t=None
) -> Path:
    """Write a position session folder (captures.csv: q1..qN[,t][,tau1..tauN],target,x,y,z[,sigma])."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "session.yaml").write_text(dump_yaml(meta, sort_keys=False, width=120))
    n = q.shape[1]
    header = (
        _joint_columns("q", n)
        + (["t"] if t is not None else [])
        + (_joint_columns("tau", n) if tau is not None else [])
        + ["target", "x", "y", "z"]
        + (["sigma"] if sigma is not None else [])
    )
    with open(folder / "captures.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for i in range(len(q)):
            vals = (
                format_row(q[i])
                + ([] if t is None else format_row([t[i]]))
                + ([] if tau is None else format_row(tau[i]))
                + [str(names[i])]
                + format_row(y[i])
                + ([] if sigma is None else format_row([np.ravel(sigma)[i] if np.ndim(sigma) else sigma]))
            )
            w.writerow(vals)
    return folder
