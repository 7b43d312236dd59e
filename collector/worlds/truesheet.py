"""The fake world's sheet of paper: where a printed point truly is, and where a beam truly meets the paper.

The world's own model of a printed sheet laid on a table (not the fit's eqs. S1, S3). A point printed at
(u, v) mm of the layout (the sheet's frame: what the printer was asked to draw) lies on the paper at

    (a, b) = (s_x u + g s_y v,  s_y v)                                              (eq. W1)

-- the printer's scale along each axis and its skew g (the paper fed a little askew: a rectangle printed
as a parallelogram). The paper lies on a table plane through the placement's centre (x, y, z + dz),
rising k_x, k_y per mm along the sheet's axes; its axes e_1 (the sheet's x, turned by the placement's yaw)
and e_2 are orthonormal in that plane, n its normal. A taped sheet is not flat: it bulges off the table by

    h(b) = A cos^2(pi b / (2 W))   (|b| <= W; 0 beyond)                              (eq. W2)

along its y axis (W half the paper's length that way), highest along its middle, flat at its taped ends.
The paper's point is then c + a e_1 + b e_2 + h(b) n (eq. W3): bending a sheet by tenths of a mm shortens
its span by (h/W)^2 W, micrometres, which the model leaves out. A beam a0 + s d meets the paper where
eq. W3 holds: the plane lifted by h, iterated (h changes by its slope, mrad, over the beam's move).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PaperSheet:
    """A printed sheet as it truly lies (eqs. W1-W3), in the true robot's base frame.

    Attributes
    ----------
    centre : (3,) array, where the layout's origin would lie on the flat table, mm
    yaw : float, the sheet's x axis from the base x axis, about +z, rad
    scale : (2,) array, the printer's scale along the sheet's x and y axes (1: exact)
    skew : float, the printer's skew g (eq. W1), mm per mm
    slope : (2,) array, the table's rise per mm along the sheet's x and y axes
    bulge : float, the paper's height A above the table along its middle (eq. W2), mm
    half_length : float, W: half the paper's length along its y axis, mm
    """

    centre: np.ndarray
    yaw: float = 0.0
    scale: np.ndarray = (1.0, 1.0)
    skew: float = 0.0
    slope: np.ndarray = (0.0, 0.0)
    bulge: float = 0.0
    half_length: float = 148.5

    @property
    def axes(self) -> np.ndarray:
        """(3, 3) rows e_1, e_2, n: the paper's axes on the table and the table's normal (unit vectors)."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        kx, ky = self.slope
        x = np.array([c, s, 0.0])
        y = np.array([-s, c, 0.0])
        n = np.array([0.0, 0.0, 1.0]) - kx * x - ky * y  # the plane z = kx x' + ky y' (sheet axes x', y')
        n /= np.linalg.norm(n)
        e1 = x - (x @ n) * n
        e1 /= np.linalg.norm(e1)
        return np.array([e1, np.cross(n, e1), n])

    def on_paper(self, uv: np.ndarray) -> np.ndarray:
        """The printed points (k, 2) mm on the paper, (a, b) (k, 2) mm (eq. W1)."""
        uv = np.atleast_2d(np.asarray(uv, dtype=float))[:, :2]
        sx, sy = self.scale
        return np.column_stack([sx * uv[:, 0] + self.skew * sy * uv[:, 1], sy * uv[:, 1]])

    def printed(self, ab: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`on_paper`: paper (a, b) (k, 2) mm to the layout's (u, v) (k, 2) mm."""
        ab = np.atleast_2d(ab)
        v = ab[:, 1] / self.scale[1]
        return np.column_stack([(ab[:, 0] - self.skew * ab[:, 1]) / self.scale[0], v])

    def height(self, b: np.ndarray) -> np.ndarray:
        """h(b) (eq. W2), mm, and its slope dh/db, for paper coordinates b (k,) mm."""
        b = np.asarray(b, dtype=float)
        inside = np.abs(b) <= self.half_length
        phase = np.pi * b / (2 * self.half_length)
        h = np.where(inside, self.bulge * np.cos(phase) ** 2, 0.0)
        dh = np.where(inside, -self.bulge * np.pi / (2 * self.half_length) * np.sin(2 * phase), 0.0)
        return h, dh

    def surface(self, uv: np.ndarray) -> np.ndarray:
        """Where printed points (k, 2) mm truly are, (k, 3) mm in the base frame (eq. W3)."""
        ab = self.on_paper(uv)
        e1, e2, n = self.axes
        h, _ = self.height(ab[:, 1])
        return np.asarray(self.centre, dtype=float) + ab[:, :1] * e1 + ab[:, 1:] * e2 + h[:, None] * n

    def normal(self, uv: np.ndarray) -> np.ndarray:
        """The paper's unit normal (k, 3) at printed points (k, 2) mm."""
        ab = self.on_paper(uv)
        e1, e2, n = self.axes
        _, dh = self.height(ab[:, 1])
        out = n[None] - dh[:, None] * e2[None]
        return out / np.linalg.norm(out, axis=1, keepdims=True)

    def hit(self, origin: np.ndarray, direction: np.ndarray, iterations: int = 30):
        """Where rays origin + s direction (k, 3) meet the paper: printed (u, v) (k, 2) mm, the points (k, 3)
        mm and s (k,) (the distance along a unit direction; NaN when a ray runs parallel to the table)."""
        o = np.atleast_2d(np.asarray(origin, dtype=float))
        d = np.atleast_2d(np.asarray(direction, dtype=float))
        o, d = np.broadcast_arrays(o, d)
        e1, e2, n = self.axes
        c = np.asarray(self.centre, dtype=float)
        across = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            h = np.zeros(len(o))
            for _ in range(iterations):  # the plane lifted by h; h moves by its slope (mrad) per pass
                s = ((c - o) @ n + h) / across
                p = o + s[:, None] * d
                b = (p - c) @ e2
                h_new, _ = self.height(b)
                if np.all(np.abs(h_new - h) < 1e-12):
                    h = h_new
                    break
                h = h_new
            s = ((c - o) @ n + h) / across
        p = o + s[:, None] * d
        ab = np.column_stack([(p - c) @ e1, (p - c) @ e2])
        return self.printed(ab), p, s

    def tangents(self, uv: np.ndarray) -> np.ndarray:
        """d surface / d(u, v) (k, 3, 2) at printed points (k, 2) mm: how a printed mm moves in space."""
        ab = self.on_paper(uv)
        e1, e2, n = self.axes
        _, dh = self.height(ab[:, 1])
        sx, sy = self.scale
        db = e2[None] + dh[:, None] * n[None]  # d point / d b, (k, 3)
        du = np.broadcast_to(sx * e1, db.shape)
        dv = self.skew * sy * e1[None] + sy * db
        return np.stack([du, dv], axis=2)
