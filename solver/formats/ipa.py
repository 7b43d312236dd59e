"""The ipa-robot-accuracy data set (Landgraf et al., CASE 2021): a UR10 measured by a laser tracker.

Robot (:func:`ur10_model`, eq. U1). Universal Robots' published standard DH table of the UR10 (CB3):
frame i = frame i-1 Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i); joint i turns about z of frame i-1,
so its screw is S_i = (z_{i-1}, -z_{i-1} x o_{i-1}) (mm, base frame at q = 0); the flange (tool0) is frame
6, the end-effector frame ``ee.M``; the link masses and centres of mass are UR's, given in each link's DH
frame i and carried to the base frame at q = 0.

Series (:func:`read_series`, docs/real-data.md "A UR10 and a laser tracker"). One folder as published:
a ``measurements_*.csv`` (``;``-separated, decimal commas) with the six joint angles (rad, UR names), the
air temperature (deg C) and the pose of the Leica T-Mac probe on the flange in the tracker's frame:
``measurement_x,y,z`` (mm) and ``measurement_rx,ry,rz`` (deg), Euler angles of the intrinsic x-y'-z''
sequence, R = Rx(rx) Ry(ry) Rz(rz) (scipy's ``'XYZ'``; checked against the robot, docs); B and C give each
value's standard deviation (``measurement_std_*``, mm and deg). The commanded goal pose, the timestamp
(B and C: truncated to the month by a spreadsheet) and the ``Trafo_*`` files are not needed: the probe
mounting and the tracker placement are fitted per session.

Session (:func:`write_ipa_session`): ``measurement: pose`` (docs/fullpose.md "Pose sessions"), captures
``q1..q6,t,temperature,x,y,z,rx,ry,rz[,sx,sy,sz,srx,sry,srz]`` with rx, ry, rz the rotation vector (rad)
and t the row order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.checks import read_text
from lasercal.solver.kinematics.model import Link, RobotModel, _frozen

M_TO_MM = 1000.0
# UR10 (CB3), UR's "Parameters for calculations of kinematics and dynamics": d, a (m), alpha (rad)
UR10_DH = {
    "d": (0.1273, 0.0, 0.0, 0.163941, 0.1157, 0.0922),
    "a": (0.0, -0.612, -0.5723, 0.0, 0.0, 0.0),
    "alpha": (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0),
}
# the same page: link masses (kg) and centres of mass (m) in each link's DH frame i
UR10_MASS = (7.1, 12.7, 4.27, 2.0, 2.0, 0.365)
UR10_COM = (
    (0.021, 0.0, 0.027),
    (0.38, 0.0, 0.158),
    (0.24, 0.0, 0.068),
    (0.0, 0.007, 0.018),
    (0.0, 0.007, 0.018),
    (0.0, 0.0, -0.026),
)
UR_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
EULER = (
    "XYZ"  # the tracker's rx, ry, rz: intrinsic x-y'-z'' (scipy's upper case), checked in docs/real-data.md
)
POSE = ("x", "y", "z", "rx", "ry", "rz")  # the published measurement_* columns


def dh_row(d: float, a: float, alpha: float, theta: np.ndarray) -> np.ndarray:
    """Rz(theta) Tz(d) Tx(a) Rx(alpha) (m, 4, 4): a standard DH row (lengths as given, angles rad)."""
    theta = np.atleast_1d(theta)
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    T = np.zeros((len(theta), 4, 4))
    T[:, 0] = np.stack([ct, -st * ca, st * sa, a * ct], axis=1)
    T[:, 1] = np.stack([st, ct * ca, -ct * sa, a * st], axis=1)
    T[:, 2] = [0.0, sa, ca, d]
    T[:, 3, 3] = 1.0
    return T


def dh_fk(q: np.ndarray, dh: dict = UR10_DH) -> np.ndarray:
    """The flange frames (m, 4, 4) mm of the standard DH chain at joint angles q (m, 6) rad (eq. U1)."""
    q = np.atleast_2d(q)
    T = np.tile(np.eye(4), (len(q), 1, 1))
    for i, (d, a, al) in enumerate(zip(dh["d"], dh["a"], dh["alpha"])):
        T = T @ dh_row(M_TO_MM * d, M_TO_MM * a, al, q[:, i])
    return T


def ur10_model() -> RobotModel:
    """The built-in ``ur10`` (eq. U1): screws, flange frame and gravity model at q = 0 (mm, rad, kg)."""
    F, screws, links = np.eye(4), [], []
    for d, a, al, mass, com in zip(UR10_DH["d"], UR10_DH["a"], UR10_DH["alpha"], UR10_MASS, UR10_COM):
        z, o = F[:3, 2], F[:3, 3]
        screws.append(np.r_[z, -np.cross(z, o)])
        F = F @ dh_row(M_TO_MM * d, M_TO_MM * a, al, 0.0)[0]
        links.append(Link(mass, _frozen(F[:3, :3] @ (M_TO_MM * np.asarray(com)) + F[:3, 3])))
    screws = np.round(np.array(screws), 9) + 0.0  # cos(pi/2) round-off: exact zeros in the file
    return RobotModel(
        name="ur10",
        joint_names=UR_JOINTS,
        screws=_frozen(screws),
        limits=_frozen(np.tile([-2 * np.pi, 2 * np.pi], (6, 1))),
        laser_dir=_frozen([0.0, 0.0, 1.0]),
        aperture=_frozen(F[:3, 3]),
        ee_pose=_frozen(np.round(F, 9) + 0.0),
        links=tuple(Link(lk.mass, _frozen(np.round(lk.com, 6) + 0.0)) for lk in links),
    )


def _series_file(folder: Path) -> Path:
    """The one ``measurements_*.csv`` of a series folder."""
    if not folder.is_dir():
        raise FormatError(folder, "not a series folder (expected the published Series_X folder)")
    found = sorted(folder.glob("measurements_*.csv"))
    if len(found) != 1:
        raise FormatError(
            folder,
            f"expected one measurements_*.csv in the series folder, found {len(found)}"
            + (f" ({', '.join(p.name for p in found)})" if found else ""),
        )
    return found[0]


def _numbers(path: Path, lines: list, header: list) -> np.ndarray:
    """The data lines (decimal commas) as floats (rows, columns); a bad cell is an error naming it."""
    text = [ln.replace(",", ".") for ln in lines]
    try:
        a = np.loadtxt(text, delimiter=";", ndmin=2)
        if a.shape[1] == len(header) and np.all(np.isfinite(a)):
            return a
    except ValueError:
        pass
    for i, ln in enumerate(text):  # only to name the first bad cell
        cells = ln.split(";")
        if len(cells) != len(header):
            raise FormatError(path, f"expected {len(header)} values, found {len(cells)}", line=i + 2)
        for c, h in zip(cells, header):
            try:
                ok = np.isfinite(float(c))
            except ValueError:
                ok = False
            if not ok:
                raise FormatError(path, f"not a finite number: {c!r}", line=i + 2, field=h)
    raise FormatError(path, "unreadable rows", line=2)  # pragma: no cover - loadtxt and the scan agree


def read_series(folder) -> dict:
    """One published series folder (module docstring) as arrays.

    Parameters
    ----------
    folder : str or Path, e.g. ``ur10-tracker/Series_A``

    Returns
    -------
    dict with ``q`` (m, 6) rad, ``T`` (m, 4, 4) the probe in the tracker frame (mm), ``std`` (m, 6) or None
    (x, y, z mm; rx, ry, rz rad, the Euler angles' stated deviations), ``temperature`` (m,) deg C or None,
    ``file``

    Raises
    ------
    FormatError
        A missing column or a bad cell, naming file, line and column.
    """
    path = _series_file(Path(folder))
    lines = [ln for ln in read_text(path).split("\n") if ln.strip()]
    if len(lines) < 2:
        raise FormatError(path, "no measurements (a header and no rows)", line=2)
    header = [h.strip() for h in lines[0].split(";")]
    need = list(UR_JOINTS) + [f"measurement_{k}" for k in POSE]  # the temperature is optional
    missing = [h for h in need if h not in header]
    if missing:
        raise FormatError(path, f"missing column(s) {', '.join(missing)}", line=1, field=missing[0])
    a = _numbers(path, lines[1:], header)
    col = {h: i for i, h in enumerate(header)}
    q = a[:, [col[h] for h in UR_JOINTS]]
    T = np.tile(np.eye(4), (len(a), 1, 1))
    T[:, :3, :3] = Rotation.from_euler(
        EULER, a[:, [col[f"measurement_{k}"] for k in POSE[3:]]], degrees=True
    ).as_matrix()
    T[:, :3, 3] = a[:, [col[f"measurement_{k}"] for k in POSE[:3]]]
    std_cols = [f"measurement_std_{k}" for k in POSE]
    std = None
    if all(h in col for h in std_cols):
        std = a[:, [col[h] for h in std_cols]]
        std[:, 3:] = np.radians(std[:, 3:])
    if np.abs(q).max() > 2 * np.pi + 1e-6:
        i, j = np.unravel_index(np.argmax(np.abs(q)), q.shape)
        raise FormatError(path, f"joint angle {q[i, j]:g}: expected rad", line=int(i) + 2, field=UR_JOINTS[j])
    temp = a[:, col["measurement_temperature"]] if "measurement_temperature" in col else None
    return {"q": q, "T": T, "std": std, "temperature": temp, "file": path}


HALVES = ("first", "second")  # a series split in recording order: rows [0, m // 2) and [m // 2, m)


def write_ipa_session(folder, out, half: str | None = None) -> int:
    """Import one series folder as a pose session (robot ur10) in ``out``; returns the number of captures.

    ``half``: 'first' or 'second' -- only that half of the series in recording order (rows [0, m // 2) or
    [m // 2, m), the split of :func:`~lasercal.solver.analysis.pose_cv.half_scores`): a later series
    split to register a model on one half and predict the other. t keeps the row's place in the series."""
    from lasercal.solver.formats.poses import pose_meta, write_pose_session

    s = read_series(folder)
    m = len(s["q"])
    if half is not None and m < 2:
        raise FormatError(s["file"], f"{m} row: too few to split in halves", line=2)
    rows = slice(0, m) if half is None else slice(0, m // 2) if half == HALVES[0] else slice(m // 2, m)
    meta = pose_meta(
        "ur10",
        sensor="laser tracker with a Leica T-Mac probe on the flange (ipa-robot-accuracy)",
        source=f"{s['file'].parent.name}/{s['file'].name}: Euler {EULER} (deg) -> rotation vector (rad); "
        "t is the row order (the published timestamps are truncated in B and C)"
        + ("" if half is None else f"; its {half} half, rows {rows.start + 1}-{rows.stop} of {m}"),
    )
    if s["std"] is None:
        meta["uncertainty"] = (
            "not stated in this series: the fit weights position and orientation by the noise it estimates "
            "from "
            "its residuals"
        )
    cut = lambda a: None if a is None else a[rows]  # noqa: E731
    t = np.arange(m, dtype=float)[rows]
    write_pose_session(out, meta, s["q"][rows], s["T"][rows], cut(s["std"]), t, cut(s["temperature"]))
    return rows.stop - rows.start
