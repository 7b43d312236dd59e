"""Minimal POE parametrisation: link frames and screws from eta (thesis Section 2.2.2).

Each revolute joint carries eta = (w'x, w'y, q'x, q'y), each prismatic joint (the laser)
eta = (v'x, v'y): the joint's screw seen from its own link frame {i}, where it is
(0, 0, 1) through the origin at nominal, so eta = 0 at nominal and no normalisation or
orthogonality constraint is ever needed.
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.kinematics.poe import adjoint, skew

_ON_ORIGIN = 1e-9  # mm: an axis this close to the base origin is taken to pass through it


def _rotation_z_to(d: np.ndarray) -> np.ndarray:
    """Rotation about e = z x d by alpha = arccos(z . d) that takes z onto unit d (eq. 2.2.16).

    The thesis leaves e unnormalised; Rodrigues' formula needs a unit axis, so it is
    normalised here. For d = -z (e = 0, alpha = pi) any axis normal to z works; x is used.
    """
    z = np.array([0.0, 0.0, 1.0])
    e = np.cross(z, d)
    s = np.linalg.norm(e)
    if s < 1e-12:
        return np.eye(3) if d[2] > 0 else np.diag([1.0, -1.0, -1.0])
    E = skew(e / s)
    alpha = np.arccos(np.clip(d[2], -1.0, 1.0))
    return np.eye(3) + np.sin(alpha) * E + (1 - np.cos(alpha)) * E @ E


def link_frame(S: np.ndarray) -> np.ndarray:
    """Link frame T_si of a joint from its screw in the base frame (eqs. 2.2.15-2.2.16).

    Revolute (|omega| = 1): z along omega, origin q at the foot of the perpendicular from
    the base origin, y along q, x = -omega x q / |q| (eq. 2.2.15); if the axis passes
    through the origin, the frame is the base frame rotated to put z on omega (2.2.16).
    Prismatic (omega = 0): as 2.2.16 with v in place of omega.

    Parameters
    ----------
    S : (6,) array, unit-omega (or prismatic, unit-v) screw

    Returns
    -------
    (4, 4) array
    """
    S = np.asarray(S, dtype=float)
    w, v = S[:3], S[3:]
    T = np.eye(4)
    if np.linalg.norm(w) < 1e-12:
        T[:3, :3] = _rotation_z_to(v / np.linalg.norm(v))
        return T
    q = np.cross(w, v)  # closest point of the axis to the origin (w unit, v = -w x q)
    dist = np.linalg.norm(q)
    if dist < _ON_ORIGIN:
        T[:3, :3] = _rotation_z_to(w)
        return T
    y = q / dist
    T[:3, 0] = np.cross(y, w)  # = v/|v|, built from y and z so that it is exactly orthonormal
    T[:3, 1] = y
    T[:3, 2] = w
    T[:3, 3] = q
    return T


def screw_from_eta(T_si: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Screw in the base frame from eta, and its derivative (eqs. 2.2.18-2.2.19).

    Revolute (len(eta) == 4): S' = (w', -w' x q'), w' = (wx, wy, sqrt(1-wx^2-wy^2)),
    q' = (qx, qy, 0). Prismatic (len(eta) == 2): S' = (0, v'), v' = (vx, vy, sqrt(...)).
    S = [Ad_T_si] S' (eq. 2.2.17). The derivative is exact at any eta; at eta = 0 it
    equals [Ad_T_si] B_i with the thesis's B_i (below eq. 2.3.26).

    Parameters
    ----------
    T_si : (4, 4) array, the link frame
    eta : (4,) or (2,) array

    Returns
    -------
    S : (6,) array
    dS_deta : (6, len(eta)) array
    """
    eta = np.asarray(eta, dtype=float)
    a, b = eta[0], eta[1]
    cz = np.sqrt(max(1.0 - a * a - b * b, 1e-12))  # a trial step outside the unit disc must not give NaN
    if eta.size == 2:
        Sp = np.array([0, 0, 0, a, b, cz])
        dSp = np.zeros((6, 2))
        dSp[3:, 0] = (1, 0, -a / cz)
        dSp[3:, 1] = (0, 1, -b / cz)
    else:
        c, d = eta[2], eta[3]
        Sp = np.array([a, b, cz, d * cz, -c * cz, c * b - d * a])  # v' = q' x w'
        dSp = np.zeros((6, 4))
        dSp[:3, 0] = (1, 0, -a / cz)
        dSp[:3, 1] = (0, 1, -b / cz)
        dSp[3:, 0] = (-a * d / cz, a * c / cz, -d)
        dSp[3:, 1] = (-b * d / cz, b * c / cz, c)
        dSp[3:, 2] = (0, -cz, b)
        dSp[3:, 3] = (cz, 0, -a)
    Ad = adjoint(T_si)
    return Ad @ Sp, Ad @ dSp


def normalise_screw(S: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Project a printed screw onto a valid zero-pitch joint screw.

    Revolute: omega scaled to unit length, v made orthogonal to omega (pitch removed).
    Prismatic: v scaled to unit length.

    Returns
    -------
    S : (6,) array, the valid screw
    norm_error : float, | |omega| - 1 | (or | |v| - 1 |) of the input
    pitch : float, omega . v / |omega| of the input, mm
    """
    S = np.asarray(S, dtype=float)
    w, v = S[:3], S[3:]
    nw = np.linalg.norm(w)
    if nw < 1e-12:
        nv = np.linalg.norm(v)
        return np.concatenate([np.zeros(3), v / nv]), abs(nv - 1), 0.0
    wu = w / nw
    pitch = float(wu @ v)
    return np.concatenate([wu, v - pitch * wu]), abs(nw - 1), pitch


def _nearest_on_axis(p: np.ndarray, w: np.ndarray, a: np.ndarray, u: np.ndarray) -> float | None:
    """Axial coordinate t along line p + t w nearest to line a + s u (None when they are parallel)."""
    n = np.cross(w, u)
    if np.linalg.norm(n) < 1e-6:
        return None
    # t solves (p + t w - a) . (w - (w.u) u) = 0, the common normal's foot on the first line
    c = w @ u
    return float((a - p) @ (w - c * u) / (1 - c * c))


def anchor_heights(
    screws: np.ndarray, tip: np.ndarray, parents=None, real=None, tips: dict | None = None
) -> np.ndarray:
    """Where each revolute joint physically sits along its axis, as a height h in its link frame (mm).

    A joint's axis is tilted, by manufacture, about the joint itself -- its bearings -- not about its
    link frame's origin (the foot of the perpendicular from the base origin, eq. 2.2.15), which may lie
    a metre away along the axis. The anchor is the mean of the feet of the common normals with the
    neighbouring axes (the tool point ``tip`` at q = 0 stands in for the last joint's next one; the
    base origin for the first joint's previous one); a parallel neighbour gives none. Tilting eta's
    axis direction by (wx, wy) moves the axis at height h by h (wx, wy): the offset at the joint is
    (qx + h wx, qy + h wy), to first order (:func:`screw_from_eta`).

    On a tree (:mod:`solver.kinematics.tree`) the neighbours are those along the branches: the previous
    one is the nearest joint that turns on the path to the base (lateral axes skipped), the next ones are
    the joints that turn whose previous one this is (a torso's last joint has one per arm), and a joint
    with none is a branch's end: its targets (``tips``) stand in.

    Parameters
    ----------
    screws : (n, 6) array, the reference model's joint screws (mm)
    tip : (3,) array, the tool point or laser aperture at q = 0, mm
    parents : (n,) int array, each joint's parent (-1: the base); default a serial chain, j - 1
    real : (n,) bool array, joints that turn or slide (False: a lateral axis, no anchor and no neighbour)
    tips : dict joint -> list of (3,) arrays, the targets at q = 0 (mm) carried by a branch's last joint
        (default: ``tip`` for every last joint)

    Returns
    -------
    (n,) array, mm (0 for prismatic joints, lateral axes and joints with no anchor)
    """
    n = len(screws)
    par = np.arange(n) - 1 if parents is None else np.asarray(parents, dtype=int)
    real = np.ones(n, bool) if real is None else np.asarray(real, bool)
    prev = np.empty(n, dtype=int)
    for k in range(n):  # the nearest turning ancestor (parents precede children)
        a = par[k]
        prev[k] = a if a < 0 or real[a] else prev[a]
    tips = tips or {}
    h = np.zeros(n)
    for j, S in enumerate(screws):
        w = S[:3]
        if not real[j] or np.linalg.norm(w) < 0.5:
            continue
        T = link_frame(S)
        o = T[:3, 3]
        nxt = [k for k in range(n) if real[k] and prev[k] == j]
        ends = [np.asarray(t, dtype=float) for t in tips.get(j, [tip])] if not nxt else []
        feet = []
        for k in [prev[j]] + nxt:
            if k < 0:
                feet.append(float(w @ (np.zeros(3) - o)))  # the base origin, projected on the axis
            elif np.linalg.norm(screws[k, :3]) < 0.5:
                feet.append(float(w @ (np.asarray(tip, dtype=float) - o)))  # the tool, projected
            else:
                wk = screws[k, :3]
                t = _nearest_on_axis(o, w, np.cross(wk, screws[k, 3:]), wk)
                if t is not None:
                    feet.append(t)
        feet += [float(w @ (e - o)) for e in ends]  # a branch's end: its targets, projected
        h[j] = np.mean(feet) if feet else 0.0
    return h
