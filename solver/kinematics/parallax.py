"""Eq. S8: where a camera that maps the paper through its markers' homography sees a spot on paper that is
not flat (the parallax of a curled sheet), from where the camera stands.

Units: mm; the curvatures k = (kxx, kxy, kyy) in 1/mm (eq. S6 of :mod:`solver.kinematics.sheet`).

A point of the paper raised by h above the sheet's plane lies, seen from the camera's centre E (the
layout's frame, z above the plane; eq. V2 of :func:`vision.plane.camera_eye`), where the ray meets the plane:

    s + d(s),   d(s) = h(s) (s - E_xy) / (E_z - h(s))  ~  h(s) (s - E_xy) / E_z

The photo is mapped to the sheet by the homography fitted to the markers' corners, which are raised too: it
takes up the part of d that a homography can (a plane's parallax is one: the sheet's tilt and the affine
part of h vanish), so the photo reads

    m = s + d(s) - G(s) theta,   theta = argmin sum over the corners c |d(c) - G(c) theta|^2          (eq. S8)

G the first-order fields of a homography near the identity (:func:`homography_fields`). Linear in k, so a
fit carries it as rows on the curl's terms. The approximation drops h / E_z (2 mm of curl seen from 600 mm:
0.3 % of a field of ~0.4 mm) and the homography's second order (~1e-3 of the field).
"""

from __future__ import annotations

import numpy as np


def curl_basis(uv: np.ndarray) -> np.ndarray:
    """Eq. S6's height field's basis (m, 3) at layout points uv (m, 2) mm: h = basis @ (kxx, kxy, kyy)."""
    uv = np.asarray(uv, dtype=float)
    return np.column_stack([0.5 * uv[:, 0] ** 2, uv[:, 0] * uv[:, 1], 0.5 * uv[:, 1] ** 2])


def relative_height_basis(uv: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """The basis (m, 3) of eq. S6's height over the plane through the ``anchors`` (k, 2) mm, k >= 3: its
    basis at uv (m, 2) mm less its affine least-squares fit there (eq. S7's free field is built on it)."""
    anchors = np.asarray(anchors, dtype=float)
    A = np.column_stack([np.ones(len(anchors)), anchors])
    coef = np.linalg.lstsq(A, curl_basis(anchors), rcond=None)[0]  # (3, 3): the affine part at the anchors
    return curl_basis(uv) - np.column_stack([np.ones(len(uv)), uv]) @ coef


def homography_fields(p: np.ndarray) -> np.ndarray:
    """The first-order displacement fields (k, 2, 8) at points p (k, 2) mm of a homography near the identity:
    d = [a1 + a2 x + a3 y - x (g1 x + g2 y), b1 + b2 x + b3 y - y (g1 x + g2 y)], per (a1..a3, b1..b3, g1,
    g2). A plane's parallax is one of them (eq. S8 with h affine), so a homography fitted to the markers
    takes up the tilt and the part of a curl's view that looks like one."""
    p = np.asarray(p, dtype=float)
    one, x, y = np.ones(len(p)), p[:, 0], p[:, 1]
    F = np.zeros((len(p), 2, 8))
    F[:, 0, :3] = np.column_stack([one, x, y])
    F[:, 1, 3:6] = np.column_stack([one, x, y])
    F[:, :, 6] = -p * x[:, None]
    F[:, :, 7] = -p * y[:, None]
    return F


def view_rows(uv: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """Eq. S8's raw rows (m, 2, 3): h(s) (s - E_xy) / E_z per (kxx, kxy, kyy), h eq. S6's height at layout
    points uv (m, 2) mm over the sheet's plane, seen from ``eye`` (m, 3) mm."""
    eye = np.asarray(eye, dtype=float)
    lever = (np.asarray(uv, dtype=float) - eye[:, :2]) / eye[:, 2:3]  # (s - E_xy) / E_z
    return lever[:, :, None] * curl_basis(uv)[:, None, :]


def parallax_rows(uv: np.ndarray, eye: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Eq. S8's rows (m, 2, 3): d(m - s)/d(kxx, kxy, kyy), mm per (1/mm), at layout points uv (m, 2) mm seen
    from ``eye`` (m, 3) mm (each capture's camera, layout frame, z above the sheet), through a homography
    fitted to the markers' ``corners`` (c, 2) mm, c >= 4: each photo's view of the curl (:func:`view_rows`)
    less the homography that best matches that view at the corners (least squares, :func:`homography_fields`).
    """
    eye = np.asarray(eye, dtype=float)
    corners = np.asarray(corners, dtype=float)
    Fc = homography_fields(corners).reshape(-1, 8)  # (2c, 8)
    at_corners = view_rows(
        np.broadcast_to(corners, (len(eye), *corners.shape)).reshape(-1, 2),
        np.repeat(eye, len(corners), axis=0),
    )
    at_corners = at_corners.reshape(len(eye), 2 * len(corners), 3)  # each photo's view at the corners
    taken = np.einsum("kc,mcj->mkj", np.linalg.pinv(Fc), at_corners)  # (m, 8, 3): the homography's share
    return view_rows(uv, eye) - np.einsum("mik,mkj->mij", homography_fields(uv), taken)


def unparallaxed(xy: np.ndarray, eye: np.ndarray, k: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Where on the paper the spot is whose photo reads ``xy`` (2,) mm, layout frame: eq. S8 inverted by
    fixed-point iteration (the field changes by ~1e-2 of a step per mm: each step gains two digits)."""
    xy, eye, k = (np.asarray(a, dtype=float) for a in (xy, eye, k))
    s = xy.copy()
    for _ in range(20):
        s, last = xy - parallax_rows(s[None], eye[None], corners)[0] @ k, s
        if np.abs(s - last).max() < 1e-12:
            break
    return s
