"""MUKCa socket data (Franzese et al., arXiv 2503.12584) as lasercal point sessions.

A ball on the Franka hand sits in one of two conical sockets 50 mm apart while the arm is
hand-guided; each ``<robot>/<position>/hole_k.csv`` holds joint angles (rad, no header, in
recording order) that all put the ball centre at one unknown point. One session per robot:
points ``<position>/hole_0``, ``<position>/hole_1`` (unknown, identified), a 50 mm distance
per position, ``t`` = recording order with ``clock: order`` (a count, not seconds: the data have
no times, so no effect in time is a candidate on them).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import SESSION_FORMAT, UNITS, Session, check_limits, write_session
from lasercal.solver.formats.table import csv_rows

HOLE_DISTANCE = 50.0  # mm, checked with calipers by the authors
# Nominal ball centre at q = 0: the hand's TCP is 103.4 mm beyond the flange (88, 0, 926) along
# the flange z axis (down at q = 0), and the ball centre 30.1 mm beyond the TCP.
NOMINAL_TOOL = (88.0, 0.0, 926.0 - 103.4 - 30.1)


HOLES = ("hole_0.csv", "hole_1.csv")


def read_hole(path: Path) -> np.ndarray:
    """Joint angles (k, 7) rad of one hole file, with errors naming file, line and column."""
    rows = []
    for ln, row in csv_rows(path):
        if len(row) != 7:
            raise FormatError(path, f"expected 7 joint angles, found {len(row)}", line=ln)
        try:
            rows.append([float(v) for v in row])
        except ValueError:
            bad = next(i for i, v in enumerate(row) if not _is_float(v))
            raise FormatError(path, f"not a number: {row[bad]!r}", line=ln, field=f"q{bad + 1}") from None
    if not rows:
        raise FormatError(path, "no joint angles")
    q = np.array(rows)
    if not np.all(np.isfinite(q)):
        r, j = np.argwhere(~np.isfinite(q))[0]
        raise FormatError(path, "not a finite number (expected rad)", field=f"q{j + 1}")
    if np.abs(q).max() > 2 * np.pi:
        raise FormatError(path, f"angles up to {np.abs(q).max():.4g}: these look like degrees (expected rad)")
    return q


def _is_float(v: str) -> bool:
    try:
        float(v)
    except ValueError:
        return False
    return True


def positions(robot_dir: Path) -> list[str]:
    """Tool positions (folders holding hole_0.csv and hole_1.csv), sorted."""
    return sorted(p.name for p in Path(robot_dir).iterdir() if all((p / h).is_file() for h in HOLES))


def half_positions(robot_dir: Path) -> dict:
    """Tool positions holding one hole file but not the other: name -> the missing file's path."""
    out = {}
    for p in sorted(Path(robot_dir).iterdir()):
        have = [(p / h).is_file() for h in HOLES]
        if any(have) and not all(have):
            out[p.name] = p / HOLES[have.index(False)]
    return out


def position_of(session: Session) -> np.ndarray:
    """Tool position of each capture (m,) ('front' for point 'front/hole_0')."""
    return np.array([nm.rsplit("/", 1)[0] for nm in session.point])


def import_mukca(robot_dir, out, only: list[str] | None = None) -> Path:
    """Write one point session for a MUKCa robot folder.

    Parameters
    ----------
    robot_dir : folder such as .../mukca/panda_1
    out : session folder to write
    only : tool positions to import (default: all)

    Returns
    -------
    the session folder
    """
    robot_dir = Path(robot_dir)
    if not robot_dir.is_dir():
        raise FormatError(robot_dir, "not a MUKCa robot folder")
    pos = positions(robot_dir)
    if only:
        missing = [p for p in only if p not in pos]
        if missing:
            raise FormatError(robot_dir, f"no tool position {missing[0]!r} (has {', '.join(pos)})")
        pos = [p for p in pos if p in only]
    half = {p: f for p, f in half_positions(robot_dir).items() if not only or p in only}
    if half:  # not skipped in silence: a newcomer would calibrate on less data than they think
        name, path = next(iter(half.items()))
        raise FormatError(
            path,
            f"missing: tool position {name} has only one of {', '.join(HOLES)} (expected both; leave it out "
            f"with --positions {','.join(pos) or 'POSITIONS'})",
        )
    if not pos:
        raise FormatError(robot_dir, "no <position>/hole_0.csv, hole_1.csv found")
    names, qs = [], []
    robot = load_model("panda")
    for p in pos:
        for h in ("hole_0", "hole_1"):
            path = robot_dir / p / f"{h}.csv"
            q = read_hole(path)
            # the solver's rule for measured angles: a hair beyond a limit is kept (warned), further refused
            check_limits(path, robot, q, [ln for ln, _ in csv_rows(path)])
            qs.append(q)
            names += [f"{p}/{h}"] * len(q)
    q = np.concatenate(qs)
    meta = {
        "format": SESSION_FORMAT,
        "robot": "panda",
        "measurement": "point",
        "units": dict(UNITS),
        "clock": "order",
        "tool": {"point": list(NOMINAL_TOOL)},
        "points": {f"{p}/{h}": None for p in pos for h in ("hole_0", "hole_1")},
        "constraints": {"distances": [[f"{p}/hole_0", f"{p}/hole_1", HOLE_DISTANCE] for p in pos]},
        "source": {
            "dataset": "MUKCa",
            "folder": str(robot_dir.resolve()),
            "note": "t is the recording order (a count), not seconds",
        },
    }
    return write_session(out, meta, np.array(names, dtype=object), np.arange(len(q), dtype=float), q)
