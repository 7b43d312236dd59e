"""The fake world's arm: where the true robot's links and laser beam are, by the world's own code.

The simulated world is not drawn with the functions the fit uses (issue 45): the truth's joint screws are
turned into plain homogeneous transforms, each the matrix exponential of its twist (Modern Robotics eq.
3.51, evaluated by :func:`scipy.linalg.expm`), and multiplied along the chain (eq. 4.14):

    T_k(q) = exp([S_1] q_1) ... exp([S_k] q_k),

the laser's aperture a = T_n(q) [M; 1] and its direction d = R_n(q) v / |v| (the laser a prismatic joint of
direction v at q = 0, its aperture M). A beam meets the plane z = z0 where a + s d has height z0.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm


def twist_matrix(screw: np.ndarray, theta: float) -> np.ndarray:
    """[S] theta (4, 4) of a screw S = (omega, v) (6,) turned by theta (rad or mm)."""
    w, v = np.asarray(screw[:3], dtype=float), np.asarray(screw[3:], dtype=float)
    out = np.zeros((4, 4))
    out[:3, :3] = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]]) * theta
    out[:3, 3] = v * theta
    return out


def link_frames(truth, q: np.ndarray) -> np.ndarray:
    """The frames T_0 = I, T_1 ... T_n (n + 1, 4, 4) of one configuration q (n,) rad: each joint's moving
    frame relative to its pose at q = 0, base frame, mm."""
    frames = [np.eye(4)]
    for S, angle in zip(truth.screws, np.asarray(q, dtype=float)):
        frames.append(frames[-1] @ expm(twist_matrix(S, angle)))
    return np.array(frames)


def screw_exponentials(screws: np.ndarray, q: np.ndarray) -> np.ndarray:
    """exp([S_j] q_j) (m, n, 4, 4) of each joint at each configuration q (m, n), in closed form (Modern
    Robotics eq. 3.51: R = I + sin q [w] + (1 - cos q) [w]^2, p = (I q + (1 - cos q) [w] + (q - sin q)
    [w]^2) v for a unit w; R = I, p = v q for a prismatic joint, w = 0) -- :func:`link_frames`' matrix
    exponential, vectorised over configurations."""
    S = np.asarray(screws, dtype=float)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w, v = S[:, :3], S[:, 3:]
    W = np.zeros((len(S), 3, 3))
    W[:, 0, 1], W[:, 0, 2], W[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    W = W - W.transpose(0, 2, 1)
    W2 = W @ W
    revolute = np.linalg.norm(w, axis=1) > 0.5
    s, c = np.sin(q)[..., None, None], np.cos(q)[..., None, None]
    th = q[..., None, None]
    eye = np.eye(3)
    R = np.where(revolute[None, :, None, None], eye + s * W + (1 - c) * W2, eye)
    V = np.where(revolute[None, :, None, None], eye * th + (1 - c) * W + (th - s) * W2, eye * th)
    out = np.zeros(q.shape + (4, 4))
    out[..., :3, :3], out[..., :3, 3], out[..., 3, 3] = R, np.einsum("mjab,jb->mja", V, v), 1.0
    return out


def link_frames_many(screws: np.ndarray, q: np.ndarray) -> np.ndarray:
    """:func:`link_frames` of many configurations q (m, n) rad: T_0 = I .. T_n, (m, n + 1, 4, 4), eq. 4.14."""
    E = screw_exponentials(screws, q)
    out = np.empty((E.shape[0], E.shape[1] + 1, 4, 4))
    out[:, 0] = np.eye(4)
    for j in range(E.shape[1]):
        out[:, j + 1] = out[:, j] @ E[:, j]
    return out


def beam(truth, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The true laser beam at configuration q (n,) rad: aperture (3,) mm and unit direction (3,)."""
    T = link_frames(truth, q)[-1]
    d = T[:3, :3] @ np.asarray(truth.laser_dir, dtype=float)
    return T[:3, :3] @ np.asarray(truth.aperture, dtype=float) + T[:3, 3], d / np.linalg.norm(d)


def plane_spot(a: np.ndarray, d: np.ndarray, z: float) -> tuple[np.ndarray, float]:
    """Where the beam a + s d (mm, unit d) meets the plane of height z: spot (3,) mm and its length s, mm
    (negative: the plane is behind the aperture)."""
    s = (float(z) - a[2]) / d[2]
    return a + s * d, float(s)


def arm_segments(truth, q: np.ndarray) -> np.ndarray:
    """The arm at configuration q as segments (k, 2, 3) mm: from the base through a point on each joint's
    axis (the foot of the common normal from the point before, at q = 0) to the laser aperture -- the
    links' centre lines, thickened into capsules for the camera's line of sight."""
    S = np.asarray(truth.screws, dtype=float)
    pts = [np.zeros(3)]
    for w, v in zip(S[:, :3], S[:, 3:]):
        r = np.cross(w, v)  # the axis's point nearest the origin (|w| = 1)
        pts.append(r + w * np.dot(pts[-1] - r, w))
    T = link_frames(truth, q)
    # a joint's point moves with the joints before it (it lies on its own axis)
    placed = [T[max(i - 1, 0)][:3, :3] @ p + T[max(i - 1, 0)][:3, 3] for i, p in enumerate(pts)]
    placed.append(T[-1][:3, :3] @ np.asarray(truth.aperture, dtype=float) + T[-1][:3, 3])
    P = np.array(placed)
    return np.stack([P[:-1], P[1:]], axis=1)
