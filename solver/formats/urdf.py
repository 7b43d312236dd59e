"""Robot models from URDF, and calibrated URDFs out.

Parser: ``urdf_parser_py`` (PyPI ``urdfdom-py``), the ROS project's own Python URDF parser,
maintained with urdfdom and light (lxml and PyYAML only). It reads the XML; the chain, the
screws and the units are ours.

In. The chain runs from ``base_link`` (default: the root) to ``tip_link`` (default: the one
leaf reached through the most movable joints); fixed joints are folded into the next
transform. At q = 0 joint i's frame is T_i = prod(origins up to joint i) (URDF metres ->
mm); a revolute/continuous joint has the screw S_i = (w, -w x p), w = R_i axis, p = T_i's
origin; a prismatic one S_i = (0, R_i axis) (thesis eq. 2.2.14 from the URDF's chain).
Limits come from the URDF (prismatic ones in mm); a continuous joint has none and gets
[-2 pi, 2 pi] (stated in the model's notes). Masses and centres of mass of the links riding
on each joint form the gravity model when every such link has an inertial.

Out. :func:`calibrated_urdf` rewrites only the ``<origin>`` and ``<axis>`` of the chain's
movable joints in the original XML (names, limits, inertias, meshes, everything else
kept): joint i's frame keeps its nominal orientation R_i, its origin moves to the point of
the calibrated axis nearest the nominal origin, and its axis becomes R_i^T w_i (for a
prismatic joint R_i^T v_i, origin kept). Fixed links get ``lasercal_<target>`` child links
of the tip (targets, or the end-effector frame {E} as ``lasercal_ee``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import FormatError
from lasercal.solver.kinematics.model import Link, RobotModel, _frozen
from lasercal.solver.kinematics.poe import inv_T

MOVABLE = ("revolute", "continuous", "prismatic")
CONTINUOUS_LIMIT = 2 * math.pi  # rad: the range given to a continuous joint (it has no limits)
M_TO_MM = 1000.0
EE_LINK = "lasercal_ee"  # the full-pose frame {E} (model.ee_pose) in every URDF lasercal writes
URDF_MAX_M = 50.0  # a joint origin further than this (m) from its parent is a length written in mm


def origin_T(xyz, rpy) -> np.ndarray:
    """The URDF ``<origin>`` transform: translation xyz (m -> mm), rotation Rz(y) Ry(p) Rx(r)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy if rpy is not None else (0, 0, 0)).as_matrix()
    T[:3, 3] = M_TO_MM * np.asarray(xyz if xyz is not None else (0, 0, 0), float)
    return T


def _parse(path: Path):
    from urdf_parser_py import urdf as U
    from urdf_parser_py.xml_reflection import core

    try:
        data = path.read_bytes()  # bytes: the XML parser honours the file's own encoding declaration
    except IsADirectoryError:
        raise FormatError(path, "is a folder (expected a URDF file)") from None
    except OSError as e:
        raise FormatError(path, f"cannot read file ({e.strerror})") from None
    messages = []
    saved = core.on_error
    core.on_error = messages.append  # the parser's warnings become our notes, not stderr noise
    try:
        robot = U.URDF.from_xml_string(data)
    except Exception as e:  # the parser raises bare exceptions on malformed XML
        reason = " ".join(str(e).split()) or type(e).__name__
        raise FormatError(path, f"not a valid URDF ({reason})") from None
    finally:
        core.on_error = saved
    return robot, messages


def _chain(robot, path: Path, base_link: str | None, tip_link: str | None) -> tuple[str, str, list]:
    """(base, tip, joints from base to tip); FormatError if no chain joins them."""
    links = {lk.name for lk in robot.links}
    for key, nm in (("base_link", base_link), ("tip_link", tip_link)):
        if nm is not None and nm not in links:
            raise FormatError(path, f"{key} {nm!r} is not a link of the URDF", field=key)
    base = base_link or robot.get_root()
    if tip_link is None:
        below = {}  # leaf -> movable joints from base

        def walk(link, k):
            kids = robot.child_map.get(link, [])
            if not kids:
                below[link] = k
            for jn, child in kids:
                walk(child, k + (robot.joint_map[jn].type in MOVABLE))

        walk(base, 0)
        most = max(below.values())
        leaves = [lk for lk, k in below.items() if k == most]
        if len(leaves) > 1:
            raise FormatError(
                path,
                f"the tree below {base!r} branches into {', '.join(sorted(leaves))}: name the chain's end "
                "with tip_link",
                field="tip_link",
            )
        tip_link = leaves[0]
    joints, link = [], tip_link
    while link != base:
        if link not in robot.parent_map:
            raise FormatError(
                path,
                f"tip_link {tip_link!r} is not below base_link {base!r}: no chain joins them",
                field="tip_link",
            )
        jn, link = robot.parent_map[link]
        joints.append(robot.joint_map[jn])
    return base, tip_link, joints[::-1]


def _missing_meshes(robot, path: Path) -> list[str]:
    notes = []
    for lk in robot.links:
        for kind in ("visuals", "collisions"):
            for g in getattr(lk, kind, []) or []:
                fn = getattr(g.geometry, "filename", None)
                if (
                    fn
                    and not fn.startswith("package://")
                    and not (path.parent / fn.replace("file://", "")).exists()
                ):
                    notes.append(
                        f"{path}: link {lk.name!r} {kind[:-1]} mesh {fn!r} not found: ignored (calibration "
                        "reads "
                        "no meshes; an exported URDF keeps the reference)"
                    )
    return notes


def load_urdf(path, base_link: str | None = None, tip_link: str | None = None) -> RobotModel:
    """A :class:`RobotModel` from the URDF chain ``base_link`` -> ``tip_link`` (module docstring).

    Parameters
    ----------
    path : str or Path, the URDF file
    base_link, tip_link : str, optional, the chain's ends (needed when the tree branches)

    Returns
    -------
    RobotModel in mm, rad; ``ee_pose`` is tip_link's frame at q = 0, ``urdf`` records file and chain
    """
    path = Path(path).resolve()
    robot, messages = _parse(path)
    base, tip, joints = _chain(robot, path, base_link, tip_link)
    notes = [f"{path}: {m}" for m in messages] + _missing_meshes(robot, path)
    T = np.eye(4)
    names, screws, limits, frames, owner = [], [], [], [], {base: -1}
    for j in joints:
        o = j.origin
        if o is not None and o.xyz is not None and np.abs(o.xyz).max() > URDF_MAX_M:
            raise FormatError(
                path,
                f"joint {j.name!r} origin xyz {list(o.xyz)} is over {URDF_MAX_M:g} m: these look like mm "
                "(URDF lengths are metres)",
                field=f"joint {j.name}",
            )
        T = T @ origin_T(o.xyz if o else None, o.rpy if o else None)
        if j.type not in MOVABLE + ("fixed",):
            raise FormatError(
                path, f"joint {j.name!r} of type {j.type!r} is not supported", field=f"joint {j.name}"
            )
        if j.type in MOVABLE:
            a = np.asarray(j.axis if j.axis is not None else (1, 0, 0), float)
            if np.linalg.norm(a) < 1e-9:
                raise FormatError(path, f"joint {j.name!r} has a zero axis", field=f"joint {j.name}.axis")
            w = T[:3, :3] @ (a / np.linalg.norm(a))
            screws.append(
                np.r_[np.zeros(3), w] if j.type == "prismatic" else np.r_[w, -np.cross(w, T[:3, 3])]
            )
            scale = M_TO_MM if j.type == "prismatic" else 1.0
            if j.type == "continuous" or j.limit is None:
                if j.type != "continuous":
                    raise FormatError(path, f"joint {j.name!r} has no <limit>", field=f"joint {j.name}.limit")
                limits.append((-CONTINUOUS_LIMIT, CONTINUOUS_LIMIT))
                notes.append(f"{path}: continuous joint {j.name!r} has no limits: [-2 pi, 2 pi] rad used")
            else:
                limits.append((scale * j.limit.lower, scale * j.limit.upper))
                if not limits[-1][0] < limits[-1][1]:
                    raise FormatError(
                        path,
                        f"joint {j.name!r}: limit lower must be below upper",
                        field=f"joint {j.name}.limit",
                    )
            names.append(j.name)
            frames.append(T.copy())
        owner[j.child] = len(names) - 1
    if not names:
        raise FormatError(path, f"no movable joint between {base!r} and {tip!r}", field="tip_link")
    links = _gravity_links(robot, joints, owner, len(names))
    return RobotModel(
        **_mimic_coupling(path, [j for j in joints if j.type in MOVABLE]),
        name=robot.name or path.stem,
        joint_names=tuple(names),
        screws=_frozen(screws),
        limits=_frozen(limits),
        laser_dir=_frozen(T[:3, 2]),  # no laser: the tip frame's z and origin stand in (unused)
        aperture=_frozen(T[:3, 3]),
        ee_pose=_frozen(T),
        links=links,
        urdf={"file": str(path), "base_link": base, "tip_link": tip, "joints": [j.name for j in joints]},
        notes=tuple(notes),
    )


def _mimic_coupling(path: Path, movable: list) -> dict:
    """The chain's ``<mimic joint=K multiplier=c offset=b>`` joints as the one-source case of a coupling
    (:mod:`solver.kinematics.model`): q_j = c q_K + b, q_K commanded (a mimic of a mimic composed), in the
    model's units (mm for a prismatic joint: c scaled by the units' ratio, b by its joint's). The RobotModel
    fields ``commanded``, ``coupling``, ``coupling_offset``; none without a mimic.

    Raises FormatError when a mimic's joint is not a movable joint of the chain, or the mimics form a cycle.
    """
    if not any(j.mimic is not None for j in movable):
        return {}
    index = {j.name: i for i, j in enumerate(movable)}
    scale = [M_TO_MM if j.type == "prismatic" else 1.0 for j in movable]

    def source(i, seen=()):
        """(commanded joint index, coefficient, offset) driving joint i, in model units."""
        mm = movable[i].mimic
        if mm is None:
            return i, 1.0, 0.0
        where = f"joint {movable[i].name}.mimic"
        if mm.joint not in index:
            raise FormatError(path, f"mimics {mm.joint!r}, not a movable joint of the chain", field=where)
        if i in seen:
            raise FormatError(path, "mimic joints form a cycle", field=where)
        k = index[mm.joint]
        c = 1.0 if mm.multiplier is None else float(mm.multiplier)
        b = 0.0 if mm.offset is None else float(mm.offset)
        r, c2, b2 = source(k, seen + (i,))
        # q_i / scale_i = c q_k / scale_k + b, q_k = c2 q_r + b2 (model units)
        f = c * scale[i] / scale[k]
        return r, f * c2, f * b2 + b * scale[i]

    commanded = [i for i, j in enumerate(movable) if j.mimic is None]
    col = {i: k for k, i in enumerate(commanded)}
    C, b = np.zeros((len(movable), len(commanded))), np.zeros(len(movable))
    for i in range(len(movable)):
        r, c, off = source(i)
        C[i, col[r]], b[i] = c, off
    return {
        "commanded": tuple(movable[i].name for i in commanded),
        "coupling": _frozen(C),
        "coupling_offset": _frozen(b),
    }


def _gravity_links(robot, joints, owner: dict, n: int) -> tuple:
    """One lumped Link per movable joint (the chain's links it carries), or () if one carries no mass."""
    T, mass, first = np.eye(4), np.zeros(n), np.zeros((n, 3))
    for j in joints:
        o = j.origin
        T = T @ origin_T(o.xyz if o else None, o.rpy if o else None)
        i = owner[j.child]
        inert = robot.link_map[j.child].inertial
        if i < 0 or inert is None or not inert.mass:
            continue
        io = inert.origin
        c = (T @ origin_T(io.xyz if io else None, None))[:3, 3]
        mass[i] += inert.mass
        first[i] += inert.mass * c
    if np.any(mass <= 0):
        return ()
    return tuple(Link(float(m), _frozen(f / m)) for m, f in zip(mass, first))


# ----------------------------------------------------------------------------- out
def _fmt(a) -> str:
    return " ".join(repr(float(x)) for x in a)


def _set_origin(el: ET.Element, T: np.ndarray) -> None:
    o = el.find("origin")
    if o is None:
        o = ET.SubElement(el, "origin")
    o.set("xyz", _fmt(T[:3, 3] / M_TO_MM))
    o.set("rpy", _fmt(Rotation.from_matrix(T[:3, :3]).as_euler("xyz")))


def calibrated_frames(model: RobotModel, nominal: RobotModel) -> list[np.ndarray]:
    """Calibrated joint frames at q = 0 (n, 4, 4): nominal orientation, origin on the calibrated axis
    nearest the nominal origin (prismatic: nominal origin)."""
    out = []
    for S, T0 in zip(model.screws, _joint_frames(nominal)):
        T = T0.copy()
        w = S[:3]
        if np.linalg.norm(w) > 0.5:
            c = np.cross(w, S[3:])  # the axis point nearest the base origin
            T[:3, 3] = c + ((T0[:3, 3] - c) @ w) * w
        out.append(T)
    return out


def _joint_frames(nominal: RobotModel) -> list[np.ndarray]:
    """Nominal joint frames at q = 0 re-read from the model's URDF."""
    path = Path(nominal.urdf["file"])
    robot, _ = _parse(path)
    _, _, joints = _chain(robot, path, nominal.urdf["base_link"], nominal.urdf["tip_link"])
    T, out = np.eye(4), []
    for j in joints:
        o = j.origin
        T = T @ origin_T(o.xyz if o else None, o.rpy if o else None)
        if j.type in MOVABLE:
            out.append(T.copy())
    return out


def calibrated_urdf(model: RobotModel) -> str:
    """The model's source URDF with calibrated joint origins and axes and fixed tool links (module docstring).

    Parameters
    ----------
    model : RobotModel with ``urdf`` (from :func:`load_urdf`, then identified)

    Returns
    -------
    str, the URDF XML
    """
    if not model.urdf:
        raise FormatError("<model>", "the model did not come from a URDF: export --format urdf needs one")
    path = Path(model.urdf["file"])
    nominal = load_urdf(path, model.urdf["base_link"], model.urdf["tip_link"])
    if nominal.n != model.n:
        raise FormatError(path, f"the URDF chain has {nominal.n} joints, the model {model.n}", field="urdf")
    new = calibrated_frames(model, nominal)
    robot, _ = _parse(path)
    _, tip, joints = _chain(robot, path, model.urdf["base_link"], model.urdf["tip_link"])
    tree = ET.parse(path, ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    root = tree.getroot()
    elements = {el.get("name"): el for el in root.findall("joint")}
    T_parent, k = np.eye(4), 0  # the current link's calibrated frame
    for j in joints:
        o = j.origin
        step = origin_T(o.xyz if o else None, o.rpy if o else None)
        if j.type in MOVABLE:
            el = elements[j.name]
            _set_origin(el, inv_T(T_parent) @ new[k])
            S = model.screws[k]
            a = new[k][:3, :3].T @ (S[3:] if j.type == "prismatic" else S[:3])
            ax = el.find("axis")
            if ax is None:
                ax = ET.SubElement(el, "axis")
            ax.set("xyz", _fmt(a / np.linalg.norm(a)))
            T_parent = new[k]
            k += 1
        else:
            T_parent = T_parent @ step
    tools = dict(model.targets) if model.targets else {}
    frames = {f"lasercal_{nm}": _point_frame(p) for nm, p in tools.items()}
    if model.ee_pose is not None and not tools:
        frames[EE_LINK] = np.asarray(model.ee_pose)
    for nm, F in frames.items():
        ET.SubElement(root, "link", name=nm)
        jt = ET.SubElement(root, "joint", name=f"{nm}_joint", type="fixed")
        ET.SubElement(jt, "parent", link=tip)
        ET.SubElement(jt, "child", link=nm)
        _set_origin(jt, inv_T(T_parent) @ F)
    root.append(
        ET.Comment(
            f" calibrated by lasercal ({__name__}): joint origins and axes of the chain; fixed lasercal_* "
            "links "
        )
    )
    ET.indent(tree)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def _point_frame(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def sensor_urdf(model: RobotModel, sensor_link: str = "sensor") -> str:
    """A separate URDF of the sensor-to-base transform: link ``sensor``, fixed joint to the base link.

    Returns
    -------
    str, the URDF XML (``^S T_base`` as the joint origin, m)
    """
    if model.sensor_pose is None or not model.urdf:
        raise FormatError("<model>", "the model has no sensor transform (sensor.T) from a URDF robot")
    root = ET.Element("robot", name=f"{sensor_link}_to_{model.urdf['base_link']}")
    ET.SubElement(root, "link", name=sensor_link)
    ET.SubElement(root, "link", name=model.urdf["base_link"])
    jt = ET.SubElement(root, "joint", name=f"{sensor_link}_to_base", type="fixed")
    ET.SubElement(jt, "parent", link=sensor_link)
    ET.SubElement(jt, "child", link=model.urdf["base_link"])
    _set_origin(jt, np.asarray(model.sensor_pose))
    tree = ET.ElementTree(root)
    ET.indent(tree)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def tip_frame(model: RobotModel) -> np.ndarray:
    """The chain's tip link at q = 0 (4, 4) mm, carried by the calibrated joints: where
    :func:`calibrated_urdf` puts it (the nominal tip, fixed in the last joint's calibrated frame).

    Parameters
    ----------
    model : RobotModel with ``urdf`` (from :func:`load_urdf`, identified or not)
    """
    path = Path(model.urdf["file"])
    nominal = load_urdf(path, model.urdf["base_link"], model.urdf["tip_link"])
    last = _joint_frames(nominal)[-1]
    return calibrated_frames(model, nominal)[-1] @ inv_T(last) @ np.asarray(nominal.ee_pose)
