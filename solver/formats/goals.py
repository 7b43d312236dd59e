"""The files of ``lasercal correct``: goals in (IN.csv), joint and Cartesian commands out (OUT.csv).

IN.csv (mm, rad, the robot's base frame), one goal a row, other columns passed through:

* ``x,y,z`` (mm): where the tool must go; optionally ``rx,ry,rz`` (rad, a rotation vector): the tool's
  orientation as well (a pose); optionally ``q1..qN`` (rad): a seed per row (the answer is the solution
  nearest it);
* or only ``q1..qN`` (rad): a joint-space program planned with the nominal model -- the tool must go
  where the nominal model puts it at q (position and orientation).

OUT.csv: the input columns, then ``cmd_q1..cmd_qN`` (rad, to 1e-9), ``cmd_x,cmd_y,cmd_z`` (mm, the
nominal model's tool position at cmd_q), with an orientation also ``cmd_rx,cmd_ry,cmd_rz`` (rad), then
``residual_mm`` (the calibrated model's miss at cmd_q), ``ok`` (true/false) and ``reason`` (why a row is
not ok; empty when it is). A ``#`` comment line first states the units, the model and the tool.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError, warn
from lasercal.solver.formats.checks import metres_hint
from lasercal.solver.formats.session import _numeric_block, check_limits
from lasercal.solver.formats.table import read_csv
from lasercal.solver.kinematics.model import RobotModel

POSITION = ("x", "y", "z")
ROTATION = ("rx", "ry", "rz")
_ROTVEC_MAX = 2 * np.pi  # rad: a rotation vector longer than a full turn is an angle in degrees


@dataclass(frozen=True, eq=False)
class Goals:
    """The rows of IN.csv.

    Attributes
    ----------
    header : list of str, the input's columns
    rows : list of list of str, the input's cells
    position : (m, 3) array or None, mm
    rotation : (m, 3) array or None, rotation vectors, rad
    q : (m, n) array or None, rad: seeds (with a position) or the program (without)
    lines : list of int, the file's line of each row
    """

    header: list
    rows: list
    position: np.ndarray | None
    rotation: np.ndarray | None
    q: np.ndarray | None
    lines: list

    @property
    def program(self) -> bool:
        """A joint-space program (only q1..qN)."""
        return self.position is None

    @property
    def oriented(self) -> bool:
        """The goals have an orientation (rx, ry, rz, or a program's nominal frames)."""
        return self.rotation is not None or self.program

    def goal(self) -> np.ndarray | None:
        """Goals for :meth:`Robot.correct`: (m, 3) positions or (m, 6) poses; None for a program."""
        if self.position is None:
            return None
        return self.position if self.rotation is None else np.hstack([self.position, self.rotation])


def load_goals(path, model: RobotModel) -> Goals:
    """Read and check IN.csv (module docstring) for a robot of ``model.n`` joints.

    Raises
    ------
    FormatError
        naming the file, the line and the column: a missing or partial column group, a column named twice,
        a joint column the robot does not have, a value that is not a finite number, a goal that looks like
        metres, rotation vectors that look like degrees (longer than 2 pi; longer than pi is a warning), a
        joint angle outside the limits (or in degrees)
    """
    header, rows = read_csv(path)
    n = model.n
    qcols = [f"q{i}" for i in range(1, n + 1)]
    if not rows:
        raise FormatError(path, "no goals: expected a header and one row per goal", line=1)
    position = _numeric_block(path, rows, header, list(POSITION), required=False)
    rotation = _numeric_block(path, rows, header, list(ROTATION), required=False)
    q = _numeric_block(path, rows, header, qcols, required=False)
    if position is None and q is None:
        raise FormatError(
            path,
            f"expected goal columns x,y,z (mm) or a program q1..q{n} (rad), got {','.join(header)}",
            line=1,
        )
    if rotation is not None and position is None:
        raise FormatError(path, "rx,ry,rz need x,y,z (the goal's position, mm)", line=1, field="rx")
    extra = [c for c in header if c.startswith("q") and c[1:].isdigit() and not 1 <= int(c[1:]) <= n]
    if extra:  # a program of another robot, or a seed column too many
        raise FormatError(
            path, f"{model.name} has {n} joints (q1..q{n}): {extra[0]} is not one", line=1, field=extra[0]
        )
    lines = [ln for ln, _ in rows]
    if position is not None:
        # per row: a goal in metres lies within a few mm of the base, where no tool can go
        near = [i for i, p in enumerate(position) if metres_hint(p)]
        if near:
            i = near[0]
            raise FormatError(path, f"x, y, z: {metres_hint(position[i])}", line=lines[i], field="x")
    if rotation is not None:
        length = np.linalg.norm(rotation, axis=1)
        long, turned = length > _ROTVEC_MAX, length > np.pi + 1e-9
        if long.any():
            i = int(np.argmax(long))
            raise FormatError(
                path,
                f"rotation vector of length {length[i]:.4g} rad: longer than a full turn "
                "(degrees? expected rad)",
                line=lines[i],
                field="rx",
            )
        if turned.any():  # the orientation of 2 pi - |r| the other way: plausible, but degrees?
            i = int(np.argmax(turned))
            warn(
                f"{path}, line {lines[i]}, column 'rx': rotation vector of length {length[i]:.4g} rad, "
                f"more than pi ({int(turned.sum())} row(s)): read as the orientation of "
                f"{2 * np.pi - length[i]:.4g} rad the other way (degrees? expected rad)"
            )
    if q is not None:
        check_limits(path, model, q, lines)
    return Goals(header, [r for _, r in rows], position, rotation, q, lines)


def write_commands(path, goals: Goals, correction, comment: str) -> None:
    """Write OUT.csv (module docstring) from the goals and a :class:`solver.control.robot.Correction`.

    Parameters
    ----------
    path : str or Path
    goals : Goals
    correction : Correction, one row per goal
    comment : str, the first line (after '# '): units, model, tool
    """
    from scipy.spatial.transform import Rotation

    n = correction.q.shape[1]
    T = correction.nominal_pose
    header = list(goals.header) + [f"cmd_q{i}" for i in range(1, n + 1)] + ["cmd_x", "cmd_y", "cmd_z"]
    cells = [_cells(correction.q, 9), _cells(T[:, :3, 3], 6)]  # rad to 1e-9, mm to 1e-6
    if goals.oriented:
        header += ["cmd_rx", "cmd_ry", "cmd_rz"]
        cells.append(_cells(Rotation.from_matrix(T[:, :3, :3]).as_rotvec(), 9))
    header += ["residual_mm", "ok", "reason"]
    cells.append(_cells(correction.residual_mm[:, None], 6))
    cells.append([["true" if ok else "false", why] for ok, why in zip(correction.ok, correction.reason)])
    with open(Path(path), "w", newline="") as f:
        f.write(f"# {comment}\n")
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        for i, row in enumerate(goals.rows):
            w.writerow(row + [c for block in cells for c in block[i]])


def _cells(a: np.ndarray, decimals: int) -> list[list[str]]:
    """Rows of fixed-point cells (``-0.000...`` written as ``0.000...``)."""
    return [[f"{v:.{decimals}f}" for v in row] for row in np.round(a, decimals) + 0.0]
