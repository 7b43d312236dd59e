"""Files of the full-pose calibration: circle-point measurements and measured poses.

``MEASUREMENTS.csv`` (circle-point measurements, Sensors 2013 Section 2.3)
--------------------------------------------------------------------------
One row per measured target position; lines starting with ``#`` are comments::

    config,q1,q2,...,qN,angle_index,x,y,z
    c01,0.10,-0.52,...,1.20,0,512.031,-80.112,233.870
    c01,0.10,-0.52,...,1.55,1,498.540,-62.003,233.861
    ...

* ``config``: a label naming the robot configuration (any text); its rows may come in
  any order.
* ``q1..qN``: the joint angles (rad) when that point was measured: the locked joints
  q1..q(N-1) are the same on every row of a configuration (within 1e-4 rad), the last
  joint qN changes monotonically with ``angle_index``.
* ``angle_index``: 0, 1, ..., m-1: the order in which the last joint visited the points.
  Index 0 is P_1: the measured pose belongs to the configuration of that row.
* ``x,y,z``: the target position in the sensor frame {S}, mm.

Every configuration has the same number m >= 3 of points (a configuration with a lost
point is better dropped than fitted from fewer), and its points must not be collinear.
Errors name the file, the line and the column.

``poses.csv`` (measured full poses, e.g. ``shared/data/fr3-camera``)
-------------------------------------------------------------------
``q1..qN`` (rad), ``r11,r12,...,r33`` the rotation of the measured frame in {S}
(row-major), ``x,y,z`` its origin (mm); one row per configuration.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.checks import metres_hint
from lasercal.solver.formats.table import csv_rows
from lasercal.solver.identify.circlepoint import circle_point_pose, collinear

LOCKED_TOL = 1e-4  # rad: the locked joints of one configuration must agree this well
_ROT_TOL = 1e-6  # |R^T R - I| above this in poses.csv is an error, not a rounding


@dataclass(frozen=True)
class CirclePointData:
    """Circle-point measurements of g configurations with m points each.

    Attributes
    ----------
    q : (g, m, n) array, joint angles at each measured point, rad
    points : (g, m, 3) array, target positions in {S}, mm
    labels : tuple of g str, configuration labels
    lines : (g,) int array, line of each configuration's first row in the file (0 if simulated)
    path : str, the source file (or '<simulated>')
    """

    q: np.ndarray
    points: np.ndarray
    labels: tuple
    lines: np.ndarray
    path: str = "<simulated>"

    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Configurations and measured full poses ^S T_E (Section 2.3).

        Returns
        -------
        q : (g, n) array, the configuration of each P_1, rad
        T : (g, 4, 4) array, mm
        """
        sense = np.sign(self.q[:, 1, -1] - self.q[:, 0, -1])
        return self.q[:, 0].copy(), circle_point_pose(self.points, sense)


@dataclass(frozen=True)
class PoseData:
    """Measured full poses.

    Attributes
    ----------
    q : (m, n) array, rad
    T : (m, 4, 4) array, measured frames in {S}, mm
    lines : (m,) int array, file line of each pose
    path : str
    """

    q: np.ndarray
    T: np.ndarray
    lines: np.ndarray
    path: str


def _joint_columns(header: list, path: Path, line: int) -> list:
    """The q1..qN column names of a header, checked to be contiguous from q1."""
    qs = [h for h in header if h.startswith("q") and h[1:].isdigit()]
    if not qs:
        raise FormatError(path, "the header has no joint columns q1..qN", line=line)
    want = [f"q{i}" for i in range(1, len(qs) + 1)]
    if sorted(qs, key=lambda h: int(h[1:])) != want:
        raise FormatError(path, f"joint columns must be q1..q{len(qs)}, got {', '.join(qs)}", line=line)
    return want


def _parse(path: Path, required: list) -> tuple[list, list, list]:
    """Header-checked rows: (column names, [(line, {column: text})], header line)."""
    rows = iter(csv_rows(path))
    try:
        hline, header = next(rows)
    except StopIteration:
        raise FormatError(path, "the file is empty") from None
    for name in required:
        if name not in header:
            raise FormatError(
                path, f"missing column '{name}' (header: {','.join(header)})", line=hline, field=name
            )
    dup = {h for h in header if header.count(h) > 1}
    if dup:
        raise FormatError(path, f"duplicate column(s) {', '.join(sorted(dup))}", line=hline)
    out = []
    for line, row in rows:
        if len(row) != len(header):
            raise FormatError(path, f"{len(row)} values but {len(header)} columns in the header", line=line)
        out.append((line, dict(zip(header, row))))
    if not out:
        raise FormatError(path, "no data rows after the header", line=hline)
    return header, out, hline


def _num(path: Path, line: int, row: dict, col: str) -> float:
    try:
        v = float(row[col])
    except ValueError:
        raise FormatError(path, f"not a number: {row[col]!r}", line=line, field=col) from None
    if not np.isfinite(v):
        raise FormatError(path, f"not a finite number: {row[col]!r}", line=line, field=col)
    return v


def circle_groups(path: Path, rows: list, qcols: list) -> dict[str, dict[int, tuple]]:
    """The rows grouped by configuration: label -> angle_index -> (line, q (n joint values, rad), [x, y, z]
    mm), in the file's order."""
    groups: dict[str, dict[int, tuple]] = {}
    for line, row in rows:
        if not row["config"]:
            raise FormatError(path, "empty configuration label", line=line, field="config")
        try:
            k = int(row["angle_index"])
        except ValueError:
            raise FormatError(
                path,
                f"angle_index must be an integer 0, 1, ..., got {row['angle_index']!r}",
                line=line,
                field="angle_index",
            ) from None
        g = groups.setdefault(row["config"], {})
        if k in g:
            raise FormatError(
                path,
                f"configuration {row['config']!r} has angle_index {k} twice (first on line {g[k][0]})",
                line=line,
                field="angle_index",
            )
        q = [_num(path, line, row, c) for c in qcols]
        p = [_num(path, line, row, c) for c in ("x", "y", "z")]
        g[k] = (line, q, p)
    return groups


def circle_configuration(path: Path, label: str, g: dict, first: str, m: int) -> tuple[int, np.ndarray, list]:
    """One configuration's circle, checked: at least 3 points, as many as the ``first`` configuration's m,
    angle_index 0..m-1, the locked joints still (within ``LOCKED_TOL``), the last joint turning one way.

    Parameters
    ----------
    path : Path; label : str, the configuration; g : dict angle_index -> (line, q, [x, y, z])
    first : str, the first configuration's label; m : int, its point count

    Returns
    -------
    l0 : int, the configuration's first line
    q : (m, n) array, the joint values, rad, by angle_index
    points : list of m [x, y, z], mm
    """
    l0 = min(v[0] for v in g.values())
    if len(g) < 3:
        raise FormatError(
            path,
            f"configuration {label!r} has {len(g)} point(s); a plane and a circle need at least 3",
            line=l0,
            field="config",
        )
    if len(g) != m:
        raise FormatError(
            path,
            f"configuration {label!r} has {len(g)} points but {first!r} has {m}: every configuration "
            "needs the same number",
            line=l0,
            field="config",
        )
    if sorted(g) != list(range(m)):
        raise FormatError(
            path,
            f"configuration {label!r}: angle_index must be 0..{m - 1}, got {sorted(g)}",
            line=l0,
            field="angle_index",
        )
    ordered = [g[k] for k in range(m)]
    q = np.array([v[1] for v in ordered])
    n = q.shape[1]
    off = np.abs(q[:, :-1] - q[0, :-1]).max(axis=0) if n > 1 else np.zeros(0)
    if np.any(off > LOCKED_TOL):
        j = int(np.argmax(off))
        bad = int(np.argmax(np.abs(q[:, j] - q[0, j])))
        raise FormatError(
            path,
            f"configuration {label!r}: locked joint q{j + 1} moved by {off[j]:.3g} rad (only q{n} may turn)",
            line=ordered[bad][0],
            field=f"q{j + 1}",
        )
    dq = np.diff(q[:, -1])
    if not (np.all(dq > 0) or np.all(dq < 0)):
        bad = int(np.argmax(np.sign(dq) != np.sign(dq[0]))) + 1 if dq[0] != 0 else 1
        raise FormatError(
            path,
            f"configuration {label!r}: q{n} must change monotonically with angle_index",
            line=ordered[bad][0],
            field=f"q{n}",
        )
    return l0, q, [v[2] for v in ordered]


def read_circlepoint_csv(path, n: int | None = None) -> CirclePointData:
    """Read and check a MEASUREMENTS.csv (format in the module docstring).

    Parameters
    ----------
    path : str or Path
    n : int, optional, the robot's joint count the file must have

    Returns
    -------
    CirclePointData

    Raises
    ------
    FormatError
        naming file, line and column, on any malformed or inconsistent row
    """
    path = Path(path)
    header, rows, hline = _parse(path, ["config", "angle_index", "x", "y", "z"])
    qcols = _joint_columns(header, path, hline)
    extra = set(header) - set(qcols) - {"config", "angle_index", "x", "y", "z"}
    if extra:
        raise FormatError(path, f"unknown column(s) {', '.join(sorted(extra))}", line=hline)
    if n is not None and len(qcols) != n:
        raise FormatError(
            path, f"the file has {len(qcols)} joint columns but the robot has {n} joints", line=hline
        )
    groups = circle_groups(path, rows, qcols)
    first = next(iter(groups))
    m = len(groups[first])
    labels, lines, Q, P = [], [], [], []
    for label, g in groups.items():
        l0, q, points = circle_configuration(path, label, g, first, m)
        labels.append(label)
        lines.append(l0)
        Q.append(q)
        P.append(points)
    P = np.array(P)
    hint = metres_hint(P.reshape(-1, 3))
    if hint:
        raise FormatError(path, hint, line=hline, field="x")
    Qa = np.array(Q)
    if np.abs(Qa).max() > 2 * np.pi:
        raise FormatError(
            path,
            f"joint angles up to {np.abs(Qa).max():.4g}: these look like degrees (expected rad)",
            line=hline,
        )
    bad = collinear(P)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise FormatError(
            path,
            f"configuration {labels[i]!r}: its points are coincident or collinear, they do not span a "
            "rotation plane",
            line=lines[i],
            field="x",
        )
    return CirclePointData(np.array(Q), P, tuple(labels), np.array(lines), str(path))


def write_circlepoint_csv(path, data: CirclePointData, comments: tuple = ()) -> None:
    """Write circle-point measurements as MEASUREMENTS.csv (format in the module docstring)."""
    g, m, n = data.q.shape
    with open(path, "w", newline="") as f:
        for c in comments:
            f.write(f"# {c}\n")
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["config"] + [f"q{i + 1}" for i in range(n)] + ["angle_index", "x", "y", "z"])
        for lab, q, p in zip(data.labels, data.q, data.points):
            for k in range(m):
                w.writerow([lab] + [f"{v:.9f}" for v in q[k]] + [k] + [f"{v:.6f}" for v in p[k]])


def read_pose_csv(path, n: int | None = None) -> PoseData:
    """Read measured full poses: columns q1..qN, r11..r33, x, y, z (mm, rad).

    Rotations are checked to be orthonormal (|R^T R - I| <= 1e-6) with det +1.

    Parameters
    ----------
    path : str or Path
    n : int, optional, the joint count the file must have

    Returns
    -------
    PoseData
    """
    path = Path(path)
    rcols = [f"r{i}{j}" for i in range(1, 4) for j in range(1, 4)]
    header, rows, hline = _parse(path, rcols + ["x", "y", "z"])
    qcols = _joint_columns(header, path, hline)
    extra = set(header) - set(qcols) - set(rcols) - {"x", "y", "z"}
    if extra:
        raise FormatError(path, f"unknown column(s) {', '.join(sorted(extra))}", line=hline)
    if n is not None and len(qcols) != n:
        raise FormatError(
            path, f"the file has {len(qcols)} joint columns but the robot has {n} joints", line=hline
        )
    q = np.array([[_num(path, ln, r, c) for c in qcols] for ln, r in rows])
    T = np.tile(np.eye(4), (len(rows), 1, 1))
    for i, (ln, r) in enumerate(rows):
        R = np.array([_num(path, ln, r, c) for c in rcols]).reshape(3, 3)
        if np.abs(R.T @ R - np.eye(3)).max() > _ROT_TOL or np.linalg.det(R) < 0:
            raise FormatError(
                path, "r11..r33 is not a rotation matrix (orthonormal, det +1)", line=ln, field="r11"
            )
        T[i, :3, :3] = R
        T[i, :3, 3] = [_num(path, ln, r, c) for c in ("x", "y", "z")]
    hint = metres_hint(T[:, :3, 3])
    if hint:
        raise FormatError(path, f"pose origins x, y, z: {hint}", line=hline, field="x")
    return PoseData(q, T, np.array([ln for ln, _ in rows]), str(path))
