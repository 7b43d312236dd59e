"""Full end-effector pose from a target on the turning last joint (circle-point analysis).

Nguyen, Zhou and Kang, "A new full pose measurement method for robot calibration",
Sensors 13 (2013) 9132-9147, Sections 2-3. Lock every joint but the last, turn it
through m >= 3 angles, measure the target's positions P_1..P_m with a 3-D point sensor
(frame {S}); the points lie on a circle about the last joint's axis. Fitting a plane
(Section 2.1) and a circle on it (Section 2.2) gives the axis direction and the centre
O, from which the frame {E} is built (Section 2.3):

    z_E = n (unit normal of the rotation plane),  x_E = O->P_1 / |O->P_1|,
    y_E = z_E x x_E,  ^S T_E = [x_E y_E z_E p_1; 0 0 0 1].

Our copy of the paper has its displayed equations only as images, so the forms below
are reconstructed from the text around them, and named by that text:

* eq. (1): the plane z = E x + F y + G; eq. (2): min sum (E x_i + F y_i + G - z_i)^2;
  eqs. (3)-(6): its solution through the point covariances (centred normal equations).
* eq. (7): a circle (u - u0)^2 + (v - v0)^2 = r^2 on the plane; eq. (8): the same as
  u^2 + v^2 + A u + B v + C = 0, linear in A, B, C; eqs. (9)-(10): its least squares
  (the algebraic, Kasa, circle fit), centre (-A/2, -B/2), r^2 = (A^2 + B^2)/4 - C.
* Section 3, eqs. (14)-(17): mean and standard deviation of the position errors and of
  the x-y-z Euler angle errors between {E} (measured) and {E'} (forward kinematics).

Two ambiguities of the paper are settled here openly:

* The sign of n: the paper leaves it open. We orient z_E so that the target advances
  positively about z_E when the joint angle increases (``sense=+1``), i.e. z_E is the
  joint's own axis direction omega_N, as in the POE model.
* O->P_1 is not exactly normal to n with noisy points, so x_E as printed would not be
  orthogonal to z_E; we use the component of O->P_1 in the plane. The origin is the
  measured P_1 itself, as the paper writes (not its projection on the circle).

Shapes: ``points`` is (..., m, 3) in mm; every function is vectorised over the leading
axes (one entry per robot configuration).
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import CirclePointError

_COLLINEAR = 1e-6  # twice the largest triangle area below this fraction of d_max^2: collinear points


def _check(points: np.ndarray) -> np.ndarray:
    """Validate (..., m, 3) finite points with m >= 3; returns them as float."""
    p = np.asarray(points, dtype=float)
    if p.ndim < 2 or p.shape[-1] != 3:
        raise CirclePointError(f"points must be shaped (..., m, 3), got {p.shape}")
    if p.shape[-2] < 3:
        raise CirclePointError(
            f"a rotation plane and circle need at least 3 points per configuration, got {p.shape[-2]}"
        )
    if not np.all(np.isfinite(p)):
        raise CirclePointError("points contain NaN or infinite coordinates")
    return p


def _triangles(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All index triples (C, 3) and twice their triangle areas (..., C)."""
    tri = np.array(list(combinations(range(p.shape[-2]), 3)))
    a, b, c = p[..., tri[:, 0], :], p[..., tri[:, 1], :], p[..., tri[:, 2], :]
    return tri, np.linalg.norm(np.cross(b - a, c - a), axis=-1)


def collinear(points: np.ndarray) -> np.ndarray:
    """Which configurations' points are coincident or (nearly) collinear.

    Twice their largest triangle area is below 1e-6 d_max^2 (d_max: their largest
    distance), i.e. they sag less than about 1e-6 d_max off a line: such points do not
    define a rotation plane.

    Parameters
    ----------
    points : (..., m, 3) array, mm

    Returns
    -------
    (...,) bool array
    """
    p = _check(points)
    _, area2 = _triangles(p)
    d2 = np.max(np.sum((p[..., :, None, :] - p[..., None, :, :]) ** 2, axis=-1), axis=(-2, -1))
    return area2.max(axis=-1) <= _COLLINEAR * d2


def farthest_triple(points: np.ndarray) -> np.ndarray:
    """The three points spanning the largest triangle (Section 2.1, "the farthest three points").

    The paper picks P1, P3, P6 of six points on a 100-degree arc without defining
    "farthest"; the largest triangle is well defined for any m and picks P1, P6 and P3
    or its mirror image P4 (equal areas up to round-off) there.

    Parameters
    ----------
    points : (..., m, 3) array, mm

    Returns
    -------
    (..., 3) int array, indices i < j < k

    Raises
    ------
    CirclePointError
        on fewer than 3 points, coincident or collinear points
    """
    p = _check(points)
    bad = np.atleast_1d(collinear(p))
    if np.any(bad):
        where = np.flatnonzero(bad).tolist()
        which = (
            f" (configuration(s) {where[:10]}{'...' if len(where) > 10 else ''}, 0-based)"
            if p.ndim > 2
            else ""
        )
        raise CirclePointError(
            f"points are coincident or collinear{which}: they do not span a rotation plane"
        )
    tri, area2 = _triangles(p)
    return tri[np.argmax(area2, axis=-1)]


def plane_frame(points: np.ndarray) -> np.ndarray:
    """The auxiliary frame O1x1y1z1 of Section 2.1, built from the three farthest points.

    z1 is the normal of the plane psi through the triple (P_i, P_j, P_k), x1 = P_k->P_i
    (P6->P1 in the paper), y1 = z1 x x1; the origin, which the paper leaves free, is the
    triple's centroid (keeps the fit's numbers small).

    Parameters
    ----------
    points : (..., m, 3) array, mm

    Returns
    -------
    (..., 4, 4) array, ^S T_1
    """
    p = _check(points)
    idx = farthest_triple(p)
    a, b, c = (np.take_along_axis(p, idx[..., k, None, None], -2)[..., 0, :] for k in range(3))
    x = a - c
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    z = np.cross(b - a, c - a)
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    T = np.zeros(p.shape[:-2] + (4, 4))
    T[..., :3, 0], T[..., :3, 1], T[..., :3, 2] = x, np.cross(z, x), z
    T[..., :3, 3] = (a + b + c) / 3
    T[..., 3, 3] = 1.0
    return T


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation plane, fitted in the frame O1x1y1z1 and moved back to {S} (eqs. 1-6).

    In O1x1y1z1 the points lie close to the x1y1-plane, so the fit z = E x + F y + G
    (eq. 1), which minimises errors along z only (eq. 2), has no systematic error from a
    steep plane. E, F solve the centred normal equations of eq. (3)
    [[Sxx, Sxy], [Sxy, Syy]] (E, F) = (Sxz, Syz) with the covariances of eqs. (4)-(6),
    and G = mean(z) - E mean(x) - F mean(y).

    Parameters
    ----------
    points : (..., m, 3) array, mm, in {S}

    Returns
    -------
    normal : (..., 3) array, unit normal in {S} (sign: +z1 side; see :func:`circle_point_pose`)
    origin : (..., 3) array, a point of the plane in {S} (where the z1 axis meets it), mm
    """
    p = _check(points)
    T1 = plane_frame(p)
    R1, o1 = T1[..., :3, :3], T1[..., :3, 3]
    loc = np.einsum("...ji,...mj->...mi", R1, p - o1[..., None, :])  # R1^T (p - o1)
    d = loc - loc.mean(axis=-2, keepdims=True)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    S = np.stack(
        [np.stack([(x * x).sum(-1), (x * y).sum(-1)], -1), np.stack([(x * y).sum(-1), (y * y).sum(-1)], -1)],
        -2,
    )
    E, F = np.moveaxis(
        np.linalg.solve(S, np.stack([(x * z).sum(-1), (y * z).sum(-1)], -1)[..., None])[..., 0], -1, 0
    )
    mean = loc.mean(axis=-2)
    G = mean[..., 2] - E * mean[..., 0] - F * mean[..., 1]
    n1 = np.stack([-E, -F, np.ones_like(E)], -1)
    n1 /= np.linalg.norm(n1, axis=-1, keepdims=True)
    normal = np.einsum("...ij,...j->...i", R1, n1)
    origin = o1 + R1[..., :, 2] * G[..., None]
    return normal, origin


def _plane_basis(normal: np.ndarray) -> np.ndarray:
    """(..., 3, 2) orthonormal in-plane axes e1, e2 (e1 from the least aligned base axis)."""
    k = np.argmin(np.abs(normal), axis=-1)
    seed = np.eye(3)[k]
    e1 = seed - np.sum(seed * normal, -1, keepdims=True) * normal
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    return np.stack([e1, np.cross(normal, e1)], -1)


def fit_circle(points: np.ndarray, normal: np.ndarray, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares circle on the fitted plane: centre and radius (eqs. 7-10).

    The points are projected onto the plane and written in an orthonormal in-plane basis
    (u, v); eq. (8) u^2 + v^2 + A u + B v + C = 0 is then linear in (A, B, C) and solved
    in the least-squares sense (eqs. 9-10).

    Parameters
    ----------
    points : (..., m, 3) array, mm
    normal, origin : (..., 3) arrays, the plane from :func:`fit_plane`

    Returns
    -------
    centre : (..., 3) array, the rotation centre O in {S}, mm
    radius : (...,) array, mm
    """
    p = _check(points)
    normal, origin = np.asarray(normal, dtype=float), np.asarray(origin, dtype=float)
    if normal.shape != p.shape[:-2] + (3,) or origin.shape != normal.shape:
        raise CirclePointError(
            f"normal {normal.shape} and origin {origin.shape} must be {p.shape[:-2] + (3,)}, one per "
            "configuration"
        )
    B = _plane_basis(normal)
    uv = np.einsum("...ji,...mj->...mi", B, p - origin[..., None, :])  # (..., m, 2)
    c0 = uv.mean(axis=-2, keepdims=True)  # centred, so that the 3x3 system is well conditioned
    w = uv - c0
    design = np.concatenate([w, np.ones(w.shape[:-1] + (1,))], -1)
    rhs = -np.sum(w * w, -1)
    sol = np.linalg.solve(
        np.swapaxes(design, -1, -2) @ design, np.einsum("...mi,...m->...i", design, rhs)[..., None]
    )[..., 0]
    A, Bc, C = sol[..., 0], sol[..., 1], sol[..., 2]
    centre_uv = np.stack([-A / 2, -Bc / 2], -1) + c0[..., 0, :]
    radius = np.sqrt(np.maximum((A * A + Bc * Bc) / 4 - C, 0.0))
    centre = origin + np.einsum("...ij,...j->...i", B, centre_uv)
    return centre, radius


def circle_point_pose(points: np.ndarray, sense: np.ndarray | float = 1.0) -> np.ndarray:
    """The full pose ^S T_E of the end-effector from its target's circle (Section 2.3).

    Parameters
    ----------
    points : (..., m, 3) array, mm: P_1..P_m in the order the joint visited them; P_1 is
        the pose's configuration
    sense : float or (...,) array, +1 if the joint angle increases from P_1 to P_m, -1 if it
        decreases; z_E is then the joint's axis direction (consecutive steps must be
        below 180 degrees so that their sense can be read from the points)

    Returns
    -------
    (..., 4, 4) array, ^S T_E = [x_E y_E z_E p_1; 0 0 0 1]
    """
    p = _check(points)
    n, o = fit_plane(p)
    centre, _ = fit_circle(p, n, o)
    r = p - centre[..., None, :]
    turn = np.sum(np.cross(r[..., :-1, :], r[..., 1:, :]) @ n[..., :, None], axis=(-2, -1))
    n = n * (np.sign(turn) * np.sign(np.asarray(sense, dtype=float)))[..., None]
    x = r[..., 0, :] - np.sum(r[..., 0, :] * n, -1, keepdims=True) * n
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    T = np.zeros(p.shape[:-2] + (4, 4))
    T[..., :3, 0], T[..., :3, 1], T[..., :3, 2] = x, np.cross(n, x), n
    T[..., :3, 3] = p[..., 0, :]
    T[..., 3, 3] = 1.0
    return T


def target_frame(screw: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The frame {E} that the method measures, for a target at ``target`` turning about ``screw``.

    Noise-free, :func:`circle_point_pose` returns exactly this frame: origin at the
    target, z along the joint axis omega, x from the axis foot to the target.

    Parameters
    ----------
    screw : (6,) array, the last joint's screw (unit omega, v), mm
    target : (3,) array, the target at the same configuration, mm

    Returns
    -------
    (4, 4) array
    """
    S, p = np.asarray(screw, dtype=float), np.asarray(target, dtype=float)
    w = S[:3]
    on_axis = np.cross(w, S[3:])  # the axis point closest to the origin (v = -w x q)
    r = p - on_axis - ((p - on_axis) @ w) * w
    if np.linalg.norm(r) < 1e-9:
        raise CirclePointError("the target lies on the joint axis: it does not move on a circle")
    x = r / np.linalg.norm(r)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(w, x), w, p
    return T


def frame_errors(T: np.ndarray, T_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position and x-y-z Euler angle errors of frames T against reference frames T_ref (Section 3).

    Position error: p - p_ref in the reference's base frame ({S}), mm. Orientation error:
    the Euler angles (x, y, z, extrinsic: R = Rz Ry Rx) of R_ref^T R, the rotation from
    {E'} to {E} about the reference frame's own axes, in rad. The paper does not say
    which frame its Euler angles are about nor whether it subtracts the frames' angles;
    for the small errors here the angles of the relative rotation are well defined
    near any pose (no gimbal lock of the absolute angles).

    Parameters
    ----------
    T, T_ref : (m, 4, 4) arrays

    Returns
    -------
    dp : (m, 3) array, mm
    deul : (m, 3) array, rad
    """
    T, T_ref = np.asarray(T, dtype=float), np.asarray(T_ref, dtype=float)
    if T.shape != T_ref.shape:
        raise CirclePointError(
            f"{T.shape[0] if T.ndim == 3 else T.shape} measured frames but "
            f"{T_ref.shape[0] if T_ref.ndim == 3 else T_ref.shape} reference frames"
        )
    dR = np.swapaxes(T_ref[..., :3, :3], -1, -2) @ T[..., :3, :3]
    deul = Rotation.from_matrix(dR.reshape(-1, 3, 3)).as_euler("xyz").reshape(T.shape[:-2] + (3,))
    return T[..., :3, 3] - T_ref[..., :3, 3], deul


def error_statistics(T: np.ndarray, T_ref: np.ndarray) -> dict:
    """Tables 1-2 of the paper: signed mean and standard deviation per axis (eqs. 14-17).

    Returns
    -------
    dict with 'position_mean', 'position_std' (3,) mm and 'euler_mean', 'euler_std' (3,)
    deg; standard deviations with the n - 1 denominator.
    """
    dp, de = frame_errors(T, T_ref)
    de = np.degrees(de)
    return {
        "position_mean": dp.mean(0),
        "position_std": dp.std(0, ddof=1),
        "euler_mean": de.mean(0),
        "euler_std": de.std(0, ddof=1),
    }
