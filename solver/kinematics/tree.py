"""Kinematic trees: several tips on one base, lateral axes, and the path from the base to a link.

A tree in minimal-POE form keeps every joint's screw S_j in the base frame at q = 0; joint j's
parent p(j) is the joint before it on the path from the base (-1: the base). The frame of the link
joint j moves is (eq. T1, Modern Robotics eq. 4.14 along a branch)

    T_j(q) = T_p(j)(q) e^[S_j] q_j,   T_-1 = I,

and a point on that link moves with every joint on its path and with no other. The product over the
path is the serial POE product of the whole joint list with the joints off the path set to 0
(e^0 = I), which is how :mod:`solver.identify.position` evaluates a target on any branch
(:func:`branch_mask`).

Lateral axes (eq. T2): a joint's link also bends across the joint, about the two axes x_j, y_j of the
joint's frame (z_j its axis). Each is a joint of its own, a child of the joint with screw
(x_j, -x_j x o_j) through the frame's origin o_j, and its value is 0 unless the link bends; a
compliance on it (:mod:`solver.kinematics.effects`, ``lateral_compliance``) bends it by c times the
gravity torque about that axis.
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.kinematics.model import Link, RobotModel, _frozen
from lasercal.solver.kinematics.poe import adjoint, exp6


def parents_of(model: RobotModel) -> np.ndarray:
    """(n,) int: each joint's parent joint (-1: the base); a serial chain's are j - 1."""
    return np.array(model.parents, dtype=int) if model.parents else np.arange(model.n) - 1


def ancestors(model: RobotModel) -> np.ndarray:
    """(n, n) bool A: A[i, j] when joint j moves the link of joint i (j on the path base..i, i included)."""
    par = parents_of(model)
    A = np.eye(model.n, dtype=bool)
    for i in range(model.n):  # parents precede children (checked on load)
        if par[i] >= 0:
            A[i] |= A[par[i]]
    return A


def link_joint(model: RobotModel, link: str | None) -> int:
    """The joint whose frame carries ``link`` (the last joint that moves it, lateral axes included); the last
    joint when ``link`` is None or the model names no links; -1 for the base."""
    if link is None or not model.joint_links:
        return model.n - 1
    idx = [i for i, nm in enumerate(model.joint_links) if nm == link]
    return idx[-1] if idx else -1


def target_joint(model: RobotModel, name: str) -> int:
    """The joint whose frame carries target ``name`` (:func:`link_joint` of its ``target_links`` entry)."""
    return link_joint(model, model.target_links.get(name))


def branch_mask(model: RobotModel, names) -> np.ndarray:
    """(m, n) float: 1 for the joints on the path of each row's target, 0 elsewhere (eq. T1).

    Parameters
    ----------
    model : RobotModel
    names : (m,) array of str, the target of each row
    """
    names = np.asarray(names, dtype=object)
    if not model.parents:
        return np.ones((len(names), model.n))
    A = np.vstack([ancestors(model), np.zeros((1, model.n), bool)])  # row -1: the base, moved by nothing
    rows = {nm: target_joint(model, nm) for nm in dict.fromkeys(names)}
    return A[[rows[nm] for nm in names]].astype(float)


def branch_groups(model: RobotModel, names) -> list[tuple[np.ndarray, np.ndarray]]:
    """The rows grouped by their target's path, each group a serial chain (eq. T1).

    A tree's rows are evaluated branch by branch on the joints of their path only (a hand's rows on the
    torso and that arm, not on the other arm's joints at 0); a serial arm is one group: every row, every
    joint.

    Parameters
    ----------
    model : RobotModel
    names : (m,) array of str, the target of each row

    Returns
    -------
    list of (rows (k,) int, path (l,) int): row indices and the joints on their path, base to tip
    """
    names = np.asarray(names, dtype=object)
    if not model.parents:
        return [(np.arange(len(names)), np.arange(model.n))]
    A = np.vstack([ancestors(model), np.zeros((1, model.n), bool)])  # row -1: the base, moved by nothing
    joint = {nm: target_joint(model, nm) for nm in dict.fromkeys(names)}
    last = np.array([joint[nm] for nm in names], dtype=int)
    return [(np.flatnonzero(last == j), np.flatnonzero(A[j])) for j in dict.fromkeys(last.tolist())]


def tree_frames(model: RobotModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's link frame T_j(q) and the joints' space twists (eq. T1).

    Parameters
    ----------
    model : RobotModel
    q : (m, n) array, rad (mm for prismatic joints)

    Returns
    -------
    T : (m, n, 4, 4) array, T_j = T_p(j) e^[S_j] q_j
    J : (m, 6, n) array, column j = Ad(T_p(j)) S_j: joint j's screw at q (Modern Robotics eq. 5.11)
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m, n = q.shape
    E = exp6(model.screws[None, :, :] * q[:, :, None])
    par = parents_of(model)
    T = np.empty((m, n, 4, 4))
    before = np.empty((m, n, 4, 4))
    for j in range(n):  # a loop over joints, vectorised over configurations
        before[:, j] = np.eye(4) if par[j] < 0 else T[:, par[j]]
        T[:, j] = before[:, j] @ E[:, j]
    return T, np.einsum("mnij,nj->min", adjoint(before), model.screws)


def with_lateral_axes(model: RobotModel, frames: np.ndarray | None = None, joints=None) -> RobotModel:
    """The model with two lateral axes after each named joint (eq. T2).

    Parameters
    ----------
    model : RobotModel
    frames : (n, 4, 4) array, each joint's frame at q = 0 (z its axis; mm), optional (default: the
        minimal-POE link frame, :func:`solver.kinematics.minimal.link_frame`)
    joints : iterable of 0-based revolute joints to give lateral axes (default: every revolute joint)

    Returns
    -------
    RobotModel whose lateral joints ``NAME.x``, ``NAME.y`` follow each joint (children of it, the
    joint's children re-parented to ``NAME.y``), limits +-0.1 rad, the joint's link (and its mass,
    carried by the last of the three) -- a serial model becomes a tree description
    """
    from lasercal.solver.kinematics.minimal import link_frame

    n = model.n
    if frames is None:
        frames = np.array([link_frame(S) for S in model.screws])
    chosen = set(range(n) if joints is None else joints) - set(np.flatnonzero(model.prismatic))
    par = parents_of(model)
    lat_of = list(model.lateral_of) if model.lateral_of else [-1] * n
    links = list(model.joint_links) if model.joint_links else [f"link{i + 1}" for i in range(n)]
    new_index, names, screws, limits, parents, jlinks, lateral, masses = {}, [], [], [], [], [], [], []
    last = {}  # original joint -> the new index its children hang from
    coupling_rows, offsets = [], []
    C = model.coupling if model.coupling is not None else np.eye(n)
    b = model.coupling_offset if model.coupling_offset is not None else np.zeros(n)
    for j in range(n):
        new_index[j] = len(names)
        names.append(model.joint_names[j])
        screws.append(model.screws[j])
        limits.append(model.limits[j])
        parents.append(-1 if par[j] < 0 else last[par[j]])
        jlinks.append(links[j])
        lateral.append(-1 if lat_of[j] < 0 else new_index[lat_of[j]])
        coupling_rows.append(C[j])
        offsets.append(b[j])
        masses.append(Link(0.0, _frozen(np.zeros(3))))
        last[j] = new_index[j]
        if j in chosen:
            for ax, col in (("x", 0), ("y", 1)):
                w = frames[j][:3, col]
                names.append(f"{model.joint_names[j]}.{ax}")
                screws.append(np.r_[w, -np.cross(w, frames[j][:3, 3])])
                limits.append(np.array([-0.1, 0.1]))
                parents.append(len(names) - 2)
                jlinks.append(links[j])
                lateral.append(new_index[j])
                coupling_rows.append(np.zeros(C.shape[1]))
                offsets.append(0.0)
                masses.append(Link(0.0, _frozen(np.zeros(3))))
            last[j] = len(names) - 1
        if model.links:
            masses[last[j]] = model.links[j]
    commanded = model.commanded or model.joint_names
    return model.replace(
        joint_names=tuple(names),
        screws=np.array(screws),
        limits=np.array(limits),
        parents=tuple(int(p) for p in parents),
        joint_links=tuple(jlinks),
        lateral_of=tuple(int(v) for v in lateral),
        links=tuple(masses) if model.links else (),
        commanded=tuple(commanded),
        coupling=np.array(coupling_rows),
        coupling_offset=np.array(offsets),
        home=None,
    )
