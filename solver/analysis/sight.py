"""Whether a camera sees a spot, and the sheet's markers, past the arm (issue 53): what a hands-free camera
session's coach plans with, so that it asks for no pose whose spot its camera cannot measure.

The arm is taken as capsules of radius r about its links' centre lines: from the base through a point on
each joint's axis (the foot of the perpendicular from the point before, at q = 0) to the laser's aperture,
each point carried by the joints before it (eq. 2.2.14's prefix products). A line of sight from the camera's
eye e to a point p is clear when it keeps more than r from every centre line (eq. V1):

    min over links k of  dist([e, p], [c_k, c_k+1]) > r.

Units: mm.
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.kinematics.laser import beam, plane_hit
from lasercal.solver.kinematics.model import RobotModel

ARM_RADIUS_MM = 70.0  # a Panda's links are 110-130 mm thick: half that and 10 mm to spare


def arm_axes(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """The arm's centre line at configurations q (m, n) rad: (m, n + 2, 3) mm, the base origin, a point on
    each joint's axis, the laser's aperture."""
    S = np.asarray(model.screws, dtype=float)
    pts = [np.zeros(3)]
    for w, v in zip(S[:, :3], S[:, 3:]):
        r = np.cross(w, v)  # the axis's point nearest the origin (|w| = 1)
        pts.append(r + w * np.dot(pts[-1] - r, w))
    b = beam(S, model.laser_dir, model.aperture, q)
    T = b.chain[:, : len(S)]  # joint k's point moves with the joints before it (it lies on its own axis)
    P = np.asarray(pts[1:])
    placed = np.einsum("mkab,kb->mka", T[..., :3, :3], P) + T[..., :3, 3]
    base = np.zeros((len(b.aperture), 1, 3))
    return np.concatenate([base, placed, b.aperture[:, None, :]], axis=1)


def segment_distance(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """The distance between segments [a0, a1] and [b0, b1], arrays (..., 3) broadcast together, mm: the
    closest points' parameters clamped to [0, 1] (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, f = (d1 * d1).sum(-1), (d2 * d2).sum(-1), (d2 * r).sum(-1)
    c, b = (d1 * r).sum(-1), (d1 * d2).sum(-1)
    denom = a * e - b * b
    s = np.where(denom > 1e-12, np.clip((b * f - c * e) / np.maximum(denom, 1e-12), 0.0, 1.0), 0.0)
    t = (b * s + f) / np.maximum(e, 1e-12)
    t_clipped = np.clip(t, 0.0, 1.0)
    s = np.where(t != t_clipped, np.clip((b * t_clipped - c) / np.maximum(a, 1e-12), 0.0, 1.0), s)
    gap = (a0 + d1 * s[..., None]) - (b0 + d2 * t_clipped[..., None])
    return np.sqrt((gap * gap).sum(-1))


def sight_clear(axes: np.ndarray, eye: np.ndarray, points: np.ndarray, radius: float = ARM_RADIUS_MM):
    """Eq. V1: whether the eye (3,) mm sees each of ``points`` (m, k, 3) mm past the arm ``axes``
    (m, n + 2, 3): (m, k) bool."""
    eye = np.asarray(eye, dtype=float)
    a0, a1 = axes[:, None, :-1, :], axes[:, None, 1:, :]  # (m, 1, links, 3)
    p = np.asarray(points, dtype=float)[:, :, None, :]  # (m, k, 1, 3)
    return (segment_distance(np.broadcast_to(eye, p.shape), p, a0, a1) > radius).all(-1)


def camera_sees(
    model: RobotModel,
    q: np.ndarray,
    z,
    eye: np.ndarray,
    markers: np.ndarray,
    need: int,
    radius: float = ARM_RADIUS_MM,
) -> np.ndarray:
    """Whether a camera at ``eye`` (3,) mm measures the spot of each configuration q (m, n) rad on the plane
    of height z mm (a float or (m,)): the spot in clear sight (eq. V1), at least ``need`` of the ``markers``
    in clear sight too, and the spot inside the hull of their centres. ``markers``: (k, 3) mm, base frame,
    their centres, or (k, c, 3) their corners: a marker is in sight when every corner is (one the arm hides
    in part is not found in the photo). Returns (m,) bool."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    axes = arm_axes(model, q)
    b = beam(np.asarray(model.screws, dtype=float), model.laser_dir, model.aperture, q)
    spot, _ = plane_hit(b.aperture, b.direction, z)
    seen = sight_clear(axes, eye, spot[:, None, :], radius)[:, 0]
    corners = np.asarray(markers, dtype=float).reshape(len(markers), -1, 3)  # (k, c, 3)
    marks = np.broadcast_to(corners.reshape(-1, 3), (len(q), corners.shape[0] * corners.shape[1], 3))
    shown = sight_clear(axes, eye, marks, radius).reshape(len(q), *corners.shape[:2]).all(-1)  # (m, k)
    centres = corners.mean(axis=1)[:, :2]
    return seen & (shown.sum(1) >= need) & inside_shown(spot[:, :2], centres, shown)


def inside_shown(spots: np.ndarray, markers: np.ndarray, shown: np.ndarray) -> np.ndarray:
    """Whether each spot (m, 2) mm lies inside the convex hull of the markers (k, 2) mm its photo shows
    (``shown`` (m, k) bool): a photo maps only that area to mm without extrapolating. (m,) bool."""
    from scipy.spatial import Delaunay, QhullError

    out = np.zeros(len(spots), bool)
    for pattern in np.unique(shown, axis=0):
        rows = (shown == pattern).all(1)
        if pattern.sum() < 3:
            continue
        try:
            out[rows] = Delaunay(markers[pattern]).find_simplex(spots[rows]) >= 0
        except QhullError:  # the markers shown lie on a line: no area
            continue
    return out
