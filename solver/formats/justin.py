"""DLR's Agile Justin: the robot from its published facts, and DLR's measurement records.

Robot (:func:`justin_model`, eq. J1). The facts file (``robot-facts.yaml``, lengths m, angles deg)
gives a Craig (modified) DH table, the transform into row i being Rx(alpha_i) Tx(r_i) Rz(theta_i + q_i)
Tz(d_i): torso rows 0..3 after the static frame ``torso_base``, each arm's rows after its static arm-base
frame on torso row 3, the TCP after each arm's last row (each static rotation taken as the nearest rotation:
the facts print cos 30 deg as 0.866). Joint i's frame F_i at q = 0 is the product of
the static frames and the rows up to i (q = 0); its screw is S_i = (z_i, -z_i x o_i) (mm). The torso's
4th joint is passive, q = -(q2 + q3) of the commanded joints (1-based: the facts' q1, q2 are the
captures' q2, q3), a coupling row of the robot file; the head's joints (q18, q19, 0 in the data) are
not described: the head's mass rides on the torso at head joints 0. The CAD point masses of each row
(in that row's frame), a 2 kg hand 0.1 m along each TCP's z and the 3 kg head are summed per joint
into the gravity model (kg, mm at q = 0). Then two lateral axes follow every joint, the x and y axes of
its DH frame (:func:`solver.kinematics.tree.with_lateral_axes`). The targets ``right`` and ``left`` (the
hand markers) start at the dataset page's guesses in the TCP frames and sit on the links
``right_hand`` and ``left_hand``.

Records (:func:`read_dlr_measurements`). DLR's ``measurements.csv``: a header ``,joints,markers``, then
per record the row index, the 19 joint values (rad) as a bracketed array and the 2 x 3 marker positions
(m, camera frame) as a quoted bracketed array over two physical lines, row 0 the right hand.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.checks import read_text
from lasercal.solver.kinematics.model import Link, RobotModel, _frozen
from lasercal.solver.kinematics.tree import with_lateral_axes
from lasercal.solver.whole import dump_yaml

M_TO_MM = 1000.0
N_COMMANDED = 19
ARMS = ("right", "left")


def craig_row(d: float, theta: float, r: float, alpha: float, q: float = 0.0) -> np.ndarray:
    """Rx(alpha) Tx(r) Rz(theta + q) Tz(d) (4, 4): a Craig DH row (lengths as given, angles rad)."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta + q), np.sin(theta + q)
    return np.array(
        [
            [ct, -st, 0, r],
            [st * ca, ct * ca, -sa, -d * sa],
            [st * sa, ct * sa, ca, d * ca],
            [0, 0, 0, 1.0],
        ]
    )


def _frame(a) -> np.ndarray:
    """A static frame of the facts (m) as a rigid transform (mm): the facts print 0.866 for cos 30 deg, so
    the rotation is taken as its nearest rotation (polar decomposition R = U V^T of its SVD)."""
    T = np.array(a, dtype=float)
    U, _, Vt = np.linalg.svd(T[:3, :3])
    T[:3, :3] = U @ Vt
    T[:3, 3] *= M_TO_MM
    return T


def justin_frames(facts: dict) -> tuple[list, list, dict]:
    """Joint names, their frames F_i at q = 0 (4, 4 mm) and the TCPs' frames at q = 0 ({arm: (4, 4)}),
    from the facts' DH table and static frames (eq. J1)."""
    fr = facts["frames"]

    def chain(T, rows):
        out = []
        for d, th, r, al in rows:
            T = T @ craig_row(M_TO_MM * d, np.radians(th), M_TO_MM * r, np.radians(al))
            out.append(T)
        return out

    torso = chain(_frame(fr["torso_base"]), facts["dh"]["torso"])
    names, frames, tcp = [f"torso_{k + 1}" for k in range(4)], list(torso), {}
    for arm in ARMS:
        rows = chain(torso[-1] @ _frame(fr[f"{arm}_arm_base"]), facts["dh"][f"{arm}_arm"])
        names += [f"{arm}_{k + 1}" for k in range(7)]
        frames += rows
        tcp[arm] = rows[-1] @ _frame(fr["tcp"])
    return names, frames, tcp


def justin_model(facts: dict) -> RobotModel:
    """The built-in ``justin`` from the facts (module docstring, eq. J1): 18 joints on a tree, the torso
    coupling, 36 lateral axes, the gravity model and the two hand markers' starting positions."""
    names, frames, tcp = justin_frames(facts)
    n = len(names)
    screws = np.array([np.r_[F[:3, 2], -np.cross(F[:3, 2], F[:3, 3])] for F in frames])
    # masses per joint: first moments (kg mm) and kg
    mass, first = np.zeros(n), np.zeros((n, 3))
    rows = [r for part in ("torso", "right_arm", "left_arm") for r in facts["masses"][part]]
    for r, x, y, z, kg in rows:
        c = frames[int(r)] @ np.r_[M_TO_MM * np.array([x, y, z]), 1.0]
        mass[int(r)] += kg
        first[int(r)] += kg * c[:3]
    for k, arm in enumerate(ARMS):
        j = 4 + 7 * k + 6
        mass[j] += 2.0  # the hand: 2 kg at 0.1 m along the TCP's z
        first[j] += 2.0 * (tcp[arm] @ np.r_[0, 0, 100.0, 1])[:3]
    fr = facts["frames"]
    hd = facts["dh"]["head"]
    head = frames[3] @ _frame(fr["head_base"])
    for d, th, r, al in hd:
        head = head @ craig_row(M_TO_MM * d, np.radians(th), M_TO_MM * r, np.radians(al))
    mass[3] += 3.0  # the head, at head joints 0
    first[3] += 3.0 * (head @ np.r_[10.0, -140.0, 0, 1])[:3]
    links = tuple(Link(float(m), _frozen(f / m)) for m, f in zip(mass, first))
    commanded = names[:3] + names[4:] + ["head_1", "head_2"]
    C = np.zeros((n, N_COMMANDED))
    for i, nm in enumerate(names):
        if nm in commanded:
            C[i, commanded.index(nm)] = 1.0
    C[3, 1] = C[3, 2] = -1.0  # the passive torso joint keeps the chest upright: q = -(q2 + q3)
    marker = {"right": [-100.0, -30.0, 100.0], "left": [-100.0, 30.0, 50.0]}
    targets = {arm: (tcp[arm] @ np.r_[marker[arm], 1.0])[:3] for arm in ARMS}
    parents = [-1, 0, 1, 2] + [3, 4, 5, 6, 7, 8, 9] + [3, 11, 12, 13, 14, 15, 16]
    joint_links = names[:10] + ["right_hand"] + names[11:17] + ["left_hand"]
    base = RobotModel(
        name="justin",
        joint_names=tuple(names),
        screws=_frozen(screws),
        limits=_frozen(np.tile([-2 * np.pi, 2 * np.pi], (n, 1))),
        laser_dir=_frozen([0, 0, 1.0]),
        aperture=_frozen(targets["right"]),
        targets={k: _frozen(v) for k, v in targets.items()},
        links=links,
        parents=tuple(parents),
        joint_links=tuple(joint_links),
        lateral_of=(-1,) * n,
        commanded=tuple(commanded),
        coupling=_frozen(C),
        coupling_offset=_frozen(np.zeros(n)),
        target_links={"right": "right_hand", "left": "left_hand"},
        # a joint error map's knots a priori 1 mrad (the defaults' 0.3 mrad is the UR10's): 5-fold on 280 of
        # the 350 shared records, the map (0.5 rad) predicted 3.614 mm with 1 mrad, 3.627 with 0.3, 3.698
        # with 3 (the other 70 records held out: docs/position.md)
        prior={"joint_map_rad": 1e-3},
        notes=(
            "built from DLR's published facts (robot-facts.yaml; solver/formats/justin.py, eq. J1); the "
            "facts give no joint limits: +-2 pi rad; the head is not described (its joints are 0 in the "
            "data)",
        ),
    )
    return with_lateral_axes(base, np.array(frames))


# ----------------------------------------------------------------------------- DLR's records
def _array(text: str, n: int, path, line: int, field: str) -> np.ndarray:
    body = text.replace("[", " ").replace("]", " ").split()
    try:
        a = np.array([float(v) for v in body])
    except ValueError:
        raise FormatError(
            path, f"{field} must be {n} numbers in brackets, got {text[:60]!r}", line=line, field=field
        ) from None
    if a.size != n or not np.all(np.isfinite(a)):
        got = f"{a.size}" if a.size != n else f"{np.count_nonzero(~np.isfinite(a))} not finite"
        raise FormatError(path, f"{field} must be {n} finite numbers, got {got}", line=line, field=field)
    return a


def read_dlr_measurements(path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """DLR's measurement records (module docstring).

    Parameters
    ----------
    path : str or Path, DLR's ``measurements.csv``

    Returns
    -------
    index : (m,) int array, each record's own row index (the first column)
    q : (m, 19) array, commanded joint values, rad
    markers : (m, 2, 3) array, the right and left hand markers, mm, camera frame
    lines : (m,) int array, the line each record starts on

    Raises
    ------
    FormatError
        Naming the file, the record's line and the field, for any record that is not three fields, a
        joint array of 19 numbers and a marker array of 2 x 3 numbers.
    """
    path = Path(path)
    text = read_text(path)
    lines_of = io.StringIO(text)
    reader = csv.reader(lines_of)
    header = next(reader, None)
    if header is None or [h.strip() for h in header[1:]] != ["joints", "markers"]:
        raise FormatError(path, "expected DLR's header ',joints,markers'", line=1)
    index, q, mk, lines = [], [], [], []
    start = reader.line_num + 1
    for rec in reader:
        if not rec or all(not f.strip() for f in rec):
            start = reader.line_num + 1
            continue
        if len(rec) != 3:
            raise FormatError(
                path, f"a record has 3 fields (index, joints, markers), got {len(rec)}", line=start
            )
        try:
            index.append(int(rec[0]))
        except ValueError:
            raise FormatError(
                path, f"row index {rec[0]!r} is not a whole number", line=start, field="index"
            ) from None
        q.append(_array(rec[1], N_COMMANDED, path, start, "joints"))
        # to the nanometre: the file's metres carry 9 digits, the product's last bits none
        mk.append(np.round(_array(rec[2], 6, path, start, "markers").reshape(2, 3) * M_TO_MM, 6))
        lines.append(start)
        start = reader.line_num + 1
    if not q:
        raise FormatError(path, "no records", line=2)
    check_units(path, np.array(q), np.array(mk), lines)
    dup = [i for i, k in enumerate(index) if k in index[:i]]
    if dup:
        raise FormatError(path, f"row index {index[dup[0]]} appears twice", line=lines[dup[0]], field="index")
    return np.array(index), np.array(q), np.array(mk), np.array(lines)


MARKERS_FAR_MM = 50_000.0  # a marker farther from a ceiling camera than 50 m was written in mm, not m


def check_units(path, q: np.ndarray, markers_mm: np.ndarray, lines) -> None:
    """Records in the wrong units, refused naming the first one: joints in degrees (beyond +-2 pi, the
    model's limits -- the facts give none -- where radians of a revolute joint cannot be) or markers in
    millimetres (read as metres: tens of kilometres from the cameras).

    Parameters
    ----------
    path : the file, for the message
    q : (m, 19) array, the records' joint values as read (rad)
    markers_mm : (m, 2, 3) array, the markers as read, converted to mm
    lines : sequence of int, each record's first line

    Raises
    ------
    FormatError
        Naming the file, the record's line and the field.
    """
    beyond = np.argwhere(np.abs(q) > 2 * np.pi)
    if beyond.size:
        i, j = beyond[0]
        raise FormatError(
            path,
            f"joint {j + 1} is {q[i, j]:g}, beyond +-2 pi rad in {len({int(k) for k in beyond[:, 0]})} of "
            f"{len(q)} records (expected radians: degrees?)",
            line=lines[i],
            field="joints",
        )
    far = np.argwhere(np.abs(markers_mm).reshape(len(q), -1) > MARKERS_FAR_MM)
    if far.size:
        i = far[0, 0]
        raise FormatError(
            path,
            f"a marker lies {np.abs(markers_mm[i]).max() / 1000:g} m from the cameras (expected metres: "
            "millimetres?)",
            line=lines[i],
            field="markers",
        )


def justin_session_meta(source: str) -> dict:
    """session.yaml of an imported Justin session: robot ``justin``, targets on the hand links."""
    from lasercal.solver.formats.positions import position_meta

    return position_meta(
        "justin",
        {"right": "right_hand", "left": "left_hand"},
        sensor="Vicon (six cameras on the ceiling), positions in the camera frame",
        source=source,
    )


def write_justin_session(src, folder) -> int:
    """DLR's records (:func:`read_dlr_measurements`) -> a position session folder.

    ``captures.csv``: q1..q19 (the commanded joints, rad), ``target`` (right, left), x, y, z (mm, camera
    frame) and ``record`` (DLR's row index, passed through): two rows per record, the right hand first.

    Returns
    -------
    int, the number of records
    """
    from lasercal.solver.formats.session import format_row

    index, q, mk, _ = read_dlr_measurements(src)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)

    (folder / "session.yaml").write_text(
        dump_yaml(
            justin_session_meta(Path(src).name),
            "# imported by `lasercal import-justin` from DLR's measurement records: mm, rad\n",
            sort_keys=False,
            width=120,
        )
    )
    with open(folder / "captures.csv", "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow([f"q{j + 1}" for j in range(N_COMMANDED)] + ["target", "x", "y", "z", "record"])
        for k, qi, m in zip(index, q, mk):
            for arm, y in zip(ARMS, m):
                w.writerow(format_row(qi) + [arm] + format_row(y) + [str(k)])
    return len(index)
